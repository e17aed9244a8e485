"""A large batch is the same simulation as batches of one, row by row (bit for bit).

Until 2026-12-03 a batch of 256 environments or more ran numba's threaded kernel twins
(``core/jit.py``), and they silently dropped their writes: the survey vehicles did not
move, no range was fused and no episode ended (the moving network's twin did not even
compile). Batch sizes below 256 were right, and every other test used them. This test
runs a batch above that size against standalone rows, so threads can only come back
when they compute the same thing."""

from __future__ import annotations

import numpy as np
import pytest

import coopnav_env
from coopnav_env.core import make_simulator
from coopnav_env.views import action_dim

BIG = 300  # above the old threaded threshold (256)
ROWS = (0, 7, BIG - 1)


@pytest.mark.parametrize("scenario", ["gao_lawnmower", "sousa_ping", "matos_moving_lbl", "swarm_mls"])
def test_rows_of_a_large_batch_equal_batches_of_one(scenario):
    cfg = coopnav_env.make_config(scenario)
    seeds = list(range(4100, 4100 + BIG))
    big = make_simulator(cfg, BIG)
    obs_big = big.reset(seeds)
    small = {r: make_simulator(cfg, 1) for r in ROWS}
    for r, sim in small.items():
        np.testing.assert_array_equal(obs_big[r], sim.reset([seeds[r]])[0])
    rng = np.random.default_rng(1)
    dim = action_dim(big)
    start = big.snapshot().survey_true_m.copy()
    for _ in range(6):
        actions = rng.uniform(-1.0, 1.0, (BIG, obs_big.shape[1], dim))
        res = big.step(actions)
        obs_big = res.obs
        for r, sim in small.items():
            one = sim.step(actions[r : r + 1])
            np.testing.assert_array_equal(obs_big[r], one.obs[0])
            np.testing.assert_array_equal(np.asarray(res.reward)[r], np.asarray(one.reward)[0])
    moved = np.abs(big.snapshot().survey_true_m - start).max(axis=-1)
    assert (moved > 1.0).all(), "a survey vehicle of the large batch did not move"
