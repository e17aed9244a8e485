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
All episodes of one (cell, policy) run as one batch of the core (``Simulator``);
trained policies act on the whole batch at once, planners one beacon at a time
(one instance per beacon and episode, as evaluate.py).

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

import argparse
import hashlib
import json
import os
import sys
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from evaluation.paired import t_interval

if TYPE_CHECKING:
    from coopnav_env.scenarios import ScenarioConfig

RANDOMIZATION_OFF = {"randomize_survey_path": (), "randomize_depth_m": (), "randomize_noise_scale": ()}


def _parse_value(key, text):
    from coopnav_env.scenarios.base import default_of

    default = default_of(key)
    if isinstance(default, bool):
        return text.lower() in ("1", "true", "yes")
    if isinstance(default, int):
        return int(float(text))
    if isinstance(default, float):
        return float(text)
    return text


def build_cells(scenario: str, cell_args: list, set_args: list) -> list:
    from coopnav_env.scenarios import make_config
    from coopnav_env.scenarios.base import check_overrides

    overrides = {}
    for item in set_args:
        key, value = item.split("=", 1)
        check_overrides({key: None})
        overrides[key] = _parse_value(key, value)
    base = make_config(scenario, **overrides)
    base = base.replace(**{k: v for k, v in RANDOMIZATION_OFF.items() if base.applies(k)})
    cells = [{}]
    for item in cell_args:
        key, values = item.split("=", 1)
        check_overrides({key: None})
        cells = [dict(c, **{key: _parse_value(key, v)}) for c in cells for v in values.split(",")]
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


def run_cell(config: ScenarioConfig, spec: str, seeds: list) -> np.ndarray:
    """Per-episode mean survey_error_m of policy ``spec`` on ``seeds`` (one batch)."""
    from coopnav_env.core import make_simulator
    from coopnav_env.views import action_dim

    B, N = len(seeds), config.n_beacons
    sim = make_simulator(config, batch_size=B)
    obs = sim.reset(np.asarray(seeds, dtype=np.int64))
    if is_planner(spec):
        from baselines import make_policy

        policies = [[make_policy(spec, config, seed=(s, j), agent=j) for j in range(N)] for s in seeds]

        def act(obs, alive):
            a = np.zeros((B, N, action_dim(sim)))
            for b in np.flatnonzero(alive):
                for j in range(N):
                    a[b, j] = policies[b][j].act(obs[b, j])
            return a
    else:
        import agents

        policy = agents.load(spec, scenario=config.name if spec == "ppo" else None)

        def act(obs, alive):
            return policy.act_batch(obs.reshape(B * N, -1)).reshape(B, N, -1).astype(np.float64)

    alive = np.ones(B, dtype=bool)
    err_sum, steps = np.zeros(B), np.zeros(B)
    while alive.any():
        res = sim.step(act(obs, alive))
        obs = res.obs
        err = res.info["survey_error_m"].mean(-1)
        err_sum += np.where(alive, err, 0.0)
        steps += alive
        alive &= ~(res.terminated | res.truncated)
    return err_sum / steps


def _job(args):
    label, config, spec, seeds = args
    t = time.perf_counter()
    with_warnings_quiet()
    return label, spec, run_cell(config, spec, seeds).tolist(), time.perf_counter() - t


def with_warnings_quiet() -> None:
    import warnings

    warnings.filterwarnings("ignore", message=".*was trained on.*")


def main(argv: Sequence[str] | None = None) -> int:
    from coopnav_env.records import atomic_write_text

    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
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
        "--workers", "--jobs", dest="jobs", type=int, default=1, metavar="N", help="worker processes (--jobs: old name)"
    )
    p.add_argument("--out", help="write the results as JSON here")
    p.add_argument("--markdown", help="write the table as Markdown here")
    args = p.parse_args(argv)

    cells = build_cells(args.scenario, args.cell, args.set)
    specs = []
    for item in args.policies.split(","):
        label, _, spec = item.strip().partition("=")
        specs.append((label, spec) if spec else (label, label))
    seeds = [args.seed + i for i in range(args.episodes)]
    cache = {}
    if args.cache and os.path.isfile(args.cache):
        with open(args.cache) as f:
            cache = json.load(f)

    results, jobs = {}, []
    for label, config in cells:
        for name, spec in specs:
            key = f"{spec}|{config_key(config)}|{args.seed}|{args.episodes}"
            if is_planner(spec) and key in cache:
                results[(label, name)] = np.array(cache[key])
            else:
                jobs.append((label, config, spec, seeds, name, key))
    t0 = time.perf_counter()
    work = [(j[0], j[1], j[2], j[3]) for j in jobs]
    if args.jobs > 1 and len(work) > 1:
        with ProcessPoolExecutor(args.jobs) as pool:
            outs = list(pool.map(_job, work))
    else:
        outs = [_job(w) for w in work]
    for (label, _config, spec, _, name, key), (_, _, per_ep, secs) in zip(jobs, outs):
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
