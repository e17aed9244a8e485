"""Trained policies against planners on a benchmark task set, on seeds you name (not the
test seeds): the table issue 23 asks for each learning lever that was tried.

    python benchmarks/lever_table.py --tasks gao_team --seed 700000 \\
        --policies ellipse,ppo,mappo=runs/gao_team_mappo,ippo=runs/gao_team_ippo \\
        --out results/levers_gao_team.json --markdown results/levers_gao_team.md

Every policy plays the task set's tasks (``evaluation.tasks``: the benchmark's overrides)
through the benchmark's own episode loop (``evaluation.episodes.run_episodes``: one
policy object per beacon and episode), episode ``i`` of every task and policy seeded
``--seed + i`` (common random numbers). ``label=spec`` names a policy; a spec is a
planner (``motion+schedule`` on ``sousa_ping``'s shared channel, e.g. ``ellipse+clock``),
``ppo`` (the shipped policy), a train.py run or a BenchMARL run
(``python -m agents.training.marl``).

The table: each task's mean error per policy (95 % t interval); for each policy that is
not a planner, its paired difference per task and pooled (per seed, the mean over the
tasks) against the best planner of the task among those given (lowest mean), and
against the first non-planner (the baseline policy, e.g. the shipped ``ppo``).

``python benchmarks/lever_table.py summarize [--policy ppo] A.json B.json ...``: one row per
task set for a policy (relative to the best planners, the worst task, lost episodes, and
whether the shift criteria hold: no task more than 5 % worse, no episode lost).

``python benchmarks/lever_table.py paired F.json A B``: policy ``A`` minus policy ``B`` of one
result, paired per seed and pooled over the tasks both drove (e.g. MAPPO minus IPPO).

Seeds: the benchmark's test seeds are refused; the default 700000 is neither a trainer's
validation range (500000 + e) nor a training seed of a run seeded below 1000
(``seed + e + k * 1_000_003``, e < 1000 environments).
"""

from __future__ import annotations

import json
import sys
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from coopnav_env.failures import MACHINE_FAILURES, one_line
from evaluation.benchmark_stats import paired_verdict
from evaluation.paired import t_interval

try:
    from benchmarks import _args
except ImportError:  # run as a script: its own folder is on the path, not the checkout
    import _args  # type: ignore[no-redef]


def _parse_policies(text: str, task_set: str | None = None) -> list:
    """[(label, spec)] of ``[label=]spec,...``; ``greedy`` and ``planners`` stand for the task
    set's greedy planners and all its planners (``evaluation.tasks.TaskSet``); a planner spec
    may carry settings (``ellipse:range_model=filter``, ``baselines.split_spec``)."""
    out = []
    for item in [s.strip() for s in text.split(",") if s.strip()]:
        head, eq, rest = item.partition("=")  # a label has no ':'; "ellipse:range_model=filter" is a spec
        label, spec = (head, rest) if eq and ":" not in head else ("", item)
        if spec in ("greedy", "planners") and not label and task_set is not None:
            from evaluation.tasks import get_task_set

            ts = get_task_set(task_set)
            out += [(p, p) for p in (ts.greedy_planners if spec == "greedy" else ts.planners)]
            continue
        out.append((label or spec, spec))
    labels = [label for label, _ in out]
    if len(set(labels)) != len(labels):
        raise ValueError(f"policy labels must differ, got {labels}")
    return out


def fingerprint(spec: str, scenario: str) -> str | None:
    """What a trained policy's spec resolves to, as a hash of its files (None for a planner):
    ``ppo`` or a run directory names other weights once a policy is re-shipped or retrained,
    so ``--reuse`` compares this, not the spec alone."""
    import hashlib
    from pathlib import Path

    from agents import resolve
    from baselines import is_planner

    if is_planner(spec):
        return None
    files: list = []
    for p in resolve(spec, scenario)[:2]:
        if p is None:
            continue
        p = Path(p)
        if p.is_dir():  # an RLlib checkpoint
            files += sorted(q for q in p.rglob("*") if q.is_file())
        elif p.name == "gate.yml":  # a gated policy: its networks are beside it
            files += [p, *sorted(p.parent.rglob("*.safetensors"))]
        else:
            files.append(p)
    digest = hashlib.sha256()
    for q in files:
        digest.update(q.read_bytes())
    return digest.hexdigest()[:16]


