"""The range's second-order terms (core.navigation.range_curvature, eqs. L1-L3) against
hand-computed values and Monte Carlo, and what they are for: a filter tens of metres
off whose beacon passes within tens of metres stays consistent with them and does not
without them. ``range_linearization="second_order"`` wires them into the survey filter."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from coopnav_env.core.navigation import gated_update, range_curvature, relative_covariance
from coopnav_env.core.sim import Simulator
from coopnav_env.scenarios import make_config


def _terms(x, P, beacon_var=0.0, Pxb=None):
    d = np.asarray(x, float)
    h = float(np.linalg.norm(d))
    Pxb = np.zeros((3, 2)) if Pxb is None else np.asarray(Pxb, float)
    Pbb = beacon_var * np.eye(2) if np.ndim(beacon_var) == 0 else np.asarray(beacon_var, float)
    return range_curvature(np.asarray(P, float), Pxb, Pbb, d / h, h), h


def test_hand_values():
    # survey 30 m east of the beacon, 10 m std in each horizontal axis, depth known:
    # M = diag(0, 1, 1) / 30, M P = diag(0, 100/30, 0): bias 100/60, variance (100/30)^2 / 2
    (bias, var), _ = _terms([30.0, 0.0, 0.0], np.diag([100.0, 100.0, 0.0]))
    assert bias == pytest.approx(100.0 / 60.0)
    assert var == pytest.approx(0.5 * (100.0 / 30.0) ** 2)
    # the beacon's variance adds to the relative position's (Pbb = 44 I2 across the line of sight)
    (bias, var), _ = _terms([30.0, 0.0, 0.0], np.diag([56.0, 56.0, 0.0]), beacon_var=44.0)
    assert bias == pytest.approx(100.0 / 60.0) and var == pytest.approx(0.5 * (100.0 / 30.0) ** 2)
    # an anisotropic Pbb (eq. N1): only its part across the line of sight bends the range
    (bias, var), _ = _terms([30.0, 0.0, 0.0], np.diag([56.0, 56.0, 0.0]), beacon_var=np.diag([500.0, 44.0]))
    assert bias == pytest.approx(100.0 / 60.0) and var == pytest.approx(0.5 * (100.0 / 30.0) ** 2)
    # error along the line of sight only: no curvature
    (bias, var), _ = _terms([30.0, 0.0, 0.0], np.diag([100.0, 0.0, 0.0]))
    assert bias == 0.0 and var == 0.0
    # a cross-covariance with the beacon's error lowers the relative variance: P - Pxb - Pxb^T + Pbb
    Pxb = np.zeros((3, 2))
    Pxb[1, 1] = 30.0
    (bias, _), _ = _terms([30.0, 0.0, 0.0], np.diag([100.0, 100.0, 0.0]), beacon_var=20.0, Pxb=Pxb)
    assert bias == pytest.approx((100.0 - 60.0 + 20.0) / 60.0)
    # no range, no terms
    assert range_curvature(np.eye(3), np.zeros((3, 2)), np.zeros((2, 2)), np.zeros(3), 0.0) == (0.0, 0.0)


def test_the_relative_covariance_is_that_of_x_minus_b():
    """Eq. (L0), the one home of Pd: the covariance of d = x - E^T b for a joint Gaussian of
    the survey's x (3) and the beacon's horizontal error b (2) with cross-covariance Pxb,
    against the joint covariance's own algebra, entry by entry and not symmetric in Pxb."""
    rng = np.random.default_rng(5)
    A = rng.normal(size=(5, 5))
    J = A @ A.T + np.eye(5)  # the joint covariance of (x, b)
    P, Pxb, Pbb = J[:3, :3], J[:3, 3:], J[3:, 3:]  # Pbb anisotropic, with a correlation
    assert abs(Pbb[0, 1]) > 0.1 and abs(Pbb[0, 0] - Pbb[1, 1]) > 0.1
    T = np.hstack([np.eye(3), -np.eye(3)[:, :2]])  # d = T (x, b)
    expected = T @ J @ T.T
    got = np.array([[relative_covariance(P, Pxb, Pbb, i, j) for j in range(3)] for i in range(3)])
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12)


