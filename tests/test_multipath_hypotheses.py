"""The multipath hypotheses held for one range (``core/multipath.py``, eqs. M4-M7)
against a two-component Gaussian sum computed here from its definition, with scipy's
exponentially modified Gaussian as the multipath likelihood."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import exponnorm, norm

from coopnav_env.core import dr_bias
from coopnav_env.core.multipath import (
    Held,
    Moments,
    blend_update,
    direct_path_weight,
    hold_hypotheses,
    range_log_likelihood,
    reweigh_hypotheses,
)

P_OUT, MU = 0.03, 30.0  # outlier_probability, outlier_mean_excess_m (gao_lawnmower)


def _likelihood(y: float, S: float) -> float:
    """(M4) from scipy: (1 - p) N(y; 0, S) + p (N(0, S) * Exp(mu))(y)."""
    sd = np.sqrt(S)
    return (1 - P_OUT) * norm.pdf(y, scale=sd) + P_OUT * exponnorm.pdf(y, MU / sd, scale=sd)


def _kalman(x, P, H, y, R):
    S = H @ P @ H + R
    K = P @ H / S
    return x + K * y, P - np.outer(K, K) * S, K, S


@pytest.mark.parametrize("y", [-3.0, 0.5, 8.0, 40.0])
@pytest.mark.parametrize("S", [1.0, 36.0, 400.0])
def test_range_likelihood_is_the_mixture(y, S):
    assert np.exp(range_log_likelihood(y, S, P_OUT, MU)) == pytest.approx(_likelihood(y, S), rel=1e-9)
    assert range_log_likelihood(y, S, 0.0, MU) == pytest.approx(norm.logpdf(y, scale=np.sqrt(S)), rel=1e-12)


def _first_range(x0, P0, X0, D0, H1, y1, R):
    """A range that passes the gate with an ambiguous weight: (M1)-(M3) and (M5)."""
    x1, P1, K, S = _kalman(x0, P0, H1, y1, R)
    X1 = X0 - np.einsum("i,k,jkl->jil", K, H1, X0)  # K H X for each beacon's block, as a Kalman step does
    D1 = D0 - np.outer(K, H1 @ D0)
    w = direct_path_weight(y1, S, P_OUT, MU)
    d, dP, dX, dD = np.zeros(3), np.zeros((3, 3)), np.zeros_like(X0), np.zeros_like(D0)
    held = hold_hypotheses(w, Moments(x0, P0, X0, D0), Moments(x1, P1, X1, D1), Held(d, dP, dX, dD))
    x, P, X, D = x1.copy(), P1.copy(), X1.copy(), D1.copy()
    blend_update(w, x0, P0, X0, x, P, X)
    D[:] = w * D1 + (1 - w) * D0
    comps = [(w, x1, P1, X1, D1), (1 - w, x0, P0, X0, D0)]
    return held, (d, dP, dX, dD), (x, P, X, D), comps


def _innovation_variance(H, P, X, R, j, beacon_var):
    """S of a range: H P H' + R, and with beacon j's error a consider state (j >= 0) eq.
    (C2)'s terms Hb Pbb Hb' + 2 H X_j Hb' with Hb = -H[:2], Pbb = beacon_var I."""
    S = H @ P @ H + R
    if j >= 0:
        S += beacon_var * (H[:2] @ H[:2]) - 2.0 * H @ X[j] @ H[:2]
    return S


def _mixture(comps, H2, z2, R, j=-1, beacon_var=0.0):
    """The Gaussian sum re-weighed by a second range z2 (its innovation at each component
    by that component's mean) and merged: mean, covariance, cross-covariances, w'."""
    weights = np.array(
        [wt * _likelihood(z2 - H2 @ x, _innovation_variance(H2, P, X, R, j, beacon_var)) for wt, x, P, X, _ in comps]
    )
    weights /= weights.sum()
    mean = sum(a * c[1] for a, c in zip(weights, comps))
    cov = sum(a * (c[2] + np.outer(c[1] - mean, c[1] - mean)) for a, c in zip(weights, comps))
    X = sum(a * c[3] for a, c in zip(weights, comps))
    D = sum(a * c[4] for a, c in zip(weights, comps))
    return mean, cov, X, D, weights[0]


