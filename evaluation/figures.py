"""The evaluation's figures, PNG at print resolution (200 dpi), drawn on matplotlib's
Agg canvas without pyplot (matplotlib is imported inside the functions only):

* ``paths.png``: both vehicles' paths (planned: wide orange under the true path; true,
  EKF, dead reckoning) and the beacons' in the first episode of each policy (a free
  panel slot holds the legend);
* ``error_vs_time.png``: survey error against time per policy (mean over episodes,
  quartile band), with dead reckoning on its own panel below (it grows to hundreds
  of metres; Gao & Chitre Figs. 7 and 11);
* ``ellipse_axes.png``: the filter's 2-sigma ellipse semi-axes against time (Matos &
  Cruz Fig. 8);
* ``frame_errors.png`` (moving network only): x and y errors in the moving frame and
  the ellipse axes of the first episode (Matos & Cruz Figs. 6-8);
* ``sweep.png`` (a sweep, instead of the above): mean error per cell and policy;
* ``benchmark_<set>.png`` (``coopnav-benchmark``, one per task set): each policy's mean
  error per task with its 95 % interval, the task's best planner ringed.

Every file is written atomically (``coopnav_env.records.atomic_write_bytes``).
"""

from __future__ import annotations

import io
import os
from typing import TYPE_CHECKING, Any

import numpy as np

from coopnav_env.records import atomic_write_bytes, plain

from .config import cell_id, sweep_layout
from .stats import find_cell

if TYPE_CHECKING:
    from .config import Plan

DPI = 200
TIME_LABEL = "time (s)"


def save_figure(fig: Any, path: str) -> None:
    """Render ``fig`` on an Agg canvas and write it to ``path`` as PNG (atomically)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI)
    atomic_write_bytes(path, buf.getvalue())


def _time_series(step_rows, policy, key):
    """(t, mean, 25th, 75th percentile) of column ``key`` against time over the episodes
    of ``policy`` (None: every policy); the thin tails of long episodes are dropped."""
    by_t: dict = {}
    for r in step_rows:
        if policy is None or r["policy"] == policy:
            by_t.setdefault(float(r["t_s"]), []).append(float(r[key]))
    if not by_t:
        return (np.array([]),) * 4
    most = max(len(v) for v in by_t.values())
    t = np.array([x for x in sorted(by_t) if len(by_t[x]) >= 0.5 * most])  # drop thin tails of long episodes
    vals = [np.array(by_t[x]) for x in t]
    return (
        t,
        np.array([v.mean() for v in vals]),
        np.array([np.percentile(v, 25) for v in vals]),
        np.array([np.percentile(v, 75) for v in vals]),
    )


def _finish(ax, xlabel, ylabel, fontsize=7, **legend):
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(True, lw=0.3)
    ax.legend(fontsize=fontsize, **legend)


def _band(ax, step_rows, policy, key, color, label, **line):
    """Mean of ``key`` over episodes against time with its quartile band; False if no data."""
    t, m, lo, hi = _time_series(step_rows, policy, key)
    if t.size == 0:
        return False
    ax.plot(t, m, color=color, label=label, **line)
    ax.fill_between(t, lo, hi, color=color, alpha=0.12, lw=0)
    return True


def draw_paths(out: str, plan: Plan) -> str:
    """paths.png: both vehicles' paths in the first episode of each policy."""
    from matplotlib.figure import Figure

    from .episodes import record_episode

    policies, config, seed = plan.policies, plan.first_config(), plan.config.seed
    n = len(policies)
    rows, cols = panel_grid(n)
    fig = Figure(figsize=(4.6 * cols, 4.2 * rows))
    spare = rows * cols > n  # a free slot holds the legend instead of staying empty
    for i, p in enumerate(policies):
        rec = record_episode(config, p, seed)
        true, dr, est, beacons = rec["survey_true_m"], rec["survey_dr_m"], rec["survey_est_m"], rec["beacon_true_m"]
        ax = fig.add_subplot(rows, cols, i + 1)
        for s in range(true.shape[1]):
            wp = rec["waypoints_m"][s, : rec["n_waypoints"][s]]
            first = s == 0
            # under the true path, wide and orange: visible where the vehicle follows it
            ax.plot(
                wp[:, 0],
                wp[:, 1],
                color="tab:orange",
                lw=3.0,
                alpha=0.55,
                solid_capstyle="round",
                label="planned" if first else None,
                zorder=1,
            )
            ax.plot(true[:, s, 0], true[:, s, 1], color="k", lw=1.3, label="survey (true)" if first else None)
            ax.plot(est[:, s, 0], est[:, s, 1], color="tab:blue", lw=0.9, label="survey (EKF)" if first else None)
            ax.plot(
                dr[:, s, 0], dr[:, s, 1], color="tab:red", lw=0.9, ls="--", label="dead reckoning" if first else None
            )
        for j in range(beacons.shape[1]):
            ax.plot(beacons[:, j, 0], beacons[:, j, 1], color="tab:green", lw=1, label="beacon" if j == 0 else None)
            ax.plot(beacons[0, j, 0], beacons[0, j, 1], "o", color="tab:green", ms=4)
        ax.set_title(f"{p} (seed {seed})", fontsize=9)
        ax.set_aspect("equal", adjustable="datalim")
        ax.tick_params(labelsize=7)
        if spare:
            ax.set_xlabel("east (m)")
            ax.set_ylabel("north (m)")
            ax.grid(True, lw=0.3)
        else:
            _finish(ax, "east (m)", "north (m)", fontsize=6, loc="best")
    if spare:
        handles, labels = fig.axes[0].get_legend_handles_labels()
        slot = fig.add_subplot(rows, cols, n + 1)
        slot.axis("off")
        slot.legend(handles, labels, loc="center", fontsize=9, title="every panel", frameon=False)
    fig.suptitle(f"{config.name}: paths of both vehicles (start of a beacon: dot)", fontsize=10)
    fig.tight_layout()
    save_figure(fig, os.path.join(out, "paths.png"))
    return "paths.png"


