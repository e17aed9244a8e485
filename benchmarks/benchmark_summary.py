"""One line per task set and challenger from benchmark results: the 20 % aim, at a glance.

    python benchmarks/benchmark_summary.py results/bench_*/results.json
    python benchmarks/benchmark_summary.py results/bench_*/results.json --per-task --markdown summary.md

Reads the ``results.json`` files that ``python -m evaluation.benchmark`` writes and, for
every task set and trained challenger in them, prints (and with ``--markdown`` writes,
atomically) one table row:

* the mean over the tasks it can drive of its mean error, and the same mean of each
  task's best planner (the planner with the lowest mean error on that task);
* their relative difference (%), the issue's aim being -20 % or lower;
* the paired difference over the task set: per episode seed, the mean over the tasks of
  its error minus the task's best planner's on that seed (episode i of every task has
  the same seed, so a seed's differences are not independent across tasks), then the
  mean and 95 % t interval (``evaluation.paired.t_interval``) over the seeds;
* wins, ties and losses over the tasks (each task's own 95 % interval, as in results.md),
  and the tasks it cannot drive (``n/a``);
* the same relative and paired differences against each task's best **greedy** planner
  (the best of the task set's ``greedy_planners``: the receding-horizon planner left out),
  which issue 23's aim is stated against (20 % below the best greedy planner, and no worse
  than the receding-horizon one: the columns against the best planner).

Nothing is recomputed from episodes: the numbers are those of results.json.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from evaluation.benchmark_stats import lowest_mean
from evaluation.paired import t_interval

try:
    from benchmarks import _args
except ImportError:  # run as a script: its own folder is on the path, not the checkout
    import _args  # type: ignore[no-redef]

AIM = -0.20  # the aim: a mean error at least 20 % below the best planner's


def _pooled(diffs: list) -> tuple:
    """Per seed, the mean over the tasks (episode i of every task has the same seed, so the
    tasks' differences on one seed are not independent); then the t interval over seeds."""
    return t_interval(np.mean(np.stack(diffs), axis=0))


def rows(results: dict) -> list:
    """(task set, challenger, n tasks, n/a, mean, best planners' mean, relative, paired mean,
    paired interval, wins, ties, losses, official, greedy) for every trained challenger;
    ``greedy``: None, or (best greedy planners' mean, relative, paired mean, paired interval)
    when the results name the task set's greedy planners."""
    out = []
    for set_name, ts in results["task_sets"].items():
        greedy = ts.get("greedy_planners")
        for challenger in ts["challengers"]:
            mine, best, diffs, g_best, g_diffs = [], [], [], [], []
            for task in ts["tasks"].values():
                entry = task["policies"].get(challenger)
                if entry is None or "mean_error_m" not in entry:
                    continue
                planner = task["policies"][task["best_planner"]]
                mine.append(entry["mean_error_m"])
                best.append(planner["mean_error_m"])
                diffs.append(np.subtract(entry["episode_mean_error_m"], planner["episode_mean_error_m"]))
                g = lowest_mean(task["policies"], greedy or ())
                if g is not None:
                    g_best.append(task["policies"][g]["mean_error_m"])
                    g_diffs.append(
                        np.subtract(entry["episode_mean_error_m"], task["policies"][g]["episode_mean_error_m"])
                    )
            if not mine:
                continue
            mean, best_mean = float(np.mean(mine)), float(np.mean(best))
            pooled, lo, hi = _pooled(diffs)
            vs_greedy = None
            if g_best and len(g_best) == len(mine):
                g_mean = float(np.mean(g_best))
                g_pooled, g_lo, g_hi = _pooled(g_diffs)
                vs_greedy = (g_mean, mean / g_mean - 1.0, g_pooled, (g_lo, g_hi))
            wins = ts["summary"][challenger]  # the benchmark's own count of the tasks' verdicts
            out.append(
                (
                    set_name,
                    challenger,
                    len(mine),
                    wins["n/a"],
                    mean,
                    best_mean,
                    mean / best_mean - 1.0,
                    pooled,
                    (lo, hi),
                    wins["win"],
                    wins["tie"],
                    wins["loss"],
                    bool(results.get("official")),
                    vs_greedy,
                )
            )
    return out


def markdown(all_rows: list) -> str:
    """The summary table; *20 % aim* against the best planner (the receding-horizon one
    included), which implies the issue's (against the best greedy planner, and no worse than
    the receding-horizon one); *vs best greedy*: relative and paired against the best greedy planner."""
    lines = [
        "| task set | policy | tasks (n/a) | mean error (m) | best planners (m) | relative | "
        "paired, pooled (m) [95 %] | wins / ties / losses | 20 % aim | best greedy (m) | vs best greedy | "
        "paired vs best greedy (m) [95 %] |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for s, c, n, na, mean, best, rel, pm, (lo, hi), w, t, l, official, greedy in all_rows:
        aim = "met" if rel <= AIM and hi < 0 else f"not met ({rel * 100:+.0f} %)"
        mark = "" if official else " (not official)"
        if greedy is None:
            g_cells = "n/a | n/a | n/a"
        else:
            g_mean, g_rel, g_pm, (g_lo, g_hi) = greedy
            g_cells = f"{g_mean:.3f} | {g_rel * 100:+.1f} % | {g_pm:+.3f} [{g_lo:+.3f}, {g_hi:+.3f}]"
        lines.append(
            f"| `{s}`{mark} | `{c}` | {n} ({na}) | {mean:.3f} | {best:.3f} | {rel * 100:+.1f} % | "
            f"{pm:+.3f} [{lo:+.3f}, {hi:+.3f}] | {w} / {t} / {l} | {aim} | {g_cells} |"
        )
    return "\n".join(lines)


def per_task_markdown(results: dict) -> str:
    """Per task set, one row per task: the best planner and its mean error, each trained
    challenger's mean error and paired difference with its verdict (``--per-task``)."""
    out = []
    for set_name, ts in results["task_sets"].items():
        head = (
            ["task", "best planner (m)"]
            + [f"`{c}` (m)" for c in ts["challengers"]]
            + [f"`{c}` - best [95 %]" for c in ts["challengers"]]
        )
        lines = [f"**`{set_name}`**", "", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        for task_name, task in ts["tasks"].items():
            best = task["best_planner"]
            cells = [f"`{task_name}`", f"`{best}` {task['policies'][best]['mean_error_m']:.3f}"]
            diffs = []
            for c in ts["challengers"]:
                e = task["policies"].get(c)
                if e is None or "mean_error_m" not in e:
                    cells.append("n/a")
                    diffs.append("n/a")
                    continue
                cells.append(f"{e['mean_error_m']:.3f}")
                pm, (lo, hi), verdict = e["paired"]["mean_m"], e["paired"]["ci95_m"], e["paired"]["verdict"]
                diffs.append(f"{pm:+.3f} [{lo:+.3f}, {hi:+.3f}] {verdict}")
            lines.append("| " + " | ".join(cells + diffs) + " |")
        out.append("\n".join(lines))
    return "\n\n".join(out)


def main(argv: Sequence[str] | None = None) -> int:
    p = _args.Parser(prog="benchmark_summary.py", description=__doc__.split("\n\n")[0])
    p.add_argument("results", nargs="+", type=Path, help="results.json files of evaluation.benchmark")
    p.add_argument("--markdown", type=Path, help="also write the table here")
    p.add_argument(
        "--per-task",
        action="store_true",
        help="also one table per task set: every task's best planner and each challenger's paired difference",
    )
    _args.add_overwrite(p, "the --markdown file")
    args = p.parse_args(argv)
    _args.outputs(p, args.overwrite, markdown=args.markdown)  # refused before any file is read
    all_rows, tables = [], []
    for path in args.results:
        try:
            results = json.loads(path.read_text())
            problem = _args.benchmark_results_problem(results)  # NaN, text, unpaired counts: not summarized
            if problem is not None:
                raise ValueError(problem)
            all_rows.extend(rows(results))
            if args.per_task:
                tables.append(per_task_markdown(results))
        except (OSError, ValueError, KeyError) as err:
            p.error(f"{path}: not a benchmark results.json ({type(err).__name__}: {err})")
    text = "\n\n".join([markdown(all_rows)] + tables)
    print(text)
    if args.markdown:
        from coopnav_env.records import atomic_write_text

        atomic_write_text(args.markdown, text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
