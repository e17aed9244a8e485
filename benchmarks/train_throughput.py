"""PPO training throughput: our batched VecEnv against SuperSuit's conversion, and the
batched TorchRL path (BenchMARL's MAPPO/IPPO on ``CoopNavTorchEnv``).

    python benchmarks/train_throughput.py                       # sousa_asv, its YAML hyperparameters
    python benchmarks/train_throughput.py --scenario gao_sea --rollouts 3 --json
    python benchmarks/train_throughput.py --only coopnav --torchrl mappo,ippo --torchrl-n-envs 256,1024

In one run, trains PPO (stable-baselines3, the scenario's configs/ppo YAML:
n_envs, n_steps, batch size, epochs, network; VecMonitor + VecNormalize as in
train.py) for the same number of rollouts on

(a) ``CoopNavVecEnv``: one batched ``Simulator`` for all environments, one row per
    beacon (coopnav_env/vector.py), with ``step_infos=False`` as train.py uses it
    (``--step-infos``: every row's info dict every step, as SuperSuit's);
(b) SuperSuit: ``pettingzoo_env_to_vec_env_v1(parallel_env(scenario))`` then
    ``concat_vec_envs_v1(..., n_envs, num_cpus=0, base_class="stable_baselines3")``:
    n_envs copies of the PettingZoo env stepped one after another (``--supersuit-cpus``
    > 0 gives SuperSuit worker processes instead);

and prints environment-steps per second (rows x steps / wall time of ``learn``)
and where the time went, profiled by wrapping the innermost VecEnv: the share of
``step``/``reset`` (the environment), the rest of collecting rollouts (policy
forward passes, VecNormalize, the buffer) and the gradient updates. Both
environments are the scenario with the YAML's ``env.overrides`` (the core's
per-episode randomization included, as train.py trains), with the environment's
own reward (the YAML's training ``reward:`` terms are CoopNavVecEnv's and cost
about as much as the info dicts they replace; ``--training-reward`` adds them).

(c) ``--torchrl mappo[,ippo]`` (the ``marl`` extra): BenchMARL's ``Experiment`` on
    ``coopnav_env.torchrl_env.CoopNavTorchEnv`` with ``--torchrl-n-envs`` environments as
    ONE simulator's batch: its collector (the policy's forward passes, the env, the
    buffer) and its PPO updates (``--torchrl-epochs`` passes over each batch of
    ``--torchrl-steps`` steps per environment in minibatches of ``--torchrl-minibatch``),
    MLPs of ``--torchrl-net``, no logger and no evaluation: the whole training loop. The
    same overrides as (a) and (b), the environment's reward. The first iteration
    (compilation, first reset) is untimed; ``--rollouts`` iterations are timed.

Steps are environment-steps: one step of one row. For (a) and (b) a row is a beacon
of an environment (SB3's rows), for (c) an environment (all its beacons act in one
row of the batch); with one beacon (sousa_asv, gao_sea) the two are the same.

A first rollout is run untimed as warm-up. Numbers depend on the machine and its
load (the aim stated by issue 4: ours faster, environment share below 15 %; issue 23:
the TorchRL path 10x SB3's whole-loop figure).
"""

from __future__ import annotations

import json
import os
import platform
import sys
import tempfile
import time
import warnings
from collections.abc import Sequence

try:
    from benchmarks import _args
except ImportError:  # run as a script: its own folder is on the path, not the checkout
    import _args  # type: ignore[no-redef]
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from agents.training import TrainConfig


def timed(venv_class: type) -> type:
    """A VecEnvWrapper that adds the wall time spent inside the wrapped VecEnv."""

    class Timed(venv_class):
        def __init__(self, venv):
            super().__init__(venv)
            self.env_s = 0.0

        def seed(self, seed=None):
            try:
                return self.venv.seed(seed)
            except AttributeError:  # SuperSuit's ConcatVecEnv: seeded by its PettingZoo env
                return [None] * self.num_envs

        def reset(self):
            t = time.perf_counter()
            out = self.venv.reset()
            self.env_s += time.perf_counter() - t
            return out

        def step_async(self, actions):
            t = time.perf_counter()
            self.venv.step_async(actions)
            self.env_s += time.perf_counter() - t

        def step_wait(self):
            t = time.perf_counter()
            out = self.venv.step_wait()
            self.env_s += time.perf_counter() - t
            return out

    return Timed


