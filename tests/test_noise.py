"""One ranging-noise convention for every mode: the filters' R equals the variance of
the ranges the simulator makes (Monte Carlo), for one-way, two-way and the moving
network's LBL exchange. ``range_noise_std_m`` is one detection's timing jitter as a
range (c sigma_t): see core/acoustics.py."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from coopnav_env.core import lbl
from coopnav_env.core.acoustics import ranging_variance_m2
from coopnav_env.core.measurements.modem import modem_range, modem_range_variance
from coopnav_env.core.moving_network import exchange_covariance_m2

C = 1500.0
N_DRAWS = 40_000


def _variance_bounds(var, n, p=0.999):
    """The interval a sample variance of n normal draws with variance var falls in with probability p."""
    lo, hi = stats.chi2.ppf([(1 - p) / 2, (1 + p) / 2], n - 1)
    return var * lo / (n - 1), var * hi / (n - 1)


@pytest.mark.parametrize("two_way", [False, True])
def test_modem_range_variance_matches_the_simulated_ranges(two_way):
    sigma = 1.3  # per detection, as range
    rng = np.random.default_rng(3 + two_way)
    survey, beacon = np.array([30.0, 40.0, 20.0]), np.array([0.0, 0.0, 2.0])
    zero = np.zeros(3)
    delays = np.zeros((2, 2))
    true = np.linalg.norm(survey - beacon)
    r = np.array(
        [
            modem_range(survey, zero, beacon, zero, C, C, sigma / C, n, two_way, 0.015, 0.0, delays)
            for n in rng.standard_normal(N_DRAWS)
        ]
    )
    R = modem_range_variance(sigma, two_way, 0.0, true, 0.0)
    assert R == pytest.approx(sigma**2 / (2.0 if two_way else 1.0))  # noqa: SIM300 - R is the noise variance, not a constant
    lo, hi = _variance_bounds(R, N_DRAWS)
    assert lo < r.var(ddof=1) < hi
    assert abs(r.mean() - true) < 4 * np.sqrt(R / N_DRAWS)  # unbiased (static vehicles, exact sound speed)


def test_modem_range_variance_adds_the_beacon_and_sound_speed_terms():
    """R = ranging noise + beacon position variance + (range x relative sound-speed std)^2."""
    assert modem_range_variance(2.0, False, 0.25, 100.0, 0.001) == pytest.approx(4.0 + 0.25 + 0.01)
    assert modem_range_variance(2.0, True, 0.0, 100.0, 0.0) == pytest.approx(2.0)
    assert ranging_variance_m2(2.0, True) == pytest.approx(2.0)


def test_lbl_exchange_covariance_is_the_one_the_filter_uses():
    """Matos & Cruz's exchange with a jitter sigma_t per detection: var(d1) = var(d2) =
    (c sigma_t)^2 / 2 = sigma_r^2, var(l) = 6 sigma_r^2, cov(d2, l) = -sigma_r^2,
    cov(d1, l) = 0 (the R of the moving-frame filter's updates)."""
    sigma = np.sqrt(2.0)  # the matos scenario's per-detection value: ranges of std 1 m
    rng = np.random.default_rng(0)
    v3 = np.tile([30.0, 40.0, 0.0], (N_DRAWS, 1))
    z = np.zeros((N_DRAWS, 3))
    b2 = np.tile([100.0, 0.0, 0.0], (N_DRAWS, 1))
    jit = sigma / C * rng.standard_normal((N_DRAWS, lbl.N_DETECTIONS))
    ex = lbl.exchange(
        lbl.Movers(v3, z, z, z, b2, z),
        np.full(N_DRAWS, C),
        np.full(N_DRAWS, C),
        jit,
        np.zeros((N_DRAWS, lbl.N_DETECTIONS)),
        np.zeros((N_DRAWS, lbl.N_DETECTIONS), dtype=bool),
        0.01,
        0.01,
        2.0,
    )
    cov = np.cov(np.stack([ex["d1"], ex["d2"], ex["l"]]))
    expect = exchange_covariance_m2(sigma)
    assert expect[0, 0] == pytest.approx(1.0)
    for i in range(3):
        lo, hi = _variance_bounds(expect[i, i], N_DRAWS)
        assert lo < cov[i, i] < hi, (i, cov[i, i], expect[i, i])
    # covariances: the sample correlation's standard error is ~1/sqrt(n)
    se = 4.0 * np.sqrt(np.outer(np.diag(expect), np.diag(expect)) / N_DRAWS)
    assert np.all(np.abs(cov - expect) < se + 1e-12)
