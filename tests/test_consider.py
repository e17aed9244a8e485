"""Issue 21's building blocks: the beacon's error as Schmidt consider states
(``core/consider.py``), covariance intersection, and the window re-fix after gate
lock-out (``core/recovery.py``), against plain-numpy references and in Monte Carlo.

Run with ``-s`` to see the Monte Carlo numbers quoted in docs/scenarios/consider-fusion.md.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import chi2

from coopnav_env.core.consider import (
    ErrorModel,
    beacon_covariance,
    beacon_reset,
    beacon_variance_along,
    beacon_variance_los,
    carry_cross_covariance,
    ci_range_update,
    ci_trace,
    consider_predict,
    covariance_intersection,
    error_model_covariance,
    gps_share,
    schmidt_range_update,
    transport_cross_covariance,
)
from coopnav_env.core.navigation import joseph_update, range_prediction
from coopnav_env.core.recovery import RangeWindow, WindowNoise, window_fix


def _spd(rng, n, scale=1.0):
    A = rng.normal(size=(n, n))
    return scale * (A @ A.T + n * np.eye(n))


def _schmidt_reference(x, P, Pxb, Pbb, y, H, R):
    """Plain numpy: the augmented state's Kalman gain with its consider rows zeroed, then
    the standard (not Joseph) form, valid for the x rows whose gain is optimal."""
    nb = Pbb.shape[0]
    Pa = np.block([[P, Pxb], [Pxb.T, Pbb]])
    Ha = np.concatenate([H, -H[:nb]])
    S = Ha @ Pa @ Ha + R
    K = (Pa @ Ha)[:3] / S
    HaPa = Ha @ Pa
    return x + K * y, P - np.outer(K, K) * S, Pxb - np.outer(K, HaPa[3:]), S


@pytest.mark.parametrize("nb", [2, 3])
def test_schmidt_update_matches_the_augmented_numpy_reference(nb):
    rng = np.random.default_rng(nb)
    for _ in range(20):
        Pa = _spd(rng, 3 + nb, 4.0)
        P, Pxb, Pbb = Pa[:3, :3].copy(), Pa[:3, 3:].copy(), Pa[3:, 3:].copy()
        x = rng.normal(size=3) * 10
        _h, H = range_prediction(x, np.zeros(3), np.zeros(1), rng.normal(size=3) * 200)
        y, R = rng.normal() * 3, 0.5 + rng.random()
        xr, Pr, Pxbr, S = _schmidt_reference(x, P, Pxb, Pbb, y, H, R)
        K = np.zeros(3)
        nis, fused = schmidt_range_update(x, P, Pxb, Pbb, y, H, R, np.inf, K)
        assert fused and nis == pytest.approx(y * y / S, rel=1e-12)
        np.testing.assert_allclose(x, xr, rtol=0, atol=1e-12 * max(1, np.abs(xr).max()))
        np.testing.assert_allclose(P, Pr, rtol=0, atol=1e-12 * np.abs(Pr).max())
        np.testing.assert_allclose(Pxb, Pxbr, rtol=0, atol=1e-12 * np.abs(Pa).max())
        np.testing.assert_array_equal(Pbb, Pa[3:, 3:])  # consider: Pbb untouched


def test_gated_schmidt_update_changes_nothing():
    x, P, Pxb, Pbb = np.zeros(3), np.eye(3), np.zeros((3, 2)), np.eye(2)
    H = np.array([1.0, 0.0, 0.0])
    K = np.ones(3)
    nis, fused = schmidt_range_update(x, P, Pxb, Pbb, 10.0, H, 1.0, 9.0, K)
    assert not fused and nis == pytest.approx(100.0 / 3.0)
    np.testing.assert_array_equal(x, 0.0)
    np.testing.assert_array_equal(P, np.eye(3))
    np.testing.assert_array_equal(K, 0.0)


def test_no_update_with_an_indefinite_innovation_variance_or_a_nan_residual():
    """A joint covariance made indefinite (Pxb too large for P and Pbb) gives S <= 0, whose
    negative NIS passed the gate and fused with a sign-flipped gain; a NaN residual passed
    the white filter's gate and wrote NaN into the state (a review). Neither updates now."""
    from coopnav_env.core.navigation import gated_update_residual

    H = np.array([1.0, 0.0, 0.0])
    P = np.diag([4.0, 4.0, 0.01])
    Pxb = np.zeros((3, 2))
    Pxb[0, 0] = 10.0  # |Pxb| > sqrt(P Pbb): S = 4 - 2 x 10 + 1 + R = -14.9
    x, P0, X0, K = np.zeros(3), P.copy(), Pxb.copy(), np.zeros(3)
    nis, fused = schmidt_range_update(x, P, Pxb, np.eye(2), 0.5, H, 0.1, 9.0, K)
    assert not fused and nis == np.inf
    assert np.all(x == 0.0) and np.array_equal(P, P0) and np.array_equal(Pxb, X0) and np.all(K == 0.0)
    nis, fused = schmidt_range_update(x, P, np.zeros((3, 2)), np.eye(2), np.nan, H, 0.1, 9.0, K)
    assert not fused and np.all(x == 0.0)
    assert not gated_update_residual(x, P, np.nan, H, 0.1, np.inf)
    assert np.all(x == 0.0) and np.array_equal(P, P0)
    assert not gated_update_residual(x, P, 0.5, H, -10.0, np.inf)  # S = 4 - 10 < 0
    assert gated_update_residual(x, P, 0.5, H, 0.1, 9.0)  # and a sound one still fuses


