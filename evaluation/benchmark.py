"""The benchmark: named task sets (``evaluation.tasks``), fixed test seeds that training
never draws (``coopnav_env.seeds.TEST_SEEDS``), a fixed episode count, and one table
that says which policy beat the best planner where.

    coopnav-benchmark --tasks sousa_grid --policies ppo --out results/bench
    python -m evaluation.benchmark --tasks sousa_grid,gao_sea --policies ppo,runs/my_run --out results/bench
    python -m evaluation.benchmark --list

Every task set's planners (those that drive its network, without the floors) and floors
(``static``, ``random``) always run; ``--policies`` adds challengers: planner names,
``ppo`` (the scenario's shipped policy), a shipped policy or a train.py run
directory. Episode ``i`` of every task and policy is seeded ``TEST_SEEDS[i]`` (common
random numbers), so policies are compared episode by episode.

Per task and policy (``results.json``, strict JSON; ``results.md``, Markdown; both
written atomically into ``--out``):

* ``mean_error_m``: the mean over episodes of each episode's mean survey error
  (``episodes.mean_error_m``: the mean over its steps), with its 95 % t interval
  (``ci95_error_m``) and the per-episode values (``episode_mean_error_m``);
* ``ranges_fused``: ranges fused per episode (pings used), mean and per episode;
* ``paired``: the per-episode difference to the task's best planner (the planner with
  the lowest ``mean_error_m``; negative: better than it), its mean and 95 % t interval
  (``evaluation.paired.t_interval``), and a verdict: ``win`` (the interval lies below
  0), ``loss`` (above 0), ``tie`` (it holds 0), ``best`` (the best planner itself);
* ``ms_per_act``: the cost per decision, the median CPU milliseconds of one ``act`` call
  (one beacon's decision, the calling thread's CPU clock: one core), measured around
  every act of the run (``run_episodes(act_seconds=...)``); per task set, ``ms_per_act``
  per policy is the median over its tasks;
* a policy that cannot drive a task is ``n/a`` there, with the reason; it wins nothing
  there. The policy says so itself (``episodes.check_policy`` asks its
  ``config_problem``): a flat-observation policy takes one observation size (one team),
  an entity policy (``agents.entity``) any team of up to five survey vehicles and three
  beacons of its action size, on the survey-beacon networks.

Per task ``wins`` lists the policies that won; per task set ``summary`` counts each
policy's wins, ties, losses and n/a.

On the survey networks the reference ``oracle`` (``baselines.horizon``: the receding-horizon
optimiser given the truth; ``evaluation.tasks.REFERENCES``) runs on every task too; it is
never the best planner. Per task ``headroom`` (``benchmark_stats.headroom_task``) gives the
best greedy planner (the best of the planners other than ``horizon``), the oracle's mean,
the headroom (best greedy minus oracle, paired interval) and, for ``horizon`` and each
challenger, the fraction of it closed, (best greedy - policy) / headroom, n/a where the
oracle is no better than the best greedy planner; per task set ``headroom`` pools them
(``benchmark_stats.summarize_headroom``). The win verdict stays against the best planner,
``horizon`` included. A run with other than the benchmark's episode
count, or with ``--set``, says in both files that it is not a benchmark result.

The statistics are ``evaluation.benchmark_stats`` (pure), the tables and files
``evaluation.benchmark_report``; this module plans, runs and is the command line.

From Python (no lock on the output directory):

    from evaluation.benchmark import build_results, plan_benchmark, run_benchmark, write_results
    plan = plan_benchmark("gao_sea", "ppo", out="results/bench")
    write_results("results/bench", build_results(plan, run_benchmark(plan)))

Exit status: 0 done; 2 bad input (an unknown task set, policy or parameter, a policy
that can drive no task, an output directory in use or holding a result without
``--overwrite``): one line on stderr, nothing written; 1 a result that cannot be
written (a non-finite error, named); 130 interrupted (nothing written).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import shlex
import signal
import sys
from collections.abc import Iterable, Sequence

import numpy as np

from coopnav_env.failures import MACHINE_FAILURES, one_line
from coopnav_env.records import plain, version_record
from coopnav_env.seeds import TEST_SEED, TEST_SEED_COUNT, TEST_SEEDS

from .benchmark_report import RESULT_FILES, render_markdown, write_results
from .benchmark_stats import compare_task, headroom_task, summarize_headroom, summarize_task_set
from .errors import UsageError, UsageParser
from .tasks import BENCHMARK_VERSION, NON_GREEDY, TASK_SETS, get_task_set

VERDICTS = ("win", "tie", "loss")

__all__ = [
    "BenchmarkPlan",
    "RESULT_FILES",
    "check_out_folder",
    "build_results",
    "compare_task",
    "main",
    "plan_benchmark",
    "render_markdown",
    "resummarize",
    "run_benchmark",
    "summarize_task_set",
    "write_results",
]


# ------------------------------------------------------------------------------------
# statistics (pure: arrays in, dicts out)


# ------------------------------------------------------------------------------------
# the plan: every check before any work


@dataclasses.dataclass
class SetPlan:
    """One task set of a run: its columns, each task's config, and the policies that
    cannot drive a task (task -> {policy: the reason})."""

    task_set: object
    columns: list  # planners, references, floors, then the challengers
    configs: dict  # task name -> ScenarioConfig
    cannot: dict  # task name -> {policy: reason}
    trained: dict  # policy -> what it resolved to (evaluation.config.resolve_trained)


@dataclasses.dataclass
class BenchmarkPlan:
    """A checked run (``plan_benchmark``): the task sets, the challengers, the episodes
    per task and policy, the ``--set`` overrides and the output directory."""

    sets: list
    challengers: list
    episodes: int
    overrides: dict
    out: str
    partial: bool = False  # --task: some tasks of the sets only
    # the code that runs: recorded when the run is planned, not when its results are written
    # (a commit made during a long run is not the one whose code produced it)
    versions: dict = dataclasses.field(default_factory=lambda: version_record())

    @property
    def seeds(self) -> list:
        """The episodes' seeds: ``TEST_SEEDS[i]`` for i < episodes."""
        return list(TEST_SEEDS[: self.episodes])

    @property
    def official(self) -> bool:
        """Whether this run is a benchmark result: every set's own episode count, no --set."""
        return not self.overrides and not self.partial and all(self.episodes == s.task_set.episodes for s in self.sets)

    def total_episodes(self) -> int:
        """Episodes the run plays (tasks x policies that can drive them x episodes)."""
        return sum((len(s.columns) - len(s.cannot[task])) * self.episodes for s in self.sets for task in s.configs)