def _setup():
    x0 = np.array([3.0, -2.0, 50.0])
    P0 = np.diag([120.0, 80.0, 0.5])
    P0[0, 1] = P0[1, 0] = 20.0
    X0 = np.random.default_rng(0).normal(0.0, 1.0, (2, 3, 2))  # two beacons' Pxb
    D0 = np.random.default_rng(1).normal(0.0, 0.5, (3, 4))
    D0[2] = 0.0
    H1 = np.array([0.96, 0.28, 0.0])
    return x0, P0, X0, D0, H1


@pytest.mark.parametrize("j", [-1, 1])  # the beacon's variance in R; beacon 1's error a consider state (C2)
# the second range agrees with the direct path, lies between, agrees with the multipath one
@pytest.mark.parametrize("toward", [0.0, 0.5, 1.0])
def test_reweighing_matches_the_two_component_gaussian_sum(toward, j):
    """(M6)-(M7) with no prediction between the ranges: the merged moments and w' equal
    those of the two-component sum re-weighed by the second range's likelihood (M4), its
    variance with each hypothesis' own cross-covariance with the beacon's error."""
    x0, P0, X0, D0, H1 = _setup()
    R = 1.0
    held_w, (d, dP, dX, dD), (x, P, X, D), comps = _first_range(x0, P0, X0, D0, H1, 28.0, R)
    assert 0.05 < held_w < 0.95  # the case the hypotheses are held for
    H2 = np.array([0.92, 0.39, 0.0])  # a cycle later, from nearly the same direction
    z2 = H2 @ ((1 - toward) * comps[0][1] + toward * comps[1][1])  # a range measured as linear in x
    mean, cov, Xr, Dr, w_ref = _mixture(comps, H2, z2, R, j, 4.0)
    w2 = reweigh_hypotheses(
        held_w, Held(d, dP, dX, dD), Moments(x, P, X, D), H2, z2 - H2 @ x, R, P_OUT, MU, j, 4.0 * np.eye(2)
    )
    assert w2 == pytest.approx(w_ref, rel=1e-9)
    if j >= 0 and toward == 0.5:  # the case sees the cross term: without it the weight is another
        assert _mixture(comps, H2, z2, R + 4.0 * (H2[:2] @ H2[:2]))[4] != pytest.approx(w_ref, rel=0.2)
    np.testing.assert_allclose(x, mean, rtol=0, atol=1e-9)
    np.testing.assert_allclose(P, cov, rtol=0, atol=1e-9)
    np.testing.assert_allclose(X, Xr, rtol=0, atol=1e-12)
    np.testing.assert_allclose(D, Dr, rtol=0, atol=1e-12)
    if toward == 0.0:  # the direct path confirmed: w' near 1 and the estimate near x1
        assert w2 > 0.99 and np.linalg.norm(x - comps[0][1]) < 0.02 * np.linalg.norm(d)
    if toward == 1.0:  # the first range was the longer path: the estimate goes back near the prior
        assert w2 < 0.01 and np.linalg.norm(x - comps[1][1]) < 0.02 * np.linalg.norm(d)


def test_reweighing_after_a_prediction_with_the_dead_reckoning_biases():
    """Between the ranges eq. (D2) predicts P and Pxd (and Q is added): each hypothesis
    predicted on its own, then re-weighed (the reference), equals the merged state
    predicted with the held differences moved by ``bias_predict(..., held=...)``; with
    dP left as it was held the covariance is off (the test sees the term)."""
    x0, P0, X0, D0, H1 = _setup()
    R = 1.0
    moved = np.array([[[25.0, 4.0]]])  # (B, S, 2): the cycle's dead-reckoned displacement
    var = np.array([[0.05**2, np.radians(1.0) ** 2, 0.05**2, 0.05**2]])
    Q = np.diag([1.0, 1.0, 0.0])
    step = np.array([10.0, 2.0, 0.0])

    def predict(P_, D_, held=None):
        P_, D_ = P_[None, None].copy(), D_[None, None].copy()
        dr_bias.bias_predict(P_, D_, moved, var, 20.0, held=held)
        return P_[0, 0] + Q, D_[0, 0]

    results = {}
    for move_dP in (True, False):
        held_w, (d, dP, dX, dD), (x, P, X, D), comps = _first_range(x0, P0, X0, D0, H1, 28.0, R)
        comps = [(wt, xc + step, *predict(Pc, Dc)[:1], Xc, predict(Pc, Dc)[1]) for wt, xc, Pc, Xc, Dc in comps]
        dP4, dD4 = dP[None, None].copy(), dD[None, None].copy()
        P, D = predict(P, D, held=(dP4, dD4) if move_dP else None)
        x = x + step
        H2 = np.array([0.92, 0.39, 0.0])
        z2 = H2 @ comps[1][1] + 4.0
        mean, cov, Xr, Dr, w_ref = _mixture(comps, H2, z2, R)
        held = Held(d, dP4[0, 0], dX, dD4[0, 0])
        w2 = reweigh_hypotheses(held_w, held, Moments(x, P, X, D), H2, z2 - H2 @ x, R, P_OUT, MU)
        results[move_dP] = (w2, w_ref, x, mean, P, cov, D, Dr, X, Xr)
    w2, w_ref, x, mean, P, cov, D, Dr, X, Xr = results[True]
    assert w2 == pytest.approx(w_ref, rel=1e-9)
    np.testing.assert_allclose(x, mean, rtol=0, atol=1e-9)
    np.testing.assert_allclose(P, cov, rtol=0, atol=1e-8)
    np.testing.assert_allclose(D, Dr, rtol=0, atol=1e-12)
    np.testing.assert_allclose(X, Xr, rtol=0, atol=1e-12)
    _, _, _, _, P_stale, cov, _, _, _, _ = results[False]
    assert np.abs(P_stale - cov).max() > 1e-3