def test_with_pbb_zero_it_is_the_ordinary_joseph_update():
    rng = np.random.default_rng(7)
    for _ in range(20):
        P = _spd(rng, 3, 3.0)
        x = rng.normal(size=3) * 10
        b = rng.normal(size=3) * 300
        h, H = range_prediction(x, np.zeros(3), np.zeros(1), b)
        z, R = h + rng.normal() * 4, 1.0 + rng.random()
        x1, P1 = x.copy(), P.copy()
        joseph_update(x1, P1, z, h, H, R)
        x2, P2, Pxb = x.copy(), P.copy(), np.zeros((3, 2))
        schmidt_range_update(x2, P2, Pxb, np.zeros((2, 2)), z - h, H, R, np.inf, np.zeros(3))
        np.testing.assert_allclose(x2, x1, rtol=0, atol=1e-12 * np.abs(x1).max())
        np.testing.assert_allclose(P2, P1, rtol=0, atol=1e-12 * np.abs(P1).max())
        np.testing.assert_array_equal(Pxb, 0.0)


def test_other_beacons_cross_covariance_is_the_augmented_joseph_update():
    """Two beacons: [x, b1, b2], b1 and b2 independent; a range from beacon 1 changes
    Pxb2 by (I - K H) (eq. C6), as the full augmented update with both consider."""
    rng = np.random.default_rng(3)
    Pa = _spd(rng, 7, 2.0)
    Pa[3:5, 5:7] = Pa[5:7, 3:5] = 0.0
    Pa += 20 * np.eye(7)  # still positive definite with the beacons made independent
    P, Pxb1, Pxb2, Pbb1 = Pa[:3, :3].copy(), Pa[:3, 3:5].copy(), Pa[:3, 5:7].copy(), Pa[3:5, 3:5].copy()
    x = np.array([5.0, -3.0, 40.0])
    _h, H = range_prediction(x, np.zeros(3), np.zeros(1), np.array([250.0, 100.0, 5.0]))
    Ha = np.concatenate([H, -H[:2], np.zeros(2)])
    S = Ha @ Pa @ Ha + 0.8
    Ka = np.zeros(7)
    Ka[:3] = (Pa @ Ha)[:3] / S
    A = np.eye(7) - np.outer(Ka, Ha)
    ref = A @ Pa @ A.T + 0.8 * np.outer(Ka, Ka)
    K = np.zeros(3)
    schmidt_range_update(x, P, Pxb1, Pbb1, 1.5, H, 0.8, np.inf, K)
    carry_cross_covariance(Pxb2, K, H)
    np.testing.assert_allclose(P, ref[:3, :3], atol=1e-12 * 40)
    np.testing.assert_allclose(Pxb1, ref[:3, 3:5], atol=1e-12 * 40)
    np.testing.assert_allclose(Pxb2, ref[:3, 5:7], atol=1e-12 * 40)


