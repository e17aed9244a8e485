"""The evaluation's tables: what every column of episodes.csv and steps.csv means
(``EPISODE_COLUMN_DOCS``, ``STEP_COLUMN_DOCS``) and every statistic of summary.json /
summary.md (``SUMMARY_COLUMN_DOCS``), with units; the CSV text; and summary.md.

These dicts are the one definition of the columns: the CSV headers are their keys in
order, summary.md's "Columns" section is written from them, and the documentation
site generates its tables from them:

    from evaluation.report import EPISODE_COLUMN_DOCS
    for name, (unit, meaning) in EPISODE_COLUMN_DOCS.items():
        print(f"| {name} | {unit} | {meaning} |")

A sweep adds one column per swept parameter to episodes.csv, after ``cell``, in the
parameter's own unit (see ``coopnav_env.scenarios.ScenarioConfig``).
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from coopnav_env.records import plain

from .config import sweep_layout
from .stats import find_cell

if TYPE_CHECKING:
    from .config import Plan

# name -> (unit, meaning); "" unit: a label
_IDENTITY_DOCS = {
    "cell": ("", "the sweep cell, as KEY=VALUE;KEY=VALUE (empty without --sweep)"),
    "policy": ("", "the policy's name as given to --policies"),
    "episode": ("", "the episode's index i (0-based) within the run"),
    "seed": ("", "the episode's seed, --seed + i (the same for every policy: common random numbers)"),
}
EPISODE_COLUMN_DOCS = {
    **_IDENTITY_DOCS,
    "steps": ("count", "steps (acoustic cycles) the episode lasted"),
    "duration_s": ("s", "simulated duration: steps x ping_interval_s"),
    "mean_error_m": ("m", "survey_error_m averaged over the episode's steps"),
    "final_error_m": ("m", "survey_error_m at the last step"),
    "max_error_m": ("m", "largest survey_error_m of the episode"),
    "mean_dr_error_m": ("m", "dr_error_m (dead reckoning alone) averaged over the episode's steps"),
    "final_dr_error_m": ("m", "dr_error_m at the last step"),
    "return": (
        "unitless",
        "sum over steps of the reward (mean over beacons); higher is better for the reward, which "
        "is not the error (see summary.md's return)",
    ),
    "ranges_fused": ("count", "acoustic ranges the survey filters fused (all survey vehicles)"),
    "outliers_rejected": ("count", "ranges the filters' outlier gate rejected (all survey vehicles)"),
    "packets_lost": ("count", "acoustic packets lost (all survey vehicles)"),
    "beacon_distance_m": ("m", "beacon-survey distance (3-D, mean over pairs) averaged over the steps"),
    "safety_violations": ("count", "steps with a beacon closer to a survey vehicle than safety_distance_m"),
    "geofence_violations": ("count", "steps with a beacon outside geofence_m (never for the moving network)"),
    "pings": ("count", "pings the beacons transmitted (on the fixed clock: every beacon every cycle)"),
    "collisions": ("count", "pings lost to overlapping arrivals (channel_mode='decide' only; 0 on the fixed clock)"),
    "energy_J": ("J", "transmit energy of the pings: pings x transmit_power_w x the ping's duration"),
}
STEP_COLUMN_DOCS = {
    **_IDENTITY_DOCS,
    "step": ("", "the step's number within the episode (1-based)"),
    "t_s": ("s", "simulated time at the end of the step: step x ping_interval_s"),
    "survey_error_m": ("m", "true horizontal error of the survey filter's (EKF) estimate, mean over survey vehicles"),
    "dr_error_m": ("m", "true horizontal error of dead reckoning alone, mean over survey vehicles"),
    "ellipse_major_m": (
        "m",
        "2-sigma semi-major axis of the filter's horizontal error ellipse, mean over survey vehicles",
    ),
    "ellipse_minor_m": ("m", "2-sigma semi-minor axis of the same ellipse"),
    "reward": ("unitless", "the step's reward, mean over beacons"),
    "beacon_distance_m": ("m", "beacon-survey distance (3-D), mean over pairs"),
    "error_x_m": ("m", "signed x error of the survey filter in the moving frame (network=moving_lbl; blank otherwise)"),
    "error_y_m": ("m", "signed y error of the survey filter in the moving frame (network=moving_lbl; blank otherwise)"),
}
EPISODE_COLUMNS = list(EPISODE_COLUMN_DOCS)
STEP_COLUMNS = list(STEP_COLUMN_DOCS)

# summary.json key -> (summary.md header, format, unit, meaning); the order of summary.md's table
_ALL_STEPS = "over every step of every episode"
SUMMARY_COLUMNS = {
    "mean_error_m": ("mean (m)", "{:.3f}", "m", f"mean of survey_error_m {_ALL_STEPS}"),
    "median_error_m": ("median", "{:.3f}", "m", f"median of survey_error_m {_ALL_STEPS}"),
    "p95_error_m": ("p95", "{:.3f}", "m", f"95th percentile of survey_error_m {_ALL_STEPS}"),
    "std_error_m": ("std", "{:.3f}", "m", f"standard deviation of survey_error_m {_ALL_STEPS}"),
    "ci95_error_m": (
        "95% CI of mean",
        "[{:.3f}, {:.3f}]",
        "m",
        "95 % interval of the mean: cluster bootstrap over episodes (2000 draws)",
    ),
    "final_error_m": ("final", "{:.3f}", "m", "final_error_m (survey error at the last step), mean over episodes"),
    "mean_dr_error_m": ("DR mean", "{:.3f}", "m", "mean_dr_error_m (dead reckoning alone), mean over episodes"),
    "mean_return": (
        "return",
        "{:.2f}",
        "unitless",
        "return (sum over the episode of the reward, mean over beacons), mean over episodes: what PPO "
        "maximizes, higher is better *for the reward*, which is not the error. The reward pays the "
        "information each fix adds to the filter (log det P before minus after; coopnav_env.core.reward), "
        "so a beacon that lets the uncertainty grow between fixes can earn more per fix: `static` can "
        "have the highest return and the worst error. Rank policies by the error columns",
    ),
    "ranges_fused": ("ranges fused", "{:.1f}", "count per episode", "ranges the filters fused, mean over episodes"),
    "outliers_rejected": (
        "outliers rej.",
        "{:.1f}",
        "count per episode",
        "ranges rejected as outliers, mean over episodes",
    ),
    "beacon_distance_m": ("beacon dist. (m)", "{:.1f}", "m", "beacon-survey distance, mean over episodes"),
    "pings": ("pings", "{:.1f}", "count per episode", "pings transmitted, mean over episodes"),
    "energy_J": ("energy (J)", "{:.0f}", "J per episode", "transmit energy of the pings, mean over episodes"),
}
FRAME_COLUMNS = {  # moving network only
    "error_x_std_m": ("x error std (m)", "{:.3f}", "m", "standard deviation of error_x_m over all steps"),
    "error_y_std_m": ("y error std (m)", "{:.3f}", "m", "standard deviation of error_y_m over all steps"),
    "error_x_mean_m": ("x mean", "{:+.3f}", "m", "mean of error_x_m (its bias)"),
    "error_y_mean_m": ("y mean", "{:+.3f}", "m", "mean of error_y_m (its bias)"),
}
SUMMARY_COLUMN_DOCS = {k: (unit, meaning) for k, (_, _, unit, meaning) in {**SUMMARY_COLUMNS, **FRAME_COLUMNS}.items()}
SUMMARY_COLUMN_DOCS.update(
    {
        "episodes": ("count", "episodes of the policy (and cell)"),
        "steps": ("count", "steps pooled into the error statistics"),
        "var_error_m2": ("m^2", f"variance of survey_error_m {_ALL_STEPS} (the sweep tables)"),
    }
)


# ------------------------------------------------------------------------------------
# CSV


def csv_text(columns: Sequence[str], rows: Iterable[Mapping[str, Any]]) -> str:
    """``rows`` (dicts) as CSV text with header ``columns``; floats written exactly (the
    shortest text that reads back to the same float), so that statistics computed again
    from the file (``--resume``) are those computed from the numbers themselves."""
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=columns, extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: _fmt(r.get(k, "")) for k in columns})
    return buf.getvalue()


def _fmt(v):
    if isinstance(v, (float, np.floating)):
        return repr(float(v))
    return v


def read_csv(path: str) -> list:
    """The rows of a CSV file (dicts of text), [] if it does not exist."""
    try:
        with open(path, newline="") as f:
            return list(csv.DictReader(f))
    except OSError:
        return []


# ------------------------------------------------------------------------------------
# summary.md


def _table(columns: dict, stats: dict) -> list:
    head = ["policy"] + [h for h, _, _, _ in columns.values()]
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for p, s in stats.items():
        cells = [
            fmt.format(*s[k]) if isinstance(s[k], (list, tuple)) else fmt.format(s[k])
            for k, (_, fmt, _, _) in columns.items()
        ]
        out.append("| " + " | ".join([p] + cells) + " |")
    return out


def policy_table(stats: dict) -> str:
    """The per-policy table of summary.md (and the moving-frame error table, if any)."""
    out = _table(SUMMARY_COLUMNS, stats)
    frame = {p: s for p, s in stats.items() if "error_x_std_m" in s}
    if frame:
        out += ["", "Moving-frame errors (Matos & Cruz sec. VIII reports std 0.25 m in x, 0.86 m in y):", ""]
        out += _table(FRAME_COLUMNS, frame)
    return "\n".join(out)


def columns_section(stats: dict, sweep: bool) -> list:
    """summary.md's "Columns" section: every column of the tables above, with its unit."""
    lines = ["## Columns", ""]
    columns = dict(SUMMARY_COLUMNS)
    if any("error_x_std_m" in s for s in stats.values()):
        columns.update(FRAME_COLUMNS)
    for key, (header, _, unit, meaning) in columns.items():
        lines.append(f"* **{header}** (`{key}`, {unit}): {meaning}.")
    if sweep:
        lines.append(
            "* **mean error (m) / variance (m^2)** (`mean_error_m` / `var_error_m2` of the cell): "
            f"mean and variance of survey_error_m {_ALL_STEPS} of the cell."
        )
    lines.append("")
    lines.append(
        "`survey_error_m`: the true horizontal distance (m) between a survey vehicle and its "
        "filter's estimate; dead reckoning (DR): the same for the vehicle's own dead reckoning alone."
    )
    return lines


