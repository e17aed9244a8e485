"""The survey's own dead-reckoning biases as consider states (core/dr_bias.py, eqs. D1-D4, R6)."""

from __future__ import annotations

import numpy as np
import pytest

import coopnav_env
from coopnav_env.core import make_simulator
from coopnav_env.core.dr_bias import bias_predict, displacement_jacobian
from coopnav_env.core.recovery import RangeWindow, WindowNoise, window_bias_cross, window_fix


def test_predict_on_an_l_shaped_path_by_hand():
    """10 m east, then 10 m north, sigma_k = 0.1, sigma_beta = 0.02 rad, no prior error:
    the first leg gives P = diag(100 * 0.01, 100 * 0.0004) = diag(1, 0.04) and
    Pxd = [[0.1, 0], [0, 0.004]]; after the second, (D2) by hand:
    G2 = [[0, -10], [10, 0]], G2 Pxd^T + Pxd G2^T = [[0, 0.96], [0.96, 0]],
    G2 Pff G2^T = diag(0.04, 1): P = [[1.04, 0.96], [0.96, 1.04]], the same as
    (G1 + G2) Pff (G1 + G2)^T for the whole 10 + 10 m path (a constant bias)."""
    P, Pxd = np.zeros((1, 1, 3, 3)), np.zeros((1, 1, 3, 4))
    var = np.array([[0.01, 0.0004, 0.0, 0.0]])
    bias_predict(P, Pxd, np.array([[[10.0, 0.0]]]), var)
    np.testing.assert_allclose(P[0, 0, :2, :2], np.diag([1.0, 0.04]), atol=1e-15)
    np.testing.assert_allclose(Pxd[0, 0, :, :2], [[0.1, 0.0], [0.0, 0.004], [0.0, 0.0]], atol=1e-15)
    bias_predict(P, Pxd, np.array([[[0.0, 10.0]]]), var)
    np.testing.assert_allclose(P[0, 0], [[1.04, 0.96, 0.0], [0.96, 1.04, 0.0], [0.0, 0.0, 0.0]], atol=1e-14)
    np.testing.assert_allclose(Pxd[0, 0, :, :2], [[0.1, -0.004], [0.1, 0.004], [0.0, 0.0]], atol=1e-15)
    assert not Pxd[0, 0, :, 2:].any()  # sigma_c = 0: the told current's columns stay 0


def test_told_current_error_grows_with_the_square_of_time():
    """Eq. (D1'): a told current off by c (sigma_c = 0.05 m/s per axis), three 20-s cycles
    with no displacement and no update: the error is 60 c, P = 60^2 sigma_c^2 I = 9 I and
    Pxd's current columns 60 sigma_c^2 I = 0.15 I. White noise of the same one-cycle
    variance (1 m^2) would give 3 I: a third."""
    P, Pxd = np.zeros((1, 1, 3, 3)), np.zeros((1, 1, 3, 4))
    var = np.array([[0.0, 0.0, 0.0025, 0.0025]])
    for _ in range(3):
        bias_predict(P, Pxd, np.zeros((1, 1, 2)), var, 20.0)
    np.testing.assert_allclose(P[0, 0, :2, :2], 9.0 * np.eye(2), rtol=1e-14)
    np.testing.assert_allclose(Pxd[0, 0, :2, 2:], 0.15 * np.eye(2), rtol=1e-14)
    assert P[0, 0, 2, 2] == 0.0 and not Pxd[0, 0, :, :2].any()


