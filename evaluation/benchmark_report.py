"""The benchmark's ``results.md`` (one table per task set: each policy's mean error, its
paired difference against the best planner, the verdicts) and the writing of a run's
files, results.json and results.md atomically, with the figures
(``evaluation.benchmark``)."""

from __future__ import annotations

import os

from coopnav_env.records import atomic_write_text, strict_json

from .outdir import BENCHMARK_RESULT_FILES as RESULT_FILES  # one home: evaluate.py refuses a folder holding them


def _cells(task: dict, cols: list, cell) -> list:
    """One table row's cells: ``cell(policy, stats, task)`` for each policy, "n/a" where skipped."""
    return ["n/a" if "skipped" in task["policies"][p] else cell(p, task["policies"][p], task) for p in cols]


def _mean_cell(policy, st, task) -> str:
    text = f"{_num(st['mean_error_m'])} [{_num(st['ci95_error_m'][0])}, {_num(st['ci95_error_m'][1])}]"
    return f"**{text}**" if policy == task["best_planner"] else text


def _paired_cell(policy, st, task) -> str:
    d = st["paired"]
    if d["verdict"] == "best":
        return "best"
    return f"{_num(d['mean_m'], 3)} [{_num(d['ci95_m'][0], 3)}, {_num(d['ci95_m'][1], 3)}] {d['verdict']}"


def _num(x: float, digits: int = 3) -> str:
    return f"{x:.{digits}f}"


def _ranges(stats: dict) -> str:
    if "skipped" in stats:
        return "n/a"
    return f"{stats['ranges_fused']:.1f}" if "ranges_fused" in stats else "-"


def _frac(f) -> str:
    return "n/a" if f is None else f"{100 * f:.0f} %"


def _opt(x, digits: int = 3) -> str:
    return "n/a" if x is None else _num(x, digits)


def _headroom_lines(s: dict) -> list:
    """The headroom table of a task set: per task the best greedy planner, the oracle, the
    headroom (best greedy minus oracle, paired interval) and the fraction each challenger
    closes; a last row pools the tasks with a headroom (``benchmark_stats.summarize_headroom``)."""
    summary = s["headroom"]
    closers = list(summary["closed"])
    oracle = next(iter(s["references"]), "oracle")
    head = ["task", "best greedy", "its mean (m)"] + [f"{p} (m)" for p in closers] + [f"{oracle} (m)"]
    head += ["headroom (m), 95 % t interval"] + [f"closed by {p}" for p in closers]
    lines = [
        "",
        "### Headroom: best greedy planner minus the oracle",
        "",
        f"The oracle (`{oracle}`: the receding-horizon optimiser given the truth, a reference, never the best "
        "planner) bounds what guidance can achieve; the headroom is the best greedy planner's mean error minus "
        "the oracle's (paired interval), and a challenger closes (best greedy - challenger) / headroom of it "
        "(100 %: as low as the oracle; 0: no better than the best greedy planner). n/a: the oracle was no better "
        "than the best greedy planner there. The win verdicts above are against the best planner, "
        "the receding-horizon one included.",
        "",
        "| " + " | ".join(head) + " |",
        "|" + "---|" * len(head),
    ]
    for task, t in s["tasks"].items():
        h = t.get("headroom")
        if h is None:
            continue
        means = [
            _opt(None if "skipped" in t["policies"].get(p, {"skipped": 1}) else t["policies"][p]["mean_error_m"])
            for p in closers
        ]
        room = (
            "n/a"
            if h["headroom_m"] is None
            else (f"{_num(h['headroom_m'])} [{_num(h['headroom_ci95_m'][0])}, {_num(h['headroom_ci95_m'][1])}]")
        )
        row = [task, h["best_greedy"] or "n/a", _opt(h["best_greedy_m"])] + means + [_opt(h["oracle_m"]), room]
        lines.append("| " + " | ".join(row + [_frac(h["closed"][p]) for p in closers]) + " |")
    n = summary["tasks"]
    pooled = [f"pooled ({n} tasks with headroom)", "", _opt(summary["best_greedy_m"])]
    pooled += [""] * len(closers) + [_opt(summary["oracle_m"]), _opt(summary["headroom_m"])]
    lines.append("| " + " | ".join(pooled + [_frac(summary["closed"][p]) for p in closers]) + " |")
    return lines