def _first_line(err: BaseException) -> str:
    return (str(err).strip().splitlines() or [type(err).__name__])[0]


def _split(text) -> list:
    if text is None:
        return []
    if isinstance(text, str):
        text = text.split(",")
    return [str(t).strip() for t in text if str(t).strip()]


def check_out_folder(out: str, overwrite: bool) -> None:
    """A one-line ``UsageError`` unless a benchmark result may be written into ``out``: not a
    file, not in use by a running evaluation, no benchmark result there unless ``overwrite``,
    never an evaluate.py result or a train.py run (``outdir.other_result`` the other way
    round), and writable. The benchmark's and ``benchmarks/resummarize.py``'s one check."""
    from coopnav_env.records import check_writable

    from . import outdir

    if os.path.exists(out) and not os.path.isdir(out):
        raise UsageError(f"output path {out!r} is a file, not a directory")
    outdir.check_not_in_use(out)
    held = [f for f in RESULT_FILES if os.path.exists(os.path.join(out, f))]
    if held and not overwrite:
        raise UsageError(
            f"{out!r} holds a benchmark result ({', '.join(held)}); use --overwrite to replace it or another --out"
        )
    if outdir.has_results(out):
        raise UsageError(f"{out!r} holds an evaluate.py result; use another --out")
    if outdir.is_training_run(out):
        raise UsageError(f"{out!r} holds a train.py run (config.yml); use another --out")
    try:
        check_writable(out)
    except OSError as err:
        raise UsageError(f"--out {out}: {err}") from None


