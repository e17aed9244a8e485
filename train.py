"""Train a PPO beacon policy (stable-baselines3) on a coopnav scenario.

    python train.py --scenario sousa_asv --timesteps 2000000 --seed 0 --out runs/sousa_ppo
    python train.py --resume runs/sousa_ppo          # continue an interrupted run (either backend)
    python train.py --backend rllib --scenario sousa_asv --timesteps 2000000 --num-env-runners 8 \
        --out runs/sousa_rllib                       # Ray RLlib instead (train_rllib.py; pip install -e ".[rllib]")

Read top to bottom: arguments -> hyperparameters (configs/ppo/<scenario>.yml, else
configs/ppo/default.yml) -> seeding -> the vectorized environment -> PPO ->
callbacks (atomic checkpoints, evaluation on fixed seeds, best model) -> learn ->
final save. Every beacon of every environment is one row of the batch, so one
policy drives them all (parameter sharing): ``coopnav_env.vector.CoopNavVecEnv``.

What a run directory holds (``--out``):

    config.yml                 the exact config used: CLI arguments, the resolved
                               hyperparameters, the scenario's parameters, versions
    model.zip                  the final SB3 model            } loaded by agents.load(dir)
    vecnormalize.pkl           its observation normalization  }
    best_model.zip, best_vecnormalize.pkl, best.json   the best evaluated model
    checkpoints/               ckpt_<steps>.zip + ckpt_<steps>_vecnormalize.pkl,
                               last_checkpoint.json (what --resume reads)
    evaluations.jsonl          one line per evaluation
    tb/                        TensorBoard logs (if tensorboard is installed)

Domain randomization: the YAML's ``env.overrides`` may set the core's per-episode
randomization (``randomize_survey_path``, ``randomize_depth_m``,
``randomize_noise_scale``, the current's spreads); every episode then draws its
path kind, depth and noise from its seed inside the one batched simulator.

Warm start: the YAML's ``init_from:`` (a train.py run directory, a shipped policy
name or a model .zip, as ``agents.resolve`` reads them) starts the network's weights
and the observation normalization from that policy instead of from scratch (the
learning-rate schedule starts afresh; the network's shape must match). A resumed
run ignores it: the checkpoint already holds the weights.

Training reward: the YAML's ``reward:`` (``{term: weight}``, see
``coopnav_env.vector``) replaces the environment's reward by a weighted sum of
training signals, for training only (evaluation always scores survey_error_m).

Evaluation: the deterministic policy on ``eval.episodes`` fixed seeds per cell
(episode ``i`` of every cell is seeded ``eval.seed + i``: common random numbers
across cells and policies), scored by the mean of ``survey_error_m`` over every
step of every episode of every cell (evaluate.py's ``mean_error_m``; lower is
better). ``eval.cells`` (``{survey_path: [...], depth_m: [...]}``) evaluates
every combination as a fixed scenario (those values set, randomization off);
without it the evaluation runs the training scenario as it is. The baselines
named in ``eval.baselines`` (``fim_a``) are scored once on the same seeds, per
cell too; ``evaluations.jsonl`` records the per-cell scores and how many cells
the policy beats each baseline in. Every file is written to a temporary name and
moved into place with ``os.replace``, so an interrupted run never leaves a half
written checkpoint. Ctrl-C (SIGINT) or SIGTERM stops at the next rollout
boundary after writing a checkpoint; ``--resume`` continues from the last one up
to the same total step count, with fresh episodes (the environments' episode
state is not saved). ``--resume RUN_DIR`` takes everything from the run's
config.yml, the backend included (an RLlib run resumes on RLlib, see
train_rllib.py); ``--scenario``, ``--timesteps`` and the other settings of the run
cannot be given with it, nor a ``--backend`` other than the run's.
"""

from __future__ import annotations

import argparse
import dataclasses
import io
import json
import os
import pickle
import platform
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parent
CONFIG_DIR = ROOT / "configs" / "ppo"
EXIT_BAD_INPUT = 2
EXIT_INTERRUPTED = 130