def run(
    task_set: str,
    policies: list,
    episodes: int,
    seed: int,
    progress: Callable[[str], Any] | None = print,
    reuse: dict | None = None,
    na: dict | None = None,
    workers: int = 1,
) -> dict:
    """{"tasks": [...], "policies": [...], "errors": {label: {task: [per-episode mean error]}}, ...}.
    ``reuse``: an earlier result of the same task set and seeds; its policies (same label,
    spec and, for a trained policy, the same files: ``fingerprint``) are taken from it instead
    of run again. ``na``: ``{label: {task: reason}}``,
    the tasks a policy cannot drive (``find_na``): not run, ``n/a`` in the tables. ``workers``:
    processes playing (task, policy) cells side by side (``evaluation.parallel``); the errors
    are the same to the bit for any count, ``seconds`` each cell's wall clock where it ran."""
    na = {label: dict((na or {}).get(label, {})) for label, _ in policies}
    from baselines import is_planner
    from evaluation.parallel import Cell, run_cells
    from evaluation.tasks import get_task_set

    ts = get_task_set(task_set)
    seeds = list(range(seed, seed + episodes))
    errors: dict = {label: {} for label, _ in policies}
    pings: dict = {label: {} for label, _ in policies}  # acoustic pings sent per episode
    seconds: dict = {label: 0.0 for label, _ in policies}
    done = set()
    prints = {label: fingerprint(spec, ts.scenario) for label, spec in policies}
    if reuse is not None:
        if reuse["task_set"] != task_set or reuse["seeds"] != [seed, seed + episodes - 1]:
            raise ValueError(f"--reuse holds {reuse['task_set']} on seeds {reuse['seeds']}, not this run's")
        for p in reuse["policies"]:
            if (p["label"], p["spec"]) in policies:
                if p.get("fingerprint") != prints[p["label"]]:
                    if progress is not None:
                        progress(f"{p['label']} ({p['spec']}): its files differ from --reuse's, run again")
                    continue
                errors[p["label"]] = reuse["errors"][p["label"]]
                pings[p["label"]] = reuse.get("pings", {}).get(p["label"], {})
                seconds[p["label"]] = reuse.get("seconds", {}).get(p["label"], 0.0)
                done.add(p["label"])
    keys, cells = [], []
    for task in ts.tasks:
        config = task.config(ts.scenario)
        for label, spec in policies:
            if label in done or task.name in na[label]:
                continue
            keys.append((task.name, label))
            cells.append(Cell(config, spec, tuple(seeds), label=f"{task_set}/{task.name} {label}", steps=False))
    for (task_name, label), result in zip(keys, run_cells(cells, workers)):
        rows = result.episodes
        errors[label][task_name] = [float(r["mean_error_m"]) for r in rows]
        pings[label][task_name] = [int(r["pings"]) for r in rows]
        seconds[label] += result.wall_s
        if progress is not None:
            progress(
                f"{task_set}/{task_name} {label}: {np.mean(errors[label][task_name]):.3f} m ({result.wall_s:.0f} s)"
            )
    return {
        "task_set": task_set,
        "tasks": [t.name for t in ts.tasks],
        "policies": [
            {"label": label, "spec": spec, "planner": is_planner(spec), "fingerprint": prints[label]}
            for label, spec in policies
        ],
        "seeds": [seed, seed + episodes - 1],
        "episodes": episodes,
        "errors": errors,
        "pings": pings,
        "seconds": seconds,
        "na": {label: why for label, why in na.items() if why},
    }


