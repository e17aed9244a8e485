"""The files of an RLlib run (``agents.training.rllib``'s part 2): the checkpoint and its
safe export, what a resume reads, the progress lines a crash leaves behind, the metrics
of a result and the evaluation of a checkpoint on the fixed seeds."""

from __future__ import annotations

import json
import os
import shutil
import sys
from pathlib import Path
from typing import Any

import numpy as np

from coopnav_env.records import atomic_write_text, read_json

from .common import Job
from .config import RLlibConfig
from .scoring import evaluate


def save_checkpoint(algo: Any, out: Path, meta: dict) -> Path:
    """The Algorithm checkpoint in ``out/checkpoint``, replaced whole: written to a
    temporary directory beside it, then renamed into place."""
    final = out / "checkpoint"
    tmp = out / f".checkpoint.tmp{os.getpid()}"
    old = out / f".checkpoint.old{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    algo.save_to_path(str(tmp.resolve()))
    from agents.rllib_policy import export

    export(tmp)  # policy_export/: the modules and filters as data, what agents.load reads (no pickle)
    atomic_write_text(tmp / "coopnav.json", json.dumps(meta))
    if final.exists():
        os.replace(final, old)
    os.replace(tmp, final)
    shutil.rmtree(old, ignore_errors=True)
    return final


def resumable_checkpoint(out: Path) -> dict | None:
    """The ``coopnav.json`` of ``out/checkpoint`` (None: nothing to resume from), after
    tidying what a killed ``save_checkpoint`` may have left: if the process died between
    its two renames (no ``checkpoint/``), the newest complete checkpoint beside it
    (``.checkpoint.tmp*`` holds ``coopnav.json`` only once complete; ``.checkpoint.old*``
    is a former ``checkpoint/``) is put back; the other leftovers are removed."""
    from agents.rllib_policy import CHECKPOINT_MARKER

    final = out / "checkpoint"
    meta = read_json(final / "coopnav.json")
    spares = [d for d in out.glob(".checkpoint.*") if d.is_dir()]
    if meta is None and not final.exists():
        complete = [(read_json(d / "coopnav.json"), d) for d in spares if (d / CHECKPOINT_MARKER).is_file()]
        complete = [(m, d) for m, d in complete if m is not None]
        if complete:
            meta, best = max(complete, key=lambda md: int(md[0].get("iteration", 0)))
            os.replace(best, final)
            print(f"note: restored {final} from {best.name} (the last save was cut short)", file=sys.stderr)
    for d in spares:
        shutil.rmtree(d, ignore_errors=True)
    if meta is None or "env_steps" not in meta or "iteration" not in meta:
        return None
    return meta


def drop_lost_iterations(out: Path, iteration: int) -> None:
    """Keep the lines of ``progress.jsonl`` up to ``iteration`` (the checkpoint a resumed
    run continues from): a run killed without a last checkpoint logged iterations whose
    training the checkpoint does not hold, and the resumed run trains them again."""
    path = out / "progress.jsonl"
    if not path.is_file():
        return
    lines = path.read_text().splitlines()

    def kept(line):
        try:
            return int(json.loads(line)["iteration"]) <= iteration
        except (ValueError, KeyError, TypeError):  # a line cut short by the kill
            return False

    keep = [line for line in lines if kept(line)]
    if len(keep) != len(lines):
        atomic_write_text(path, "".join(line + "\n" for line in keep))


def metrics(result: dict) -> dict:
    """The few numbers of an RLlib result that a run records."""
    er = result.get("env_runners", {}) or {}

    def num(v):
        try:
            v = float(v)
        except (TypeError, ValueError):
            return None
        return v if np.isfinite(v) else None

    steps = result.get("num_env_steps_sampled_lifetime", er.get("num_env_steps_sampled_lifetime", 0))
    return {
        "iteration": int(result.get("training_iteration", 0)),
        "env_steps": int(num(steps) or 0),
        "episode_return_mean": num(er.get("episode_return_mean")),
        "survey_error_m": num(er.get("survey_error_m")),
        "episodes": int(num(er.get("num_episodes_lifetime")) or 0),
        "time_s": num(result.get("time_total_s")),
    }


def evaluate_checkpoint(path: str | Path, config: RLlibConfig, job: Job) -> dict | None:
    """The deterministic policy of checkpoint ``path`` on the fixed evaluation seeds
    (``scoring.evaluate``); None with ``eval.episodes`` 0."""
    if config.eval.episodes <= 0:
        return None
    from agents.rllib_policy import batch_actor

    return evaluate(batch_actor(path, job.scenario_config), job.cells, config.eval.episodes, config.eval.seed)


def _last_json_line(path: Path) -> dict | None:
    try:
        lines = path.read_text().splitlines()
    except FileNotFoundError:
        return None
    for line in reversed(lines):
        try:
            return json.loads(line)
        except ValueError:  # a line cut short
            continue
    return None