def fail(message: str, code: int = EXIT_BAD_INPUT):
    """One line on stderr and exit: bad input is not a traceback."""
    print(f"train.py: error: {message}", file=sys.stderr)
    sys.exit(code)


# ----------------------------------------------------------------------------------
# 1. arguments
# ----------------------------------------------------------------------------------
def _int_at_least(text, low: int) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if value < low:
        raise argparse.ArgumentTypeError(f"must be >= {low}, got {text!r}")
    return value


def positive_int(text):
    return _int_at_least(text, 1)


def nonnegative_int(text):
    return _int_at_least(text, 0)


class OneLineParser(argparse.ArgumentParser):
    def error(self, message):
        fail(message)


def parse_args(argv=None):
    p = OneLineParser(description="Train a PPO beacon policy on a coopnav scenario.")
    p.add_argument("--scenario", help="scenario name (coopnav_env.list_scenarios())")
    p.add_argument("--timesteps", type=positive_int, help="total environment steps (rows: beacons x envs)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", help="run directory to create")
    p.add_argument("--resume", metavar="RUN_DIR", help="continue the run in RUN_DIR from its last checkpoint")
    p.add_argument("--n-envs", type=positive_int, help="environments in the batch (overrides the YAML)")
    p.add_argument("--config", help="hyperparameter YAML (default: configs/ppo/<scenario>.yml, else default.yml)")
    p.add_argument("--device", default="cpu")
    p.add_argument("--threads", type=positive_int, default=1,
                   help="torch threads (default 1: PPO's small batches gain little from more, and a busy "
                        "machine makes extra threads spin)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--verbose", type=int, default=0)
    p.add_argument("--backend", choices=("sb3", "rllib"),
                   help="sb3: stable-baselines3 PPO on one machine (default); rllib: Ray RLlib PPO "
                        "(train_rllib.py, configs/rllib/; pip install -e '.[rllib]'); with --resume, the run's own")
    p.add_argument("--num-env-runners", type=nonnegative_int,
                   help="rllib: env runner processes (overrides the YAML; 0: sample in this process)")
    p.add_argument("--ray-address", help="rllib: a running Ray cluster to join ('auto', or host:port)")
    p.add_argument("--tune", action="append", metavar="KEY=V1,V2",
                   help="rllib: a Ray Tune grid (repeatable; KEY: seed or a PPOConfig.training keyword)")
    args = p.parse_args(argv)
    if args.resume is not None:  # the backend is the run's (resumed_backend), the rest its config.yml's
        given = [f"--{n.replace('_', '-')}" for n in ("scenario", "timesteps", "out", "n_envs", "config", "tune")
                 if getattr(args, n) is not None]
        if given:
            fail(f"--resume continues a run with its own config.yml; drop {', '.join(given)}")
        return args
    args.backend = args.backend or "sb3"
    if args.backend == "sb3":
        _sb3_only(args)
    missing = [f"--{n}" for n in ("scenario", "timesteps", "out") if getattr(args, n) is None]
    if missing:
        fail(f"missing {', '.join(missing)} (or --resume RUN_DIR)")
    return args


def _sb3_only(args, why: str = ""):
    given = [f"--{n.replace('_', '-')}" for n in ("num_env_runners", "ray_address", "tune")
             if getattr(args, n) is not None]
    if given:
        fail(f"{', '.join(given)} only with --backend rllib{why}")


def resumed_backend(args) -> str:
    """The backend of the run ``--resume`` names (its config.yml's ``args.backend``;
    sb3 if absent). A one-line error if that is not a run directory, if ``--backend``
    names the other backend, or if an RLlib option is given for an SB3 run."""
    out = Path(args.resume)
    saved = read_json(out / "config.yml", load=yaml.safe_load) if out.is_dir() else None
    if not isinstance(saved, dict) or not isinstance(saved.get("args"), dict):
        fail(f"{out} is not a train.py run directory (no config.yml)")
    backend = saved["args"].get("backend") or "sb3"
    if backend not in ("sb3", "rllib"):
        fail(f"{out}/config.yml: unknown backend {backend!r}")
    if args.backend is not None and args.backend != backend:
        fail(f"{out} is a --backend {backend} run; drop --backend {args.backend}")
    if backend == "sb3":
        _sb3_only(args, f" ({out} is an sb3 run)")
    return backend