def build(
    kind: str,
    scenario: str,
    n_envs: int,
    seed: int,
    supersuit_cpus: int,
    config: TrainConfig,
    step_infos: bool = False,
    training_reward: bool = False,
) -> Any:
    """``config``: the scenario's ``agents.training.TrainConfig``."""
    from stable_baselines3.common.vec_env import VecEnvWrapper

    overrides = dict(config.env.overrides)
    if kind == "coopnav":
        from coopnav_env.vector import CoopNavVecEnv

        raw = CoopNavVecEnv(
            scenario,
            n_envs=n_envs,
            seed=seed,
            step_infos=step_infos,
            reward_terms=config.reward if training_reward else None,
            **overrides,
        )
    else:
        import supersuit as ss

        import coopnav_env

        vec = ss.pettingzoo_env_to_vec_env_v1(coopnav_env.parallel_env(scenario, seed=seed, **overrides))
        raw = ss.concat_vec_envs_v1(vec, n_envs, num_cpus=supersuit_cpus, base_class="stable_baselines3")
    return timed(VecEnvWrapper)(raw)


def measure(
    kind: str,
    scenario: str,
    config: TrainConfig,
    n_envs: int,
    rollouts: int,
    seed: int,
    supersuit_cpus: int,
    step_infos: bool = False,
    training_reward: bool = False,
) -> dict:
    import dataclasses

    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    from agents.training.sb3 import learning_rate, policy_kwargs

    torch.manual_seed(seed)
    inner = build(kind, scenario, n_envs, seed, supersuit_cpus, config, step_infos, training_reward)
    ppo_hp = dict(config.ppo)
    gamma = float(ppo_hp.get("gamma", 0.99))
    venv = VecNormalize(VecMonitor(inner), gamma=gamma, **dataclasses.asdict(config.normalize))
    lr = learning_rate(ppo_hp.pop("learning_rate", 3e-4))
    kwargs = policy_kwargs(ppo_hp.pop("policy_kwargs", None))
    model = PPO(
        config.policy, venv, learning_rate=lr, policy_kwargs=kwargs, seed=seed, device="cpu", verbose=0, **ppo_hp
    )
    per_rollout = model.n_steps * venv.num_envs

    class Phases(BaseCallback):
        def _on_training_start(self):
            self.rollout_s, self.t = 0.0, None

        def _on_rollout_start(self):
            self.t = time.perf_counter()

        def _on_rollout_end(self):
            self.rollout_s += time.perf_counter() - self.t

        def _on_step(self):
            return True

    model.learn(per_rollout)  # warm-up: one rollout and its update, untimed
    inner.env_s = 0.0
    phases = Phases()
    t0 = time.perf_counter()
    model.learn(rollouts * per_rollout, callback=phases, reset_num_timesteps=False)
    wall = time.perf_counter() - t0
    steps = rollouts * per_rollout
    inner.close()
    return {
        "kind": kind,
        "rows": venv.num_envs,
        "steps": steps,
        "wall_s": wall,
        "steps_per_s": steps / wall,
        "env_s": inner.env_s,
        "env_share": inner.env_s / wall,
        "rollout_other_share": (phases.rollout_s - inner.env_s) / wall,
        "update_share": (wall - phases.rollout_s) / wall,
    }


ENV_SECONDS = [0.0]  # time inside CoopNavTorchEnv's _step and _reset (measure_torchrl)


