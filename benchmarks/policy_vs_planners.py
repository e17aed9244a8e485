"""Trained policies against the planners on a grid of cells, with common random numbers.

    python benchmarks/policy_vs_planners.py --scenario sousa_asv \\
        --policies ppo,fim_a,fim_b --episodes 50 --seed 600000 \\
        --cell depth_m=1,5,20,50 --cell survey_path=stationary,lawnmower,circle,spiral \\
        --cache results/planner_cache.json --out results/sousa_table.json
    python benchmarks/policy_vs_planners.py --scenario gao_sea --policies runs/gao_ppo,ellipse --episodes 50

A policy is a planner name (``baselines.list_policies()``), ``ppo`` (the shipped PPO
policy of the scenario, ``agents.load("ppo", scenario=...)``), or a train.py run
directory / shipped policy name / model .zip (``agents.load``); ``label=spec`` names
it in the table. Every cell is the scenario with the cell's parameters set and the
per-episode randomization off; episode ``i`` of every cell and every policy uses
seed ``--seed + i`` (the core's random numbers are counter-based per environment,
so every policy meets the same noise, biases and start: common random numbers).
All episodes of one (cell, policy) run as one batch of the core, through the
evaluation's own runner (``evaluation.parallel.run_cells``, ``run_episodes``: one
policy instance per beacon and episode, a privileged planner told the truth, as
evaluate.py; ``--workers N`` plays N cells side by side, with the same numbers).

Score: ``survey_error_m`` (mean over survey vehicles) averaged over every step of
every episode, as evaluate.py's ``mean_error_m``. The table gives it per cell and
policy with a 95 % interval (t interval over the episodes' means; the episodes of
a cell have equal length, so the mean of episode means is the pooled mean), and
for the first policy the paired difference to every other one (same seeds: the
difference of episode means, its t interval, and whether it is below zero).
``--cache FILE`` keeps the per-episode means of planners (deterministic given
config, seeds and code) so that a second run does not recompute them; delete the
file when the planners or the core change.
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from evaluation.paired import t_interval

try:
    from benchmarks import _args
except ImportError:  # run as a script: its own folder is on the path, not the checkout
    import _args  # type: ignore[no-redef]

if TYPE_CHECKING:
    from coopnav_env.scenarios import ScenarioConfig

RANDOMIZATION_OFF = {"randomize_survey_path": (), "randomize_depth_m": (), "randomize_noise_scale": ()}


def build_cells(base: ScenarioConfig, cell_args: list) -> list:
    """[(label, config)] of the grid ``--cell KEY=V1,V2,...`` over ``base`` (the scenario with its
    ``--set``), the per-episode randomization off; a ``ValueError`` of one line naming a bad item
    (not KEY=..., an unknown parameter, a value the parameter cannot take)."""
    from coopnav_env.scenarios.base import check_overrides
    from evaluation.config import parse_assignment, parse_value

    base = base.replace(**{k: v for k, v in RANDOMIZATION_OFF.items() if base.applies(k)})
    cells: list[dict] = [{}]
    for item in cell_args:
        key, values = parse_assignment(item, "--cell")
        if (problem := _args.unknown_parameter(key)) is not None:
            raise ValueError(problem)
        check_overrides({key: None})
        cells = [dict(c, **{key: parse_value(key, v)}) for c in cells for v in values.split(",")]
    return [(";".join(f"{k}={v}" for k, v in c.items()) or "all", base.replace(**c)) for c in cells]


# Scenario parameters added after the cache format was fixed enter the key only when they
# differ from their default, so that a cache stays valid for the configs that do not use
# them (their numbers did not change; benchmarks' caches are checked against a rerun).
FIELDS_ADDED_AFTER_CACHE_V1 = (
    "network",
    "boat_max_speed_mps",
    "boat_max_turn_rate_dps",
    "acoustic_sensor",
    "mls_snr_db_at_1m",
    "mls_max_range_m",
    "frame_orientation_deg",
    "frame_orientation_spread_deg",
    "baseline_target_m",
    "boat_transit_speed_mps",
    "survey_speed_mps",
    "speed_encoder_noise_mps",
    "initial_frame_orientation_std_deg",
    "initial_frame_orientation_error_deg",
    "initial_current_std_mps",
    "initial_baseline_std_m",
    "frame_q_position_m2ps",
    "frame_q_orientation_rad2ps",
    "frame_q_current_m2ps3",
    "frame_q_baseline_m2ps",
    "baseline_tolerance_m",
    "baseline_penalty",
    "frame_rotation_tolerance_deg",
    "rotation_penalty",
    "min_baseline_distance_m",
    "approach_penalty",
)


def config_key(config: ScenarioConfig) -> str:
    from coopnav_env.scenarios import ScenarioConfig

    # every parameter's default, those of sections the default config leaves out included (a
    # getattr on the config would refuse a parameter of an absent section, e.g. the MLS array's)
    default = ScenarioConfig().to_flat_dict(all_parameters=True)
    fields = {
        k: v
        for k, v in config.to_flat_dict(all_parameters=True).items()
        if k not in FIELDS_ADDED_AFTER_CACHE_V1 or v != default.get(k)
    }
    return hashlib.sha1(repr(fields).encode()).hexdigest()[:16]


def is_planner(spec: str) -> bool:
    from baselines import list_policies

    return spec in list_policies()


def is_privileged(spec: str, config: ScenarioConfig) -> bool:
    """Whether planner ``spec`` is told the truth before it acts (``privileged``: the oracle)."""
    from baselines.base import motion_name, policy_class

    return is_planner(spec) and bool(getattr(policy_class(motion_name(spec), config.network), "privileged", False))


def run_cells_of(jobs: list, workers: int) -> list:
    """Per job (label, config, spec, seeds, ...): (per-episode mean survey_error_m, seconds),
    each job one ``evaluation.parallel.Cell`` (``run_episodes``: the evaluation's own runner,
    so a privileged planner such as the oracle is told the truth) on ``workers`` processes."""
    from evaluation.parallel import Cell, run_cells

    cells = [
        Cell(config, spec, tuple(seeds), label=f"{label} {spec}", steps=False)
        for label, config, spec, seeds, *_ in jobs
    ]
    with_warnings_quiet()
    return [([row["mean_error_m"] for row in r.episodes], r.wall_s) for r in run_cells(cells, workers)]


def with_warnings_quiet() -> None:
    import warnings

    warnings.filterwarnings("ignore", message=".*was trained on.*")


def main(argv: Sequence[str] | None = None) -> int:
    from coopnav_env.records import atomic_write_text
    from evaluation.parallel import check_workers

    p = _args.Parser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scenario", default="sousa_asv")
    p.add_argument(
        "--policies",
        default="ppo,fim_a,fim_b",
        help="comma-separated: planner names, 'ppo', run dirs or policy names; label=spec to rename",
    )
    p.add_argument("--episodes", type=int, default=50)
    p.add_argument("--seed", type=int, default=600000, help="episode i of every cell uses seed SEED + i")
    p.add_argument(
        "--cell",
        action="append",
        default=[],
        metavar="KEY=V1,V2,...",
        help="grid parameter (repeatable); none: the scenario itself",
    )
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="scenario override")
    p.add_argument("--cache", help="JSON file caching the planners' per-episode means")
    p.add_argument(
        "--workers",
        "--jobs",
        dest="jobs",
        default="1",
        metavar="N",
        help="worker processes, 0: every core (--jobs: old name)",
    )
    p.add_argument("--out", help="write the results as JSON here")
    p.add_argument("--markdown", help="write the table as Markdown here")
    _args.add_overwrite(p, "the --out and --markdown files (--cache is read and extended, never refused)")
    args = p.parse_args(argv)
    _args.outputs(p, args.overwrite, out=args.out, markdown=args.markdown)  # refused before any run
    _args.outputs(p, True, cache=args.cache)  # a cache is meant to be there: read, then extended
    _args.count(p, args.episodes, "--episodes", low=2)
    seeds = _args.seeds(p, args.seed, args.episodes)
    base = _args.scenario_config(p, args.scenario, _args.overrides(p, args.set))
    try:
        cells = build_cells(base, args.cell)
    except ValueError as err:
        p.error(f"--cell: {_args.first_line(err)}" if not str(err).startswith("--cell") else _args.first_line(err))
    specs = []
    for item in _args.names(p, args.policies, "--policies"):
        label, _, spec = item.strip().partition("=")
        specs.append((label, spec) if spec else (label, label))
    for _, spec in dict.fromkeys(specs):  # each loads and drives the scenario: one line now, not after the planners
        _args.policy(p, spec, cells[0][1], seeds[0], "--policies")
    cache = {}
    if args.cache and os.path.isfile(args.cache):
        from coopnav_env.safe_load import read_json

        try:
            cache = read_json(args.cache)
        except ValueError as err:
            p.error(f"--cache {args.cache}: not a JSON cache of this script ({_args.first_line(err)})")
        if not isinstance(cache, dict):
            p.error(f"--cache {args.cache}: not a JSON cache of this script (a {type(cache).__name__})")

    results, jobs = {}, []
    for label, config in cells:
        for name, spec in specs:
            # "<name>@truth" for a privileged planner (the oracle): before 2026-12-06 the script
            # never told it the truth, so a cache of then holds horizon's figures under "oracle"
            cached = f"{spec}@truth" if is_privileged(spec, config) else spec
            key = f"{cached}|{config_key(config)}|{args.seed}|{args.episodes}"
            if is_planner(spec) and key in cache:
                results[(label, name)] = np.array(cache[key])
            else:
                jobs.append((label, config, spec, seeds, name, key))
    t0 = time.perf_counter()
    try:
        outs = run_cells_of(jobs, check_workers(args.jobs))
    except (ValueError, OSError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    for (label, _config, spec, _, name, key), (per_ep, secs) in zip(jobs, outs):
        results[(label, name)] = np.array(per_ep)
        print(f"  {label:<40} {name:<12} {np.mean(per_ep):8.3f} m  [{secs:.0f} s]", file=sys.stderr, flush=True)
        if is_planner(spec):
            cache[key] = per_ep
    if args.cache and jobs:
        Path(args.cache).parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(args.cache, json.dumps(cache))

    names = [n for n, _ in specs]
    first = names[0]
    table = []
    for label, _ in cells:
        row = {"cell": label}
        for n in names:
            m, lo, hi = t_interval(results[(label, n)])
            row[n] = {"mean": m, "ci95": [lo, hi]}
        for n in names[1:]:
            d, lo, hi = t_interval(results[(label, first)] - results[(label, n)])
            row[f"{first}-{n}"] = {"mean": d, "ci95": [lo, hi], "lower": bool(d < 0)}
        table.append(row)
    pooled = {n: float(np.mean([results[(label, n)].mean() for label, _ in cells])) for n in names}
    wins = {n: sum(r[f"{first}-{n}"]["lower"] for r in table) for n in names[1:]}
    sig = {n: sum(r[f"{first}-{n}"]["ci95"][1] < 0 for r in table) for n in names[1:]}

    lines = [
        f"{args.scenario}: mean survey_error_m (m) and 95 % interval, {args.episodes} episodes per cell, "
        f"seeds {args.seed}..{args.seed + args.episodes - 1} (common random numbers)",
        "",
    ]
    head = "| cell | " + " | ".join(names) + " | " + " | ".join(f"{first} - {n}" for n in names[1:]) + " |"
    lines += [head, "|" + "---|" * (1 + len(names) + len(names) - 1)]
    for r in table:
        cols = [f"{r[n]['mean']:.3f} [{r[n]['ci95'][0]:.3f}, {r[n]['ci95'][1]:.3f}]" for n in names]
        cols += [
            f"{r[f'{first}-{n}']['mean']:+.3f} [{r[f'{first}-{n}']['ci95'][0]:+.3f}, "
            f"{r[f'{first}-{n}']['ci95'][1]:+.3f}]"
            for n in names[1:]
        ]
        lines.append(f"| {r['cell']} | " + " | ".join(cols) + " |")
    lines.append(
        "| mean of cells | "
        + " | ".join(f"{pooled[n]:.3f}" for n in names)
        + " | "
        + " | ".join("" for _ in names[1:])
        + " |"
    )
    lines.append("")
    for n in names[1:]:
        lines.append(
            f"{first} has a lower mean than {n} in {wins[n]}/{len(cells)} cells "
            f"({sig[n]}/{len(cells)} with the paired 95 % interval below zero)"
        )
    text = "\n".join(lines)
    print(text)
    print(f"[{time.perf_counter() - t0:.0f} s]", file=sys.stderr)
    if args.markdown:
        Path(args.markdown).parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(args.markdown, text + "\n")
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(
            args.out,
            json.dumps(
                {
                    "scenario": args.scenario,
                    "episodes": args.episodes,
                    "seed": args.seed,
                    "policies": dict(specs),
                    "cells": table,
                    "mean_of_cells": pooled,
                    "cells_lower": wins,
                    "cells_significantly_lower": sig,
                    "per_episode": {f"{c}|{n}": results[(c, n)].round(5).tolist() for c, _ in cells for n in names},
                },
                indent=1,
            )
            + "\n",
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