def find_na(task_set: str, policies: list, seed: int) -> dict:
    """``{label: {task: reason}}`` for the tasks each policy cannot drive (one observation
    each, ``evaluation.episodes.check_policy``: a flat policy on a team task). A policy
    that drives none of the set's tasks is refused (ValueError): that is a wrong policy,
    not a table with one column of ``n/a``."""
    from evaluation.episodes import check_policy
    from evaluation.tasks import get_task_set

    ts = get_task_set(task_set)
    out: dict = {}
    for label, spec in policies:
        for task in ts.tasks:
            try:
                check_policy(spec, task.config(ts.scenario), seed)
            except Exception as err:
                out.setdefault(label, {})[task.name] = (str(err).strip().splitlines() or [type(err).__name__])[0]
        if len(out.get(label, {})) == len(ts.tasks):
            first = next(iter(out[label].values()))
            raise ValueError(f"policy {label!r} ({spec}) cannot drive any task of {task_set}: {first}")
    return out


def _driven(result: dict, label: str) -> list:
    """The tasks of ``result`` that ``label`` drove (every task but its ``n/a``)."""
    na = result.get("na", {}).get(label, {})
    return [t for t in result["tasks"] if t not in na]


def _pooled(a: dict, b: dict, tasks: list) -> tuple:
    """(mean, lo, hi) of the paired difference a - b pooled over the tasks: per seed, the
    mean over the tasks, then the t interval over the seeds."""
    return t_interval(np.mean([np.asarray(a[t]) - np.asarray(b[t]) for t in tasks], axis=0))


def against_planners(result: dict, label: str) -> dict:
    """``label`` against each task's best planner of ``result`` (``compare_task``: the lowest
    mean, the paired difference and its verdict): the best planner per task, the means, the
    relative gap per task and the worst task, the pooled paired difference, the verdict
    counts and the lost episodes."""
    from evaluation.benchmark_stats import compare_task

    tasks, errs = _driven(result, label), result["errors"]
    planners = [p["label"] for p in result["policies"] if p["planner"]]
    per = {t: compare_task({**{p: errs[p][t] for p in planners}, label: errs[label][t]}, planners) for t in tasks}
    best = {t: per[t]["best_planner"] for t in tasks}
    rel = {t: np.mean(errs[label][t]) / np.mean(errs[best[t]][t]) - 1.0 for t in tasks}
    verdicts = [per[t]["policies"][label]["paired"]["verdict"] for t in tasks]
    return {
        "best": best,
        "mean": float(np.mean([np.mean(errs[label][t]) for t in tasks])),
        "ref": float(np.mean([np.mean(errs[best[t]][t]) for t in tasks])),
        "rel": rel,
        "worst": max(tasks, key=lambda t: rel[t]),
        "pooled": _pooled(errs[label], {t: errs[best[t]][t] for t in tasks}, tasks),
        "counts": {v: verdicts.count(v) for v in ("win", "tie", "loss")},
        "lost": lost_episodes(errs, label, planners, tasks),
        "na": len(result["tasks"]) - len(tasks),
    }


def lost_episodes(errs: dict, label: str, planners: list, tasks: list, factor: float = 10.0) -> int:
    """Episodes (over the tasks) where ``label`` loses the survey vehicle while a planner keeps
    it: its error above ``factor`` times the lowest planner error of the same seed."""
    n = 0
    for t in tasks:
        best = np.min([np.asarray(errs[p][t]) for p in planners], axis=0)
        n += int(np.sum(np.asarray(errs[label][t]) > factor * best))
    return n