# ----------------------------------------------------------------------------------
# 2. hyperparameters: a small YAML per scenario (the rl-baselines3-zoo habit)
# ----------------------------------------------------------------------------------
def hyperparameter_file(scenario: str, explicit: str | None, config_dir: Path = CONFIG_DIR) -> Path:
    """The --config file, else config_dir/<scenario>.yml, else config_dir/default.yml."""
    if explicit:
        path = Path(explicit)
        if not path.is_file():
            fail(f"no such hyperparameter file: {explicit}")
        return path
    for name in (f"{scenario}.yml", "default.yml"):
        if (config_dir / name).is_file():
            return config_dir / name
    fail(f"no hyperparameter file for {scenario!r} in {config_dir} (and no default.yml)")


def load_hyperparameters(path: Path) -> dict:
    with open(path) as f:
        hp = yaml.safe_load(f) or {}
    if not isinstance(hp, dict):
        fail(f"{path}: expected a mapping of hyperparameters")
    known = {"policy", "n_envs", "ppo", "normalize", "env", "eval", "checkpoint_every_steps", "reward", "init_from"}
    unknown = sorted(set(hp) - known)
    if unknown:
        fail(f"{path}: unknown section(s) {', '.join(unknown)}; valid: {', '.join(sorted(known))}")
    env = hp.get("env") or {}
    if "variants" in env:
        fail(f"{path}: env.variants is gone: set the core's per-episode randomization in env.overrides "
             "(randomize_survey_path, randomize_depth_m, randomize_noise_scale)")
    extra = sorted(set(env) - {"overrides"})
    if extra:
        fail(f"{path}: unknown env entr(y/ies) {', '.join(extra)}; valid: overrides")
    return hp


def warm_start_files(spec) -> tuple:
    """(model zip, vecnormalize pickle or None) of the YAML's ``init_from``."""
    import agents

    try:
        model, stats, _ = agents.resolve(str(spec))
    except ValueError as err:
        raise ValueError(f"init_from: {err}") from None
    if model.name == "gate.yml":
        raise ValueError(f"init_from: {spec!r} is a gate of two networks ({model}); name one of its networks "
                         "(the directories that file lists)")
    if model.suffix != ".zip":
        raise ValueError(f"init_from: {spec!r} is not a stable-baselines3 model ({model}): an SB3 run or policy only")
    return model, stats


def learning_rate(value):
    """A float, or "lin_<x>": linear decay from x to 0 (rl-baselines3-zoo)."""
    if isinstance(value, str) and value.startswith("lin_"):
        start = float(value[4:])
        return lambda progress_remaining: progress_remaining * start
    return float(value)


def policy_kwargs(spec: dict | None) -> dict:
    import torch.nn as nn

    spec = dict(spec or {})
    if "activation_fn" in spec:
        name = spec["activation_fn"]
        table = {"tanh": nn.Tanh, "relu": nn.ReLU, "elu": nn.ELU, "leaky_relu": nn.LeakyReLU}
        if name not in table:
            fail(f"unknown activation_fn {name!r}; valid: {', '.join(table)}")
        spec["activation_fn"] = table[name]
    return spec


