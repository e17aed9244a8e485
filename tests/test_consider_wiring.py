"""The consider states, the fix counter, the multipath weighting and the GPS
Gauss-Markov error wired into the survey simulator (issue 21;
docs/scenarios/consider-fusion.md). The building blocks' own tests: test_consider.py."""

from __future__ import annotations

import numpy as np
import pytest

import coopnav_env
from coopnav_env.core import make_simulator
from coopnav_env.core.multipath import direct_path_weight
from coopnav_env.scenarios import PAPER_FILTER

STILL = {"packet_loss_near": 0.0, "packet_loss_far": 0.0, "outlier_probability": 0.0}


def _run(config, cycles, seed=11, batch=3):
    sim = make_simulator(config, batch)
    sim.reset(list(range(seed, seed + batch)))
    for _ in range(cycles):
        sim.step(np.full((batch, config.n_beacons, 2), 0.3))
    return sim.state


def test_schmidt_with_an_exact_beacon_is_the_papers_filter():
    """Pbb = 0 (a beacon whose GPS is exact, fixing every cycle) and Pxb = 0: the wired
    Schmidt update (eqs. C2-C5 on the 5-state augmented covariance) is Gao & Chitre's
    eqs. 9-13 to round-off, over 40 cycles with outliers, losses and the gate at work."""
    base = coopnav_env.make_config(
        "gao_lawnmower", gps_noise_m=0.0, range_outlier_model="gate", lockout_recovery="nearest_point"
    )
    white = _run(base.replace(beacon_error_fusion="white"), 40)
    schmidt = _run(base.replace(beacon_error_fusion="schmidt"), 40)
    assert np.all(schmidt.s_Pxb == 0.0)
    np.testing.assert_allclose(schmidt.s_est, white.s_est, rtol=0, atol=1e-9)
    np.testing.assert_allclose(schmidt.s_P, white.s_P, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("tau", [0.0, 300.0])
def test_the_fix_counter_resets_the_cross_covariance(tau):
    """A DVL beacon surfaces every 100 s. On the cycle of its fix the survey, hearing the
    new counter in the ping, first keeps of Pxb the GPS error's share, var(g) Sigma(e)^-1, decayed
    by exp(-dt / tau) over the dt since the last fix it heard (eq. C8'; zeroes it, eq. C8,
    with a white GPS error): the
    step gives what the same step gives from a state where that was done by hand; a
    filter that ignored the counter would differ, as a step without a fix shows."""
    c = coopnav_env.make_config(
        "gao_sea",
        beacon_surface_every_s=100.0,
        beacon_surface_above_std_m=0.0,
        beacon_surfacing="instant",  # the fix at once, ranging throughout (a timed surfacing has a dwell away)
        gps_error_time_constant_s=tau,
        **STILL,
    )
    probe = make_simulator(c, 1)
    probe.reset([5])
    fix_cycles = []
    for k in range(12):
        probe.step(np.full((1, 1, 2), 0.3))
        if probe.state.b_surfacings[0, 0]:
            fix_cycles.append(k)
    k_fix = fix_cycles[1]  # the second fix: the survey heard the first one 100 s earlier
    a, b = make_simulator(c, 1), make_simulator(c, 1)
    for sim in (a, b):
        sim.reset([5])
        for _ in range(k_fix):
            sim.step(np.full((1, 1, 2), 0.3))
    assert np.abs(a.state.s_Pxb).max() > 1e-3  # the survey has learnt a correlation
    dt = 100.0
    # eq. C8': the GPS part of the old error, var(g) Sigma_seen^-1 with Sigma_seen the beacon's 2x2
    # covariance as last heard (per-axis variance m and deviator a + 1j c, eq. N1), by numpy's own algebra
    m, dev = a.state.s_var_seen_m2[0, 0, 0], a.state.s_dev_seen_m2[0, 0, 0]
    sigma = np.array([[m + dev.real, dev.imag], [dev.imag, m - dev.real]])
    lam, V = np.linalg.eigh(sigma)
    share = V @ np.diag(np.minimum(1.0, c.gps_noise_m**2 / lam)) @ V.T
    assert np.linalg.eigvalsh(share).min() > 0.0 and np.linalg.eigvalsh(share).max() < 1.0
    b.state.s_Pxb[:] = np.exp(-dt / tau) * b.state.s_Pxb @ share if tau > 0 else 0.0
    b.state.s_fix_seen[:] = (a.state.b_fix_count[0, 0] + 1) % 16  # as if heard already
    b.state.s_fix_seen_t_s[:] = a.state.t_s[0] + c.ping_interval_s
    a.step(np.full((1, 1, 2), 0.3))
    b.step(np.full((1, 1, 2), 0.3))
    assert a.state.b_surfacings[0, 0] == 1
    np.testing.assert_allclose(a.state.s_est, b.state.s_est, rtol=0, atol=1e-12)
    np.testing.assert_allclose(a.state.s_P, b.state.s_P, rtol=0, atol=1e-12)
    np.testing.assert_allclose(a.state.s_Pxb, b.state.s_Pxb, rtol=0, atol=1e-12)
    # the counter mattered: without the reset the update differs
    c2 = make_simulator(c, 1)
    c2.reset([5])
    for _ in range(k_fix):
        c2.step(np.full((1, 1, 2), 0.3))
    c2.state.s_fix_seen[:] = (c2.state.b_fix_count[0, 0] + 1) % 16
    c2.state.s_fix_seen_t_s[:] = c2.state.t_s[0] + c.ping_interval_s
    c2.step(np.full((1, 1, 2), 0.3))
    assert np.abs(c2.state.s_P - a.state.s_P).max() > 1e-6


def test_a_fix_keeps_only_the_gps_errors_share_of_the_correlation():
    """Eq. C8' against the linear model it comes from. The beacon's old error e = g + d, GPS
    error g (1 m std per axis) plus 5 m of dead reckoning d; the survey's error learnt e
    through ranges: x = -0.8 e + n. The fix makes the beacon's error e' = phi g + w (20 s
    later, tau 300 s), so Cov(x, e') = -0.8 phi var(g) = -0.748 per axis. Before (a review),
    Pxb <- phi Pxb kept the dead reckoning's part too: -19.5, and the joint covariance of x
    and e' had an eigenvalue of -11.0 (indefinite). Now the exact value, and the joint is
    positive semi-definite."""
    from coopnav_env.core.kernel_records import consider_view
    from coopnav_env.core.measurements.modem import ModemRanging, _heard_fix_count

    c = coopnav_env.make_config("gao_sea", gps_noise_m=1.0, gps_error_time_constant_s=300.0)
    sim = make_simulator(c, 1)
    sim.reset([3])
    prm = ModemRanging(sim).params
    var_g, var_d, a, dt = 1.0, 25.0, 0.8, 20.0
    var_e = var_g + var_d
    # the joint of (x (3), g (2), d (2)) per axis, x = -a (g + d) + n in the horizontal
    J = np.zeros((7, 7))
    J[3:5, 3:5], J[5:7, 5:7] = var_g * np.eye(2), var_d * np.eye(2)
    T = np.zeros((3, 7))
    T[:2, 3:5] = T[:2, 5:7] = -a * np.eye(2)
    Pxx = T @ J @ T.T + np.diag([4.0, 4.0, 0.01])
    Pxe = -a * var_e * np.eye(3, 2)  # Cov(x, e), e = g + d: the ranges saw the sum
    st = sim.state
    st.s_P[0, 0] = Pxx
    st.s_Pxb[0, 0, 0] = Pxe
    st.s_var_seen_m2[0, 0, 0] = var_e
    st.s_fix_seen_t_s[0, 0, 0] = 0.0
    st.s_hyp_w[:] = 1.0
    assert prm.gps_var_m2 == var_g  # var(g) is the GPS receiver's, whatever a later ping sends
    _heard_fix_count(consider_view(st), prm, 0, 0, 0, dt)
    phi = np.exp(-dt / 300.0)
    exact = -a * phi * var_g * np.eye(3, 2)
    np.testing.assert_allclose(st.s_Pxb[0, 0, 0], exact, rtol=1e-12, atol=1e-15)
    joint = np.block([[Pxx, exact], [exact.T, var_g * np.eye(2)]])
    assert np.linalg.eigvalsh(joint).min() > 0.0
    old = np.block([[Pxx, phi * Pxe], [phi * Pxe.T, var_g * np.eye(2)]])
    assert np.linalg.eigvalsh(old).min() < -10.0  # what the review found


def test_a_fix_keeps_the_gps_share_of_an_anisotropic_error():
    """Eq. C8' with the beacon's covariance 2x2 (eq. N1): its dead reckoning d drifted 5 m
    across its track (east) and 1 m along it, so Sigma_e = var(g) I + diag(25, 1). With
    x = -0.8 e + n, Cov(x, e) = -0.8 Sigma_e, and the fix leaves Cov(x, e') = -0.8 phi var(g)
    I: Pxb Sigma_e^-1 var(g). The scalar share with the per-axis mean m = 14 (what the survey
    knew before the deviator was carried) gives -1.4 east and -0.11 north where both are
    -0.75."""
    from coopnav_env.core.kernel_records import consider_view
    from coopnav_env.core.measurements.modem import ModemRanging, _heard_fix_count

    c = coopnav_env.make_config("gao_sea", gps_noise_m=1.0, gps_error_time_constant_s=300.0)
    sim = make_simulator(c, 1)
    sim.reset([3])
    prm = ModemRanging(sim).params
    a, dt = 0.8, 20.0
    sigma_e = np.diag([26.0, 2.0])
    m, dev = 0.5 * np.trace(sigma_e), complex(0.5 * (sigma_e[0, 0] - sigma_e[1, 1]), sigma_e[0, 1])
    st = sim.state
    st.s_Pxb[0, 0, 0] = np.vstack([-a * sigma_e, np.zeros((1, 2))])
    st.s_var_seen_m2[0, 0, 0], st.s_dev_seen_m2[0, 0, 0] = m, dev
    st.s_fix_seen_t_s[0, 0, 0] = 0.0
    st.s_hyp_w[:] = 1.0
    _heard_fix_count(consider_view(st), prm, 0, 0, 0, dt)
    exact = -a * np.exp(-dt / 300.0) * 1.0 * np.eye(3, 2)
    np.testing.assert_allclose(st.s_Pxb[0, 0, 0], exact, rtol=1e-12, atol=1e-15)


def test_gps_error_is_gauss_markov_with_its_time_constant():
    """An ASV's GPS error over 400 cycles of 20 s, 64 runs: its lag-one correlation is
    exp(-T / tau) (0.936 at tau = 300 s; 0 for the papers' white error) and its std per axis
    gps_noise_m (a stationary first-order Gauss-Markov process)."""
    out = {}
    for tau in (300.0, 0.0):
        c = coopnav_env.make_config(
            "sousa_asv", ping_interval_s=20.0, gps_error_time_constant_s=tau, max_cycles=500, mission_duration_s=0.0
        )
        sim = make_simulator(c, 64)
        sim.reset(list(range(64)))
        errs = []
        for _ in range(400):
            sim.step(np.zeros((64, 1, 2)))
            errs.append(sim.state.b_nav_err[:, 0, 0].copy())
        e = np.array(errs)  # (cycles, runs)
        out[tau] = (np.mean(e[1:] * e[:-1]) / np.mean(e * e), e.std())
    assert out[300.0][0] == pytest.approx(np.exp(-20.0 / 300.0), abs=0.03)
    assert abs(out[0.0][0]) < 0.03
    for tau in out:
        assert out[tau][1] == pytest.approx(0.5, rel=0.05)  # sousa_asv's gps_noise_m


def test_direct_path_weight_by_hand():
    """Eqs. M1-M2 at y = 15 m, S = 36 m^2, p = 3 %, mu = 30 m: g0 = N(15; 0, 36) =
    exp(-3.125) / (6 sqrt(2 pi)), g1 = exp(0.02 - 0.5) Phi((15 - 1.2) / 6) / 30; and the
    limits: no multipath (w = 1), a range as much too short (w near 1)."""
    from math import erf, exp, pi, sqrt

    g0 = exp(-3.125) / (6 * sqrt(2 * pi))
    g1 = exp(36 / 1800 - 0.5) * 0.5 * (1 + erf((15 - 1.2) / 6 / sqrt(2))) / 30
    w = 0.97 * g0 / (0.97 * g0 + 0.03 * g1)
    assert direct_path_weight(15.0, 36.0, 0.03, 30.0) == pytest.approx(w, rel=1e-12)
    assert direct_path_weight(15.0, 36.0, 0.0, 30.0) == 1.0
    short = direct_path_weight(-15.0, 36.0, 0.03, 30.0)  # a longer path cannot make a range short
    assert 0.99 < short < 1.0 and short > direct_path_weight(15.0, 36.0, 0.03, 30.0)


def test_direct_path_weight_with_a_vanishing_excess():
    """An excess far below the noise leaves the two paths' likelihoods equal, so w is the prior
    1 - p; at mu = 1e-308 the old code divided by mu^2 = 0 (found by test_properties)."""
    assert direct_path_weight(2.0, 36.0, 0.03, 1e-308) == pytest.approx(0.97, rel=1e-12)
    assert direct_path_weight(2.0, 36.0, 0.03, 1e-5) == pytest.approx(0.97, rel=1e-5)  # the limit, approached
    assert direct_path_weight(2.0, 36.0, 0.03, 1e-3) == pytest.approx(0.97, rel=1e-3)
    # the log form and the asymptotic series agree where they meet (z = (y - S / mu) / sd = -30)
    mu_30 = 36.0 / (2.0 + 30.0 * 6.0)
    below, above = (
        direct_path_weight(2.0, 36.0, 0.03, mu_30 * 0.999999),
        direct_path_weight(2.0, 36.0, 0.03, mu_30 * 1.000001),
    )
    assert below == pytest.approx(above, rel=1e-7)


def test_ping_grows_by_the_consider_fields_and_switches_are_checked():
    c = coopnav_env.make_config("sousa_ping")
    assert c.ping_bits == c.ping_packet_bits + 20
    assert c.replace(beacon_error_fusion="white").ping_bits == c.ping_packet_bits
    for key, bad in (
        ("beacon_error_fusion", "schmit"),
        ("lockout_recovery", "nearest"),
        ("range_outlier_model", "pda"),
    ):
        with pytest.raises(ValueError, match=f"unknown {key} '{bad}'(; did you mean '[a-z_]+'\\?)?;? valid: "):
            coopnav_env.make_config("gao_sea", **{key: bad})
    with pytest.raises(ValueError, match="recovery_window"):
        coopnav_env.make_config("gao_sea", recovery_window=2)
    with pytest.raises(ValueError, match="gps_error_time_constant_s"):
        coopnav_env.make_config("gao_sea", gps_error_time_constant_s=-1.0)
    assert set(PAPER_FILTER) <= set(coopnav_env.parameter_names())
