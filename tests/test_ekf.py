"""The survey vehicle's batched EKF (Gao & Chitre eqs. 4-13).

1. step by step against filterpy's ExtendedKalmanFilter (an independent
   implementation, Joseph-form update) for several filters at once;
2. numerical properties: symmetric positive definite covariance, masking, the
   range Jacobian, the chi-square gate;
3. Monte Carlo filter consistency of the full simulator (NEES).
"""

import numpy as np
import pytest
from filterpy.kalman import ExtendedKalmanFilter
from scipy.stats import chi2, norm, poisson

from benchmarks.nees_per_cycle import CASES
from coopnav_env.core import navigation
from coopnav_env.core.sim import Simulator
from coopnav_env.scenarios import make_config


# ----------------------------------------------------------------------------------
# helpers
# ----------------------------------------------------------------------------------
def _hx(x, beacon):
    """eq. (7): the range from the beacon, for filterpy (x is (3, 1))."""
    return np.array([[np.linalg.norm(x[:, 0] - beacon)]])


def _hjac(x, beacon):
    """eq. (8): the unit vector from the beacon, as a 1x3 Jacobian."""
    d = x[:, 0] - beacon
    return (d / np.linalg.norm(d))[None, :]


def _random_spd(g, n, scale):
    A = g.normal(size=(n, 3, 3)) * scale
    return A @ np.swapaxes(A, -1, -2) + 0.5 * np.eye(3)


def _coopnav_range_update(x, P, z, beacon, R, mask):
    """One range update with coopnav, the one-leg zero-delay model of eq. (7)-(8)."""
    B = x.shape[0]
    h, H = navigation.range_model(x, np.zeros((B, 3)), np.zeros((B, 1)), beacon)
    return navigation.scalar_update(x, P, z, h, H, R, mask)


def _recorded_sequence(B, n_steps, seed):
    """Predictions (dx, Q) and range measurements to a moving beacon, per filter."""
    g = np.random.default_rng(seed)
    x_true = g.uniform(-50, 50, size=(B, 3))
    x_true[:, 2] = g.uniform(2, 20, size=B)
    steps = []
    beacon = g.uniform(-200, 200, size=(B, 3))
    beacon[:, 2] = 1.0
    for _ in range(n_steps):
        dx = g.normal(size=(B, 3)) * np.array([20.0, 20.0, 0.5])  # dead-reckoned motion R v tau
        x_true = x_true + dx + g.normal(size=(B, 3)) * np.array([1.0, 1.0, 0.1])
        q = g.uniform(0.1, 3.0, size=B)
        Q = np.zeros((B, 3, 3))
        Q[:, 0, 0] = Q[:, 1, 1] = q
        Q[:, 2, 2] = 0.01 * q
        Q[:, 0, 1] = Q[:, 1, 0] = 0.3 * q  # a correlated Q exercises the full matrix algebra
        beacon = beacon + g.normal(size=(B, 3)) * np.array([25.0, 25.0, 0.2])  # the beacon moves
        R = g.uniform(0.5, 4.0, size=B)
        z = np.linalg.norm(x_true - beacon, axis=1) + np.sqrt(R) * g.normal(size=B)
        mask = g.uniform(size=B) > 0.2  # some filters miss some ranges
        steps.append(dict(dx=dx, Q=Q, beacon=beacon.copy(), z=z, R=R, mask=mask))
    return steps