def test_nothing_is_held_for_a_certain_range_and_a_stale_hold_changes_nothing():
    """w = 1, or a multipath hypothesis below PRUNE_WEIGHT (w = 0.99): nothing is held;
    a hold whose direct hypothesis no longer fits P is refused and changes nothing."""
    x0, P0, X0, D0, H1 = _setup()
    d, dP, dX, dD = np.zeros(3), np.zeros((3, 3)), np.zeros_like(X0), np.zeros_like(D0)
    assert hold_hypotheses(1.0, Moments(x0, P0, X0, D0), Moments(x0, P0, X0, D0), Held(d, dP, dX, dD)) == 1.0
    assert hold_hypotheses(0.99, Moments(x0, P0, X0, D0), Moments(x0, P0, X0, D0), Held(d, dP, dX, dD)) == 1.0
    # a hold whose direct hypothesis no longer fits P (e.g. P shrank by a fix since): refused, nothing moves
    d[:] = [30.0, 0.0, 0.0]
    dP[:] = np.diag([50.0, 0.0, 0.0])
    x, P, X, D = x0.copy(), np.diag([10.0, 10.0, 0.5]), X0.copy(), D0.copy()
    assert reweigh_hypotheses(0.6, Held(d, dP, dX, dD), Moments(x, P, X, D), H1, 3.0, 1.0, P_OUT, MU) == 0.6
    np.testing.assert_array_equal(x, x0)
    np.testing.assert_array_equal(P, np.diag([10.0, 10.0, 0.5]))


def test_held_hypotheses_in_the_simulator():
    """``range_outlier_model="hold"`` on ``gao_lawnmower`` with a 20 % multipath rate:
    hypotheses are held (w below 1 - PRUNE_WEIGHT) and re-weighed, the estimates differ
    from the merge-only filter's, every covariance stays positive definite, and a batch
    row equals the same seed run alone to the bit (the held state is per row)."""
    import coopnav_env
    from coopnav_env.core import make_simulator
    from coopnav_env.core.multipath import PRUNE_WEIGHT

    runs = {}
    for model in ("mixture", "hold"):
        c = coopnav_env.make_config("gao_lawnmower", range_outlier_model=model, outlier_probability=0.2)
        sim = make_simulator(c, 4)
        sim.reset([5, 6, 7, 8])
        held = 0
        for _ in range(30):
            sim.step(np.full((4, 1, 2), 0.3))
            held += int((sim.state.s_hyp_w < 1.0).sum())
            assert np.all(np.linalg.eigvalsh(sim.state.s_P[..., :2, :2]) > 0.0)
        runs[model] = (sim.state.s_est.copy(), held)
    assert runs["mixture"][1] == 0 and runs["hold"][1] >= 5
    assert np.abs(runs["hold"][0] - runs["mixture"][0]).max() > 1e-3
    assert np.all(sim.state.s_hyp_w[sim.state.s_hyp_w < 1.0] <= 1.0 - PRUNE_WEIGHT)
    alone = make_simulator(c, 1)
    alone.reset([7])
    for _ in range(30):
        alone.step(np.full((1, 1, 2), 0.3))
    np.testing.assert_array_equal(alone.state.s_est[0], runs["hold"][0][2])
