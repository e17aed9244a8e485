"""The receding-horizon planner against the best greedy planner, task by task, paired.

    python benchmarks/horizon_vs_greedy.py --tasks gao_sea,gao_lawnmower,sousa_grid --episodes 50 --workers 2

For every task of the benchmark's task sets (``evaluation.tasks``), every planner that
drives its network except the floors and the challenger (the greedy ones: ``fim_a``,
``fim_b``, ``ellipse``, ``circle``) and the challenger (``horizon``) play the same
episodes: episode ``i`` is seeded ``TEST_SEEDS[i]`` as in the benchmark (common random
numbers; ``--first-seed`` moves them, e.g. to tune on other seeds). The best greedy
planner of a task is the one with the lowest mean error there (chosen after the fact,
which favours it); the table gives its mean, the challenger's, and the paired difference
(challenger minus best greedy: mean of the per-episode differences of
``mean_error_m`` with its 95 % t interval, ``evaluation.paired.t_interval``): **win**
when the interval lies below 0, **loss** above, **tie** otherwise.

For tuning (on seeds other than the test seeds: ``--first-seed``), ``--variant
NAME:BASE:KEY=VALUE,...`` names a planner ``NAME``: ``BASE`` with other constructor
arguments (e.g. ``--variant h8:horizon:horizon=8,n_samples=128``), usable as
``--challenger`` or ``--against``; ``--against POLICY`` compares the challenger with that
policy instead of the best greedy planner (e.g. joint against per-beacon team planning):

    python benchmarks/horizon_vs_greedy.py --tasks gao_team --first-seed 9000 --episodes 8 \
        --variant hpeers:horizon:team=peers --against hpeers
"""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence

import numpy as np

from baselines.base import is_planner, make_policy, split_spec
from evaluation.paired import t_interval
from evaluation.parallel import Cell, add_workers_argument, check_workers, run_cells

try:
    from benchmarks import _args
except ImportError:  # run as a script: its own folder is on the path, not the checkout
    import _args  # type: ignore[no-redef]

EXCLUDED = ("static", "random", "oracle")


def variant_spec(text: str) -> tuple[str, str]:
    """``NAME:BASE:KEY=VALUE,...`` -> (NAME, the planner spec ``BASE:KEY=VALUE:...`` that
    ``make_policy`` reads in any process, ``baselines.split_spec``)."""
    name, base, args = (text.split(":", 2) + ["", ""])[:3]
    return name, ":".join([base, *filter(None, args.split(","))])