# ----------------------------------------------------------------------------------
# 1. against filterpy
# ----------------------------------------------------------------------------------
def test_batched_ekf_matches_filterpy():
    B, n_steps = 6, 40
    g = np.random.default_rng(2024)
    x = g.uniform(-50, 50, size=(B, 3))
    P = _random_spd(g, B, 3.0)
    filters = []
    for b in range(B):
        f = ExtendedKalmanFilter(dim_x=3, dim_z=1)
        f.x = x[b].reshape(3, 1).copy()
        f.P = P[b].copy()
        f.F = np.eye(3)
        f.B = np.eye(3)
        filters.append(f)

    n_updates = 0
    for step in _recorded_sequence(B, n_steps, seed=7):
        x, P = navigation.predict(x, P, step["dx"], step["Q"])
        for b, f in enumerate(filters):
            f.Q = step["Q"][b]
            f.predict(u=step["dx"][b].reshape(3, 1))
        for b, f in enumerate(filters):
            np.testing.assert_allclose(x[b], f.x[:, 0], rtol=0, atol=1e-9)
            np.testing.assert_allclose(P[b], f.P, rtol=0, atol=1e-9)

        x_new, P_new, y, S = _coopnav_range_update(x, P, step["z"], step["beacon"], step["R"], step["mask"])
        for b, f in enumerate(filters):
            if not step["mask"][b]:
                continue
            f.update(
                np.array([[step["z"][b]]]),
                _hjac,
                _hx,
                R=np.array([[step["R"][b]]]),
                args=(step["beacon"][b],),
                hx_args=(step["beacon"][b],),
            )
            n_updates += 1
            # the innovation (eq. 10) and its variance (eq. 11) as well
            assert y[b] == pytest.approx(float(f.y[0, 0]), abs=1e-9)
            assert S[b] == pytest.approx(float(f.S[0, 0]), abs=1e-9)
        x, P = x_new, P_new
        for b, f in enumerate(filters):
            np.testing.assert_allclose(x[b], f.x[:, 0], rtol=0, atol=1e-9)
            np.testing.assert_allclose(P[b], f.P, rtol=0, atol=1e-9)
    # the sequence really exercised the update, and the filters moved
    assert n_updates > 0.6 * B * n_steps
    assert np.all(np.trace(P, axis1=1, axis2=2) < 100.0)


def test_axis_measurement_matches_filterpy_linear_update():
    """Depth (axis 2) and GPS (axes 0, 1) updates are the linear case H = e_axis."""
    g = np.random.default_rng(11)
    B = 4
    x = g.normal(size=(B, 3)) * 10
    P = _random_spd(g, B, 2.0)
    for axis, r in [(2, 0.05**2), (0, 2.1**2), (1, 2.1**2)]:
        z = x[:, axis] + g.normal(size=B)
        H = navigation.axis_measurement(axis, (B,))
        assert H.shape == (B, 3)
        x_new, P_new, _, _ = navigation.scalar_update(x, P, z, x[:, axis], H, np.full(B, r), np.ones(B, bool))
        for b in range(B):
            f = ExtendedKalmanFilter(dim_x=3, dim_z=1)
            f.x, f.P = x[b].reshape(3, 1).copy(), P[b].copy()
            e = np.eye(3)[axis][None, :]
            f.update(np.array([[z[b]]]), lambda s, e=e: e, lambda s, axis=axis: s[axis : axis + 1], R=np.array([[r]]))
            np.testing.assert_allclose(x_new[b], f.x[:, 0], atol=1e-9)
            np.testing.assert_allclose(P_new[b], f.P, atol=1e-9)
        x, P = x_new, P_new


# ----------------------------------------------------------------------------------
# 2. numerical properties
# ----------------------------------------------------------------------------------
def test_covariance_stays_symmetric_positive_definite():
    g = np.random.default_rng(99)
    B = 8
    x = np.zeros((B, 3))
    P = np.broadcast_to(np.diag([1e4, 1e4, 1e-2]), (B, 3, 3)).copy()  # badly conditioned on purpose
    Q = np.diag([1e-6, 1e-6, 1e-8])
    for k in range(1000):
        x, P = navigation.predict(x, P, g.normal(size=(B, 3)), Q)
        beacon = x + g.normal(size=(B, 3)) * np.array([100.0, 100.0, 5.0])
        R = 10.0 ** g.uniform(-6, 1, size=B)  # down to 1 mm: large gains, where P = (I-KH)P breaks
        h, H = navigation.range_model(x, np.zeros((B, 3)), np.zeros((B, 1)), beacon)
        z = h + np.sqrt(R) * g.normal(size=B)
        x, P, _, _ = navigation.scalar_update(x, P, z, h, H, R, g.uniform(size=B) < 0.9)
        assert np.all(np.isfinite(P))
        np.testing.assert_allclose(P, np.swapaxes(P, -1, -2), rtol=0, atol=1e-10 * np.abs(P).max())
        assert np.all(np.linalg.eigvalsh(P) > 0), f"P lost positive definiteness at update {k}"