def plan_benchmark(
    tasks: str | Sequence[str],
    policies: str | Sequence[str] | None = None,
    episodes: int | None = None,
    overrides: dict | None = None,
    out: str = "results/benchmark",
    overwrite: bool = False,
    trust_pickle: bool = False,
    check_out: bool = True,
    only_tasks: str | Sequence[str] | None = None,
) -> BenchmarkPlan:
    """Check everything and build the plan; raises UsageError (one line). ``tasks``: task
    set names (a list or "a,b"; "all": every set); ``policies``: the challengers;
    ``episodes``: None: each set's own count (the same for every set); ``overrides``:
    scenario parameters set on every task (a quick look, not the benchmark); ``only_tasks``:
    task names (a list or "a,b") to run instead of every task of the sets (a part of the
    benchmark: its result says so)."""
    from baselines import is_planner, list_policies, motion_name

    from .config import _unknown_policy, coerce_value, resolve_trained
    from .episodes import check_policy

    names = _split(tasks)
    if names == ["all"]:
        names = list(TASK_SETS)
    if not names:
        raise UsageError(f"no task set given; valid: {', '.join(TASK_SETS)}, all")
    if len(set(names)) != len(names):
        raise UsageError("a task set is listed twice")
    sets = []
    for n in names:
        try:
            sets.append(get_task_set(n))
        except KeyError:
            from coopnav_env.names import did_you_mean

            raise UsageError(
                f"unknown task set {n!r}{did_you_mean(n, list(TASK_SETS) + ['all'])} valid: {', '.join(TASK_SETS)}, all"
            ) from None
    only = _split(only_tasks)
    if only:
        from coopnav_env.names import did_you_mean

        known = [t.name for s in sets for t in s.tasks]
        for t in only:
            if t not in known:
                raise UsageError(
                    f"unknown task {t!r} in {', '.join(names)}{did_you_mean(t, known)} valid: "
                    f"{', '.join(dict.fromkeys(known))}"
                )
        sets = [dataclasses.replace(s, tasks=tuple(t for t in s.tasks if t.name in only)) for s in sets]
        sets = [s for s in sets if s.tasks]
    challengers = _split(policies)
    if len(set(challengers)) != len(challengers):
        raise UsageError("a policy is listed twice")
    if episodes is None:
        counts = {s.episodes for s in sets}
        if len(counts) > 1:
            raise UsageError(f"the task sets have different episode counts ({sorted(counts)}): run them separately")
        episodes = counts.pop()
    if isinstance(episodes, bool) or not isinstance(episodes, (int, np.integer)):
        raise UsageError(f"--episodes must be an integer, got {episodes!r}")
    if not 2 <= episodes <= TEST_SEED_COUNT:
        raise UsageError(f"--episodes must be in [2, {TEST_SEED_COUNT}] (an interval needs two), got {episodes}")
    if check_out:  # before the policies are checked (which can compile the simulator for a minute)
        check_out_folder(out, overwrite)
    try:
        overrides = {k: coerce_value(k, v) for k, v in (overrides or {}).items()}
    except UsageError:
        raise
    except ValueError as err:
        raise UsageError(_first_line(err)) from None
    seed = TEST_SEEDS[0]
    plans, drivable = [], dict.fromkeys(challengers, 0)
    for ts in sets:
        base = list(ts.planners) + list(ts.references) + list(ts.floors)
        columns = base + [p for p in challengers if p not in base]
        trained, unresolved = {}, {}
        for p in columns:
            if is_planner(p):  # a registered planner, or "<motion>+<schedule>" of one
                if motion_name(p) not in list_policies(ts.network):
                    unresolved[p] = f"planner {p!r} cannot drive the {ts.network} network"
                continue
            try:
                trained[p] = resolve_trained(p, ts.scenario, trust_pickle)
            except ValueError as err:
                import agents

                if isinstance(err, agents.PolicyFormatError):
                    raise UsageError(f"policy {p!r}: {_first_line(err)}") from None
                unresolved[p] = _first_line(_unknown_policy(p, ts.scenario, err, list_policies()))
            except Exception as err:  # any failure to find it
                unresolved[p] = _first_line(_unknown_policy(p, ts.scenario, err, list_policies()))
        configs: dict = {}
        cannot: dict = {}
        for task in ts.tasks:
            try:
                configs[task.name] = config = task.config(ts.scenario, **overrides)
            except ValueError as err:
                raise UsageError(f"task {ts.name}/{task.name}: {_first_line(err)}") from None
            cannot[task.name] = {}
            for p in columns:
                if p in unresolved:
                    cannot[task.name][p] = unresolved[p]
                    continue
                try:
                    check_policy(p, config, seed)
                except KeyboardInterrupt:
                    raise
                except Exception as err:  # a policy that cannot act here
                    if p not in challengers:
                        raise UsageError(
                            f"planner {p!r} cannot drive task {ts.name}/{task.name}: {_first_line(err)}"
                        ) from None
                    cannot[task.name][p] = _first_line(err)
                    continue
                if p in drivable:
                    drivable[p] += 1
        plans.append(SetPlan(ts, columns, configs, cannot, trained))
    for p, n in drivable.items():
        if n == 0:
            reasons = [r for s in plans for c in s.cannot.values() for q, r in c.items() if q == p]
            raise UsageError(f"policy {p!r} can drive no task of {', '.join(names)}: {reasons[0]}")
    return BenchmarkPlan(plans, challengers, int(episodes), overrides, out, partial=bool(only))


