"""A planner driving every beacon of a batch of the core, cycle by cycle: what the
consistency and surfacing benchmarks (``benchmarks/nees_per_cycle.py``,
``benchmarks/beacon_surfacing.py``) measure on. (The evaluation's episodes,
``evaluation.episodes``, add the files, seeds and policies of a benchmark run.)"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np


def planned_steps(
    scenario: str, planner: str, overrides: dict, runs: int, seed: int, planner_kwargs: dict | None = None
) -> Iterator[tuple]:
    """Run ``runs`` episodes of ``scenario`` (with ``overrides``) as one batch, seeds
    ``seed + i``, ``planner`` (with ``planner_kwargs``) driving every beacon (its own
    instance per run and beacon, seeded ``seed + i``); yield ``(config, simulator, result,
    live)`` after every step, ``live`` (runs,) the episodes that had not ended before it,
    until all have ended."""
    import coopnav_env
    from coopnav_env.core import make_simulator

    from .base import make_policy, tell_truth

    cfg = coopnav_env.make_config(scenario, **overrides)
    sim = make_simulator(cfg, runs)
    obs = sim.reset(list(range(seed, seed + runs)))
    policies: list[list[Any]] = [
        [make_policy(planner, cfg, seed=seed + b, agent=n, **(planner_kwargs or {})) for n in range(cfg.n_beacons)]
        for b in range(runs)
    ]
    for row in policies:
        for p in row:
            p.reset()
    done = np.zeros(runs, dtype=bool)
    for _ in range(cfg.max_cycles):
        tell_truth(policies, sim)  # a privileged planner (the oracle) plans on the truth, as in evaluation
        actions = np.zeros((runs, cfg.n_beacons, 2))
        for b in range(runs):
            for n in range(cfg.n_beacons):
                actions[b, n] = policies[b][n].act(obs[b, n])
        res = sim.step(actions)
        obs = res.obs
        yield cfg, sim, res, ~done
        done = done | np.asarray(res.terminated) | np.asarray(res.truncated)
        if done.all():
            return