def test_masked_row_is_unchanged():
    g = np.random.default_rng(3)
    B = 5
    x = g.normal(size=(B, 3)) * 10
    P = _random_spd(g, B, 1.0)
    beacon = g.normal(size=(B, 3)) * 100
    z = np.linalg.norm(x - beacon, axis=1) + 5.0  # a big innovation, so an update would move x
    mask = np.array([True, False, True, False, False])
    x_new, P_new, y, _S = _coopnav_range_update(x, P, z, beacon, np.ones(B), mask)
    np.testing.assert_array_equal(x_new[~mask], x[~mask])
    np.testing.assert_array_equal(P_new[~mask], P[~mask])
    assert np.all(np.linalg.norm(x_new[mask] - x[mask], axis=1) > 0.1)
    assert np.all(np.trace(P_new[mask], axis1=1, axis2=2) < np.trace(P[mask], axis1=1, axis2=2))
    # the innovation is reported for every row, masked or not
    np.testing.assert_allclose(y, 5.0, atol=1e-9)
    # NaN in a masked-out row does not leak into the result
    z_nan = z.copy()
    z_nan[1] = np.nan
    x2, P2, _, _ = _coopnav_range_update(x, P, z_nan, beacon, np.ones(B), mask)
    np.testing.assert_array_equal(x2[1], x[1])
    assert np.all(np.isfinite(x2)) and np.all(np.isfinite(P2))


def test_range_model_multi_leg_and_jacobian():
    g = np.random.default_rng(8)
    B = 5
    x = g.normal(size=(B, 3)) * 50
    v = g.normal(size=(B, 3))
    beacon = g.normal(size=(B, 3)) * 50
    delays = np.stack([np.zeros(B), g.uniform(0.05, 0.3, B)], -1)
    h, H = navigation.range_model(x, v, delays, beacon)
    # hand: the mean of the two legs' distances (TWTT), each leg ends at x + v d
    leg0 = np.linalg.norm(x - beacon, axis=1)
    leg1 = np.linalg.norm(x + v * delays[:, 1:] - beacon, axis=1)
    np.testing.assert_allclose(h, 0.5 * (leg0 + leg1), rtol=1e-12)
    # H is the gradient of h: central differences
    eps = 1e-5
    for i in range(3):
        dx = np.zeros(3)
        dx[i] = eps
        fd = (
            navigation.range_model(x + dx, v, delays, beacon)[0] - navigation.range_model(x - dx, v, delays, beacon)[0]
        ) / (2 * eps)
        np.testing.assert_allclose(H[:, i], fd, atol=1e-8)
    # one leg of zero delay is eq. (7)-(8)
    h1, H1 = navigation.range_model(x, v, np.zeros((B, 1)), beacon)
    np.testing.assert_allclose(h1, leg0, rtol=1e-14)
    np.testing.assert_allclose(H1, (x - beacon) / leg0[:, None], rtol=1e-14)


def test_gate_threshold_is_chi_square_quantile():
    for p in (0.9, 0.99, 0.999):
        assert navigation.gate_threshold(p) == pytest.approx(chi2.ppf(p, 1), rel=1e-12)
        # 1 dof: the square of the two-sided normal quantile
        assert navigation.gate_threshold(p) == pytest.approx(norm.ppf(0.5 + p / 2) ** 2, rel=1e-9)
        # 2 dof: exponential, -2 ln(1 - p)
        assert navigation.gate_threshold(p, 2) == pytest.approx(-2 * np.log(1 - p), rel=1e-9)
    assert navigation.gate_threshold(0.999) == pytest.approx(10.8276, abs=1e-4)  # 3.2905^2
    cfg = make_config("gao_lawnmower")
    sim = Simulator(cfg, batch_size=1)
    assert sim.gate == pytest.approx(chi2.ppf(cfg.range_gate_probability, 1), rel=1e-12)


# ----------------------------------------------------------------------------------
# 3. Monte Carlo consistency of the full simulator
# ----------------------------------------------------------------------------------
N_RUNS = 100
FAST_RUNS = 30  # the default suite's runs per scenario; the slow versions use N_RUNS
CYCLE_BAND = chi2.ppf([0.025, 0.975], 2)  # one cycle's horizontal NEES, 95 %
P999 = chi2.ppf(0.999, 2)