def panel_grid(n: int) -> tuple:
    """(rows, columns) for ``n`` panels: at most 3 columns, the fewest empty slots (then
    the fewest rows); 4 panels are 2 x 2, not 3 + 1 with two empty."""
    if n <= 3:
        return 1, max(n, 1)
    best = min(((-(-n // c)) * c - n, -(-n // c), c) for c in (2, 3))
    return best[1], best[2]


def draw_benchmark(out: str, results: dict) -> list:
    """benchmark_<set>.png per task set of a benchmark result (``evaluation.benchmark``):
    per task, each policy's mean survey error with its 95 % t interval, the task's best
    planner ringed; a log scale when the floors are far above the rest. Returns the names."""
    from matplotlib.figure import Figure

    written = []
    for name, s in results["task_sets"].items():
        cols, tasks = s["columns"], list(s["tasks"])
        fig = Figure(figsize=(max(6.5, 0.55 * len(tasks) * max(len(cols), 3) / 3 + 2.5), 4.6))
        ax = fig.add_subplot(1, 1, 1)
        width = 0.8 / max(len(cols), 1)
        means = []
        for k, p in enumerate(cols):
            xs, ys, lo, hi, best = [], [], [], [], []
            for i, t in enumerate(tasks):
                st = s["tasks"][t]["policies"].get(p, {})
                if "mean_error_m" not in st:
                    continue
                xs.append(i - 0.4 + width * (k + 0.5))
                ys.append(st["mean_error_m"])
                lo.append(st["mean_error_m"] - st["ci95_error_m"][0])
                hi.append(st["ci95_error_m"][1] - st["mean_error_m"])
                best.append(p == s["tasks"][t]["best_planner"])
            if not xs:
                continue
            challenger = p in s["challengers"] and p not in s["planners"] + s["floors"]
            reference = p in s.get("references", [])
            kind = " (challenger)" if challenger else " (floor)" if p in s["floors"] else ""
            kind = " (reference)" if reference and not challenger else kind
            marker = "D" if challenger else ("v" if p in s["floors"] else "^" if reference else "o")
            ax.errorbar(
                xs,
                ys,
                yerr=[lo, hi],
                fmt=marker,
                ms=5 if challenger else 4,
                lw=1,
                capsize=2,
                color=f"C{k}",
                label=p + kind,
            )
            bx = [x for x, b in zip(xs, best) if b]
            by = [y for y, b in zip(ys, best) if b]
            if bx:
                ax.plot(
                    bx,
                    by,
                    "o",
                    ms=11,
                    mfc="none",
                    mec="k",
                    mew=1.2,
                    label="best planner of the task"
                    if not any(h.get_label() == "best planner of the task" for h in ax.lines)
                    else None,
                )
            means += ys
        if means and min(means) > 0 and max(means) / min(means) > 10:  # floors far above the planners
            ax.set_yscale("log")
        ax.set_xticks(range(len(tasks)))
        ax.set_xticklabels(
            tasks, rotation=35 if len(tasks) > 4 else 0, ha="right" if len(tasks) > 4 else "center", fontsize=7
        )
        ax.set_xlim(-0.6, len(tasks) - 0.4)
        ax.set_xlabel("task")
        ax.set_ylabel("mean survey error (m), 95 % t interval")
        tag = "" if results.get("official") else " (not a benchmark result)"
        ax.set_title(
            f"benchmark {name} ({s['scenario']})\n{results['episodes']} test episodes per task and policy{tag}",
            fontsize=9,
        )
        ax.grid(True, axis="y", lw=0.3)
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
        fig.tight_layout()
        filename = f"benchmark_{name}.png"
        save_figure(fig, os.path.join(out, filename))
        written.append(filename)
    return written


def draw_error_vs_time(out: str, plan: Plan, step_rows: list) -> str:
    """error_vs_time.png: the policies' survey error on its own scale (top) and dead
    reckoning's (bottom), against a shared time axis."""
    from matplotlib.figure import Figure

    config = plan.first_config()
    fig = Figure(figsize=(7.5, 6.5))
    top = fig.add_subplot(2, 1, 1)
    bottom = fig.add_subplot(2, 1, 2, sharex=top)
    for i, p in enumerate(plan.policies):
        _band(top, step_rows, p, "survey_error_m", f"C{i}", p)
    # dead reckoning does not depend on the beacons: the same in every policy's episodes
    _band(bottom, step_rows, None, "dr_error_m", "k", "dead reckoning (all policies)", ls="--")
    top.set_title(f"{config.name}: survey error, mean over episodes (band: quartiles)", fontsize=10)
    _finish(top, TIME_LABEL, "EKF horizontal error (m)", fontsize=8)
    bottom.set_title("dead reckoning alone (no acoustic fixes)", fontsize=9)
    _finish(bottom, TIME_LABEL, "DR horizontal error (m)", fontsize=8)
    fig.tight_layout()
    save_figure(fig, os.path.join(out, "error_vs_time.png"))
    return "error_vs_time.png"


def draw_ellipse_axes(out: str, plan: Plan, step_rows: list) -> str:
    """ellipse_axes.png: the filter's 2-sigma semi-axes against time, per policy."""
    from matplotlib.figure import Figure

    config = plan.first_config()
    fig = Figure(figsize=(7.5, 4.5))
    ax = fig.add_subplot(1, 1, 1)
    for i, p in enumerate(plan.policies):
        t, m, _, _ = _time_series(step_rows, p, "ellipse_major_m")
        t2, m2, _, _ = _time_series(step_rows, p, "ellipse_minor_m")
        if t.size == 0:
            continue
        ax.plot(t, m, color=f"C{i}", label=f"{p} major")
        ax.plot(t2, m2, color=f"C{i}", ls=":", label=f"{p} minor")
    ax.set_title(f"{config.name}: EKF uncertainty-ellipse axes, mean over episodes", fontsize=10)
    _finish(ax, TIME_LABEL, "2-sigma semi-axis (m)", ncol=2)
    fig.tight_layout()
    save_figure(fig, os.path.join(out, "ellipse_axes.png"))
    return "ellipse_axes.png"


def draw_frame_errors(out: str, plan: Plan, step_rows: list) -> str:
    """frame_errors.png, Matos & Cruz Figs. 6-8 for the first episode of each policy: the
    x and y errors in the moving frame and the filter's ellipse axes against time."""
    from matplotlib.figure import Figure

    config, seed = plan.first_config(), plan.config.seed
    first_cell = cell_id(plan.cells[0])
    fig = Figure(figsize=(7.5, 7.5))
    axes = [fig.add_subplot(3, 1, i + 1) for i in range(3)]
    for i, p in enumerate(plan.policies):
        rows = [r for r in step_rows if r["policy"] == p and int(r["seed"]) == seed and r["cell"] == first_cell]
        if not rows:
            continue
        t = np.array([float(r["t_s"]) for r in rows])
        for ax, key in zip(axes[:2], ("error_x_m", "error_y_m")):
            v = np.array([float(r[key]) for r in rows])
            ax.plot(t, v, color=f"C{i}", lw=0.8, label=f"{p} (std {v.std():.2f} m)")
        # the step rows' ellipse columns: 2-sigma semi-axes, plotted as they are
        axes[2].plot(t, [float(r["ellipse_major_m"]) for r in rows], color=f"C{i}", lw=0.9, label=f"{p} major")
        axes[2].plot(t, [float(r["ellipse_minor_m"]) for r in rows], color=f"C{i}", lw=0.9, ls=":", label=f"{p} minor")
    for ax, label in zip(axes, ("x error (m)", "y error (m)", "2-sigma semi-axes (m)")):
        _finish(ax, TIME_LABEL, label)
    fig.suptitle(f"{config.name}, seed {seed}: moving-frame errors (cf. Matos & Cruz Figs. 6-8)", fontsize=10)
    fig.tight_layout()
    save_figure(fig, os.path.join(out, "frame_errors.png"))
    return "frame_errors.png"


def draw_sweep_figure(out: str, plan: Plan, summary: dict) -> str:
    """sweep.png: mean survey error against the first swept parameter, one panel per
    policy (one error scale), one line per combination of the other parameters."""
    from matplotlib.figure import Figure

    row_key, xs, col_cells = sweep_layout(plan.sweep)
    numeric = all(isinstance(x, (int, float)) for x in xs)
    n = len(plan.policies)
    fig = Figure(figsize=(5.0 * n, 4.0))
    first = None
    for i, p in enumerate(plan.policies):
        ax = fig.add_subplot(1, n, i + 1, sharey=first)  # one error scale for every policy
        first = first or ax
        for cc in col_cells:
            ys = []
            for x in xs:
                st = find_cell(summary, plain({row_key: x, **cc}), p)
                ys.append(np.nan if st is None else st["mean_error_m"])
            xv = xs if numeric else list(range(len(xs)))
            ax.plot(xv, ys, "o-", label=", ".join(str(v) for v in cc.values()) or p)
        if not numeric:
            ax.set_xticks(range(len(xs)))
            ax.set_xticklabels([str(x) for x in xs])
        ax.set_title(p)
        _finish(ax, row_key, "mean survey error (m)")
    fig.tight_layout()
    save_figure(fig, os.path.join(out, "sweep.png"))
    return "sweep.png"


def draw_all(out: str, plan: Plan, step_rows: list, summary: dict) -> list:
    """Every figure of the run (a sweep: sweep.png only); returns the file names."""
    if plan.sweep:
        return [draw_sweep_figure(out, plan, summary)]
    written = [draw_paths(out, plan), draw_error_vs_time(out, plan, step_rows), draw_ellipse_axes(out, plan, step_rows)]
    if plan.first_config().network == "moving_lbl":
        written.append(draw_frame_errors(out, plan, step_rows))
    return written
