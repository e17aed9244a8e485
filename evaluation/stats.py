"""Statistics of an evaluation: the survey-error statistics of a policy over all steps of
all its episodes (with a cluster-bootstrap interval of the mean over episodes), the
moving-frame error statistics, and ``summarize``, which builds summary.json's content
per policy (and per sweep cell, plus the grid pooled).

The error statistics pool every step of every episode: the mean is the pooled mean,
and its 95 % interval resamples whole episodes (2000 draws, a fixed generator), so
steps of one episode are never treated as independent.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from coopnav_env.records import plain

from .config import cell_id

if TYPE_CHECKING:
    from .config import Plan


def error_stats(step_rows: list, episode_rows: list, n_boot: int = 2000) -> dict:
    """One policy's statistics (summary.json's ``policies.<name>``) from its step and
    episode rows (dicts; values may be the CSV's text)."""
    err = np.array([float(r["survey_error_m"]) for r in step_rows])
    by_ep: dict = {}
    for r in step_rows:
        by_ep.setdefault(int(r["seed"]), []).append(float(r["survey_error_m"]))
    sums = np.array([np.sum(v) for v in by_ep.values()])
    counts = np.array([len(v) for v in by_ep.values()])
    mean = float(err.mean())
    if len(sums) > 1:  # cluster bootstrap over episodes of the pooled (ratio) mean
        rng = np.random.default_rng(12345)
        idx = rng.integers(0, len(sums), size=(n_boot, len(sums)))
        boot = sums[idx].sum(1) / counts[idx].sum(1)
        ci = [float(np.percentile(boot, 2.5)), float(np.percentile(boot, 97.5))]
    else:
        ci = [mean, mean]

    def ep_mean(key):
        return float(np.mean([float(r[key]) for r in episode_rows]))

    return {
        "episodes": len(episode_rows),
        "steps": int(err.size),
        "mean_error_m": mean,
        "median_error_m": float(np.median(err)),
        "p95_error_m": float(np.percentile(err, 95)),
        "std_error_m": float(err.std()),
        "var_error_m2": float(err.var()),
        "ci95_error_m": ci,
        "final_error_m": ep_mean("final_error_m"),
        "mean_dr_error_m": ep_mean("mean_dr_error_m"),
        "mean_return": ep_mean("return"),
        "ranges_fused": ep_mean("ranges_fused"),
        "outliers_rejected": ep_mean("outliers_rejected"),
        "beacon_distance_m": ep_mean("beacon_distance_m"),
        "pings": ep_mean("pings"),
        "energy_J": ep_mean("energy_J"),
        **frame_error_stats(step_rows),
    }


def frame_error_stats(step_rows: list) -> dict:
    """Moving-frame error statistics (Matos & Cruz sec. VIII): the standard deviation
    of the x and y errors over all steps; empty for scenarios without them."""
    ex = [float(r["error_x_m"]) for r in step_rows if r.get("error_x_m", "") != ""]
    ey = [float(r["error_y_m"]) for r in step_rows if r.get("error_y_m", "") != ""]
    if not ex:
        return {}
    return {
        "error_x_std_m": float(np.std(ex)),
        "error_y_std_m": float(np.std(ey)),
        "error_x_mean_m": float(np.mean(ex)),
        "error_y_mean_m": float(np.mean(ey)),
    }


def _per_policy(policies, ep_rows, step_rows, cells: set) -> dict:
    out = {}
    for p in policies:
        eps = [r for r in ep_rows if r["policy"] == p and r["cell"] in cells]
        sts = [r for r in step_rows if r["policy"] == p and r["cell"] in cells]
        if eps and sts:
            out[p] = error_stats(sts, eps)
    return out


def summarize(plan: Plan, ep_rows: list, step_rows: list) -> dict:
    """summary.json's content: the run's scenario, episodes, seed and overrides, and per
    policy ``error_stats``; a sweep adds ``sweep`` and ``cells`` (per cell: ``params``
    and ``policies``), and ``policies`` is then pooled over every cell of the grid."""
    policies, cells = plan.policies, plan.cells
    cell_stats = [
        {"params": plain(cell), "policies": _per_policy(policies, ep_rows, step_rows, {cell_id(cell)})}
        for cell in cells
    ]
    config = plan.config
    summary = {
        "scenario": config.scenario,
        "episodes": plan.episodes,
        "seed": config.seed,
        "overrides": plan.run_info["overrides"],
    }
    if plan.sweep:
        summary["sweep"] = plan.run_info["sweep"]
        summary["cells"] = cell_stats
        summary["policies"] = _per_policy(policies, ep_rows, step_rows, {cell_id(c) for c in cells})  # pooled
    else:
        summary["policies"] = cell_stats[0]["policies"]
    return summary


def find_cell(summary: dict, params: dict, policy: str) -> dict | None:
    """The statistics of ``policy`` in the sweep cell whose parameters include ``params``
    (JSON values), or None."""
    for c in summary.get("cells", []):
        if all(c["params"].get(k) == v for k, v in params.items()):
            return c["policies"].get(policy)
    return None