def markdown(result: dict) -> str:
    tasks, errs = result["tasks"], result["errors"]
    pols = result["policies"]
    planners = [p["label"] for p in pols if p["planner"]]
    learned = [p["label"] for p in pols if not p["planner"]]
    lines = [
        f"Task set `{result['task_set']}`, {result['episodes']} episodes per task, seeds "
        f"{result['seeds'][0]}-{result['seeds'][1]}: mean survey error (m), 95 % t interval.",
        "",
        "| task | " + " | ".join(p["label"] for p in pols) + " |",
        "|---|" + "---|" * len(pols),
    ]
    for t in tasks:
        cells = []
        for p in pols:
            if t not in errs[p["label"]]:
                cells.append("n/a")
                continue
            m, lo, hi = t_interval(errs[p["label"]][t])
            cells.append(f"{m:.3f} [{lo:.3f}, {hi:.3f}]")
        lines.append(f"| {t} | " + " | ".join(cells) + " |")
    pings = result.get("pings") or {}
    if all(pings.get(p["label"]) for p in pols):  # pings per episode, when every policy's is recorded
        lines += ["", "Pings per episode (mean over the tasks' episodes):", ""]
        lines += ["| " + " | ".join(p["label"] for p in pols) + " |", "|" + "---|" * len(pols)]
        cells = []
        for p in pols:
            per = pings.get(p["label"]) or {}
            cells.append(f"{np.mean([np.mean(per[t]) for t in tasks if t in per]):.1f}")
        lines.append("| " + " | ".join(cells) + " |")
    if not learned:
        return "\n".join(lines) + "\n"
    base = learned[0]
    lines += [
        "",
        "Paired against each task's best planner given"
        + (f" and against `{base}`" if len(learned) > 1 else "")
        + " (per seed; pooled: the mean over the tasks); relative: mean over tasks against the best planners'.",
        "",
        "| policy | mean (m) | relative to best planner | paired vs best planner (m) | wins / ties / losses"
        " | worst task vs its best planner | lost" + (f" | paired vs `{base}` (m) |" if len(learned) > 1 else " |"),
        "|---|---|---|---|---|---|---|" + ("---|" if len(learned) > 1 else ""),
    ]
    best: dict = {}
    for label in learned:
        mean = float(np.mean([np.mean(errs[label][t]) for t in _driven(result, label)]))
        row = [f"`{label}`", f"{mean:.3f}"]
        if planners:
            a = against_planners(result, label)
            best, (m, lo, hi), n, worst = {**best, **a["best"]}, a["pooled"], a["counts"], a["worst"]
            row += [
                f"{100 * (mean - a['ref']) / a['ref']:+.1f} %",
                f"{m:+.3f} [{lo:+.3f}, {hi:+.3f}]",
                f"{n['win']} / {n['tie']} / {n['loss']}" + (f" ({a['na']} n/a)" if a["na"] else ""),
                f"{worst} {100 * a['rel'][worst]:+.1f} %",
                str(a["lost"]),
            ]
        else:
            row += ["", "", "", "", ""]
        if len(learned) > 1:
            if label == base:
                row.append("")
            else:
                both = [t for t in _driven(result, label) if t in _driven(result, base)]
                m, lo, hi = _pooled(errs[label], errs[base], both)
                row.append(f"{m:+.3f} [{lo:+.3f}, {hi:+.3f}] {paired_verdict(lo, hi)}")
        lines.append("| " + " | ".join(row) + " |")
    if best:
        lines += [
            "",
            "Best planner per task: " + ", ".join(f"{t} `{best[t]}`" for t in tasks if t in best) + ". *lost*: "
            "episodes where the policy's error is above 10x the lowest planner error of the same seed.",
        ]
    na = result.get("na", {})
    if na:
        lines += [
            "",
            "n/a: "
            + "; ".join(f"`{label}` on {', '.join(why)}: {next(iter(why.values()))}" for label, why in na.items()),
        ]
    return "\n".join(lines) + "\n"


