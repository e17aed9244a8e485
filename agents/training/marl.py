"""Multi-agent training on the batched core with BenchMARL: one command, one run folder.

    python -m agents.training.marl --algorithm mappo --task gao_sea --frames 3000000 --out runs/gao_sea_mappo
    python -m agents.training.marl --algorithm ippo --task gao_sea/two_beacons --model gru --out runs/g2
    python -m agents.training.marl --algorithm masac --task sousa_ping --set lr=1e-4 --out runs/ping_masac

Needs the ``marl`` extra (``pip install -e ".[marl]"``). ``--task`` names a coopnav task
set (``agents.training.benchmarl_task.CoopNavTask``: the benchmark's task sets), optionally
``/<task>`` of that set (default: the set's first task). The experiment's settings are
BenchMARL's ``base_experiment.yaml`` with ``configs/benchmarl/experiment/coopnav.yaml``'s
changes, then ``--n-envs``, ``--frames`` and ``--set FIELD=VALUE``; the algorithm's and the
model's are BenchMARL's YAML (``benchmarl/conf``). One env-step (a BenchMARL "frame") is
one step of one environment row; the ``--n-envs`` rows are ONE simulator's batch.

**The run folder** (``--out``, default ``runs/marl/<task>-<algorithm>-seed<seed>``) must
be absent or empty and is locked for the run (``agents.training.runlock``). BenchMARL
writes into ``<out>/.partial/`` while it runs; at the end the experiment folder (CSV
logs, marl-eval JSON, BenchMARL's checkpoint) is moved to ``<out>/benchmarl`` in one
rename, the policy's weights are saved as ``<out>/policy.safetensors`` and ``<out>/run.json``
(command, configs, seed, frames, wall time, env-steps/s, the last batch's mean return and
survey error) is written atomically last: a folder with ``run.json`` is a finished run.
BenchMARL's checkpoint is a pickle (``torch.save``): load only your own.

**The best weights** (``--eval-every-steps N``): every N env-steps and at the end the policy
plays ``--eval-episodes`` validation episodes (seeded ``--eval-seed`` + i, never the test
seeds) as ``evaluate.py`` plays it, and ``<out>/best`` (a run folder of its own)
keeps the lowest mean survey error's weights (``agents.training.marl_validation``); run.json
lists every validation. A run's last weights are not its best.

Progress: a bar on a terminal, a line every 30 s elsewhere (``coopnav_env.progress``).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shlex
import sys
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from benchmarl.experiment.callback import Callback

from coopnav_env.seeds import VALIDATION_SEED

from .config import ConfigError, like_default, parse_assignments

ALGORITHMS = ("mappo", "ippo", "masac", "maddpg", "iddpg", "isac")  # BenchMARL's continuous-action algorithms
# BenchMARL's models that read the flat observation; its Deep Sets and GNN need set (entity)
# inputs, which the flat observation is not ("DeepSets found no set inputs")
MODELS = ("mlp", "gru", "lstm")
EXPERIMENT_YAML = "experiment/coopnav.yaml"

__all__ = ["ALGORITHMS", "MODELS", "build_experiment", "build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m agents.training.marl",
        description="Train coopnav beacons with BenchMARL (MAPPO, IPPO, MASAC, ...) on the batched core.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=__doc__.split("\n\n")[1],
    )
    p.add_argument("--algorithm", default="mappo", help=f"one of {', '.join(ALGORITHMS)} (default: mappo)")
    p.add_argument("--task", required=True, help="a coopnav task set, optionally /<task> of it (e.g. gao_sea/calm)")
    p.add_argument("--frames", type=int, help="env-steps to train (BenchMARL's max_n_frames; default: the YAML's)")
    p.add_argument(
        "--out", help="run folder to create, absent or empty (default: runs/marl/<task>-<algorithm>-seed<seed>)"
    )
    p.add_argument("--seed", type=int, default=0, help="base seed: row e plays episodes seed + e + k * 1_000_003")
    p.add_argument("--n-envs", type=int, help="environments in the batch (on/off_policy_n_envs_per_worker)")
    p.add_argument("--model", default="mlp", help=f"policy model: {', '.join(MODELS)} (default: mlp)")
    p.add_argument("--critic-model", default="mlp", help="critic model (default: mlp)")
    p.add_argument("--experiment-config", help=f"experiment YAML (default: configs/benchmarl/{EXPERIMENT_YAML})")
    p.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE", help="an experiment setting")
    p.add_argument(
        "--algorithm-set",
        action="append",
        default=[],
        metavar="FIELD=VALUE",
        help="an algorithm setting (BenchMARL's algorithm YAML, e.g. use_tanh_normal=false, entropy_coef=0.01)",
    )
    p.add_argument(
        "--override",
        action="append",
        default=[],
        metavar="PARAM=VALUE",
        help="a scenario parameter on top of the task's",
    )
    p.add_argument(
        "--state", choices=("privileged", "observations"), help="the critics' state (default: the task YAML's)"
    )
    p.add_argument(
        "--reward-term",
        action="append",
        default=[],
        metavar="SIGNAL=WEIGHT",
        help="the training reward as weighted terms (coopnav_env.vector.REWARD_TERMS; repeat; default: the "
        "task YAML's reward_terms, else the env's reward)",
    )
    p.add_argument(
        "--eval-every-steps",
        type=int,
        default=0,
        metavar="N",
        help="every N env-steps and at the end, play --eval-episodes validation episodes with the deterministic "
        "actor (as evaluate.py plays it) and keep the best weights in <out>/best (a run folder; 0: never)",
    )
    p.add_argument("--eval-episodes", type=int, default=16, help="validation episodes (default: 16)")
    p.add_argument(
        "--eval-seed",
        type=int,
        default=VALIDATION_SEED,
        help=f"validation episode i is seeded EVAL_SEED + i (default: {VALIDATION_SEED})",
    )
    p.add_argument("--threads", type=int, default=1, help="torch threads (default: 1)")
    return p


def _choice(value: str, valid: Sequence[str], what: str) -> str:
    if value not in valid:
        from coopnav_env.names import did_you_mean

        raise ConfigError(f"unknown {what} {value!r}{did_you_mean(value, valid)} valid: {', '.join(valid)}")
    return value


def _model_config(name: str) -> Any:
    from benchmarl.models import GruConfig, LstmConfig, MlpConfig

    return {"mlp": MlpConfig, "gru": GruConfig, "lstm": LstmConfig}[name].get_from_yaml()


def _algorithm_config(name: str, changes: Mapping[str, Any] | None = None) -> Any:
    """BenchMARL's config of algorithm ``name`` (its YAML) with ``changes`` (``--algorithm-set``):
    an unknown field, or a value of another type than the default's, is one ``ConfigError``."""
    import dataclasses

    import benchmarl.algorithms as algos

    config = getattr(algos, f"{name.capitalize()}Config").get_from_yaml()
    fields = sorted(f.name for f in dataclasses.fields(config))
    for key, value in (changes or {}).items():
        _choice(key, fields, f"{name} setting")
        default = getattr(config, key)
        if not like_default(value, default):
            raise ConfigError(f"--algorithm-set {key} must be like its default {default!r}, got {value!r}")
    return dataclasses.replace(config, **(changes or {}))


