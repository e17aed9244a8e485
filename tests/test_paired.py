"""Paired statistics on a toy case with a known answer."""

import numpy as np
import pytest

from evaluation.paired import t_interval


def test_t_interval_known_answer():
    # mean 2, sample std 1, n = 4: half-width t(0.975, 3) * 1 / 2 = 3.182446 / 2
    m, lo, hi = t_interval([1.0, 2.0, 2.0, 3.0])
    s = np.std([1.0, 2.0, 2.0, 3.0], ddof=1)
    assert m == 2.0
    assert hi - m == pytest.approx(3.182446305284263 * s / 2.0, rel=1e-9)
    assert m - lo == pytest.approx(hi - m)


def test_pairing_removes_the_common_episode_effect():
    """Two policies whose episodes share a large common term and differ by 0.1: the
    paired interval is tight around -0.1; the unpaired spread would swamp it."""
    rng = np.random.default_rng(0)
    episode = rng.normal(0.0, 5.0, 50)
    a = episode + 1.0 + rng.normal(0, 0.01, 50)
    b = episode + 1.1 + rng.normal(0, 0.01, 50)
    _m, lo, hi = t_interval(a - b)
    assert lo < -0.1 < hi and hi < 0
    assert t_interval([0.7]) == (0.7, 0.7, 0.7)