# ------------------------------------------------------------------------------------
# running


def _progress_bar(total: int, show: bool | None):
    """A bar on a terminal (advancing with every step of every episode), one line per task
    and policy elsewhere (``coopnav_env.progress``); None with ``show`` False."""
    from coopnav_env.progress import Progress

    if not total or show is False:
        return None
    return Progress(total, unit="episode", desc="benchmark", mode="bar" if show else None)


def run_benchmark(plan: BenchmarkPlan, progress: bool | None = None, workers: int = 1) -> dict:
    """Run every (task set, task, policy) of ``plan`` on the test seeds; returns
    ``{set: {task: {policy: {"mean_error_m": [...], "ranges_fused": [...]} or None}}}``.
    ``workers``: processes running cells side by side (``evaluation.parallel``; 0: every
    core); the results are the same to the bit for any count."""
    from .parallel import Cell, run_cells

    bar = _progress_bar(plan.total_episodes(), progress)
    keys, cells = [], []
    for sp in plan.sets:
        for task, config in sp.configs.items():
            for p in sp.columns:
                if p not in sp.cannot[task]:
                    keys.append((sp.task_set.name, task, p))
                    label = f"{sp.task_set.name}/{task} {p}"
                    cells.append(Cell(config, p, tuple(plan.seeds), label=label, steps=False, act_seconds=True))
    done: dict = {}
    try:
        for key, result in zip(keys, run_cells(cells, workers, bar)):
            rows = result.episodes
            done[key] = {
                "mean_error_m": [r["mean_error_m"] for r in rows],
                "ranges_fused": [r["ranges_fused"] for r in rows],
                "ms_per_act": 1e3 * float(np.median(result.act_seconds)),
            }
    finally:
        if bar is not None:
            bar.close()
    raw: dict = {}
    for sp in plan.sets:
        per_set: dict = raw.setdefault(sp.task_set.name, {})
        for task in sp.configs:
            per_set[task] = {p: done.get((sp.task_set.name, task, p)) for p in sp.columns}
    return raw


def build_results(plan: BenchmarkPlan, raw: dict, command: str | None = None) -> dict:
    """results.json's content from ``raw`` (``run_benchmark``'s result)."""
    first = TEST_SEED
    sets = {}
    for sp in plan.sets:
        ts = sp.task_set
        tasks = {}
        closers = _closers(ts.planners, plan.challengers, ts.references)
        for task in ts.tasks:
            per_task = raw[ts.name][task.name]
            errors = {p: None if v is None else v["mean_error_m"] for p, v in per_task.items()}
            ranges = {p: v["ranges_fused"] for p, v in per_task.items() if v is not None}
            result = compare_task(errors, ts.planners, ranges_fused=ranges, skipped=sp.cannot[task.name])
            for p, v in per_task.items():  # cost per decision: median CPU ms per act (run_episodes' act_seconds)
                if v is not None and "ms_per_act" in v:
                    result["policies"][p]["ms_per_act"] = v["ms_per_act"]
            tasks[task.name] = {"overrides": plain(dict(task.overrides)), "about": task.about, **result}
        headroom = _add_headrooms(tasks, ts.greedy_planners, closers, ts.references)
        sets[ts.name] = {
            "scenario": ts.scenario,
            "about": ts.about,
            "episodes": plan.episodes,
            "benchmark_episodes": ts.episodes,
            "planners": list(ts.planners),
            "greedy_planners": list(ts.greedy_planners),
            "references": list(ts.references),
            "floors": list(ts.floors),
            "challengers": list(plan.challengers),
            "columns": list(sp.columns),
            "trained_policies": sp.trained,
            "tasks": tasks,
            "summary": summarize_task_set(tasks, sp.columns),
            "ms_per_act": _cost_per_decision(tasks, sp.columns),
            "headroom": headroom,
        }
    return {
        "benchmark_version": BENCHMARK_VERSION,
        "official": plan.official,
        "not_official_because": _not_official(plan),
        "command": command,
        "episodes": plan.episodes,
        "seeds": {"first": first, "last": first + plan.episodes - 1, "rule": "episode i: TEST_SEEDS[i] = first + i"},
        "set_overrides": plain(plan.overrides),
        "confidence": 0.95,
        "task_sets": sets,
        "versions": plan.versions,
    }