def _clock_class() -> type:
    """A BenchMARL callback marking the end of each iteration's collection and of its
    updates. BenchMARL pickles its callbacks: the class is made a module global (BenchMARL
    is imported only when the TorchRL path runs)."""
    if "_Clock" not in globals():
        from benchmarl.experiment.callback import Callback

        class _Clock(Callback):
            def __init__(self) -> None:
                super().__init__()
                self.collected: list = []
                self.trained: list = []
                self.env_s: list = []

            def on_batch_collected(self, batch: Any) -> None:
                self.collected.append(time.perf_counter())

            def on_train_end(self, training_td: Any, group: str) -> None:
                self.trained.append(time.perf_counter())
                self.env_s.append(ENV_SECONDS[0])

        _Clock.__qualname__ = _Clock.__name__
        globals()["_Clock"] = _Clock
    return globals()["_Clock"]


def _batched_result(
    kind: str, n_envs: int, steps: int, frames: int, wall: float, env_s: float, collect_s: float, **settings: Any
) -> dict:
    """A batched path's figures: ``collect_s`` is the whole collection (the simulator's
    ``env_s`` included), the rest of ``wall`` the updates; ``settings`` are recorded as given."""
    import torch

    return {
        "kind": kind,
        "rows": n_envs,
        "steps": frames,
        "wall_s": wall,
        "steps_per_s": frames / wall,
        "env_s": env_s,
        "env_share": env_s / wall,
        "rollout_other_share": (collect_s - env_s) / wall,
        "update_share": (wall - collect_s) / wall,
        **settings,
        "steps_per_env": steps,
        "torch_threads": torch.get_num_threads(),
    }


def measure_loop(
    algorithm: str,
    scenario: str,
    overrides: dict,
    n_envs: int,
    steps: int,
    minibatch: int,
    epochs: int,
    net: Sequence[int],
    rollouts: int,
    seed: int,
    threads: int = 1,
) -> dict:
    """Whole-loop env-steps/s of ``agents.training.batched_ppo`` (``algorithm`` mappo: the
    critic on the state; ippo: on each observation) on the batched TorchRL env: ``rollouts``
    timed iterations (collection + update) after one untimed, from the loop's own
    per-iteration clock."""
    from agents.training.batched_ppo import BatchedPPOConfig, train

    config = BatchedPPOConfig(
        scenario=scenario,
        n_envs=n_envs,
        n_steps=steps,
        epochs=epochs,
        minibatch=minibatch,
        net=tuple(net),
        critic="state" if algorithm == "mappo" else "observation",
        seed=seed,
        overrides=dict(overrides),
    )
    result = train(config, (rollouts + 1) * n_envs * steps, progress=False, threads=threads)
    timed = result["log"][1:]
    env_s = sum(r["env_s"] for r in timed)
    collect_s = env_s + sum(r["collect_s"] for r in timed)
    wall = collect_s + sum(r["update_s"] for r in timed)
    frames = len(timed) * n_envs * steps
    settings = {"minibatch": min(minibatch, n_envs * steps), "epochs": epochs, "net": list(net)}
    return _batched_result(f"loop-{algorithm}", n_envs, steps, frames, wall, env_s, collect_s, **settings)


