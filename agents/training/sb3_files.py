"""The files of an SB3 run that ``agents.training.sb3`` reads back: the checkpoint record
and its files (``checkpoint_files``), a resume before the first checkpoint
(``restart_from_scratch``), where the evaluation schedule goes on (``last_evaluation_step``),
a warm start's files (``warm_start_files``) and loading weights, optimizer state and
normalization statistics into a freshly built PPO (``load_state``, ``read_stats``,
``restore_stats``). Every failure is a ``ConfigError`` with one line saying what."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

from agents import formats
from agents.formats import PolicyFormatError
from coopnav_env.records import read_json

from .config import ConfigError

RESTART_OUTPUTS = (
    "evaluations.jsonl",
    "best.json",
    "best_model.safetensors",
    "best_vecnormalize.safetensors",
    "baseline_eval.json",
)


def checkpoint_files(out: Path, trust_pickle: bool = False) -> dict | None:
    """``last_checkpoint.json`` of run ``out`` with its files as paths (None: no
    checkpoint yet). Its files must lie in ``checkpoints/`` and, if pickle-based,
    be trusted; a ``ConfigError`` else."""
    import agents

    ckpt_dir = out / "checkpoints"
    last = ckpt_dir / "last_checkpoint.json"
    if not last.is_file():
        return None
    try:
        info = read_json(last)
        entry: dict[str, Any] = {
            "num_timesteps": int(info["num_timesteps"]),
            "model": str(info["model"]),
            "vecnormalize": str(info["vecnormalize"]),
        }
    except (OSError, ValueError, KeyError, TypeError, OverflowError):
        raise ConfigError(f"{last} is not a checkpoint record (num_timesteps, model, vecnormalize)") from None
    if not 0 <= entry["num_timesteps"] <= 10**12:
        raise ConfigError(f"{last}: num_timesteps {entry['num_timesteps']} is out of range [0, 10**12]")
    try:
        from agents.safe_paths import check_tree

        check_tree(out)  # checkpoints/ or a file in it linked from outside the run: refused
        for key in ("model", "vecnormalize"):
            entry[key] = formats.check_inside(ckpt_dir, entry[key], f"{last}: {key}")
        agents._check_trusted([entry["model"], entry["vecnormalize"]], trust_pickle)
    except PolicyFormatError as err:
        raise ConfigError(str(err)) from None
    for key in ("model", "vecnormalize"):
        if not entry[key].is_file():
            raise ConfigError(f"{last} names {entry[key].name}, which is missing from {ckpt_dir}")
    return entry


def restart_from_scratch(out: Path) -> None:
    """``--resume`` of a run stopped before its first checkpoint: it starts again from
    step 0 with its config.yml. Nothing is deleted: a run holding a model or
    evaluations but no checkpoint (an old run, a damaged one) is refused instead."""
    if (out / "model.safetensors").is_file():
        raise ConfigError(
            f"{out} holds a final model but no checkpoint record (checkpoints/last_checkpoint.json): not resumable"
        )
    kept = [name for name in RESTART_OUTPUTS if name != "baseline_eval.json" and (out / name).exists()]
    if kept:
        raise ConfigError(
            f"{out} has no checkpoint (checkpoints/last_checkpoint.json) but holds {', '.join(kept)}: "
            "resuming would restart it and lose them; not resumable (start a new run with --out)"
        )
    print(
        f"note: {out} has no checkpoint yet (stopped before its first one): starting it from scratch with its "
        f"config.yml",
        file=sys.stderr,
    )


def last_evaluation_step(out: Path, steps: int) -> int:
    """The step count of the last evaluation in ``out/evaluations.jsonl`` at or before
    ``steps`` (0: none), where a resumed run's evaluation schedule goes on from."""
    try:
        lines = (out / "evaluations.jsonl").read_text().splitlines()
    except (OSError, UnicodeDecodeError):
        return 0
    done = 0
    for line in lines:
        try:
            n = json.loads(line)["num_timesteps"]
        except (ValueError, KeyError, TypeError, RecursionError):
            continue
        if isinstance(n, int) and not isinstance(n, bool) and done < n <= steps:
            done = n
    return done


def warm_start_files(spec: Any, trust_pickle: bool = False) -> tuple:
    """(model file, normalization file or None) of ``init_from`` (``agents.resolve``)."""
    import agents
    from agents import rllib_policy

    if rllib_policy.is_rllib_path(str(spec)):
        raise ConfigError(
            f"init_from: {spec!r} is not a stable-baselines3 model (an RLlib run): an SB3 run or policy only"
        )
    try:
        model, stats, _ = agents.resolve(str(spec), trust_pickle=trust_pickle)
    except ValueError as err:
        raise ConfigError(f"init_from: {err}") from None
    if model.name == "gate.yml":
        raise ConfigError(
            f"init_from: {spec!r} is a gate of two networks ({model}); name one of its networks "
            "(the directories that file lists)"
        )
    if model.suffix not in (".zip", ".safetensors"):
        raise ConfigError(f"init_from: {spec!r} is not a stable-baselines3 model ({model}): an SB3 run or policy only")
    return model, stats


def load_state(model: Any, path: Path, device: str, what: str, restore_steps: bool = False) -> None:
    """Load a model file's network weights (and optimizer state, if it holds one) into
    ``model`` (a PPO built from the config); with ``restore_steps`` its step count too.
    A trusted pickle-based .zip goes through SB3's ``set_parameters``."""
    if path.suffix == ".zip":
        try:
            model.set_parameters(str(path), exact_match=True, device=device)
        except (RuntimeError, ValueError, KeyError) as err:
            raise ConfigError(f"{what} does not fit this network: {_first_line(err)}") from None
        return
    try:
        spec, state, optim = formats.read_model(path)
    except PolicyFormatError as err:
        raise ConfigError(str(err)) from None
    try:
        model.policy.load_state_dict(state, strict=True)
        if optim is not None:
            model.policy.optimizer.load_state_dict(optim)
    except (RuntimeError, ValueError, KeyError) as err:
        raise ConfigError(f"{what} does not fit this network: {_first_line(err)}") from None
    if restore_steps:
        model.num_timesteps = int(spec.get("num_timesteps", 0))
        model._n_updates = int(spec.get("n_updates", 0))


def read_stats(path: str | Path) -> dict | None:
    """A VecNormalize statistics file's contents (``agents.load_stats``); a ``ConfigError`` if unreadable."""
    import agents

    try:
        return agents.load_stats(path)
    except PolicyFormatError as err:
        raise ConfigError(str(err)) from None


def restore_stats(vecnorm: Any, stats: dict, path: str | Path) -> None:
    """Put ``stats`` (read from ``path``) into ``vecnorm``; a ``ConfigError`` naming ``path`` if they do not fit."""
    try:
        formats.restore_vecnormalize(vecnorm, stats)
    except PolicyFormatError as err:
        raise ConfigError(f"{path}: {err}") from None


def _first_line(err) -> str:
    return str(err).splitlines()[0] if str(err) else type(err).__name__