def _closers(planners: Iterable[str], challengers: Iterable[str], references: Iterable[str]) -> list:
    """Whose share of the headroom a task set reports: its non-greedy planners, then the challengers."""
    from baselines import motion_name

    closers = [p for p in planners if motion_name(p) in NON_GREEDY]
    return closers + [p for p in challengers if p not in closers and p not in references]


def _add_headrooms(tasks: dict, greedy: list, closers: list, references: list) -> dict | None:
    """Each task's ``headroom`` (``headroom_task``, set in place in ``tasks``) and the task set's
    pooled one (``summarize_headroom``); None without a reference."""
    if not references:
        return None
    for task in tasks.values():
        task["headroom"] = headroom_task(task, greedy, closers, oracle=references[0])
    return summarize_headroom({name: task["headroom"] for name, task in tasks.items()}, closers)


def resummarize(results: dict) -> dict:
    """``results`` (a results.json's content) with every headroom recomputed by this code's
    rules (``headroom_task``, ``summarize_headroom``) from the per-episode errors it holds:
    a table of an earlier run under a changed rule, without running it again. The rest is
    kept; ``resummarized`` records the benchmark version whose rules were applied."""
    sets = {}
    for name, ts in results["task_sets"].items():
        ts = dict(ts, tasks={t: dict(task) for t, task in ts["tasks"].items()})
        if ts.get("references"):
            closers = _closers(ts["planners"], ts["challengers"], ts["references"])
            ts["headroom"] = _add_headrooms(ts["tasks"], ts["greedy_planners"], closers, ts["references"])
        sets[name] = ts
    return dict(results, task_sets=sets, resummarized={"rules_of_benchmark_version": BENCHMARK_VERSION})


def _cost_per_decision(tasks: dict, columns: list) -> dict:
    """Per policy the median over the set's tasks of its median CPU ms per act (None where it ran on none)."""
    out = {}
    for p in columns:
        ms = [t["policies"][p]["ms_per_act"] for t in tasks.values() if "ms_per_act" in t["policies"].get(p, {})]
        out[p] = float(np.median(ms)) if ms else None
    return out


def _not_official(plan: BenchmarkPlan) -> list:
    why = []
    for sp in plan.sets:
        if plan.episodes != sp.task_set.episodes:
            why.append(f"{plan.episodes} episodes per task, not {sp.task_set.name}'s {sp.task_set.episodes}")
    if plan.partial:
        why.append("--task: " + ", ".join(t.name for sp in plan.sets for t in sp.task_set.tasks) + " only")
    if plan.overrides:
        why.append("--set " + " ".join(f"{k}={v}" for k, v in plan.overrides.items()))
    return why


# ------------------------------------------------------------------------------------
# results.md


# ------------------------------------------------------------------------------------
# the command line


def build_parser(prog: str | None = None) -> argparse.ArgumentParser:
    from .parallel import add_workers_argument

    p = UsageParser(
        prog=prog,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Run policies on the benchmark's task sets (fixed test seeds, never trained on) "
        "against the planners, and write results.json and results.md to OUT.",
        epilog="task sets: "
        + ", ".join(f"{n} ({s.scenario}, {len(s.tasks)} tasks)" for n, s in TASK_SETS.items())
        + "\nexample:\n  %(prog)s --tasks sousa_grid --policies ppo --out results/bench",
    )
    p.add_argument(
        "--tasks", default=None, help="comma-separated task sets, or all (default with --task: the sets that hold it)"
    )
    p.add_argument(
        "--task",
        default=None,
        metavar="NAME",
        help="run only this task (comma-separated names; --list shows them): a quick look, not a benchmark result",
    )
    p.add_argument(
        "--policies",
        default=None,
        help="challengers, comma-separated: ppo, a shipped policy, a train.py run directory, or planners, "
        "with settings as NAME:KEY=VALUE (ellipse:range_model=filter) (the task sets' planners and floors "
        "always run)",
    )
    p.add_argument(
        "--episodes",
        type=int,
        default=None,
        help="episodes per task and policy (default: the task set's, 50); another count is a quick "
        "look, not a benchmark result",
    )
    p.add_argument(
        "--set",
        dest="sets",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="set a scenario parameter on every task (a quick look, not a benchmark result)",
    )
    p.add_argument("--out", default="results/benchmark", help="output directory (default: results/benchmark)")
    p.add_argument("--overwrite", action="store_true", help="replace a benchmark result already in OUT")
    p.add_argument("--list", action="store_true", help="list the task sets and their tasks, and exit")
    p.add_argument(
        "--no-progress",
        action="store_true",
        help="no progress (default: a bar on a terminal, a line per task and policy elsewhere)",
    )
    p.add_argument("--no-figures", action="store_true", help="write no benchmark_<set>.png")
    add_workers_argument(p, "tasks and policies")
    p.add_argument(
        "--trust-pickle",
        action="store_true",
        help="accept trained policies in pickle-based formats (only files you trust)",
    )
    return p