def test_predict_and_reset():
    Pxb = np.arange(6.0).reshape(3, 2)
    consider_predict(Pxb, 20.0, np.inf)
    np.testing.assert_array_equal(Pxb, np.arange(6.0).reshape(3, 2))
    consider_predict(Pxb, 20.0, 200.0)
    np.testing.assert_allclose(Pxb, np.exp(-0.1) * np.arange(6.0).reshape(3, 2), rtol=1e-15)
    beacon_reset(Pxb)
    np.testing.assert_array_equal(Pxb, 0.0)


# --- covariance intersection ----------------------------------------------------------
def _ci_numpy(a, A, b, B, w):
    Ci = w * np.linalg.inv(A) + (1 - w) * np.linalg.inv(B)
    C = np.linalg.inv(Ci)
    return C @ (w * np.linalg.solve(A, a) + (1 - w) * np.linalg.solve(B, b)), C


@pytest.mark.parametrize("use_det", [False, True])
def test_two_estimate_ci_matches_a_grid_search(use_det):
    rng = np.random.default_rng(11)
    for _ in range(10):
        A, B = _spd(rng, 3), _spd(rng, 3, 2.0)
        a, b = rng.normal(size=3), rng.normal(size=3)
        out_x, out_P = np.zeros(3), np.zeros((3, 3))
        w = covariance_intersection(a, A, b, B, use_det, out_x, out_P)
        grid = np.linspace(0, 1, 4001)
        C = np.linalg.inv(grid[:, None, None] * np.linalg.inv(A) + (1 - grid)[:, None, None] * np.linalg.inv(B))
        crit = np.linalg.det(C) if use_det else np.trace(C, axis1=1, axis2=2)
        assert abs(w - grid[int(np.argmin(crit))]) < 1e-3
        xr, Cr = _ci_numpy(a, A, b, B, w)
        np.testing.assert_allclose(out_x, xr, atol=1e-10)
        np.testing.assert_allclose(out_P, Cr, atol=1e-10)