def _nees_run(scenario="gao_lawnmower", runs=N_RUNS, **overrides):
    """NEES of every run at every cycle of ``scenario``, the beacon circling the survey.

    Returns (nees_3d, nees_2d, active): (cycles, runs) arrays; ``active`` marks the
    runs still inside their episode at that cycle.
    """
    cfg = make_config(scenario, **overrides)
    sim = Simulator(cfg, batch_size=runs)
    sim.reset(np.arange(runs))
    # A fixed action sequence for every run: heading (cos, sin) of an angle turning by
    # 2 pi / 34 per cycle. At 1.3 m/s and 20 s per cycle this is a circle of about 140 m
    # radius that, from the start south-west of the survey, goes around the 130 x 100 m
    # area anticlockwise once every 34 cycles.
    theta0, dtheta = -np.pi / 4, 2 * np.pi / 34
    n3, n2, active = [], [], []
    done = np.zeros(runs, dtype=bool)
    for k in range(cfg.max_cycles):
        th = theta0 + dtheta * k
        action = np.broadcast_to(np.array([np.cos(th), np.sin(th)]), (runs, sim.N, 2)).astype(np.float64)
        res = sim.step(action.copy())
        st = sim.state
        e = st.s_est[:, 0] - st.s_pos[:, 0]
        P = st.s_P[:, 0]
        n3.append(np.einsum("bi,bi->b", e, np.linalg.solve(P, e[..., None])[..., 0]))
        n2.append(np.einsum("bi,bi->b", e[:, :2], np.linalg.solve(P[:, :2, :2], e[:, :2, None])[..., 0]))
        active.append(~done)
        done = done | res.terminated | res.truncated
        if done.all():
            break
    return np.array(n3), np.array(n2), np.array(active)


def _nees_summary(scenario="gao_lawnmower", runs=N_RUNS, **overrides):
    """Per run-cycle figures of the horizontal NEES (every run while in its episode): the
    mean against the band of a mean of ``runs`` chi-square(2), the fraction inside one
    cycle's 95 % band, and the count above the 99.9 % point against the largest count a
    consistent filter reaches with probability 99.9 % (Poisson with mean 0.1 % of the
    run-cycles); the 3-D mean at the cycles where every run is active."""
    n3, n2, active = _nees_run(scenario, runs, **overrides)
    v = n2[active]
    full = active.all(1)
    lo3, hi3 = chi2.ppf([0.025, 0.975], 3 * runs) / runs
    lo2, hi2 = chi2.ppf([0.025, 0.975], 2 * runs) / runs
    return dict(
        runs=runs,
        run_cycles=len(v),
        mean2=float(v.mean()),
        band2=(lo2, hi2),
        in_band=float(np.mean((v >= CYCLE_BAND[0]) & (v <= CYCLE_BAND[1]))),
        above=int(np.sum(v > P999)),
        above_bound=int(poisson.ppf(0.999, 0.001 * len(v))),
        mean3=float(n3[full].mean()),
        band3=(lo3, hi3),
    )


def _format(r):
    return (
        f"\n{r['runs']} runs, {r['run_cycles']} run-cycles; horizontal NEES mean {r['mean2']:.3f} "
        f"(band of the mean [{r['band2'][0]:.3f}, {r['band2'][1]:.3f}]), {r['in_band']:.1%} of run-cycles in "
        f"[{CYCLE_BAND[0]:.3f}, {CYCLE_BAND[1]:.2f}], {r['above']} above {P999:.1f} "
        f"({r['above'] / r['run_cycles']:.2%}; bound <= {r['above_bound']}); "
        f"3-D mean {r['mean3']:.3f} (band [{r['band3'][0]:.3f}, {r['band3'][1]:.3f}])"
    )


MATCHED = dict(
    beacon_kinds=("asv",),
    survey_speed_scale_error_std=0.0,
    compass_bias_std_deg=0.0,
    compass_noise_deg=0.0,
    attitude_noise_deg=0.0,
    current_speed_mps=0.0,
    current_speed_spread_mps=0.0,
    current_gm_std_mps=0.1,
    current_gm_time_constant_s=0.01,
    outlier_probability=0.0,
    temperature_uncertainty_c=0.0,
    clock_offset_std_s=0.0,
    clock_drift_ppm=0.0,
    process_noise_horizontal_m2ps=(20.0 * 0.1) ** 2 / 20.0,
)


@pytest.mark.parametrize("gps_tau", [0.0, 300.0])
def test_nees_harness_on_a_matched_model(gps_tau):
    """Control: when the truth has exactly the noise the filter assumes, NEES is chi-square
    per cycle.

    Every bias is switched off and the only process noise is a current that is white
    from cycle to cycle (Gauss-Markov with tau = 0.01 s, redrawn once per 20 s cycle,
    std 0.1 m/s per axis): the position error gains N(0, (20 s * 0.1 m/s)^2) = N(0, 4 m^2)
    per axis and cycle, i.e. Q = 4 / 20 = 0.2 m^2/s. The beacon is an ASV whose GPS
    error is white (the papers' filter, the beacon's variance in R) or Gauss-Markov with
    tau = 300 s (the consider states, eq. C7 with phi = exp(-T / tau)). Without outliers
    the measurements are Gaussian. The per-cycle checks: the mean inside its band, at
    least 90 % of run-cycles inside one cycle's 95 % band, the 99.9 % exceedances within
    what a consistent filter gives (a wrong range model, a unit slip in Q, or a
    correlated beacon error fused as white would fail them).
    """
    fusion = "white" if gps_tau == 0.0 else "schmidt"
    r = _nees_summary(runs=FAST_RUNS, gps_error_time_constant_s=gps_tau, beacon_error_fusion=fusion, **MATCHED)
    report = _format(r)
    print(report)
    lo2, hi2 = r["band2"]
    assert r["run_cycles"] >= 20 * FAST_RUNS, report
    assert lo2 <= r["mean2"] <= hi2, report
    assert r["in_band"] >= 0.9, report
    assert r["above"] <= r["above_bound"], report