def summary(results: list, label: str = "ppo", within: float = 0.05) -> str:
    """One row per result (task set) for policy ``label``: its mean against the best
    planners', the worst task, the lost episodes, and whether the shift criteria hold (no
    task worse than its best planner by more than ``within``, no episode lost)."""
    lines = [
        f"| task set | episodes | `{label}` (m) | best planners (m) | relative | worst task vs its best planner "
        f"| lost | within {100 * within:g} % and none lost |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        if label not in r["errors"] or not any(p["planner"] for p in r["policies"]):
            continue
        a = against_planners(r, label)
        mean, ref, worst, lost = a["mean"], a["ref"], a["worst"], a["lost"]
        ok = "yes" if a["rel"][worst] <= within and lost == 0 else "**no**"
        lines.append(
            f"| `{r['task_set']}` | {r['episodes']} | {mean:.3f} | {ref:.3f} | {100 * (mean - ref) / ref:+.1f} % "
            f"| {worst} ({a['best'][worst]}) {100 * a['rel'][worst]:+.1f} % | {lost} | {ok} |"
        )
    return "\n".join(lines) + "\n"


def read_result(path: str) -> dict:
    """A result written by ``--out`` (refused with the path if it is missing or not one)."""
    from coopnav_env.safe_load import read_json

    result = read_json(path)
    if not isinstance(result, dict) or not isinstance(result.get("errors"), dict):
        raise ValueError(f"{path}: {'no such file' if result is None else 'not a lever_table.py --out result'}")
    n = None  # episode i of every task and policy has the same seed: one count for all
    for label, by_task in result["errors"].items():
        if not isinstance(by_task, dict):
            raise ValueError(f"{path}: not a lever_table.py --out result (errors.{label} is not per task)")
        for task, errors in by_task.items():
            problem = _args.episode_errors_problem(errors, f"errors.{label}.{task}", n)
            if problem is not None:
                raise ValueError(f"{path}: {problem}")
            n = len(errors)
    return result


def paired(result: dict, a: str, b: str) -> str:
    """``a`` minus ``b`` of one result: per seed, the mean over the tasks both drove, and the
    95 % t interval over the seeds, as one line."""
    for label in (a, b):
        if label not in result["errors"]:
            raise ValueError(f"no policy {label!r} in the result; it has {', '.join(result['errors'])}")
    tasks = [t for t in _driven(result, a) if t in _driven(result, b)]
    if not tasks:
        raise ValueError(f"{a!r} and {b!r} drove no task in common")
    mean, lo, hi = _pooled(result["errors"][a], result["errors"][b], tasks)
    seeds = len(result["errors"][a][tasks[0]])
    return f"{a} - {b}: {mean:+.3f} [{lo:+.3f}, {hi:+.3f}] m over {seeds} seeds, {len(tasks)} tasks"


def main(argv: Sequence[str] | None = None) -> int:
    from evaluation.parallel import add_workers_argument

    p = _args.Parser(description=__doc__.split("\n\n")[0])
    p.add_argument("--tasks", required=True, help="a benchmark task set (python -m evaluation.benchmark --list)")
    p.add_argument(
        "--policies",
        required=True,
        help="comma-separated [label=]spec: a planner, greedy (the set's greedy planners), planners (all "
        "of them), ppo, a run folder",
    )
    p.add_argument(
        "--episodes",
        type=int,
        help="episodes per task and policy (default: the task set's own count, the benchmark's 50; "
        "the shift criterion is judged at 50)",
    )
    p.add_argument("--seed", type=int, default=700_000, help="episode i of every task and policy uses SEED + i")
    p.add_argument(
        "--reuse",
        help="an earlier --out of the same task set and seeds: its policies (same label, spec and "
        "files) are not run again",
    )
    p.add_argument("--out", help="write the per-episode errors as JSON here")
    p.add_argument("--markdown", help="write the table as Markdown here")
    add_workers_argument(p, "tasks and policies")
    _args.add_overwrite(p, "the --out and --markdown files (with --reuse of the same file too)")
    if argv is None:
        argv = sys.argv[1:]
    if argv and argv[0] == "summarize":  # lever_table.py summarize [--policy ppo] A.json B.json ...
        q = _args.Parser(prog="lever_table.py summarize")
        q.add_argument("files", nargs="+")
        q.add_argument("--policy", default="ppo")
        sargs = q.parse_args(argv[1:])
        try:
            results = [read_result(f) for f in sargs.files]
            if not any(sargs.policy in r["errors"] for r in results):  # an empty table is no answer
                held = sorted({label for r in results for label in r["errors"]})
                from coopnav_env.names import did_you_mean

                raise ValueError(
                    f"no policy {sargs.policy!r} in {', '.join(sargs.files)}{did_you_mean(sargs.policy, held)} "
                    f"they have: {', '.join(held)}"
                )
            print(summary(results, sargs.policy), end="")
        except ValueError as err:
            print(f"error: {err}", file=sys.stderr)
            return 2
        return 0
    if argv and argv[0] == "paired":  # lever_table.py paired F.json A B
        q = _args.Parser(prog="lever_table.py paired")
        q.add_argument("file")
        q.add_argument("a")
        q.add_argument("b")
        pargs = q.parse_args(argv[1:])
        try:
            print(paired(read_result(pargs.file), pargs.a, pargs.b))
        except ValueError as err:
            print(f"error: {err}", file=sys.stderr)
            return 2
        return 0
    args = p.parse_args(argv)
    _args.outputs(p, args.overwrite, out=args.out, markdown=args.markdown)  # refused before any run
    from coopnav_env.records import atomic_write_text
    from coopnav_env.seeds import check_seed, refuse_test_seeds
    from evaluation.limits import MAX_EPISODES
    from evaluation.parallel import check_workers
    from evaluation.tasks import get_task_set

    try:
        task_set = get_task_set(args.tasks)
        if args.episodes is None:
            args.episodes = task_set.episodes
        policies = _parse_policies(args.policies, args.tasks)
        if not policies:
            raise ValueError(f"--policies names nothing (got {args.policies!r}): give at least one")
        if args.episodes < 2:
            raise ValueError(f"--episodes must be >= 2 (a t interval), got {args.episodes}")
        if args.episodes > MAX_EPISODES:
            raise ValueError(
                f"--episodes must be at most {MAX_EPISODES} (evaluation.limits.MAX_EPISODES), got {args.episodes}"
            )
        check_seed(args.seed, "--seed")
        workers = check_workers(args.workers)
        refuse_test_seeds(args.seed, args.episodes, what="--seed")
        na = find_na(args.tasks, policies, args.seed)  # one observation each: n/a, or refused if none driven
        for label, why in na.items():
            print(f"note: {label} is n/a on {', '.join(why)}: {next(iter(why.values()))}", file=sys.stderr)
    except (KeyError, ValueError) as err:
        message = err.args[0] if isinstance(err, KeyError) and err.args else str(err)
        print(f"error: {message}", file=sys.stderr)
        return 2
    reuse = None
    if args.reuse:
        try:  # before the runs: a file that is not an earlier result is one line
            reuse = read_result(args.reuse)
        except (ValueError, OSError) as err:
            print(f"error: --reuse: {err if isinstance(err, ValueError) else one_line(err)}", file=sys.stderr)
            return 2
    try:
        result = run(args.tasks, policies, args.episodes, args.seed, lambda s: print(s, flush=True), reuse, na, workers)
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    except MACHINE_FAILURES as err:  # out of memory, a lost worker: one line
        print(f"error: {one_line(err)}", file=sys.stderr)
        return 2
    result["command"] = " ".join(["python", "benchmarks/lever_table.py", *argv])
    table = markdown(result)
    print(table)
    if args.out:
        atomic_write_text(args.out, json.dumps(result, indent=1))
    if args.markdown:
        atomic_write_text(args.markdown, table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