@pytest.mark.parametrize("use_det", [False, True])
def test_range_ci_is_the_information_form_at_the_best_omega(use_det):
    rng = np.random.default_rng(5)
    for _ in range(10):
        P = _spd(rng, 3, 10.0)
        x = rng.normal(size=3)
        _h, H = range_prediction(x, np.zeros(3), np.zeros(1), np.array([300.0, 50.0, 0.0]))
        y, R = 2.0, 1.0
        x1, P1 = x.copy(), P.copy()
        w = ci_range_update(x1, P1, y, H, R, use_det)
        grid = np.linspace(1e-4, 1, 4000)
        Y = grid[:, None, None] * np.linalg.inv(P) + (1 - grid)[:, None, None] * np.outer(H, H) / R
        crit = 1 / np.linalg.det(Y) if use_det else np.trace(np.linalg.inv(Y), axis1=1, axis2=2)
        assert abs(w - grid[int(np.argmin(crit))]) < 1e-3
        C = np.linalg.inv(w * np.linalg.inv(P) + (1 - w) * np.outer(H, H) / R)  # (CI1)
        np.testing.assert_allclose(P1, C, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(x1, x + C @ H * (1 - w) * y / R, atol=1e-9)  # (CI2)
        assert ci_trace(P, H, R, w) == pytest.approx(np.trace(C))


# --- Monte Carlo: a beacon whose error is a bias -----------------------------------------
RUNS, PINGS = 200, 50


def _nees(e, P):
    return float(e @ np.linalg.solve(P, e))


def test_monte_carlo_consistency_with_a_biased_beacon():
    """A static survey vehicle at 50 m depth, a beacon at 10 m circling it at 300 m; the
    beacon's reported position is off by a constant bias per run drawn from N(0, Pbb)
    (std 5 and 4 m, correlated). The ordinary EKF with the beacon's variance along the
    line of sight in R (today's treatment) is over-confident; Schmidt-Kalman is consistent."""
    rng = np.random.default_rng(2026)
    Pbb = np.array([[25.0, 8.0], [8.0, 16.0]])
    L = np.linalg.cholesky(Pbb)
    R = 1.0
    P0 = np.diag([400.0, 400.0, 0.25])
    truth = np.array([0.0, 0.0, 50.0])
    nees = {"ekf": np.empty((RUNS, PINGS)), "schmidt": np.empty((RUNS, PINGS)), "ci": np.empty((RUNS, PINGS))}
    K = np.zeros(3)
    for run in range(RUNS):
        bias = L @ rng.normal(size=2)  # b = true beacon minus reported
        x0 = truth + np.sqrt(np.diag(P0)) * rng.normal(size=3)
        phase = rng.uniform(0, 2 * np.pi)
        f = {k: (x0.copy(), P0.copy()) for k in nees}
        Pxb = np.zeros((3, 2))
        for k in range(PINGS):
            ang = phase + 2 * np.pi * k / 40
            b_true = np.array([300 * np.cos(ang), 300 * np.sin(ang), 10.0])
            b_rep = b_true.copy()
            b_rep[:2] -= bias
            z = np.linalg.norm(truth - b_true) + np.sqrt(R) * rng.normal()
            for name, (x, P) in f.items():
                h, H = range_prediction(x, np.zeros(3), np.zeros(1), b_rep)
                if name == "ekf":
                    joseph_update(x, P, z, h, H, R + H[:2] @ Pbb @ H[:2])
                elif name == "schmidt":
                    schmidt_range_update(x, P, Pxb, Pbb, z - h, H, R, np.inf, K)
                else:
                    ci_range_update(x, P, z - h, H, R + H[:2] @ Pbb @ H[:2], False)
                nees[name][run, k] = _nees(truth[:2] - x[:2], P[:2, :2])
    lo, hi = chi2.ppf([0.025, 0.975], 2 * RUNS) / RUNS
    c_lo, c_hi, c_999 = chi2.ppf([0.025, 0.975, 0.999], 2)
    stats = {}
    for name, v in nees.items():
        mean = v.mean()
        inside = np.mean((v >= c_lo) & (v <= c_hi))
        exceed = np.mean(v > c_999)
        cycles_in = np.mean((v.mean(axis=0) >= lo) & (v.mean(axis=0) <= hi))
        stats[name] = (mean, inside, exceed, cycles_in)
        print(
            f"\n{name:8s} NEES mean {mean:7.2f} (band {lo:.2f}-{hi:.2f}); last ping {v[:, -1].mean():7.2f}; "
            f"run-cycles in [{c_lo:.3f}, {c_hi:.2f}]: {inside:.1%}; > chi2.999: {exceed:.2%}; "
            f"cycles with the run-mean in band: {cycles_in:.0%}"
        )
    assert stats["ekf"][0] > hi  # over-confident
    mean, inside, exceed, _ = stats["schmidt"]
    assert lo <= mean <= hi and inside >= 0.85 and exceed <= 3 * 0.001
    assert stats["ci"][0] <= hi  # CI never over-confident (conservative)


# --- lock-out recovery ---------------------------------------------------------------------
TRIALS = 500


def _old_reinit(x, P, y, Hxy, R):
    """``navigation.reinit_on_range`` on the horizontal state (x (2,), P (2, 2))."""
    g = np.hypot(*Hxy)
    u, t = Hxy / g, np.array([-Hxy[1], Hxy[0]]) / g
    x += y * u / g
    across = t @ P @ t + y * y
    P[:, :] = (R + y * y) / g**2 * np.outer(u, u) + across * np.outer(t, t)


def _ekf_h(x, b, dz, z, P, R):
    d = np.array([x[0] - b[0], x[1] - b[1], dz])
    h = np.linalg.norm(d)
    Hxy = d[:2] / h
    return z - h, Hxy, Hxy @ P @ Hxy + R


def test_window_refix_after_lockout_beats_the_nearest_point_restart():
    """A survey at 1 m/s dead-reckoning (q = 0.05 m^2/s per axis), locked out 30 m off with
    a 2 m std; a beacon at 1.5 m/s, 300-600 m away, biased by N(0, 3^2 I); 3-6 ranges
    20 s apart. New: ``window_fix`` on the window. Old: restart from the first range
    (the lock-out's), then the ordinary EKF with DR predicts on the others. Both judged
    at the last ping: Mahalanobis distance <= 3 (NEES <= 9) and the mean NEES."""
    rng = np.random.default_rng(21)
    R, q, dt, dz = 1.0, 0.05, 20.0, 40.0
    Pbb = 9.0 * np.eye(2)
    noise = WindowNoise(R, Pbb, q, 50.0)
    res = {"new": [], "old": []}
    cross = np.zeros((2, 2, 2))  # sum of (x - x_hat) b^T, and of the fix's Pxb
    for _ in range(TRIALS):
        M = rng.integers(3, 7)
        age = dt * np.arange(M - 1, -1, -1.0)
        psi, beta = rng.uniform(0, 2 * np.pi, 2)
        v_s = np.array([np.cos(psi), np.sin(psi)])
        xK = rng.normal(size=2) * 100
        steps = np.sqrt(q * dt) * rng.normal(size=(M - 1, 2))  # DR error per interval
        err = np.vstack([np.cumsum(steps[::-1], axis=0)[::-1], np.zeros((1, 2))])  # error of shift k
        shift = v_s * age[:, None] + err
        r0, brg = rng.uniform(300, 600), rng.uniform(0, 2 * np.pi)
        b0 = xK - v_s * age[0] + r0 * np.array([np.cos(brg), np.sin(brg)])
        b_true = b0 + 1.5 * np.array([np.cos(beta), np.sin(beta)]) * (age[0] - age)[:, None]
        bias = 3.0 * rng.normal(size=2)
        b_rep = b_true - bias
        x_true = xK - v_s * age[:, None]
        z = np.sqrt(((x_true - b_true) ** 2).sum(axis=1) + dz * dz) + np.sqrt(R) * rng.normal(size=M)
        off = rng.uniform(0, 2 * np.pi)
        x0 = xK + 30.0 * np.array([np.cos(off), np.sin(off)])  # locked-out estimate at the fix time
        P0 = 4.0 * np.eye(2)
        win = RangeWindow(z, b_rep, shift, np.full(M, dz), age)
        ox, oP, oX = np.zeros(2), np.zeros((2, 2)), np.zeros((2, 2))
        window_fix(win, M, noise, x0, P0, ox, oP, oX)
        res["new"].append((np.linalg.norm(ox - xK), _nees(xK - ox, oP)))
        cross += np.outer(xK - ox, bias), oX
        # old: the lock-out's range is the first; the estimate then was x0 moved back by the DR
        x, P = x0 - shift[0], P0.copy()
        y, Hxy, _ = _ekf_h(x, b_rep[0], dz, z[0], P, R)
        _old_reinit(x, P, y, Hxy, R)
        for k in range(1, M):
            x += shift[k - 1] - shift[k]
            P += q * dt * np.eye(2)
            y, Hxy, S = _ekf_h(x, b_rep[k], dz, z[k], P, R)
            S += Hxy @ Pbb @ Hxy  # the beacon's variance in R, as the modem kernel does
            Kk = P @ Hxy / S
            x += Kk * y
            P -= np.outer(Kk, Kk) * S
        res["old"].append((np.linalg.norm(x - xK), _nees(xK - x, P)))
    lo, hi = chi2.ppf([0.025, 0.975], 2 * TRIALS) / TRIALS
    out = {}
    for name, v in res.items():
        v = np.array(v)
        out[name] = (
            np.mean(v[:, 1] <= 9.0),
            v[:, 1].mean(),
            np.median(v[:, 0]),
            np.mean(v[:, 0]),
            np.percentile(v[:, 0], 95),
        )
        print(
            f"\n{name}: within 3 sigma {out[name][0]:.1%}; NEES mean {out[name][1]:.2f} (band {lo:.2f}-{hi:.2f}); "
            f"error median {out[name][2]:.1f} m, mean {out[name][3]:.1f} m, 95th pct {out[name][4]:.1f} m"
        )
    print(
        f"cross-covariance with the beacon's bias: sample {np.round(cross[0] / TRIALS, 1).tolist()}, "
        f"the fix's Pxb on average {np.round(cross[1] / TRIALS, 1).tolist()}"
    )
    assert out["new"][0] >= 0.95 and lo <= out["new"][1] <= hi
    # the sample cross-covariance's standard error is about 10 m x 3 m / sqrt(500) = 1.3 m^2
    assert np.abs(cross[0] - cross[1]).max() / TRIALS < 3.0
    assert out["old"][0] < out["new"][0] and out["old"][3] > out["new"][3]


def test_pbb_message_codes_dominate_the_sent_covariance():
    """24 bits (three 8-bit codes) whose decoded Pbb is never smaller than the sent one
    (every eigenvalue of decoded - sent >= 0), and not much larger."""
    from coopnav_env.core.consider import decode_pbb, encode_pbb

    rng = np.random.default_rng(4)
    out = np.zeros((2, 2))
    growth = []
    for _ in range(2000):
        s = 10 ** rng.uniform(-1, 3, 2)
        rho = rng.uniform(-0.99, 0.99)
        Pbb = np.array([[s[0] ** 2, rho * s[0] * s[1]], [rho * s[0] * s[1], s[1] ** 2]])
        codes = encode_pbb(Pbb)
        assert all(0 <= c <= 255 for c in codes)
        decode_pbb(*codes, out)
        assert np.linalg.eigvalsh(out - Pbb).min() >= -1e-9 * s.max() ** 2
        growth.append(np.trace(out) / np.trace(Pbb))
    assert max(growth) < 1.25


def test_monte_carlo_two_beacons_random_walk_and_fixes():
    """Eqs. (C6)-(C8) in Monte Carlo: two beacons ping in turn. A's error is a random walk
    (Pbb grows by Qb a ping, C7 with tau = inf) and restarts from a 1 m GPS fix every 20
    pings (C8: Pxb_A <- 0); B's is a constant bias. Each range carries the other beacon's
    cross-covariance (C6). Schmidt stays consistent; the white-R EKF does not. The prior
    std is 5 m: with 20 m the first ranges' linearization error (about 400 / (2 x 250) =
    0.8 m) is as large as A's 1 m fix and its noise, and the NEES starts near 3 for
    every EKF, Schmidt or not (the EKF's own limit, not the consider states')."""
    rng = np.random.default_rng(77)
    runs, pings = 200, 60
    Qb, Pfix, PbbB = 0.5 * np.eye(2), np.eye(2), np.diag([16.0, 9.0])
    R, P0, truth = 1.0, np.diag([25.0, 25.0, 0.25]), np.array([0.0, 0.0, 50.0])
    nees = {"ekf": np.empty((runs, pings)), "schmidt": np.empty((runs, pings))}
    K = np.zeros(3)
    for run in range(runs):
        errA, PbbA = rng.normal(size=2), Pfix.copy()
        errB = np.sqrt(np.diag(PbbB)) * rng.normal(size=2)
        x0 = truth + np.sqrt(np.diag(P0)) * rng.normal(size=3)
        f = {k: (x0.copy(), P0.copy()) for k in nees}
        Pxb = np.zeros((2, 3, 2))
        for k in range(pings):
            if k > 0:
                consider_predict(Pxb[0], 20.0, np.inf)
                errA = errA + np.sqrt(0.5) * rng.normal(size=2)
                PbbA = PbbA + Qb
                if k % 20 == 0:
                    errA, PbbA = rng.normal(size=2), Pfix.copy()
                    beacon_reset(Pxb[0])
            j = k % 2
            ang = 2 * np.pi * k / 40 + np.pi * j
            b_true = np.array([(250 + 100 * j) * np.cos(ang), (250 + 100 * j) * np.sin(ang), 10.0])
            b_rep = b_true.copy()
            b_rep[:2] -= errA if j == 0 else errB
            Pbb = PbbA if j == 0 else PbbB
            z = np.linalg.norm(truth - b_true) + np.sqrt(R) * rng.normal()
            for name, (x, P) in f.items():
                h, H = range_prediction(x, np.zeros(3), np.zeros(1), b_rep)
                if name == "ekf":
                    joseph_update(x, P, z, h, H, R + H[:2] @ Pbb @ H[:2])
                else:
                    schmidt_range_update(x, P, Pxb[j], Pbb, z - h, H, R, np.inf, K)
                    carry_cross_covariance(Pxb[1 - j], K, H)
                nees[name][run, k] = _nees(truth[:2] - x[:2], P[:2, :2])
    lo, hi = chi2.ppf([0.025, 0.975], 2 * runs) / runs
    c_lo, c_hi, c_999 = chi2.ppf([0.025, 0.975, 0.999], 2)
    for name, v in nees.items():
        print(
            f"\ntwo beacons, {name:8s} NEES mean {v.mean():6.2f} (band {lo:.2f}-{hi:.2f}); run-cycles in band "
            f"{np.mean((v >= c_lo) & (v <= c_hi)):.1%}; > chi2.999: {np.mean(v > c_999):.2%}"
        )
    assert nees["ekf"].mean() > hi
    v = nees["schmidt"]
    assert lo <= v.mean() <= hi and np.mean((v >= c_lo) & (v <= c_hi)) >= 0.85 and np.mean(v > c_999) <= 0.003


def _pbb(var, dev):
    out = np.empty((2, 2))
    beacon_covariance(var, dev, out)
    return out


def test_the_beacons_covariance_from_its_message_hand_values():
    """Eq. N1's Pbb = [[m + a, c], [c, m - a]] and its projections: along a row h, h Pbb h^T
    (eq. C2's Hb Pbb Hb^T); along a direction, the variance white fusion adds to R (a range:
    along the line of sight; a bearing: across it). An isotropic Pbb gives exactly what the
    scalar per-axis variance gave before, bit for bit."""
    P = _pbb(5.0, 3.0 + 1.0j)
    np.testing.assert_array_equal(P, [[8.0, 1.0], [1.0, 2.0]])
    h = np.array([0.6, -0.8])
    assert beacon_variance_along(P, *h) == pytest.approx(h @ P @ h)
    assert beacon_variance_along(P, *(3 * h)) == pytest.approx(9 * h @ P @ h)
    assert beacon_variance_los(P, *(3 * h)) == pytest.approx(h @ P @ h)  # the length does not matter
    assert beacon_variance_los(P, 1.0, 0.0) == 8.0 and beacon_variance_los(P, 0.0, -2.0) == 2.0
    assert beacon_variance_los(P, 0.0, 0.0) == 5.0  # no direction: the per-axis mean
    rng = np.random.default_rng(3)
    for v, (h0, h1) in zip(rng.uniform(0.01, 100, 50), rng.normal(size=(50, 2))):
        iso = _pbb(v, 0j)
        assert beacon_variance_along(iso, h0, h1) == v * (h0 * h0 + h1 * h1)
        assert beacon_variance_los(iso, h0, h1) == v


@settings(max_examples=200, deadline=None)
@given(
    var=st.floats(0.01, 400.0),
    frac=st.floats(0.0, 0.999),
    angle=st.floats(-np.pi, np.pi),
    gps=st.floats(0.01, 50.0),
    phi=st.floats(0.0, 1.0),
    seed=st.integers(0, 2**16),
)
def test_the_gps_share_is_var_g_times_the_inverse_covariance_capped(var, frac, angle, gps, phi, seed):
    """Eq. C8' with the beacon's 2x2 covariance Sigma as last heard: Pxb <- phi Pxb M with
    M = var(g) Sigma^-1 and each eigenvalue of M capped at 1, against numpy's eigh."""
    dev = var * frac * np.exp(1j * angle)
    sigma = _pbb(var, dev)
    lam, V = np.linalg.eigh(sigma)
    M = V @ np.diag(np.minimum(1.0, gps / np.maximum(lam, 1e-300))) @ V.T
    X = np.random.default_rng(seed).normal(size=(3, 2))
    got = X.copy()
    gps_share(got, gps, var, dev, phi)
    np.testing.assert_allclose(got, phi * X @ M, rtol=1e-9, atol=1e-12)


def test_the_gps_share_of_an_isotropic_covariance_is_the_scalar():
    """With no deviator, eq. C8' is the scalar phi min(1, var(g) / m) to the bit; never heard
    (m = 0): the share is 1."""
    X = np.random.default_rng(0).normal(size=(3, 2))
    got = X.copy()
    gps_share(got, 1.0, 7.0, 0j, 0.9)
    np.testing.assert_array_equal(got, X * (0.9 * (1.0 / 7.0)))
    got = X.copy()
    gps_share(got, 1.0, 0.0, 0j, 0.5)
    np.testing.assert_array_equal(got, 0.5 * X)


def test_the_gps_share_of_a_singular_covariance_keeps_the_flat_axis_whole():
    """Eq. C8' where Sigma_seen is singular (|deviator| = m: all of the beacon's error on one
    axis, e.g. the one-cycle compass error alone on a straight run): along the flat axis the
    old error was all GPS error, so the share there is 1 (var(g) / 0 capped), along the other
    var(g) / 2m. Sigma = [[2, 0], [0, 0]] (m = 1, a = 1) with var(g) = 0.5: M = diag(0.25, 1).
    (A mutation review found a share of 0 on the flat axis passed every test: the hypothesis
    test above draws |deviator| < m only.)"""
    X = np.arange(1.0, 7.0).reshape(3, 2)
    got = X.copy()
    gps_share(got, 0.5, 1.0, 1.0 + 0j, 1.0)
    np.testing.assert_allclose(got, X @ np.diag([0.25, 1.0]), rtol=1e-12)


def test_the_cross_covariance_follows_a_turn_of_the_track_by_hand():
    """Eqs. N2-N3 with the constant compass bias b0 alone (and a white part w small beside it):
    100 m east of its fix the beacon's error is -i b0 D1 = (0, -100 b0), all north; after it
    turned, 100 m north, it is -i b0 (100 i) = (100 b0, 0), all east: b2_x = -b1_y. So
    Cov(b2, b1) = [[w, -1e4 s^2], [0, w]], and a survey correlated with the old north error
    by p is correlated with the new east error by -p (N3), where eq. C7's phi = 1 keeps it on
    north, an axis whose variance has fallen to w."""
    sb2, w = 1e-4, 1e-6
    model = ErrorModel(sb2, -sb2, 0.0, 0.0)
    m1 = np.array([100.0, 0.0, 100.0, 100.0, 0.0, 0.0, w])  # D east, s, G (a straight leg), no lock loss
    m2 = np.array([0.0, 100.0, 200.0, 0.0, 0.0, 0.0, w])
    c = error_model_covariance(m2, m1, model)
    np.testing.assert_allclose(c, [w, -1.0, 0.0, w], rtol=1e-12, atol=1e-15)
    sigma1 = error_model_covariance(m1, m1, model)
    np.testing.assert_allclose(sigma1, [w, 0.0, 0.0, w + 1.0], rtol=1e-12, atol=1e-15)
    Pxb = np.zeros((3, 2))
    Pxb[1, 1] = 0.7
    transport_cross_covariance(Pxb, m2, m1, model)
    np.testing.assert_allclose(
        Pxb, [[0.0, 0.0], [-0.7 / (1.0 + w), 0.7 * w / (1.0 + w)], [0.0, 0.0]], rtol=1e-9, atol=1e-12
    )
    # a random walk alone (no constant errors): Cov(b2, b1) = Sigma1, Pxb kept (eq. C7, phi = 1)
    walk = ErrorModel(0.0, 0.0, 0.0, 0.0)
    X = np.arange(6.0).reshape(3, 2)
    Y = X.copy()
    transport_cross_covariance(Y, np.r_[m2[:6], 5.0], np.r_[m1[:6], 2.0], walk)
    np.testing.assert_allclose(Y, X, rtol=1e-12)
    # never heard (Sigma1 = 0): nothing changes
    transport_cross_covariance(Y, m2, np.zeros(7), walk)
    np.testing.assert_array_equal(Y, X)