def main(argv: Sequence[str] | None = None) -> int:
    from baselines import list_policies
    from coopnav_env.seeds import TEST_SEEDS

    p = _args.Parser(description=__doc__.split("\n\n")[0])
    p.add_argument("--tasks", default="gao_sea,gao_lawnmower,sousa_grid", help="comma-separated task sets")
    p.add_argument("--task", default=None, help="only these tasks (comma-separated names; default: every task)")
    p.add_argument("--challenger", default="horizon", help="comma-separated: one table row per task and challenger")
    p.add_argument("--against", default=None, help="compare with this policy, not the best greedy planner")
    p.add_argument(
        "--variant", action="append", default=[], metavar="NAME:BASE:KEY=VALUE,...", help="a planner variant"
    )
    p.add_argument("--episodes", type=int, default=50)
    p.add_argument("--first-seed", type=int, default=None, help="episode i uses this + i (default TEST_SEEDS[i])")
    add_workers_argument(p, "the cells (a task and a policy)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="on every task")
    p.add_argument("--markdown", help="also write the table here")
    p.add_argument("--json", help="write the per-episode errors here as they come (a partial run is usable)")
    _args.add_overwrite(p, "the --markdown and --json files")
    args = p.parse_args(argv)
    _args.outputs(p, args.overwrite, markdown=args.markdown, json=args.json)  # refused before any run
    _args.count(p, args.episodes, "--episodes", low=0)  # 0 and 1 refused below, once the variants are checked
    if args.first_seed is None:
        seeds = [int(s) for s in TEST_SEEDS[: args.episodes]]
    else:
        seeds = _args.seeds(p, args.first_seed, max(args.episodes, 1), "--first-seed")[: args.episodes]
    probe_seed = seeds[0] if seeds else int(TEST_SEEDS[0])  # the episode a policy is checked on
    extra = _args.overrides(p, args.set)
    task_sets = {name: _args.task_set(p, name) for name in _args.names(p, args.tasks, "--tasks")}
    try:
        workers = check_workers(args.workers)
        specs = dict(variant_spec(v) for v in args.variant)
        for name, text in specs.items():  # a bad base or keyword: one line now, not in a worker
            split_spec(text)
            if not is_planner(text.split(":")[0]):
                raise ValueError(f"--variant {name}: {text.split(':')[0]!r} is not a planner")
    except ValueError as err:
        p.error(str(err))
    variants = list(specs)
    only = set() if args.task is None else set(_args.names(p, args.task, "--task"))
    every_task = [t.name for ts in task_sets.values() for t in ts.tasks]
    for name in sorted(only - set(every_task)):
        from coopnav_env.names import did_you_mean

        p.error(
            f"--task: no task {name!r} in {args.tasks}{did_you_mean(name, every_task)} valid: {', '.join(every_task)}"
        )
    challengers = _args.names(p, args.challenger, "--challenger")
    cells: list[Cell] = []
    keys: list[tuple[str, str, str]] = []
    order: list[tuple[str, str, list]] = []
    checked: set[str] = set()  # the variants built once to check their settings, the policies per task set
    for set_name, ts in task_sets.items():
        if args.against:
            greedy = [args.against]
        else:
            greedy = [
                q
                for q in list_policies(ts.network)
                if q not in EXCLUDED and q not in challengers and q not in variants and q != "horizon"
            ]
        for task in ts.tasks:
            if only and task.name not in only:
                continue
            order.append((set_name, task.name, greedy))
            try:
                config = ts.task(task.name).config(ts.scenario, **extra)
            except ValueError as err:
                p.error(f"--set on {set_name}/{task.name}: {_args.first_line(err)}")
            for q in [*challengers, *greedy]:
                if q in specs and q not in checked:  # its settings checked once, here
                    try:
                        make_policy(specs[q], config)
                    except ValueError as err:
                        p.error(f"--variant {q}: {err}")
                    checked.add(q)
                elif q not in specs and (q in challengers or q == args.against) and f"{set_name} {q}" not in checked:
                    option = "--challenger" if q in challengers else "--against"
                    _args.policy(p, q, config, probe_seed, option)  # it loads and drives the task set's network
                    checked.add(f"{set_name} {q}")
                keys.append((set_name, task.name, q))
                label = f"{set_name}/{task.name} {q}"
                cells.append(Cell(config, specs.get(q, q), tuple(seeds), label, steps=False, act_seconds=True))
    _args.count(p, args.episodes, "--episodes", low=2)
    scores: dict = {}
    cpu: dict[str, float] = {}
    from coopnav_env.progress import Progress

    bar = Progress(total=len(cells) * len(seeds), unit="episode", desc="task x policy")
    bar.stage(f"{len(cells)} cells (a task and a policy, {len(seeds)} episodes each) on {workers} workers")
    # the evaluation's episode loop and process pool (evaluation.parallel), in the cells' order
    for (s, t, q), out in zip(keys, run_cells(cells, workers, bar)):
        errs = [r["mean_error_m"] for r in out.episodes]
        scores[s, t, q] = np.asarray(errs)
        sec = float(sum(out.act_seconds))
        cpu[q] = cpu.get(q, 0.0) + sec
        bar.stage(f"{s}/{t} {q}: {np.mean(errs):.3f} m ({sec:.0f} s of decisions)")
        if args.json:
            from coopnav_env.records import atomic_write_text

            dump = {f"{a}/{b}/{x}": v.tolist() for (a, b, x), v in scores.items()}
            atomic_write_text(args.json, json.dumps({"seeds": seeds, "episode_mean_error_m": dump}) + "\n")
    bar.close()
    c = ", ".join(challengers)
    lines = [
        f"{args.episodes} episodes per task and policy, seeds {seeds[0]}..{seeds[-1]}"
        + (f", --set {' '.join(args.set)}" if args.set else "")
        + f"; {c} minus {args.against or 'the task' + chr(39) + 's best greedy planner'}, mean survey_error_m (m), "
        "paired 95 % t interval.",
        "",
        f"| task set | task | {'against' if args.against else 'best greedy'} | its mean (m) | challenger | "
        "its mean (m) | difference [95 % interval] | verdict |",
        "|---|---|---|---|---|---|---|---|",
    ]
    tally: dict = {}
    for s, t, greedy in order:
        best = min(greedy, key=lambda q: float(scores[s, t, q].mean()))
        for q in challengers:
            m, lo, hi = t_interval(scores[s, t, q] - scores[s, t, best])
            verdict = "win" if hi < 0 else "loss" if lo > 0 else "tie"
            tally.setdefault((s, q), {"win": 0, "tie": 0, "loss": 0})[verdict] += 1
            lines.append(
                f"| {s} | {t} | {best} | {scores[s, t, best].mean():.2f} | {q} | {scores[s, t, q].mean():.2f} | "
                f"{m:+.2f} [{lo:+.2f}, {hi:+.2f}] | {verdict} |"
            )
    lines += ["", "| task set | challenger | wins | ties | losses |", "|---|---|---|---|---|"]
    lines += [f"| {s} | {q} | {v['win']} | {v['tie']} | {v['loss']} |" for (s, q), v in tally.items()]
    lines += [
        "",
        "CPU seconds of the decisions per policy (all tasks): "
        + ", ".join(f"{q} {v:.0f}" for q, v in sorted(cpu.items())),
    ]
    text = "\n".join(lines)
    print(text)
    if args.markdown:
        from coopnav_env.records import atomic_write_text

        atomic_write_text(args.markdown, text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