def trained_lines(trained: dict) -> list:
    """What each trained policy name resolved to (``config.resolve_trained``), one line each."""
    out = []
    for name, r in trained.items():
        if r["shipped"] is not None:
            what = f"the shipped policy `{r['shipped']}` (`{r['model']}`)"
        else:
            what = f"the trained model `{r['model']}`"
        out.append(f"* `{name}`: {what}")
    return out


def markdown(summary: dict, plan: Plan) -> str:
    """summary.md: the run, the per-policy table (pooled over a sweep's grid), a sweep's
    Table I/II layout per policy, and the Columns section."""
    lines = [f"# Evaluation: {summary['scenario']}", ""]
    ov = summary.get("overrides") or {}
    lines.append(
        f"{summary['episodes']} episodes per policy{' and cell' if plan.sweep else ''}, seeds "
        f"{summary['seed']}..{summary['seed'] + summary['episodes'] - 1} (common random numbers)"
        + (f"; overrides: {', '.join(f'{k}={v}' for k, v in ov.items())}" if ov else "")
        + "."
    )
    lines.append(
        "Error: `survey_error_m` (true horizontal error of the EKF estimate) over all steps of all "
        "episodes; the 95 % interval of the mean is a bootstrap over episodes."
    )
    lines.append("")
    if plan.trained:
        lines += ["Trained policies:", ""] + trained_lines(plan.trained) + [""]
    title = "pooled over the grid" if plan.sweep else "per policy"
    lines += [f"## Summary ({title})", "", policy_table(summary["policies"]), ""]
    if plan.sweep:
        row_key, xs, col_cells = sweep_layout(plan.sweep)
        for p in plan.policies:
            lines += [f"## {p}: mean error (m) / variance (m^2)", ""]
            head = [row_key] + [", ".join(f"{v}" for v in c.values()) or "value" for c in col_cells]
            lines.append("| " + " | ".join(head) + " |")
            lines.append("|" + "---|" * len(head))
            for rv in xs:
                row = [f"{rv}"]
                for cc in col_cells:
                    st = find_cell(summary, plain({row_key: rv, **cc}), p)
                    row.append("-" if st is None else f"{st['mean_error_m']:.3f} / {st['var_error_m2']:.3f}")
                lines.append("| " + " | ".join(row) + " |")
            lines.append("")
    lines += columns_section(summary["policies"], bool(plan.sweep))
    return "\n".join(lines)