def render_markdown(results: dict) -> str:
    """results.md: per task set the errors, the paired differences to the best planner,
    the ranges fused and the wins."""
    v = results["versions"]
    commit = (v.get("git_commit") or "unknown")[:12] + (" (modified)" if v.get("git_dirty") else "")
    lines = [f"# coopnav benchmark v{results['benchmark_version']}", ""]
    if not results["official"]:
        lines += [f"**Not a benchmark result**: {'; '.join(results['not_official_because'])}.", ""]
    lines += [
        f"Commit {commit}, coopnav {v.get('coopnav', '?')}; {results['episodes']} episodes per task and "
        f"policy on the test seeds {results['seeds']['first']} + i (i < {results['episodes']}), the same "
        "for every policy.",
        "",
    ]
    if results.get("command"):
        lines += [f"Command: `{results['command']}`", ""]
    for name, s in results["task_sets"].items():
        cols = s["columns"]
        lines += [
            f"## {name} ({s['scenario']})",
            "",
            s["about"] + ".",
            "",
            f"Planners: {', '.join(s['planners'])}; references: {', '.join(s.get('references', [])) or 'none'}; "
            f"floors: {', '.join(s['floors'])}; challengers: {', '.join(s['challengers']) or 'none'}.",
            "",
        ]
        trained = {p: t for p, t in s["trained_policies"].items() if t}
        for p, t in trained.items():
            lines.append(f"- `{p}`: {t.get('shipped') or 'run directory'}, model `{t['model']}`")
        if trained:
            lines.append("")
        lines += [
            "### Mean survey error (m), 95 % t interval",
            "",
            "Mean over episodes of each episode's mean error; **bold**: the task's best planner.",
            "",
            "| task | " + " | ".join(cols) + " |",
            "|---|" + "---|" * len(cols),
        ]
        for task, t in s["tasks"].items():
            lines.append(f"| {task} | " + " | ".join(_cells(t, cols, _mean_cell)) + " |")
        lines += [
            "",
            "### Paired difference to the best planner (m), 95 % t interval",
            "",
            "Per episode, policy minus the task's best planner on the same seed; negative: lower error. "
            "win: the interval lies below 0; loss: above 0; tie: it holds 0.",
            "",
            "| task | best planner | " + " | ".join(cols) + " | wins |",
            "|---|---|" + "---|" * len(cols) + "---|",
        ]
        for task, t in s["tasks"].items():
            cells = _cells(t, cols, _paired_cell)
            wins = ", ".join(t["wins"]) or "-"
            lines.append(f"| {task} | {t['best_planner']} | " + " | ".join(cells) + f" | {wins} |")
        lines += [
            "",
            "### Ranges fused per episode (pings used)",
            "",
            "| task | " + " | ".join(cols) + " |",
            "|---|" + "---|" * len(cols),
        ]
        for task, t in s["tasks"].items():
            cells = [_ranges(t["policies"][p]) for p in cols]
            lines.append(f"| {task} | " + " | ".join(cells) + " |")
        n = len(s["tasks"])
        lines += [
            "",
            f"### Wins over {n} tasks",
            "",
            "ms per act: the cost per decision, the median CPU milliseconds of one beacon's decision (one "
            "core), median over the tasks.",
            "",
            "| policy | wins | ties | losses | best planner | n/a | tasks won | ms per act |",
            "|---|---|---|---|---|---|---|---|",
        ]
        cost = s.get("ms_per_act") or {}
        for p in cols:
            c = s["summary"][p]
            lines.append(
                f"| {p} | {c['win']} | {c['tie']} | {c['loss']} | {c['best']} | {c['n/a']} | "
                f"{', '.join(c['tasks_won']) or '-'} | {_opt(cost.get(p))} |"
            )
        if s.get("headroom"):
            lines += _headroom_lines(s)
        skipped = sorted(
            {(p, st["skipped"]) for t in s["tasks"].values() for p, st in t["policies"].items() if "skipped" in st}
        )
        if skipped:
            lines += ["", "n/a: " + "; ".join(f"`{p}`: {why}" for p, why in skipped)]
        lines.append("")
    return "\n".join(lines)


def write_results(out: str, results: dict, figures: bool = True) -> list:
    """Write results.json (strict JSON) and results.md atomically, and with ``figures``
    one ``benchmark_<set>.png`` per task set (``evaluation.figures.draw_benchmark``);
    returns their names. A non-finite value raises ValueError naming it, before
    anything is written."""
    text = strict_json(results)
    md = render_markdown(results)
    os.makedirs(out, exist_ok=True)
    atomic_write_text(os.path.join(out, "results.json"), text)
    atomic_write_text(os.path.join(out, "results.md"), md)
    names = list(RESULT_FILES)
    if figures:
        from .figures import draw_benchmark

        names += draw_benchmark(out, results)
    return names