def _check_per_cycle(r, report):
    lo2, hi2 = r["band2"]
    assert lo2 <= r["mean2"] <= hi2, report
    assert r["in_band"] >= 0.85, report
    assert r["above"] <= r["above_bound"], report


@pytest.mark.parametrize("scenario", ["gao_lawnmower", "gao_sea", "sousa_asv"])
def test_nees_per_cycle(scenario):
    """Issue 21: per cycle, not the time average. With the beacon's own navigation
    errors (the lake trial's GPS, the sea trial's drifting DVL dead reckoning with
    surfacing, sousa_asv's GPS-positioned ASV), the consider states, the multipath
    handling, the lock-out re-fix and the Sousa scenarios' one-sided gate (the defaults):
    over every run-cycle, the mean horizontal NEES inside the band of a
    mean of the runs' chi-square(2), at least 85 % of run-cycles inside one cycle's
    95 % band [0.051, 7.38], and no more exceedances of the 99.9 % point than a filter
    at issue 21's limit (3x the nominal 0.1 %) gives with probability 99.9 % (a Poisson
    count; exceedances cluster in time within a run, so over 30 runs the nominal
    bound of the matched-model control above is too tight for a simulated sea: gao_sea's
    30 runs here have 11 in 1940 run-cycles, 5.7x, and 0.6x over the 100 held-out runs of
    the docs). 100 runs: the slow test below, with the 3x bound itself, and
    benchmarks/nees_per_cycle.py (docs/scenarios/consider-fusion.md)."""
    r = _nees_summary(scenario, runs=FAST_RUNS)
    r["above_bound"] = int(poisson.ppf(0.999, 0.003 * r["run_cycles"]))  # issue 21's 3x
    report = _format(r)
    print(report)
    _check_per_cycle(r, report)


GAO_SEA_KNOWN = pytest.mark.xfail(
    strict=True,
    reason="issue 21, open: gao_sea with surfacing, mean NEES 1.323 below its band (2.8x beyond the 99.9 % point)",
)


# benchmarks/nees_per_cycle.py's case 2, issue 21's first target: two hours, the beacon never surfacing
_LABEL, _SCENARIO, _PLANNER, NO_SURFACING_2H = CASES[2]
assert _SCENARIO == "gao_sea" and "no surfacing" in _LABEL


@pytest.mark.slow
@pytest.mark.parametrize(
    ("scenario", "overrides"),
    [
        ("gao_lawnmower", {}),
        pytest.param("gao_sea", {}, marks=GAO_SEA_KNOWN),
        ("gao_sea", NO_SURFACING_2H),
        ("sousa_asv", {}),
    ],
    ids=["gao_lawnmower", "gao_sea", "gao_sea_2h_no_surfacing", "sousa_asv"],
)
def test_nees_per_cycle_100_runs(scenario, overrides):
    """``test_nees_per_cycle`` over 100 runs, with issue 21's bound on the exceedances:
    at most 3x the nominal 0.1 %. gao_sea fails at its defaults, a strict xfail so that a fix
    shows (mean 1.323 below its band, 18 run-cycles above the point, 2.8x, with eq. C8' at the
    beacon's fixes; 1.340 and 3.4x before it; 1.344 before round 8's filter; issue 21's target
    for gao_sea is two hours without surfacing, which benchmarks/nees_per_cycle.py case 2
    measures, 0.1x): the tail is the first-order range update after close passes far off, the
    mean its Q (docs/scenarios/consider-fusion.md#curvature)."""
    r = _nees_summary(scenario, runs=N_RUNS, **overrides)
    report = _format(r)
    print(report)
    _check_per_cycle(r, report)
    assert r["above"] <= 0.003 * r["run_cycles"], report
