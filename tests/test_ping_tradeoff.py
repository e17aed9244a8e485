"""benchmarks/ping_tradeoff.py: the oracle's rows are the oracle's (told the truth before each
act), not ``horizon``'s, which is what the oracle falls back to without a snapshot."""

from __future__ import annotations

import numpy as np

from benchmarks import ping_tradeoff
from coopnav_env import make_config


def test_the_oracle_rows_are_told_the_truth():
    config = make_config("sousa_ping", max_cycles=4)
    seeds = [700000, 700001]
    oracle = ping_tradeoff.run(config, "oracle+clock", {"every": 1}, seeds)
    blind = ping_tradeoff.run(config, "horizon+clock", {"every": 1}, seeds)
    np.testing.assert_array_equal(oracle[1], [8, 8])  # both ASVs in each of the 4 slots
    assert np.all(np.isfinite(oracle[0]))
    assert not np.allclose(oracle[0], blind[0])  # the truth moved the oracle's ASVs elsewhere
