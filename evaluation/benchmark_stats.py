"""The benchmark's statistics, pure (arrays in, dicts out): each policy's mean error with
its t interval per task, the paired difference against the task's best planner and
its verdict, and the win/tie/loss counts of a task set (``evaluation.benchmark``)."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np


def paired_verdict(lo: float, hi: float) -> str:
    """A challenger's verdict from the interval [lo, hi] of its paired difference (its
    error minus the reference's): "win" below 0, "loss" above 0, else "tie"."""
    return "win" if hi < 0 else "loss" if lo > 0 else "tie"


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
            verdict = paired_verdict(d_lo, d_hi)
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


def lowest_mean(policies: dict, candidates: Iterable[str]) -> str | None:
    """The policy of ``candidates`` with the lowest mean error among those that ran in a
    task's ``policies`` (``compare_task``'s result; a skipped one has no mean); the first
    listed on a tie; None if none ran. The best greedy planner of a task, for one."""
    ran = [p for p in candidates if "mean_error_m" in policies.get(p, {})]
    return min(ran, key=lambda p: float(policies[p]["mean_error_m"])) if ran else None


def headroom_task(
    task: dict,
    greedy: Iterable[str],
    challengers: Iterable[str],
    oracle: str = "oracle",
    confidence: float = 0.95,
) -> dict:
    """The headroom of one task (``compare_task``'s result ``task``): how much lower than
    the best greedy planner's error the reference ``oracle`` (guidance given the truth)
    gets, and the fraction of that each challenger closes.

    ``best_greedy``: the planner of ``greedy`` with the lowest mean error (g); ``oracle_m``:
    the oracle's mean error (o); ``headroom_m`` = g - o, with the paired 95 % t interval of
    the per-episode differences (``headroom_ci95_m``); for each policy p of ``challengers``
    that ran, with mean error c,

        closed[p] = (g - c) / (g - o)

    (1: as low as the oracle; 0: no better than the best greedy planner; negative: worse
    than it; above 1: lower than the oracle). With no oracle run, or an oracle not resolved
    below the best greedy planner (the paired interval of g - o not above 0: no headroom
    measured), every fraction is None and ``na`` says why, not a division by zero or a
    fraction of noise: on ``matos_moving_lbl`` headrooms of 0.003 m whose intervals held 0
    gave 464 % and -14144 % (benchmark v6 measures only resolved headrooms)."""
    from .paired import t_interval

    pol = task["policies"]

    def mean(p: str) -> float | None:
        st = pol.get(p)
        return None if st is None or "skipped" in st else float(st["mean_error_m"])

    best = lowest_mean(pol, greedy)
    out: dict[str, Any] = {"best_greedy": best, "best_greedy_m": None if best is None else mean(best)}
    challengers = list(challengers)
    o = mean(oracle)
    out.update({"oracle": oracle, "oracle_m": o, "headroom_m": None, "headroom_ci95_m": None})
    out["closed"] = dict.fromkeys(challengers)
    if best is None or o is None:
        out["na"] = f"no {'greedy planner' if best is None else oracle} ran on this task"
        return out
    g = float(pol[best]["mean_error_m"])
    diff = np.asarray(pol[best]["episode_mean_error_m"], float) - np.asarray(pol[oracle]["episode_mean_error_m"], float)
    _, lo, hi = t_interval(diff, confidence)
    out["headroom_m"], out["headroom_ci95_m"] = g - o, [lo, hi]
    if not g - o > 0:
        out["na"] = f"{oracle} no better than the best greedy planner ({best})"
        return out
    if not lo > 0:
        out["na"] = f"{oracle} not resolved below the best greedy planner ({best}): its interval holds 0"
        return out
    for p in challengers:
        c = mean(p)
        out["closed"][p] = None if c is None else (g - c) / (g - o)
    return out


def summarize_headroom(headrooms: dict, challengers: Iterable[str]) -> dict:
    """A task set's headroom from its tasks' ``headroom_task`` results (task -> result):
    over the tasks with a headroom (``closed`` defined), the mean best-greedy and oracle
    errors, the mean headroom, and per challenger the pooled fraction closed,
    sum(g - c) / sum(g - o) over the tasks where it ran (so a task with a larger
    headroom weighs more; None where it ran on none)."""
    challengers = list(challengers)
    with_room = {t: h for t, h in headrooms.items() if "na" not in h}
    out: dict[str, Any] = {"tasks": len(with_room), "tasks_without": sorted(set(headrooms) - set(with_room))}
    if not with_room:
        out.update(best_greedy_m=None, oracle_m=None, headroom_m=None, closed=dict.fromkeys(challengers))
        return out
    g = np.array([h["best_greedy_m"] for h in with_room.values()])
    o = np.array([h["oracle_m"] for h in with_room.values()])
    out.update(best_greedy_m=float(g.mean()), oracle_m=float(o.mean()), headroom_m=float((g - o).mean()))
    closed: dict[str, float | None] = {}
    for p in challengers:
        num = den = 0.0
        for h in with_room.values():
            f = h["closed"].get(p)
            if f is not None:
                room = h["best_greedy_m"] - h["oracle_m"]
                num, den = num + f * room, den + room
        closed[p] = num / den if den > 0 else None
    out["closed"] = closed
    return out
