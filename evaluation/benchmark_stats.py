"""The benchmark's statistics, pure (arrays in, dicts out): each policy's mean error with
its t interval per task, the paired difference against the task's best planner and
its verdict, and the win/tie/loss counts of a task set (``evaluation.benchmark``)."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np


def compare_task(
    episode_errors: dict,
    planners: Iterable[str],
    ranges_fused: dict | None = None,
    skipped: dict | None = None,
    confidence: float = 0.95,
) -> dict:
    """One task's statistics from ``episode_errors`` (policy -> per-episode mean errors,
    episode ``i`` of every policy on the same seed; None: the policy cannot drive the
    task, for the reason in ``skipped``), ``planners`` (the names the best planner is
    chosen from) and ``ranges_fused`` (policy -> ranges fused per episode). Returns
    ``{"best_planner", "policies": {name: stats}, "wins"}`` (see the module docstring)."""
    from .paired import t_interval

    ranges_fused, skipped = ranges_fused or {}, skipped or {}
    runs = {p: np.asarray(v, dtype=float) for p, v in episode_errors.items() if v is not None}
    lengths = {len(v) for v in runs.values()}
    if len(lengths) > 1:
        raise ValueError(f"policies played different numbers of episodes: {sorted(lengths)}")
    candidates = [p for p in planners if p in runs]
    if not candidates:
        raise ValueError("no planner ran on this task")
    best = min(candidates, key=lambda p: (float(runs[p].mean()), candidates.index(p)))
    out, wins = {}, []
    for p, v in episode_errors.items():
        if v is None:
            out[p] = {"skipped": skipped.get(p, "cannot drive this task")}
            continue
        x = runs[p]
        mean, lo, hi = t_interval(x, confidence)
        stats = {
            "episodes": int(x.size),
            "mean_error_m": mean,
            "ci95_error_m": [lo, hi],
            "episode_mean_error_m": x.tolist(),
        }
        rf = ranges_fused.get(p)
        if rf is not None:
            rf = np.asarray(rf, dtype=float)
            stats["ranges_fused"] = float(rf.mean())
            stats["episode_ranges_fused"] = rf.tolist()
        if p == best:
            stats["paired"] = {"vs": best, "mean_m": 0.0, "ci95_m": [0.0, 0.0], "verdict": "best"}
        else:
            d_mean, d_lo, d_hi = t_interval(x - runs[best], confidence)
            verdict = "win" if d_hi < 0 else "loss" if d_lo > 0 else "tie"
            stats["paired"] = {"vs": best, "mean_m": d_mean, "ci95_m": [d_lo, d_hi], "verdict": verdict}
            if verdict == "win":
                wins.append(p)
        out[p] = stats
    return {"best_planner": best, "policies": out, "wins": wins}


def summarize_task_set(tasks: dict, policies: Iterable[str]) -> dict:
    """Per policy the count of each verdict over ``tasks`` (task -> ``compare_task``'s
    result): ``{policy: {"win", "tie", "loss", "best", "n/a", "tasks_won"}}``."""
    out = {}
    for p in policies:
        counts: dict[str, Any] = {"win": 0, "tie": 0, "loss": 0, "best": 0, "n/a": 0, "tasks_won": []}
        for name, task in tasks.items():
            stats = task["policies"].get(p)
            if stats is None or "skipped" in stats:
                counts["n/a"] += 1
                continue
            verdict = stats["paired"]["verdict"]
            counts[verdict] += 1
            if verdict == "win":
                counts["tasks_won"].append(name)
        out[p] = counts
    return out