def measure_torchrl(
    algorithm: str,
    scenario: str,
    overrides: dict,
    n_envs: int,
    steps: int,
    minibatch: int,
    epochs: int,
    net: Sequence[int],
    rollouts: int,
    seed: int,
    threads: int = 1,
    activation: str = "tanh",
) -> dict:
    """Whole-loop env-steps/s of BenchMARL's ``algorithm`` (mappo, ippo) on the batched
    TorchRL env: ``rollouts`` timed iterations (collection + updates) after one untimed;
    ``activation``: the MLPs' (``tanh``, BenchMARL's default, or ``relu``)."""
    import dataclasses
    import logging
    import warnings

    from agents.training.benchmarl_task import CoopNavClass
    from agents.training.marl import _quiet_benchmarl_bar, build_experiment, experiment_config
    from coopnav_env.torchrl_env import CoopNavTorchEnv

    warnings.filterwarnings("ignore", message="SyncDataCollector has been deprecated")
    warnings.filterwarnings("ignore", message="No episode terminated this iteration")
    logging.getLogger("torchrl").setLevel(logging.WARNING)
    _quiet_benchmarl_bar()
    per_batch = n_envs * steps
    changes = {
        "on_policy_n_envs_per_worker": n_envs,
        "on_policy_collected_frames_per_batch": per_batch,
        "on_policy_minibatch_size": min(minibatch, per_batch),
        "on_policy_n_minibatch_iters": epochs,
        "max_n_frames": (rollouts + 1) * per_batch,
        "evaluation": False,
        "loggers": [],
        "create_json": False,
        "checkpoint_at_end": False,
    }
    config = experiment_config(None, None, None, changes, on_policy=True)
    task = CoopNavClass(
        name=scenario.upper(),
        config={"scenario": scenario, "tasks": {"train": {}}, "task": "train", "overrides": dict(overrides)},
    )

    ENV_SECONDS[0] = 0.0
    step, reset = CoopNavTorchEnv._step, CoopNavTorchEnv._reset

    def timed_step(self, td):
        t = time.perf_counter()
        out = step(self, td)
        ENV_SECONDS[0] += time.perf_counter() - t
        return out

    def timed_reset(self, td=None, **kw):
        t = time.perf_counter()
        out = reset(self, td, **kw)
        ENV_SECONDS[0] += time.perf_counter() - t
        return out

    clock = _clock_class()()
    import torch
    from benchmarl.models import MlpConfig

    mlp = dataclasses.replace(  # the policy's and the critic's
        MlpConfig.get_from_yaml(),
        num_cells=list(net),
        activation_class={"tanh": torch.nn.Tanh, "relu": torch.nn.ReLU}[activation],
    )
    CoopNavTorchEnv._step, CoopNavTorchEnv._reset = timed_step, timed_reset  # type: ignore[method-assign]
    try:
        with tempfile.TemporaryDirectory() as folder:  # BenchMARL writes its config there, even without loggers
            config.save_folder = folder
            experiment = build_experiment(algorithm, task, seed, config, mlp, mlp, callbacks=[clock])
            torch.set_num_threads(threads)  # numba's OpenMP start (threaded kernels, >= 256 envs) resets torch's
            experiment.run()
    finally:
        CoopNavTorchEnv._step, CoopNavTorchEnv._reset = step, reset  # type: ignore[method-assign]
    # timed: from the end of the first iteration's updates to the end of the last one's
    t0, t1 = clock.trained[0], clock.trained[-1]
    wall = t1 - t0
    collect = sum(c - t for c, t in zip(clock.collected[1:], clock.trained[:-1]))
    env_time = clock.env_s[-1] - clock.env_s[0]
    frames = rollouts * per_batch
    settings = {"minibatch": min(minibatch, per_batch), "epochs": epochs, "net": list(net)}
    return _batched_result(f"torchrl-{algorithm}", n_envs, steps, frames, wall, env_time, collect, **settings)


