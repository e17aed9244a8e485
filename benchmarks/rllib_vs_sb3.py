"""PPO training throughput: Ray RLlib (train.py --backend rllib) against SB3 (train.py).

    python benchmarks/rllib_vs_sb3.py                              # sousa_asv, short runs
    python benchmarks/rllib_vs_sb3.py --scenario gao_sea --rllib-runners 0,1,2 --json

In one process, on the same scenario, machine and PPO settings (``--batch`` env
steps per update, ``--epochs`` passes over it in minibatches of ``--minibatch``,
a ``--net`` tanh MLP for policy and value, one torch thread for the learner),
trains for ``--iterations`` timed updates after one untimed warm-up update and
prints environment steps per second (environment cycles: one step of one
environment, whatever its number of beacons; agent steps are that times the
beacons), wall time of training included:

* SB3: ``CoopNavVecEnv`` (one batched simulator, ``--sb3-envs`` environments, every
  beacon a row) + VecMonitor + VecNormalize, as train.py trains;
* RLlib, new API stack, for each of ``--rllib-runners`` (0: the driver samples; k:
  k env runner processes, each stepping ``--envs-per-runner`` copies of the PettingZoo
  env through ``coopnav_env.rllib_env.CoopNavRLlibEnv``) on a small local Ray
  instance; the learner in the driver (``num_learners=0``), one module per beacon kind,
  the MeanStdFilter as configs/rllib; the build time (Ray workers starting) is reported
  apart and not in the rate.

The environment's own reward is used by both (the training-reward terms cost the
same in both). Numbers depend on the machine and its load; see the README's
"Training on Ray RLlib" for the measured figures and what they mean.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
import warnings
from collections.abc import Sequence

try:
    from benchmarks import _args
except ImportError:  # run as a script: its own folder is on the path, not the checkout
    import _args  # type: ignore[no-redef]

os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    p = _args.Parser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scenario", default="sousa_asv")
    p.add_argument("--batch", type=int, default=8192, help="env steps per PPO update (both)")
    p.add_argument("--minibatch", type=int, default=1024)
    p.add_argument("--epochs", type=int, default=10)
    p.add_argument("--net", default="64,64", help="hidden layer sizes")
    p.add_argument("--iterations", type=int, default=2, help="timed updates after the warm-up one")
    p.add_argument("--sb3-envs", type=int, default=64, help="environments in SB3's batched VecEnv")
    p.add_argument("--rllib-runners", default="0,2", help="comma-separated num_env_runners values to measure")
    p.add_argument("--envs-per-runner", type=int, default=16, help="num_envs_per_env_runner (vectorized copies)")
    p.add_argument("--skip-sb3", action="store_true")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    args = p.parse_args(argv)
    for name in ("batch", "minibatch", "epochs", "iterations", "sb3_envs", "envs_per_runner"):
        if getattr(args, name) < 1:
            p.error(f"--{name.replace('_', '-')} must be at least 1, got {getattr(args, name)}")
    _args.int_list(p, args.net, "--net")  # the hidden layers: checked before either library is timed
    try:
        runners = [int(r) for r in args.rllib_runners.split(",") if r.strip()]
        if any(r < 0 for r in runners):
            raise ValueError
    except ValueError:
        p.error(f"--rllib-runners: whole numbers >= 0 separated by commas, got {args.rllib_runners!r}")
    from coopnav_env import list_scenarios

    if args.scenario not in list_scenarios():
        from coopnav_env.names import did_you_mean

        p.error(f"--scenario: no scenario {args.scenario!r}{did_you_mean(args.scenario, list_scenarios())}")
    return args


def sb3_rate(args: argparse.Namespace, n_beacons: int) -> dict:
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    from coopnav_env.vector import CoopNavVecEnv

    torch.set_num_threads(1)
    n_steps = max(args.batch // args.sb3_envs, 1)
    venv = VecNormalize(
        VecMonitor(CoopNavVecEnv(args.scenario, n_envs=args.sb3_envs, seed=0, step_infos=False)), gamma=0.99
    )
    rows = n_steps * args.sb3_envs * n_beacons  # SB3 counts rows (beacon steps)
    model = PPO(
        "MlpPolicy",
        venv,
        n_steps=n_steps,
        batch_size=min(args.minibatch * n_beacons, rows),
        n_epochs=args.epochs,
        policy_kwargs={"net_arch": [int(h) for h in args.net.split(",")], "activation_fn": torch.nn.Tanh},
        seed=0,
        device="cpu",
        verbose=0,
    )
    model.learn(rows)  # warm-up update
    t = time.perf_counter()
    model.learn(rows * args.iterations, reset_num_timesteps=False)
    wall = time.perf_counter() - t
    env_steps = n_steps * args.sb3_envs * args.iterations
    return {
        "backend": "sb3",
        "config": f"CoopNavVecEnv x{args.sb3_envs}",
        "env_steps": env_steps,
        "wall_s": round(wall, 2),
        "env_steps_per_s": round(env_steps / wall, 1),
        "agent_steps_per_s": round(env_steps * n_beacons / wall, 1),
        "build_s": None,
    }


def rllib_rate(args: argparse.Namespace, runners: int, n_beacons: int) -> dict:
    import torch

    from agents.training import rllib as trainer
    from agents.training.config import RLlibConfig, from_dict

    torch.set_num_threads(1)
    hp = {
        "ppo": {
            "lr": 3e-4,
            "gamma": 0.99,
            "lambda_": 0.95,
            "clip_param": 0.2,
            "vf_loss_coeff": 0.5,
            "grad_clip": 0.5,
            "train_batch_size_per_learner": args.batch,
            "minibatch_size": args.minibatch,
            "num_epochs": args.epochs,
        },
        "model": {
            "fcnet_hiddens": [int(h) for h in args.net.split(",")],
            "fcnet_activation": "tanh",
            "vf_share_layers": False,
        },
        "normalize_obs": True,
        "env_runners": {
            "num_env_runners": runners,
            "num_envs_per_env_runner": args.envs_per_runner,
            "num_cpus_per_env_runner": 1,
            "rollout_fragment_length": "auto",
        },
        "learners": {"num_learners": 0},
        "env": {"overrides": {}},
        "reward": {},
    }
    config, _ = trainer.build_config(from_dict(RLlibConfig, {**hp, "scenario": args.scenario, "seed": 0}))
    t = time.perf_counter()
    algo = config.build_algo()
    build = time.perf_counter() - t
    try:
        first = trainer.metrics(algo.train())  # warm-up update
        t = time.perf_counter()
        for _ in range(args.iterations):
            last = trainer.metrics(algo.train())
        wall = time.perf_counter() - t
    finally:
        algo.stop()
    env_steps = last["env_steps"] - first["env_steps"]
    label = "driver samples" if runners == 0 else f"{runners} env runner(s)"
    return {
        "backend": "rllib",
        "config": f"{label} x{args.envs_per_runner} env(s)",
        "env_steps": env_steps,
        "wall_s": round(wall, 2),
        "env_steps_per_s": round(env_steps / wall, 1),
        "agent_steps_per_s": round(env_steps * n_beacons / wall, 1),
        "build_s": round(build, 1),
    }


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    warnings.filterwarnings("ignore")
    from coopnav_env import make_config

    config = make_config(args.scenario)
    n_beacons = config.n_beacons
    runner_counts = [int(r) for r in args.rllib_runners.split(",") if r.strip()]
    rows = []
    if not args.skip_sb3:
        rows.append(sb3_rate(args, n_beacons))
    if runner_counts:
        import ray

        needed = max(runner_counts) + 1
        cores = os.cpu_count() or 1
        ray.init(
            num_cpus=max(cores, needed),
            include_dashboard=False,
            log_to_driver=False,
            object_store_memory=200 * 2**20,
            runtime_env={"env_vars": {"RAY_USAGE_STATS_ENABLED": "0"}},
        )
        try:
            for r in runner_counts:
                rows.append(rllib_rate(args, r, n_beacons))
        finally:
            ray.shutdown()
    import ray as _ray
    import stable_baselines3
    import torch

    result = {
        "scenario": args.scenario,
        "beacons": n_beacons,
        "batch": args.batch,
        "minibatch": args.minibatch,
        "epochs": args.epochs,
        "net": args.net,
        "iterations": args.iterations,
        "cores": os.cpu_count(),
        "load_average": [round(v, 2) for v in os.getloadavg()],
        "python": platform.python_version(),
        "ray": _ray.__version__,
        "stable_baselines3": stable_baselines3.__version__,
        "torch": str(torch.__version__),
        "results": rows,
    }
    if args.json:
        print(json.dumps(result))
        return 0
    print(
        f"{args.scenario}: {n_beacons} beacon(s); PPO {args.batch} env steps/update, {args.epochs} epochs, "
        f"minibatch {args.minibatch}, net {args.net}; {args.iterations} timed updates; {os.cpu_count()} cores, "
        f"load {result['load_average'][0]}"
    )
    print("| backend | configuration | env-steps/s | agent-steps/s | timed env steps | wall (s) | build (s) |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['backend']} | {r['config']} | {r['env_steps_per_s']:,.0f} | {r['agent_steps_per_s']:,.0f} | "
            f"{r['env_steps']} | {r['wall_s']} | {r['build_s'] if r['build_s'] is not None else ''} |"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