def test_matches_monte_carlo():
    rng = np.random.default_rng(5)
    # the bias (L2), for any covariance: second order in sigma / h, the remainder
    # O(sigma^4 / h^3), here ~0.02 m
    x = np.array([60.0, 80.0, 10.0])  # 100.5 m off, a depth difference of 10 m
    A = rng.normal(size=(3, 3))
    P = np.diag([120.0, 60.0, 1.0]) + 5.0 * (A @ A.T) / 3.0
    (bias, _), h = _terms(x, P)
    r = np.linalg.norm(rng.multivariate_normal(x, P, size=4_000_000), axis=1)
    assert r.mean() - h == pytest.approx(bias, abs=0.03)
    assert bias > 0.3  # large enough that the check above means something
    # the variance (L3), for an error across the line of sight only, where it is the whole
    # of the range's variance (along the line of sight the first-order H P H^T dominates and
    # the third-order term's covariance with it is of the same order as L3)
    x = np.array([100.0, 0.0, 0.0])
    # 5 m and 2.5 m std: the next order, -Cov(q, q^2) / (8 h^4) with q the squared error
    # across, is 0.7 % of the variance here (3 % at 10 m and 5 m)
    P = np.diag([0.0, 25.0, 6.25])
    (bias, var), h = _terms(x, P)
    assert var == pytest.approx(0.5 * (0.25**2 + 0.0625**2))
    d = x + rng.normal(size=(2_000_000, 3)) * np.sqrt(np.diag(P))
    r = np.linalg.norm(d, axis=1)
    assert r.var() == pytest.approx(var, rel=0.02)
    assert r.mean() - h == pytest.approx(bias, rel=0.02)


@pytest.mark.parametrize("second_order,consistent", [(False, False), (True, True)])
def test_a_close_pass_far_off_is_consistent_only_with_the_curvature(second_order, consistent):
    """One range update of a filter 15 m (std) off, the beacon 60 m from its estimate:
    over 4000 draws the posterior NEES mean is near 2 with the second-order terms, and
    13 with the first-order update alone, which exceeds the 99.9 % point in a fifth of
    the draws. (The posterior is not Gaussian there: the second-order filter still
    exceeds it in 2-3 % of draws; at 20 m std and 25 m, first order 238 and 55 %,
    second order 2.7 and 3.5 %.)"""
    rng = np.random.default_rng(11)
    n, sigma, sigma_r = 4000, 15.0, 1.0
    P0 = np.diag([sigma**2, sigma**2, 0.01])
    est = np.array([60.0, 0.0, 0.0])  # the estimate; the beacon at the origin
    nees, fused = [], 0
    for _ in range(n):
        truth = est + rng.multivariate_normal(np.zeros(3), P0)
        z = np.linalg.norm(truth) + sigma_r * rng.normal()
        x, P = est.copy(), P0.copy()
        h = float(np.linalg.norm(x))
        H = x / h
        R = sigma_r**2
        if second_order:
            bias, var = range_curvature(P, np.zeros((3, 2)), np.zeros((2, 2)), H, h)
            h, R = h + bias, R + var
        if gated_update(x, P, z, h, H, R, 1e12):  # no gate: the update itself is judged
            fused += 1
            e = (x - truth)[:2]
            nees.append(float(e @ np.linalg.solve(P[:2, :2], e)))
    nees = np.array(nees)
    above = np.mean(nees > chi2.ppf(0.999, 2))
    assert fused == n
    if consistent:
        assert 1.7 < nees.mean() < 2.6 and above < 0.04, (nees.mean(), above)
    else:
        assert nees.mean() > 8.0 and above > 0.1, (nees.mean(), above)


def test_the_option_is_wired_and_first_order_is_untouched():
    """``range_linearization``: "first_order" leaves the filter as it was (the terms are
    not computed), "second_order" changes it where the error is large against the range."""

    def run(**kw):
        cfg = make_config("gao_sea", max_cycles=30, **kw)
        sim = Simulator(cfg, batch_size=4)
        sim.reset(np.arange(4))
        for _ in range(30):
            sim.step(np.broadcast_to(np.array([1.0, 0.0]), (4, sim.N, 2)).copy())
        return sim.state.s_est.copy(), sim.state.s_P.copy()

    x1, P1 = run()
    x1b, P1b = run(range_linearization="first_order")
    _, P2 = run(range_linearization="second_order")
    assert np.array_equal(x1, x1b) and np.array_equal(P1, P1b)
    assert not np.array_equal(P1, P2)
    # the curvature only adds variance: the second-order filter is never more confident here
    assert np.all(np.trace(P2[..., :2, :2], axis1=-2, axis2=-1) >= np.trace(P1[..., :2, :2], axis1=-2, axis2=-1) - 1e-9)
    with pytest.raises(ValueError, match="second_order"):
        make_config("gao_sea", range_linearization="second_ordr")
    # the moving network's and the MLS array's filters have no second-order update: refused, not ignored
    for scenario in ("matos_moving_lbl", "swarm_mls"):
        with pytest.raises(ValueError, match="range_linearization='first_order'"):
            make_config(scenario, range_linearization="second_order")