def main(argv: Sequence[str] | None = None) -> int:
    from agents.training.cli import threads_arg  # train.py's --threads: 1 to this machine's CPUs
    from agents.training.config import ConfigError, TrainConfig, hyperparameter_file, load_config

    p = _args.Parser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scenario", default="sousa_asv")
    p.add_argument("--config", help="hyperparameter YAML (default: the scenario's, as train.py)")
    p.add_argument("--n-envs", type=int, help="override the YAML's n_envs")
    p.add_argument("--rollouts", type=int, default=2, help="timed PPO rollouts (+ their updates) per measurement")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--supersuit-cpus", type=int, default=0)
    p.add_argument("--only", choices=["coopnav", "supersuit", "none"], help="SB3 paths to run (none: only --torchrl)")
    p.add_argument(
        "--training-reward",
        action="store_true",
        help="CoopNavVecEnv computes the YAML's training reward terms (train.py does)",
    )
    p.add_argument(
        "--step-infos",
        action="store_true",
        help="CoopNavVecEnv builds every row's info dict every step (train.py does not)",
    )
    p.add_argument("--threads", type=threads_arg, default=1, help="torch threads (train.py's default and range: 1)")
    p.add_argument("--torchrl", default="", help="also BenchMARL on the TorchRL env: mappo, ippo or mappo,ippo")
    p.add_argument(
        "--loop",
        default="",
        help="also agents.training.batched_ppo (one readable PPO loop) on the TorchRL env: mappo, ippo or mappo,ippo; "
        "with the --torchrl-* settings",
    )
    p.add_argument("--torchrl-n-envs", default="1024", help="environments in its batch (comma list: one run each)")
    p.add_argument("--torchrl-steps", type=int, default=64, help="steps per environment per iteration")
    p.add_argument("--torchrl-minibatch", type=int, default=8192, help="PPO minibatch (env-steps)")
    p.add_argument("--torchrl-epochs", type=int, default=4, help="PPO passes over each batch")
    p.add_argument("--torchrl-net", default="128,128", help="hidden layers of the policy and the critic")
    p.add_argument(
        "--torchrl-activation", choices=["tanh", "relu"], default="tanh", help="the MLPs' activation (BenchMARL: tanh)"
    )
    p.add_argument("--json", action="store_true")
    args = p.parse_args(argv)
    warnings.filterwarnings("ignore", message="The `render_mode` attribute is not defined")  # SuperSuit's
    from coopnav_env import list_scenarios

    if args.scenario not in list_scenarios():
        print(
            f"train_throughput.py: error: unknown scenario {args.scenario!r}; valid scenarios: "
            f"{', '.join(list_scenarios())}",
            file=sys.stderr,
        )
        return 2
    try:
        config = load_config(hyperparameter_file("sb3", args.scenario, args.config), TrainConfig)
    except ConfigError as err:
        print(f"train_throughput.py: error: {err}", file=sys.stderr)
        return 2
    n_envs = config.n_envs if args.n_envs is None else args.n_envs
    _args.count(p, n_envs, "--n-envs", bound="MAX_ENVS")
    _args.count(p, args.rollouts, "--rollouts", bound="MAX_STEPS")
    _args.seeds(p, args.seed)
    _args.count(p, args.supersuit_cpus, "--supersuit-cpus", low=0, bound="MAX_ENVS")
    kinds = [args.only] if args.only else ["coopnav", "supersuit"]
    if args.only == "none":
        kinds = []
    batched = [("--torchrl", args.torchrl, measure_torchrl), ("--loop", args.loop, measure_loop)]
    for flag, algorithms, _ in batched:  # every setting of the batched runs, before the first measurement
        for algorithm in [a for a in algorithms.split(",") if a]:
            if algorithm not in ("mappo", "ippo"):
                p.error(f"{flag} takes mappo and ippo, got {algorithm!r}")
    if args.torchrl or args.loop:
        torchrl_n_envs = _args.int_list(p, args.torchrl_n_envs, "--torchrl-n-envs", high=_args.MAX_ENVS)
        net = _args.int_list(p, args.torchrl_net, "--torchrl-net")
        _args.count(p, args.torchrl_steps, "--torchrl-steps", bound="MAX_STEPS")
        _args.count(p, args.torchrl_minibatch, "--torchrl-minibatch", bound="MAX_ENVS")
        _args.count(p, args.torchrl_epochs, "--torchrl-epochs", bound="MAX_STEPS")
    import importlib.util

    if "supersuit" in kinds and importlib.util.find_spec("supersuit") is None:  # the [bench] extra: now, not after
        p.error(  # the coopnav measurement
            "the SuperSuit comparison needs supersuit (pip install -e '.[bench]'); "
            "or measure without it: --only coopnav"
        )
    for flag, module in (("--torchrl", "benchmarl"), ("--loop", "torchrl")):
        if getattr(args, flag[2:]) and importlib.util.find_spec(module) is None:
            p.error(f"{flag} needs {module}, the marl extra (pip install -e '.[marl]')")
    import torch

    torch.set_num_threads(args.threads)
    results = []

    def done(r: dict) -> None:  # each figure on stderr as it comes: a long run killed early keeps them
        results.append(r)
        print(f"measured {r['kind']} rows {r['rows']}: {r['steps_per_s']:.0f} env-steps/s", file=sys.stderr, flush=True)

    for k in kinds:
        done(
            measure(
                k,
                args.scenario,
                config,
                n_envs,
                args.rollouts,
                args.seed,
                args.supersuit_cpus,
                args.step_infos,
                args.training_reward,
            )
        )
    for flag, algorithms, measure_batched in batched:
        for algorithm in [a for a in algorithms.split(",") if a]:
            extra = {"activation": args.torchrl_activation} if flag == "--torchrl" else {}
            for n in torchrl_n_envs:
                done(
                    measure_batched(
                        algorithm,
                        args.scenario,
                        dict(config.env.overrides),
                        n,
                        args.torchrl_steps,
                        args.torchrl_minibatch,
                        args.torchrl_epochs,
                        net,
                        args.rollouts,
                        args.seed,
                        args.threads,
                        **extra,
                    )
                )
    meta = {
        "scenario": args.scenario,
        "n_envs": n_envs,
        "step_infos": args.step_infos,
        "training_reward": args.training_reward,
        "overrides": config.env.overrides,
        "n_steps": config.ppo.get("n_steps"),
        "n_epochs": config.ppo.get("n_epochs"),
        "batch_size": config.ppo.get("batch_size"),
        "net_arch": (config.ppo.get("policy_kwargs") or {}).get("net_arch"),
        "rollouts": args.rollouts,
        "torch_threads": torch.get_num_threads(),
        "cpus": os.cpu_count(),
        "python": platform.python_version(),
        "load_avg_1m": os.getloadavg()[0],
    }
    by_kind = {r["kind"]: r for r in results}
    if "coopnav" in by_kind and "supersuit" in by_kind:
        meta["speedup"] = by_kind["coopnav"]["steps_per_s"] / by_kind["supersuit"]["steps_per_s"]
    if "coopnav" in by_kind:
        for r in results:
            if r["kind"].startswith(("torchrl", "loop")):
                r["vs_sb3"] = r["steps_per_s"] / by_kind["coopnav"]["steps_per_s"]
    if args.json:
        print(json.dumps({"meta": meta, "results": results}, indent=2))
        return 0
    print(
        f"PPO on {args.scenario}: n_envs {n_envs}, n_steps {meta['n_steps']}, batch {meta['batch_size']}, "
        f"{meta['n_epochs']} epochs, net {meta['net_arch']}, {args.rollouts} timed rollouts, "
        f"{meta['torch_threads']} torch threads, load {meta['load_avg_1m']:.1f}"
    )
    print(
        f"{'vec env':<18}{'rows':>6}{'steps':>9}{'wall s':>9}{'steps/s':>10}{'env':>8}{'rollout other':>15}"
        f"{'update':>9}"
    )
    for r in results:
        print(
            f"{r['kind']:<18}{r['rows']:>6}{r['steps']:>9}{r['wall_s']:>9.1f}{r['steps_per_s']:>10.0f}"
            f"{r['env_share']:>8.1%}{r['rollout_other_share']:>15.1%}{r['update_share']:>9.1%}"
            + (f"  {r['vs_sb3']:.1f}x SB3" if "vs_sb3" in r else "")
        )
    if any(r["kind"].startswith("loop") for r in results):
        print("loop: agents.training.batched_ppo with the torchrl settings below")
    if any(r["kind"].startswith(("torchrl", "loop")) for r in results):
        print(
            f"torchrl: BenchMARL, {args.torchrl_steps} steps per env per iteration, "
            f"minibatch {args.torchrl_minibatch}, {args.torchrl_epochs} epochs, net {args.torchrl_net} "
            f"({args.torchrl_activation}); "
            "timed iterations after one untimed"
        )
    if "speedup" in meta:
        print(f"coopnav VecEnv / SuperSuit: {meta['speedup']:.1f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
