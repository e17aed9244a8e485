"""The learning curve of a run: ``learning_curve.png`` in its run directory.

    from agents.training.curve import draw_learning_curve
    draw_learning_curve("runs/sousa_ppo")       # also: coopnav-train --plot runs/sousa_ppo

Two panels, one x axis each: the validation error (``evaluations.jsonl``:
``survey_error_m`` on the validation seeds, lower is better) against environment steps,
and against training time (``train_s``: the wall clock since learning started, without
the validations), with each planner's error on the same seeds (``baseline_eval.json``)
as a horizontal line and the best model marked. ``train.py`` draws it when a run ends
or stops (stable-baselines3 runs; an RLlib run's progress.jsonl has no validations).
"""

from __future__ import annotations

import io
import json
import math
from pathlib import Path
from typing import TypeGuard

__all__ = ["FILENAME", "draw_learning_curve"]

FILENAME = "learning_curve.png"


def _records(run: Path) -> list:
    path = run / "evaluations.jsonl"
    if not path.is_file():
        return []
    out = []
    for line in path.read_text().splitlines():
        try:
            out.append(json.loads(line))
        except ValueError:  # a line cut by a crash: skip it
            continue
    keys = ("survey_error_m", "num_timesteps")
    return [r for r in out if isinstance(r, dict) and all(_number(r.get(k)) for k in keys)]


def _number(x: object) -> TypeGuard[float]:
    """A finite real number (not a bool): what a record's fields must be to be drawn; a line
    with anything else (a hand-edited or foreign file) is skipped as a cut one is."""
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def draw_learning_curve(run: str | Path, path: str | Path | None = None) -> Path | None:
    """Draw ``run``'s learning curve into ``path`` (default ``RUN/learning_curve.png``),
    200 dpi, atomically. Returns the path, or None when the run has no validation yet."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from coopnav_env.records import atomic_write_bytes, read_json

    run = Path(run)
    records = _records(run)
    if not records:
        return None
    baselines = read_json(run / "baseline_eval.json") or {}
    best = read_json(run / "best.json") or {}
    baselines = baselines if isinstance(baselines, dict) else {}  # anything else: drawn without them
    best = best if isinstance(best, dict) else {}
    steps = [r["num_timesteps"] for r in records]
    errors = [r["survey_error_m"] for r in records]
    times = [next((t for t in (r.get("train_s"), r.get("wall_s")) if _number(t)), 0.0) for r in records]
    fig = Figure(figsize=(10, 4.2))
    FigureCanvasAgg(fig)
    left, right = fig.add_subplot(1, 2, 1), None
    right = fig.add_subplot(1, 2, 2, sharey=left)
    for ax, xs, label in (
        (left, steps, "environment steps (rows: beacons x environments)"),
        (right, times, "training time (s, validations excluded)"),
    ):
        ax.plot(xs, errors, "o-", color="tab:blue", ms=3.5, lw=1.4, label="PPO (validation)")
        for k, (name, score) in enumerate(sorted(baselines.items())):
            value = score.get("survey_error_m") if isinstance(score, dict) else None
            if _number(value):
                ax.axhline(value, color=f"C{k + 1}", ls="--", lw=1.1, label=f"{name} ({value:.3f} m)")
        if best.get("num_timesteps") in steps:
            i = steps.index(best["num_timesteps"])
            ax.plot(
                [xs[i]],
                [errors[i]],
                marker="*",
                ms=13,
                color="tab:blue",
                mec="k",
                ls="none",
                label=f"best model ({errors[i]:.3f} m)",
            )
        ax.set_xlabel(label)
        ax.grid(True, lw=0.3)
    # an early blow-up (hundreds of metres) would flatten the rest: clip the axis, mark what is above it
    import statistics

    scores = [v.get("survey_error_m") for v in baselines.values() if isinstance(v, dict)]
    lines = [v for v in scores if _number(v)]
    top = 2.5 * max([statistics.median(errors)] + lines)
    if max(errors) > top:
        for ax, xs in ((left, steps), (right, times)):
            above = [x for x, e in zip(xs, errors) if e > top]
            ax.set_ylim(0, top)
            ax.plot(
                above,
                [top * 0.98] * len(above),
                "^",
                color="tab:red",
                ms=7,
                ls="none",
                label=f"off the scale (up to {max(errors):.0f} m)" if ax is right else None,
            )
    left.set_ylabel("validation mean survey error (m)")
    right.legend(fontsize=7, loc="best")
    record: dict = {}
    try:
        import yaml

        record = yaml.safe_load((run / "config.yml").read_text()) or {}
    except (OSError, ValueError, ImportError, AttributeError):
        pass
    scenario = (record.get("args") or {}).get("scenario", "?") if isinstance(record, dict) else "?"
    fig.suptitle(
        f"{run.name}: PPO on {scenario}, validation error (lower is better) beside the planners on the same seeds",
        fontsize=10,
    )
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=200)
    out = Path(path) if path is not None else run / FILENAME
    atomic_write_bytes(out, buf.getvalue())
    return out