def test_predict_without_updates_is_the_bias_of_the_whole_path():
    """With no update in between, any sequence of displacements D_t leaves
    P = (sum G_t) Pff (sum G_t)^T and Pxd = (sum G_t) Pff: the error of a constant bias
    over the whole path, not the sum of independent ones (which would be sum G Pff G^T)."""
    rng = np.random.default_rng(3)
    D = rng.normal(0.0, 5.0, (30, 2, 3, 2))  # 30 cycles of 20 s, batch (2, 3)
    var = np.array([[0.0025, 3e-4, 0.0025, 0.0025], [0.01, 1e-4, 1e-4, 1e-4]])
    P, Pxd = np.zeros((2, 3, 3, 3)), np.zeros((2, 3, 3, 4))
    for d in D:
        bias_predict(P, Pxd, d, var, 20.0)
    Gs = displacement_jacobian(D.sum(0), 20.0 * len(D))
    Pff = np.zeros((2, 1, 4, 4))
    for i in range(4):
        Pff[:, 0, i, i] = var[:, i]
    np.testing.assert_allclose(P, Gs @ Pff @ np.swapaxes(Gs, -1, -2), rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(Pxd, Gs @ Pff, rtol=1e-10, atol=1e-12)


def test_d1_matches_the_dead_reckoning_of_the_substeps():
    """Eq. (D1) against ``substeps._advance_vehicle``'s arithmetic: the dead reckoning adds
    u dt h e^{-i beta} while the vehicle moves u (1 + k) dt h, so the true displacement is
    the dead-reckoned one times (1 + k) e^{i beta} ~ D + k D + beta J D (J: east -> north)."""
    k, beta = 0.04, np.radians(1.5)
    D_dr = 7.0 * np.exp(1j * 0.3) * np.exp(-1j * beta)  # what the dead reckoning adds
    d_true = 7.0 * np.exp(1j * 0.3) * (1.0 + k)
    G = displacement_jacobian(np.array([D_dr.real, D_dr.imag]))
    lin = G[:2] @ np.array([k, beta, 0.0, 0.0])
    err = d_true - D_dr
    # the rest is second order, k beta + beta^2 / 2 of |D| (2 % here); a wrong sign would be 100 %
    assert np.hypot(err.real - lin[0], err.imag - lin[1]) < 0.05 * abs(err)


def _dead_reckoning_nees(consider: bool, runs: int = 200, cycles: int = 60) -> np.ndarray:
    """sousa_asv's lawnmower with every ping lost (the survey dead-reckons, 5 min), Q
    shrunk to the compass noise's white share ((1 m/s x 1 s x 1 degree)^2 per 1-s sub-step
    across the track, 1.5e-4 m^2/s per axis): the horizontal NEES at the end of each run."""
    c = coopnav_env.make_config(
        "sousa_asv",
        packet_loss_near=1.0,
        packet_loss_far=1.0,
        process_noise_horizontal_m2ps=1.5e-4,
        survey_bias_consider=consider,
        max_cycles=cycles,
    )
    return _end_nees(c, runs, cycles, 730000)[0]


def _end_nees(config, runs: int, cycles: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Runs ``runs`` episodes of ``config`` (seeds ``seed`` + i, beacons holding still) for
    ``cycles`` cycles; returns the end horizontal NEES (runs,) and error (runs, 2)."""
    sim = make_simulator(config, runs)
    sim.reset(list(range(seed, seed + runs)))
    for _ in range(cycles):
        res = sim.step(np.zeros((runs, config.n_beacons, 2)))
    e = np.asarray(res.info["survey_error_en_m"])[:, 0]
    P = np.asarray(res.info["survey_cov_en_m2"])[:, 0]
    return np.einsum("bi,bi->b", e, np.linalg.solve(P, e[..., None])[..., 0]), e


def test_dead_reckoning_nees_is_chi_square_with_the_biases_considered():
    """Without ranges the survey's error after 5 min is its speed-scale and compass bias
    over the path (sigma 5 % and 1 degree: metres) plus the initial error. With the
    biases as consider states the end NEES of 200 runs averages 2 (chi-square(2): the 99 %
    band of the mean of 200 is [1.67, 2.37]) and 0.1 % exceed 13.8; with Q's white noise
    alone (the filter before eq. D2) it averages 5.3 and 8 % exceed 13.8 (these seeds;
    with them: 1.73 and 0.5 %)."""
    with_bias = _dead_reckoning_nees(True)
    assert 1.67 < with_bias.mean() < 2.37, with_bias.mean()
    assert np.mean(with_bias > 13.8) <= 0.01
    without = _dead_reckoning_nees(False)
    assert without.mean() > 4.0, without.mean()
    assert np.mean(without > 13.8) > 0.05


def _window():
    """Four ranges to a beacon moving east along y = 0 while the survey moves north."""
    x_true = np.array([40.0, 30.0])
    beacon = np.array([[0.0, 0.0], [10.0, 0.0], [20.0, 0.0], [30.0, 0.0]])
    shift = np.array([[0.0, 30.0], [0.0, 20.0], [0.0, 10.0], [0.0, 0.0]])
    dz = np.full(4, 5.0)
    z = np.sqrt(((x_true - shift - beacon) ** 2).sum(1) + dz**2)
    return RangeWindow(z, beacon, shift, dz, np.array([30.0, 20.0, 10.0, 0.0])), x_true


def test_window_bias_cross_against_a_linear_reference_and_monte_carlo():
    """Eq. (R6): the fix's cross-covariance with (k, beta, c_e, c_n) is P J^T Sigma^-1 Uf Pff (a numpy
    reference from the Jacobian), and it is what a Monte Carlo of biased shifts gives:
    each draw moves the survey's true track by G_k phi and the fix follows it."""
    win, x_true = _window()
    noise = WindowNoise(0.25, np.zeros((2, 2)), 0.0, 50.0, 0.05, np.radians(2.0), 0.05)
    x, P, Pxb, out = np.empty(2), np.empty((2, 2)), np.empty((2, 2)), np.empty((2, 4))
    window_fix(win, 4, noise, x_true + np.array([3.0, -2.0]), np.eye(2), x, P, Pxb)
    window_bias_cross(x, win, 4, noise, P, out)
    # reference: J, Sigma, Uf in numpy
    d = x - win.shift - win.beacon
    zh = np.sqrt((d**2).sum(1) + win.dz**2)
    J = d / zh[:, None]
    Js = np.stack([-win.shift[:, 1], win.shift[:, 0]], 1)
    Uf = np.concatenate([np.stack([(J * win.shift).sum(1), (J * Js).sum(1)], 1), win.age_s[:, None] * J], 1)
    Pff = np.diag([0.05**2, np.radians(2.0) ** 2, 0.05**2, 0.05**2])
    Sigma = 0.25 * np.eye(4) + Uf @ Pff @ Uf.T
    ref = P @ J.T @ np.linalg.solve(Sigma, Uf @ Pff)
    np.testing.assert_allclose(out, ref, rtol=1e-9, atol=1e-12)
    assert np.abs(out).max() > 1e-3  # the shifts are tens of metres: a real correlation
    # Monte Carlo: true shifts s_k + G_k phi, noise-free ranges; E[(x_true - x_hat) phi^T]
    rng = np.random.default_rng(5)
    phis = rng.multivariate_normal(np.zeros(4), Pff, 4000)
    errs = np.empty((len(phis), 2))
    for i, phi in enumerate(phis):
        true_shift = win.shift + phi[0] * win.shift + phi[1] * Js + win.age_s[:, None] * phi[2:]
        z = np.sqrt(((x_true - true_shift - win.beacon) ** 2).sum(1) + win.dz**2)
        w = RangeWindow(z, win.beacon, win.shift, win.dz, win.age_s)
        window_fix(w, 4, noise, x_true, np.eye(2), x, P, Pxb)
        errs[i] = x_true - x
    mc = errs.T @ phis / len(phis)
    np.testing.assert_allclose(mc, out, atol=0.1 * np.abs(out).max())


@pytest.mark.parametrize("param", ["survey_bias_consider"])
def test_the_papers_filter_leaves_the_biases_out(param):
    assert coopnav_env.scenarios.PAPER_FILTER[param] is False
    assert coopnav_env.make_config("sousa_asv").survey_bias_consider is True


def test_told_current_error_is_considered_end_to_end():
    """gao_lawnmower with uninformative ranges (noise 1 km: the pings still carry the
    beacon's current, Gao II-A) and only the told current's error as a bias (0.1 m/s per
    axis; no speed-scale error or compass bias), Q the compass noise's white share: after
    12 cycles (240 s, an error of about 24 m per axis) the survey's end NEES over 200 runs
    averages 2 (chi-square(2); the 99 % band of the mean of 200 is [1.67, 2.37]). Before
    the told current was a consider state (eq. D1') the filter had only Q for it and the
    mean was in the hundreds."""
    runs, cycles = 200, 12
    c = coopnav_env.make_config(
        "gao_lawnmower",
        range_noise_std_m=1000.0,
        outlier_probability=0.0,
        survey_speed_scale_error_std=0.0,
        compass_bias_std_deg=0.0,
        beacon_current_estimate_error_mps=0.1,
        process_noise_horizontal_m2ps=5e-4,
        max_cycles=cycles,
    )
    nees, e = _end_nees(c, runs, cycles, 731000)
    assert np.median(np.hypot(e[:, 0], e[:, 1])) > 10.0  # the current's error dominates
    assert 1.67 < nees.mean() < 2.37, nees.mean()


def test_untold_current_second_moment_by_hand():
    """Eq. (D1''): (s^2 + spread^2 / 3) / 2 per axis, the Gauss-Markov part left to Q; the told
    current's error where a beacon AUV tells one (eq. D1'); 0 at the defaults of the scenarios
    with an ASV beacon."""
    from coopnav_env.core import dr_bias

    c = coopnav_env.make_config(
        "sousa_asv", current_speed_mps=0.3, current_speed_spread_mps=0.3, current_gm_std_mps=0.1
    )
    assert dr_bias.current_error_std_mps(c) == pytest.approx(np.sqrt((0.09 + 0.03) / 2), rel=1e-12)
    assert dr_bias.considered_biases(coopnav_env.make_config("sousa_asv"))[2] == 0.0
    assert dr_bias.current_error_std_mps(coopnav_env.make_config("gao_lawnmower")) == 0.05  # told: its error
    untold = coopnav_env.make_config("gao_lawnmower", survey_uses_beacon_current=False)
    assert dr_bias.current_error_std_mps(untold) == pytest.approx(dr_bias.untold_current_std_mps(untold))


def test_untold_current_is_considered_end_to_end():
    """sousa_asv with a 0.3 m/s current in a direction drawn over +-180 deg that no beacon
    tells the ROV, uninformative ranges (noise 1 km) and no other bias: after 24 cycles (120
    s, about 36 m of drift) the end NEES over 200 runs averages 2 (the 99 % band of the mean
    of 200 is [1.67, 2.37]). Before eq. (D1'') the filter had only Q (0.001 m^2/s) for it and
    the mean was 318."""
    runs, cycles = 200, 24
    c = coopnav_env.make_config(
        "sousa_asv",
        range_noise_std_m=1000.0,
        outlier_probability=0.0,
        survey_speed_scale_error_std=0.0,
        compass_bias_std_deg=0.0,
        current_speed_mps=0.3,
        current_direction_spread_deg=180.0,
        max_cycles=cycles,
    )
    nees, e = _end_nees(c, runs, cycles, 732000)
    assert np.median(np.hypot(e[:, 0], e[:, 1])) > 20.0  # the current dominates
    assert 1.67 < nees.mean() < 2.37, nees.mean()