# ----------------------------------------------------------------------------------
# 3. atomic files
# ----------------------------------------------------------------------------------
def atomic_write_bytes(path: Path, data: bytes):
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    with open(tmp, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def atomic_write_text(path: Path, text: str):
    atomic_write_bytes(path, text.encode())


def save_model(model, path: Path):
    buf = io.BytesIO()
    model.save(buf)
    atomic_write_bytes(path, buf.getvalue())


def save_vecnormalize(vecnorm, path: Path):
    """VecNormalize.save pickles the wrapper without its venv; the same, atomically."""
    atomic_write_bytes(path, pickle.dumps(vecnorm))


def plain(obj):
    """Tuples -> lists, recursively, for yaml.safe_dump."""
    if isinstance(obj, dict):
        return {k: plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [plain(v) for v in obj]
    return obj


# ----------------------------------------------------------------------------------
# 4. evaluation on fixed seeds
# ----------------------------------------------------------------------------------
RANDOMIZATION_OFF = {"randomize_survey_path": (), "randomize_depth_m": (), "randomize_noise_scale": ()}


def eval_cells(scenario_config, ev: dict) -> list:
    """[(label, ScenarioConfig)] the evaluation runs: every combination of ``eval.cells``
    ({parameter: [values]}) as a fixed scenario, or without cells the training
    scenario (label "all"); the per-episode randomization is off in every cell (the
    scenario's own survey_path, depth_m and noise levels unless the cell sets them)."""
    grid = ev.get("cells") or {}
    base = scenario_config.replace(**RANDOMIZATION_OFF)
    if not grid:
        return [("all", base)]
    if not isinstance(grid, dict):
        raise ValueError(f"eval.cells must map parameters to lists of values, got {grid!r}")
    cells = [{}]
    for name, values in grid.items():
        if not isinstance(values, (list, tuple)) or not values:
            raise ValueError(f"eval.cells entry {name!r} must be a non-empty list of values")
        cells = [dict(c, **{name: v}) for c in cells for v in values]
    return [(";".join(f"{k}={v}" for k, v in cell.items()), base.replace(**cell)) for cell in cells]


def evaluate(act, cells: list, episodes: int, seed: int) -> dict:
    """Run ``act(obs (rows, D), venv) -> actions (rows, 2)`` for one episode in each of
    ``episodes`` environments seeded ``seed + e`` in every cell of ``cells``
    ([(label, ScenarioConfig)], see ``eval_cells``). Score: survey_error_m (the
    info's mean over survey vehicles) averaged over every step of every episode of
    every cell, as evaluate.py's ``mean_error_m``; ``per_cell`` the same per cell."""
    from coopnav_env.vector import CoopNavVecEnv

    per_cell, per_episode, total, count = {}, [], 0.0, 0
    for label, config in cells:
        venv = CoopNavVecEnv(config, n_envs=episodes, seed=seed)
        N = venv.n_beacons
        obs = venv.reset()
        running = np.ones(episodes, dtype=bool)
        err_sum = np.zeros(episodes)
        steps = np.zeros(episodes)
        while running.any():
            obs, _, done, infos = venv.step(act(obs, venv))
            err = np.array([infos[e * N]["survey_error_m"] for e in range(episodes)])
            err_sum += np.where(running, err, 0.0)
            steps += running
            running &= ~done[::N]
        per_cell[label] = float(err_sum.sum() / steps.sum())
        per_episode.extend((err_sum / steps).round(4).tolist())
        total += err_sum.sum()
        count += steps.sum()
    return {"survey_error_m": float(total / count), "episodes": episodes * len(cells),
            "survey_error_m_per_episode": per_episode, "per_cell": per_cell}


def baseline_actor(name: str):
    """A batch actor from one baselines policy per row (reset at the first step of a
    new evaluation environment)."""
    from baselines import make_policy

    policies = {}

    def act(obs, venv):
        if policies.get("venv") is not venv:
            policies.clear()
            policies["venv"] = venv
            for row in range(venv.num_envs):
                e, j = divmod(row, venv.n_beacons)
                policies[row] = make_policy(name, venv.config, seed=int(venv.episode_seeds[e]), agent=j)
        return np.stack([policies[row].act(obs[row]) for row in range(venv.num_envs)])

    return act


def baselines_on_eval_seeds(out: Path, cells: list, names, episodes: int, seed: int) -> dict:
    """The planners ``names`` scored on the evaluation seeds, once per run: read from
    and written (atomically) to ``out/baseline_eval.json``; name -> {survey_error_m, per_cell}."""
    scores = read_json(out / "baseline_eval.json") or {}
    for name in names or []:
        if name in scores:
            continue
        try:
            result = evaluate(baseline_actor(name), cells, episodes, seed)
        except ImportError as err:  # the baselines package is not there
            print(f"baseline {name} not evaluated: {err}", file=sys.stderr)
            continue
        scores[name] = {"survey_error_m": result["survey_error_m"], "per_cell": result["per_cell"]}
    atomic_write_text(out / "baseline_eval.json", json.dumps(scores))
    return scores


def model_actor(model, vecnorm):
    def act(obs, venv):
        return model.predict(vecnorm.normalize_obs(obs), deterministic=True)[0]

    return act


# ----------------------------------------------------------------------------------
# 5. the callback: checkpoints, evaluation, best model, stop on signal
# ----------------------------------------------------------------------------------
def make_callback(out: Path, hp: dict, cells: list, vecnorm, baseline_scores: dict, state: dict):
    from stable_baselines3.common.callbacks import BaseCallback

    ckpt_dir = out / "checkpoints"
    ckpt_every = int(hp.get("checkpoint_every_steps", 100_000))
    ev = hp.get("eval", {}) or {}
    eval_every = int(ev.get("every_steps", 100_000))
    eval_episodes = int(ev.get("episodes", 32))
    eval_seed = int(ev.get("seed", 1_000_000))

    class RunCallback(BaseCallback):
        """At every rollout start (the model has been trained on every step counted so
        far): checkpoint and evaluate when due; stop after a signal."""

        def _on_training_start(self):
            self.trained_steps = self.last_ckpt = self.last_eval = self.model.num_timesteps

        def _on_rollout_start(self):
            self.trained_steps = steps = self.model.num_timesteps
            if steps - self.last_ckpt >= ckpt_every:
                self.checkpoint()
            if eval_every > 0 and steps - self.last_eval >= eval_every:
                self.evaluate()

        def _on_step(self):
            return not state["stop"]

        def checkpoint(self):
            steps = self.model.num_timesteps
            if read_json(ckpt_dir / "last_checkpoint.json") == {"num_timesteps": steps, "model": f"ckpt_{steps:010d}.zip",
                                                                 "vecnormalize": f"ckpt_{steps:010d}_vecnormalize.pkl"}:
                return
            ckpt_dir.mkdir(exist_ok=True)
            model_file, stats_file = f"ckpt_{steps:010d}.zip", f"ckpt_{steps:010d}_vecnormalize.pkl"
            save_model(self.model, ckpt_dir / model_file)
            save_vecnormalize(vecnorm, ckpt_dir / stats_file)
            previous = read_json(ckpt_dir / "last_checkpoint.json")
            atomic_write_text(ckpt_dir / "last_checkpoint.json", json.dumps(
                {"num_timesteps": steps, "model": model_file, "vecnormalize": stats_file}))
            if previous and previous["model"] != model_file:  # keep the last two
                for old in sorted(ckpt_dir.glob("ckpt_*.zip"))[:-2]:
                    old.unlink(missing_ok=True)
                    (ckpt_dir / old.name.replace(".zip", "_vecnormalize.pkl")).unlink(missing_ok=True)
            self.last_ckpt = steps

        def evaluate(self):
            t0 = time.perf_counter()
            result = evaluate(model_actor(self.model, vecnorm), cells, eval_episodes, eval_seed)
            score = result["survey_error_m"]
            now = time.perf_counter()
            record = {"num_timesteps": self.model.num_timesteps, "wall_s": round(now - state["t0"], 1),
                      "wall_s_since_start": round(now - state["started"], 1),
                      "survey_error_m": score,
                      **{f"{k}_survey_error_m": v["survey_error_m"] for k, v in baseline_scores.items()}}
            if len(cells) > 1:
                record["per_cell"] = {k: round(v, 4) for k, v in result["per_cell"].items()}
                for k, v in baseline_scores.items():
                    record[f"cells_beating_{k}"] = sum(result["per_cell"][c] < v["per_cell"][c] for c in v["per_cell"])
            with open(out / "evaluations.jsonl", "a") as f:
                f.write(json.dumps(record) + "\n")
            self.logger.record("eval/survey_error_m", score)
            for k, v in baseline_scores.items():
                self.logger.record(f"eval/{k}_survey_error_m", v["survey_error_m"])
                if f"cells_beating_{k}" in record:
                    self.logger.record(f"eval/cells_beating_{k}", record[f"cells_beating_{k}"])
            best = read_json(out / "best.json")
            if best is None or score < best["survey_error_m"]:
                save_model(self.model, out / "best_model.zip")
                save_vecnormalize(vecnorm, out / "best_vecnormalize.pkl")
                atomic_write_text(out / "best.json", json.dumps(record))
            beaten = [k for k, v in baseline_scores.items() if score < v["survey_error_m"]]
            print(f"eval @ {self.model.num_timesteps}: survey_error_m {score:.3f}"
                  + "".join(f", {k} {v['survey_error_m']:.3f}" for k, v in baseline_scores.items())
                  + "".join(f", beats {k} in {record[f'cells_beating_{k}']}/{len(cells)} cells"
                            for k in baseline_scores if f"cells_beating_{k}" in record)
                  + (f" (beats {', '.join(beaten)})" if beaten else "")
                  + f" [{time.perf_counter() - t0:.1f} s]", flush=True)
            self.last_eval = self.model.num_timesteps

    return RunCallback()


def resume_seed(seed: int, steps: int) -> int:
    """The seed of a run resumed at ``steps``: deterministic, and (almost surely) not
    repeating the first run's episodes."""
    return int(np.random.SeedSequence([int(seed) % 2**32, steps]).generate_state(1)[0] >> 1)


def read_json(path: Path, load=json.load):
    """A JSON file's content (or YAML's, with load=yaml.safe_load), or None if it is missing."""
    try:
        with open(path) as f:
            return load(f)
    except FileNotFoundError:
        return None


def versions() -> dict:
    import gymnasium
    import pettingzoo
    import stable_baselines3
    import torch

    def git(*args):
        try:
            return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, timeout=10).stdout.strip()
        except (OSError, subprocess.SubprocessError):
            return ""

    commit = git("rev-parse", "HEAD") or None
    dirty = bool(git("status", "--porcelain", "--untracked-files=no")) if commit else None
    return {"python": platform.python_version(), "numpy": np.__version__, "torch": str(torch.__version__),
            "stable_baselines3": str(stable_baselines3.__version__), "gymnasium": str(gymnasium.__version__),
            "pettingzoo": str(pettingzoo.__version__), "git_commit": commit,
            "git_dirty": dirty}


# ----------------------------------------------------------------------------------
# 6. main
# ----------------------------------------------------------------------------------
def main(argv=None) -> int:
    started = time.perf_counter()
    args = parse_args(argv)
    if args.resume is not None:
        args.backend = resumed_backend(args)
    if args.backend == "rllib":  # Ray is imported only here, and only for this backend
        try:
            import ray  # noqa: F401
            import ray.rllib  # noqa: F401
        except ImportError:
            fail('--backend rllib needs Ray RLlib, which is not installed: pip install -e ".[rllib]"')
        import train_rllib

        return train_rllib.main(args, argv)
    from coopnav_env import list_scenarios, make_config

    # --- the run directory, its config, and (when resuming) the checkpoint ----------
    if args.resume:
        out = Path(args.resume)
        saved = read_json(out / "config.yml", load=yaml.safe_load)
        if saved is None:
            fail(f"{out} is not a train.py run directory (no config.yml)")
        ckpt = read_json(out / "checkpoints" / "last_checkpoint.json")
        if ckpt is None:
            fail(f"{out} has no checkpoint to resume from (checkpoints/last_checkpoint.json)")
        run = saved["args"]
        hp = saved["hyperparameters"]
        hp_path = saved["hyperparameter_file"]
    else:
        if args.scenario not in list_scenarios():
            fail(f"unknown scenario {args.scenario!r}; valid scenarios: {', '.join(list_scenarios())}")
        out = Path(args.out)
        if out.exists() and any(out.iterdir()):
            fail(f"{out} exists and is not empty; use --resume {out} to continue it, or another --out")
        path = hyperparameter_file(args.scenario, args.config)
        hp = load_hyperparameters(path)
        if args.n_envs:
            hp["n_envs"] = args.n_envs
        hp_path = str(path)
        run = {"scenario": args.scenario, "timesteps": args.timesteps, "seed": args.seed}
        ckpt = None

    scenario, total, seed = run["scenario"], int(run["timesteps"]), int(run["seed"])
    env_spec = hp.get("env", {}) or {}
    overrides = dict(env_spec.get("overrides", {}) or {})
    try:
        scenario_config = make_config(scenario, **overrides)
    except ValueError as err:
        fail(f"{hp_path}: {err}")
    from coopnav_env.vector import CoopNavVecEnv, check_reward_terms

    try:
        reward_terms = check_reward_terms(hp.get("reward"))
    except ValueError as err:
        fail(f"{hp_path}: reward: {err}")
    ev = hp.get("eval", {}) or {}
    try:
        cells = eval_cells(scenario_config, ev)
    except ValueError as err:
        fail(f"{hp_path}: {err}")
    n_envs = int(hp.get("n_envs", 16))
    warm = None
    if hp.get("init_from") and not args.resume:
        try:
            warm = warm_start_files(hp["init_from"])
        except ValueError as err:
            fail(f"{hp_path}: {err}")

    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.utils import set_random_seed
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    out.mkdir(parents=True, exist_ok=True)
    if not args.resume:
        config = {
            "command": "python train.py " + " ".join(shlex.quote(a) for a in (sys.argv[1:] if argv is None else argv)),
            "args": run, "hyperparameter_file": hp_path, "hyperparameters": hp,
            "scenario_config": dataclasses.asdict(scenario_config),
            "eval_cells": [label for label, _ in cells],
            "versions": versions(),
        }
        atomic_write_text(out / "config.yml", yaml.safe_dump(plain(config), sort_keys=False))

    # --- seeding: python, numpy, torch; the environments from the same seed ---------
    start_steps = int(ckpt["num_timesteps"]) if ckpt else 0
    run_seed = seed if not ckpt else resume_seed(seed, start_steps)
    set_random_seed(run_seed)
    torch.set_num_threads(args.threads)

    # --- the environment: one batched simulator, VecMonitor, VecNormalize -----------
    venv = VecMonitor(CoopNavVecEnv(scenario_config, n_envs=n_envs, seed=run_seed, step_infos=False,
                                    reward_terms=reward_terms))
    norm = {"norm_obs": True, "norm_reward": True, "clip_obs": 10.0, **(hp.get("normalize", {}) or {})}
    ppo_hp = dict(hp.get("ppo", {}) or {})
    gamma = float(ppo_hp.get("gamma", 0.99))
    if ckpt:
        with open(out / "checkpoints" / ckpt["vecnormalize"], "rb") as f:
            vecnorm = pickle.load(f)
        vecnorm.set_venv(venv)
        vecnorm.training = True
    else:
        vecnorm = VecNormalize(venv, gamma=gamma, **norm)

    # --- PPO ----------------------------------------------------------------------
    try:
        import tensorboard  # noqa: F401

        tb_dir = str(out / "tb")
    except ImportError:
        tb_dir = None
    if ckpt:
        model = PPO.load(out / "checkpoints" / ckpt["model"], env=vecnorm, device=args.device,
                         tensorboard_log=tb_dir, verbose=args.verbose)
        model.set_random_seed(run_seed)
    else:
        ppo_hp.pop("policy", None)
        lr = learning_rate(ppo_hp.pop("learning_rate", 3e-4))
        kwargs = policy_kwargs(ppo_hp.pop("policy_kwargs", None))
        try:
            model = PPO(hp.get("policy", "MlpPolicy"), vecnorm, learning_rate=lr, policy_kwargs=kwargs,
                        seed=run_seed, device=args.device, tensorboard_log=tb_dir, verbose=args.verbose, **ppo_hp)
        except (TypeError, ValueError, AssertionError) as err:
            fail(f"{hp_path}: bad PPO hyperparameters: {str(err).splitlines()[0] if str(err) else type(err).__name__}")
        if warm:  # weights and normalization from another policy; the optimizer state comes with the weights
            try:
                model.set_parameters(str(warm[0]), exact_match=True, device=args.device)
            except (RuntimeError, ValueError, KeyError) as err:
                fail(f"{hp_path}: init_from {warm[0]} does not fit this network: {str(err).splitlines()[0]}")
            if warm[1] is not None:
                with open(warm[1], "rb") as f:
                    source = pickle.load(f)
                vecnorm.obs_rms, vecnorm.ret_rms = source.obs_rms.copy(), source.ret_rms.copy()
    if tb_dir is None:  # a note, not an error: after the inputs are known to be good, on stdout
        print("note: tensorboard is not installed, so no TensorBoard logs (pip install -e '.[train]')")

    # --- baselines on the evaluation seeds (once per run) --------------------------
    baseline_scores = read_json(out / "baseline_eval.json") or {}
    if int(ev.get("every_steps", 100_000)) > 0:
        baseline_scores = baselines_on_eval_seeds(out, cells, ev.get("baselines"), int(ev.get("episodes", 32)),
                                                  int(ev.get("seed", 1_000_000)))

    # --- learn, stopping cleanly on SIGINT/SIGTERM -----------------------------------
    state = {"stop": False, "t0": time.perf_counter(), "started": started}

    def request_stop(signum, frame):
        state["stop"] = True
        signal.signal(signum, signal.default_int_handler if signum == signal.SIGINT else signal.SIG_DFL)

    old_handlers = {s: signal.signal(s, request_stop) for s in (signal.SIGINT, signal.SIGTERM)}
    callback = make_callback(out, hp, cells, vecnorm, baseline_scores, state)
    progress = not args.no_progress and _has_progress_bar()
    try:
        model.learn(total_timesteps=max(total - start_steps, 0), callback=callback, progress_bar=progress,
                    reset_num_timesteps=not ckpt, tb_log_name="ppo")
    finally:
        for s, h in old_handlers.items():
            signal.signal(s, h)
    if state["stop"]:
        # the steps of the rollout cut short were not trained on: the checkpoint does not count them
        model.num_timesteps = getattr(callback, "trained_steps", start_steps)
        callback.checkpoint()
        print(f"stopped at {model.num_timesteps} steps; continue with: python train.py --resume {out}",
              file=sys.stderr)
        return EXIT_INTERRUPTED

    # --- final evaluation and model, beside its normalization and config ----------
    callback.checkpoint()
    if int(ev.get("every_steps", 100_000)) > 0 and callback.last_eval != model.num_timesteps:
        callback.evaluate()
    save_model(model, out / "model.zip")
    save_vecnormalize(vecnorm, out / "vecnormalize.pkl")
    elapsed = time.perf_counter() - state["t0"]
    print(f"done: {model.num_timesteps} steps ({model.num_timesteps - start_steps} in this run, {elapsed:.0f} s, "
          f"{(model.num_timesteps - start_steps) / elapsed:.0f} steps/s); "
          f"model in {out}")
    return 0


def _has_progress_bar() -> bool:
    try:
        import rich  # noqa: F401
        import tqdm  # noqa: F401
    except ImportError:
        return False
    return True


if __name__ == "__main__":
    sys.exit(main())