def list_text() -> str:
    lines = []
    for n, s in TASK_SETS.items():
        lines.append(
            f"{n}: scenario {s.scenario}, {s.episodes} episodes per task; planners "
            f"{', '.join(s.planners)}; floors {', '.join(s.floors)}"
        )
        for t in s.tasks:
            ov = ", ".join(f"{k}={v}" for k, v in t.overrides.items()) or "as configured"
            lines.append(f"  {t.name}: {ov}")
    return "\n".join(lines)


def main(argv: list[str] | None = None, prog: str | None = None) -> int:
    """The command line; returns the exit status (0; 2 bad input; 1 a result that cannot be
    written; 130 interrupted)."""
    prog = prog or "coopnav-benchmark"
    argv = list(sys.argv[1:] if argv is None else argv)
    try:  # SIGTERM stops the run like Ctrl-C
        previous_handler = signal.signal(signal.SIGTERM, _terminate)
    except ValueError:  # not the main thread
        previous_handler = None
    try:
        return _main(argv, prog)
    finally:
        if previous_handler is not None:
            signal.signal(signal.SIGTERM, previous_handler)


def _terminate(signum, frame):
    raise KeyboardInterrupt(f"signal {signum}")


def _main(argv: list, prog: str) -> int:
    from . import outdir
    from .config import parse_assignments
    from .parallel import check_workers

    try:
        args = build_parser(prog).parse_args(argv)
        if args.list:
            print(list_text())
            return 0
        if args.task is not None and not _split(args.task):  # '' or ',': not "every task"
            raise UsageError(f"--task names no task (got {args.task!r}); `--list` shows them")
        if args.tasks is None and args.task is not None:
            wanted = set(_split(args.task))
            args.tasks = ",".join(n for n, s in TASK_SETS.items() if wanted & {t.name for t in s.tasks}) or "all"
        if args.tasks is None:
            raise UsageError(f"--tasks is required: {', '.join(TASK_SETS)} or all")
        sets = parse_assignments(args.sets, "--set")
        try:
            workers = check_workers(args.workers)
        except ValueError as err:
            raise UsageError(str(err)) from None
        from coopnav_env.progress import announce_after

        with announce_after(
            "checking the task sets and the policies (the first run also compiles the simulator, about a minute)", 2.0
        ):
            plan = plan_benchmark(
                args.tasks,
                args.policies,
                args.episodes,
                sets,
                args.out,
                args.overwrite,
                args.trust_pickle,
                only_tasks=args.task,
            )
        command = " ".join([prog, shlex.join(argv)]).strip()
        with outdir.OutputLock(args.out, command):
            raw = run_benchmark(plan, progress=False if args.no_progress else None, workers=workers)
            results = build_results(plan, raw, command)
            try:
                files = write_results(args.out, results, figures=not args.no_figures)
            except ValueError as err:
                print(f"{prog}: error: {_first_line(err)}; nothing written", file=sys.stderr)
                return 1
    except UsageError as err:
        print(f"{prog}: error: {_first_line(err)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"{prog}: interrupted; nothing written", file=sys.stderr)
        return 130
    except MACHINE_FAILURES as err:  # a full disk, out of memory, a lost worker: one line
        print(f"{prog}: error: {one_line(err)}; nothing written", file=sys.stderr)
        return 2
    print(render_markdown(results))
    print(f"\nwrote {args.out}/: {', '.join(files)}")
    return 0


if __name__ == "__main__":
    sys.exit(main(prog="python -m evaluation.benchmark"))