def experiment_config(
    path: str | Path | None, n_envs: int | None, frames: int | None, changes: dict, on_policy: bool
) -> Any:
    """BenchMARL's ``ExperimentConfig``: its defaults, the coopnav YAML's changes, then
    ``n_envs``, ``frames`` and ``changes``. A batch larger than ``frames`` is cut to it
    (rounded to whole steps of the batch), and the evaluation interval to a multiple of it."""
    import dataclasses

    from benchmarl.experiment import ExperimentConfig
    from benchmarl.utils import _read_yaml_config

    from .benchmarl_task import CONFIG_DIR

    base = ExperimentConfig.get_from_yaml()
    values = _read_yaml_config(str(path or CONFIG_DIR / EXPERIMENT_YAML))
    fields = {f.name for f in dataclasses.fields(ExperimentConfig)}
    for key in [*values, *changes]:
        _choice(key, sorted(fields), "experiment setting")
    config = dataclasses.replace(base, **values)
    kind = "on_policy" if on_policy else "off_policy"
    if n_envs is not None:
        if n_envs < 1:
            raise ConfigError(f"--n-envs must be >= 1, got {n_envs}")
        setattr(config, f"{kind}_n_envs_per_worker", n_envs)
    if frames is not None:
        if frames < 1:
            raise ConfigError(f"--frames must be >= 1, got {frames}")
        config.max_n_frames = frames
    for key, value in changes.items():  # e.g. a number where BenchMARL's default is one (not Adam's TypeError)
        default = getattr(config, key)
        if not like_default(value, default):
            kind = "true or false" if isinstance(default, bool) else "a number"
            raise ConfigError(f"--set {key} must be {kind} (BenchMARL's default {default!r}), got {value!r}")
    config = dataclasses.replace(config, **changes)
    n = getattr(config, f"{kind}_n_envs_per_worker")
    per_batch = getattr(config, f"{kind}_collected_frames_per_batch")
    if config.max_n_frames is not None and config.max_n_frames < per_batch:
        per_batch = max(n, config.max_n_frames // n * n)
        setattr(config, f"{kind}_collected_frames_per_batch", per_batch)
        if on_policy:
            config.on_policy_minibatch_size = min(config.on_policy_minibatch_size, per_batch)
        else:
            config.off_policy_train_batch_size = min(config.off_policy_train_batch_size, per_batch)
    if config.evaluation_interval % per_batch:
        config.evaluation_interval = max(per_batch, config.evaluation_interval // per_batch * per_batch)
    return config


class ProgressCallback(Callback):
    """A BenchMARL callback that shows the run's progress (``coopnav_env.progress``) in
    env-steps. BenchMARL pickles its callbacks with the experiment: the bar is not kept."""

    def __init__(self, total: int) -> None:
        super().__init__()
        self.total = int(total)
        self.bar: Any = None
        self.last_return: float | None = None
        self.last_error_m: float | None = None

    def __getstate__(self) -> dict:
        return {**self.__dict__, "bar": None}

    def on_batch_collected(self, batch: Any) -> None:
        from coopnav_env.progress import Progress

        if self.bar is None:
            self.bar = Progress(total=self.total, unit="env-steps", desc="training")
        self.bar.update(batch.numel())
        err = batch.get(("next", "info", "survey_error_m"), None)
        self.last_error_m = None if err is None else float(err.float().mean())
        ret = getattr(self.experiment, "mean_return", None)
        self.last_return = None if ret is None else float(ret)
        text = f"mean return {self.last_return:.3g}" if self.last_return is not None else "training"
        if self.last_error_m is not None:
            text += f", survey error {self.last_error_m:.1f} m"
        self.bar.stage(text)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def build_experiment(
    algorithm: str,
    task: Any,
    seed: int,
    config: Any,
    model: Any = "mlp",
    critic_model: Any = "mlp",
    callbacks: Sequence[Any] = (),
    algorithm_changes: Mapping[str, Any] | None = None,
) -> Any:
    """BenchMARL's ``Experiment`` for a coopnav ``task`` (``benchmarl_task.get_task``);
    ``model`` and ``critic_model``: a name of ``MODELS`` (BenchMARL's YAML) or a ``ModelConfig``;
    ``algorithm_changes``: fields of the algorithm's config (``--algorithm-set``)."""
    from benchmarl.experiment import Experiment

    return Experiment(
        task=task,
        algorithm_config=_algorithm_config(algorithm, algorithm_changes),
        model_config=_model_config(model) if isinstance(model, str) else model,
        critic_model_config=_model_config(critic_model) if isinstance(critic_model, str) else critic_model,
        seed=seed,
        config=config,
        callbacks=list(callbacks),
    )


def _quiet_benchmarl_bar() -> None:
    """BenchMARL draws its own tqdm bar (no switch); ours replaces it (bar or lines)."""
    import functools

    import benchmarl.experiment.experiment as bx
    from tqdm import tqdm

    bx.tqdm = functools.partial(tqdm, disable=True)


def run(args: argparse.Namespace, command: str) -> dict:
    from coopnav_env.seeds import refuse_test_seeds

    from . import runlock
    from .benchmarl_task import get_task

    algorithm = _choice(args.algorithm, ALGORITHMS, "algorithm")
    _choice(args.model, MODELS, "model")
    _choice(args.critic_model, MODELS, "critic model")
    set_name, _, task_name = args.task.partition("/")
    if args.eval_every_steps < 0 or args.eval_episodes < 1:
        raise ConfigError(
            f"--eval-every-steps must be >= 0 and --eval-episodes >= 1, got {args.eval_every_steps} and "
            f"{args.eval_episodes}"
        )
    try:
        refuse_test_seeds(args.seed, 1, what="--seed")
        if args.eval_every_steps:
            refuse_test_seeds(args.eval_seed, args.eval_episodes, what="--eval-seed")
    except ValueError as err:
        raise ConfigError(str(err)) from None
    out = Path(args.out or f"runs/marl/{args.task.replace('/', '_')}-{algorithm}-seed{args.seed}")
    changes = parse_assignments(args.set, "--set")
    overrides = parse_assignments(args.override, "--override")
    import logging
    import warnings

    warnings.filterwarnings("ignore", message="TaskConfig python dataclass not found")
    warnings.filterwarnings("ignore", message="SyncDataCollector has been deprecated")  # BenchMARL 1.5.2's use
    logging.getLogger("torchrl").setLevel(logging.WARNING)  # one INFO line per buffer and spec check
    try:
        task_changes: dict[str, Any] = {}
        if overrides:
            task_changes["overrides"] = overrides
        if args.state:
            task_changes["state"] = args.state
        if args.reward_term:
            task_changes["reward_terms"] = parse_assignments(args.reward_term, "--reward-term")
        task = get_task(set_name, task_name or None, **task_changes)
        from .benchmarl_task import scenario_config

        scenario = scenario_config(task.config, set_name)  # checks the overrides now, not after the setup
    except ValueError as err:
        raise ConfigError(str(err)) from None
    algorithm_changes = parse_assignments(args.algorithm_set, "--algorithm-set")
    algo = _algorithm_config(algorithm, algorithm_changes)
    try:
        config = experiment_config(args.experiment_config, args.n_envs, args.frames, changes, algo.on_policy())
    except (TypeError, ValueError) as err:
        raise ConfigError(str(err)) from None
    runlock.claim(out, new=True, command=command)
    partial = out / ".partial"
    partial.mkdir()
    config.save_folder = str(partial.resolve())
    import torch

    _quiet_benchmarl_bar()
    progress = ProgressCallback(int(config.get_max_n_frames(algo.on_policy())))
    callbacks: list[Any] = [progress]
    task_fields = {"task": f"coopnav/{set_name}", "task_config": task.config, "scenario": scenario.name}
    validation = None
    if args.eval_every_steps:
        from .marl_validation import ValidationCallback

        validation = ValidationCallback(
            args.eval_every_steps,
            args.eval_episodes,
            args.eval_seed,
            scenario,
            task_fields,
            algorithm,
            args.model,
            scratch=partial / "validation",
            best=partial / "best",
        )
        callbacks.append(validation)
    experiment = build_experiment(
        algorithm, task, args.seed, config, args.model, args.critic_model, callbacks, algorithm_changes
    )
    torch.set_num_threads(max(int(args.threads), 1))  # after the envs: numba's OpenMP start resets torch's count
    t0 = time.perf_counter()
    from coopnav_env.torchrl_env import NonFiniteAction

    try:
        experiment.run()
    except NonFiniteAction as err:  # the env refuses NaN actions: say so in one line, keep the files
        seen = int(progress.bar.n) if progress.bar is not None else 0
        raise TrainingDiverged(
            f"training diverged after about {seen:,} env-steps: {err} (the policy's parameters became NaN; "
            f"a scaled reward (--reward-term weights such as 0.01: BenchMARL does not normalize rewards), "
            f"--algorithm-set use_tanh_normal=false or a lower --set lr=... may help); BenchMARL's files are in "
            f"{partial}: remove {out} to train again"
        ) from None
    finally:
        progress.close()
    wall = time.perf_counter() - t0
    validation_s = validation.seconds if validation is not None else 0.0  # inside wall: taken out of env-steps/s
    best = validation.finish() if validation is not None else None
    os.replace(experiment.folder_name, out / "benchmarl")
    if best is not None:
        os.replace(partial / "best", out / "best")
    partial.rmdir()
    from .marl_validation import save_weights

    save_weights(experiment, out / "policy.safetensors")
    frames = int(experiment.total_frames)
    from ..benchmarl_policy import policy_record

    record = {
        "command": command,
        **policy_record(experiment, algorithm, args.model),  # what agents.load rebuilds the actor from
        **task_fields,
        "critic_model": args.critic_model,
        "seed": args.seed,
        "experiment_config": {k: v for k, v in vars(config).items() if _jsonable(v)},
        "frames": frames,
        "wall_s": wall,
        "env_steps_per_s": frames / (wall - validation_s) if wall > validation_s else None,
        "validation_s": validation.seconds if validation is not None else 0.0,
        "last_mean_return": progress.last_return,
        "last_batch_survey_error_m": progress.last_error_m,
        **(
            {}
            if validation is None
            else {
                "validation": validation.history,
                "validation_seeds": [validation.seeds[0], validation.seeds[-1]],
                "best": best,
            }
        ),
        "torch_threads": torch.get_num_threads(),
        "load_avg_1m": os.getloadavg()[0],
        "python": platform.python_version(),
    }
    from coopnav_env.records import atomic_write_text

    atomic_write_text(out / "run.json", json.dumps(record, indent=2, default=str))
    return record


class TrainingDiverged(RuntimeError):
    """The run stopped because its policy's actions became NaN (one line; exit status 1)."""


def _jsonable(value: Any) -> bool:
    try:
        json.dumps(value)
    except (TypeError, ValueError):
        return False
    return True


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    command = "python -m agents.training.marl " + shlex.join(sys.argv[1:] if argv is None else list(argv))
    from . import runlock

    try:
        record = run(args, command)
    except ConfigError as err:
        print(f"marl: error: {err}", file=sys.stderr)
        return 2
    except TrainingDiverged as err:
        print(f"marl: error: {err}", file=sys.stderr)
        return 1
    finally:
        runlock.release_all()
    from coopnav_env.progress import format_seconds, say

    say(
        f"done: {record['frames']} env-steps in {format_seconds(record['wall_s'])} "
        f"({record['env_steps_per_s']:.0f} env-steps/s); run folder {args.out or 'runs/marl/...'}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
