"""The MLS azimuth/range/heading sensor (coopnav_env/core/mls/; Kottege & Zimmer,
Acoustics '08): the paper's equations on hand-computed values, noise-free geometry,
the corrected error bounds against a numerical Jacobian, the signal level against the
analytic mode, a short tank sweep against the paper's headline bounds, bad input and
determinism."""

from __future__ import annotations

import math

import numpy as np
import pytest

from benchmarks.mls_analytic_vs_signal import run_grid
from benchmarks.mls_tank import headline_checks, run_sweep, statistics
from coopnav_env.core.acoustics import mackenzie_sound_speed
from coopnav_env.core.mls import (
    MLSConfig,
    MLSSensor,
    PeakTracker,
    Reflection,
    error_statistics,
    estimate_from_delays,
    geometric_truth,
    mls_error_bounds,
    wrap_angle_rad,
)

D, L, V, FS = 0.3, 0.5, 1500.0, 96_000.0


@pytest.fixture(scope="module")
def quiet():
    """No noise, no reflection."""
    return MLSSensor(MLSConfig(snr_db_at_1m=math.inf))


@pytest.fixture(scope="module")
def sensor():
    return MLSSensor(MLSConfig())


def _pose(range_m, azimuth_deg, rel_heading_deg):
    a = math.radians(azimuth_deg)
    return np.array([range_m * math.cos(a), range_m * math.sin(a)]), math.radians(rel_heading_deg), np.zeros(2), 0.0


# --- the paper's equations ----------------------------------------------------------
def test_eq4_adjustment():
    deg = np.array([0.0, 179.0, 180.0, 181.0, -181.0, 200.0, -200.0, 359.0, 540.0])
    want = np.array([0.0, 179.0, 180.0, -179.0, 179.0, -160.0, 160.0, -1.0, 180.0])
    assert np.allclose(np.degrees(wrap_angle_rad(np.radians(deg))), want)


def test_eqs_1_to_10_hand_computed():
    # delta_1 = 0.15 m -> beta_1 = 60 deg -> theta_1 = -30 deg; delta_2 = -0.15 sqrt2 m ->
    # beta_2 = 135 deg -> theta_2 = +45 deg (the quadrant-aware eq. 2); theta = 7.5 deg.
    # r_11..r_22 = 1.0, 1.1, 1.2, 1.3 m: r_1 = sqrt(1.0825), r_2 = sqrt(1.5425) (eq. 8),
    # r = sqrt(1.25) (eq. 9); heading atan2(r1 sin th1 - r2 sin th2, r1 cos th1 - r2 cos th2)
    # = atan2(-1.398427, 0.022829) = -89.0646 deg (eq. 10).
    m = estimate_from_delays(
        [9.6, -13.576450198781712],
        [[64.0, 70.4], [76.8, 83.2]],
        hydrophone_base_m=D,
        projector_spacing_m=L,
        sound_speed_mps=V,
        sample_rate_hz=FS,
        estimator="paper",
    )
    assert np.degrees(m.sub_azimuths_rad) == pytest.approx([-30.0, 45.0], abs=1e-9)
    assert math.degrees(m.azimuth_rad) == pytest.approx(7.5, abs=1e-9)
    assert m.sub_ranges_m == pytest.approx([1.0404326023342405, 1.241974234837422], abs=1e-12)
    assert float(m.range_m) == pytest.approx(1.118033988749895, abs=1e-12)
    assert math.degrees(m.heading_rad) == pytest.approx(-89.06459112414973, abs=1e-9)


def test_eq2_clips_beyond_endfire():
    # |delta| > d (noise near +-90 deg): the sub-azimuth saturates at -+90 deg, no NaN
    m = estimate_from_delays(
        [25.0, -25.0],
        [[64.0, 70.4], [76.8, 83.2]],
        hydrophone_base_m=D,
        projector_spacing_m=L,
        sound_speed_mps=V,
        sample_rate_hz=FS,
        estimator="paper",
    )
    assert np.degrees(m.sub_azimuths_rad) == pytest.approx([-90.0, 90.0])


def test_paper_statistics_eqs_15_to_19():
    mu, sigma, avgdev = error_statistics([1.0, 2.0, 3.0, 6.0])
    assert (mu, sigma, avgdev) == pytest.approx((3.0, math.sqrt(3.5), 1.5))


# --- geometry -----------------------------------------------------------------------
POSES = [
    (1.0, 0.0, 150.0),
    (1.0, 40.0, 60.0),
    (2.0, -70.0, 10.0),
    (0.6, 10.0, 90.0),
    (3.0, 55.0, -120.0),
    (1.5, -30.0, 180.0),
]


@pytest.mark.parametrize("pose", POSES)
def test_ideal_estimator_is_exact(quiet, pose):
    args = _pose(*pose)
    m = quiet.ideal_measurement(*args)
    az, r, hd = geometric_truth(*args)
    assert float(m.azimuth_rad) == pytest.approx(float(az), abs=1e-10)
    assert float(m.range_m) == pytest.approx(float(r), abs=1e-10)
    assert float(wrap_angle_rad(m.heading_rad - hd)) == pytest.approx(0.0, abs=1e-10)


def test_paper_eq5_bias_in_the_tank_geometry():
    # the mean of the sub-azimuths (eq. 5) is biased at r ~ l: 1.54 deg over the whole tank sweep
    s = MLSSensor(MLSConfig(snr_db_at_1m=math.inf, estimator="paper"))
    m = s.ideal_measurement(*_pose(1.0, 0.0, 150.0))
    assert math.degrees(m.azimuth_rad) == pytest.approx(1.543, abs=0.002)


def test_front_back_ambiguity(quiet):
    # a sender straight behind reads as straight ahead, heading mirrored: 180 - alpha
    m = quiet.ideal_measurement(*_pose(2.0, 180.0, 30.0))
    assert math.degrees(m.azimuth_rad) == pytest.approx(0.0, abs=1e-9)
    assert float(m.range_m) == pytest.approx(2.0, abs=1e-12)
    assert math.degrees(m.heading_rad) == pytest.approx(150.0, abs=1e-9)


def test_world_frame_poses(quiet):
    # the same relative geometry anywhere in the world, any observer heading
    rel = quiet.ideal_measurement(*_pose(1.7, 25.0, 70.0))
    psi = 2.1
    c, s = math.cos(psi), math.sin(psi)
    p_rel = np.array([1.7 * math.cos(math.radians(25.0)), 1.7 * math.sin(math.radians(25.0))])
    obs = np.array([100.0, -40.0])
    m = quiet.ideal_measurement(
        obs + np.array([c * p_rel[0] - s * p_rel[1], s * p_rel[0] + c * p_rel[1]]), psi + math.radians(70.0), obs, psi
    )
    for a, b in zip(m[:3], rel[:3]):
        assert float(a) == pytest.approx(float(b), abs=1e-9)


@pytest.mark.parametrize("pose", POSES[:5])
def test_noise_free_signal_recovers_pose(quiet, pose):
    """Without noise the signal level is off only by the cubic spline's peak locking
    (a few hundredths of a sample), which the analytic mode reproduces."""
    args = _pose(*pose)
    m = quiet.measure_signal(*args, rng=np.random.default_rng(0))
    az, r, hd = geometric_truth(*args)
    assert abs(math.degrees(m.azimuth_rad - az)) < 0.3
    assert abs(float(m.range_m - r)) < 1.5e-3
    assert abs(math.degrees(wrap_angle_rad(m.heading_rad - hd))) < 2.0  # grows as r / l
    tdoa, toa = quiet.true_delays(*args)
    assert np.all(np.abs(m.tdoa_samples - tdoa) < 0.1) and np.all(np.abs(m.toa_samples - toa) < 0.1)
    # the peak locking is tabulated exactly
    assert m.tdoa_samples == pytest.approx(tdoa + quiet.interpolation_bias_samples(tdoa), abs=2e-4)
    assert m.toa_samples == pytest.approx(toa + quiet.interpolation_bias_samples(toa), abs=2e-4)
    a = quiet.measure_analytic(*args, normals=np.zeros(MLSSensor.N_NORMALS))
    assert float(a.azimuth_rad) == pytest.approx(float(m.azimuth_rad), abs=1e-4)
    assert float(a.range_m) == pytest.approx(float(m.range_m), abs=1e-5)
    assert float(a.heading_rad) == pytest.approx(float(m.heading_rad), abs=5e-4)


def test_sound_speed_from_mackenzie_and_its_error():
    s = MLSSensor(MLSConfig(snr_db_at_1m=math.inf, water_temperature_c=15.0, assumed_temperature_c=20.0))
    assert s.sound_speed_true_mps == pytest.approx(float(mackenzie_sound_speed(15.0, 0.0, 0.5)))
    # the receiver's sound speed error scales every distance: range bias = r (c_assumed/c_true - 1)
    args = _pose(3.0, 20.0, 45.0)
    m = s.ideal_measurement(*args)
    ratio = s.sound_speed_assumed_mps / s.sound_speed_true_mps
    assert float(m.range_m) == pytest.approx(3.0 * ratio, rel=1e-3)
    assert float(m.range_m) - 3.0 > 0.03  # ~+1.6 %: 15 vs 20 degC


def test_wall_reflection_arrives_on_the_image_path():
    # wall x = 2 m (normal east); sender at (1, 0) heading 0 (bow at 1.25 m), observer at the origin
    s = MLSSensor(
        MLSConfig(
            snr_db_at_1m=math.inf,
            band_hz=None,
            reflection=Reflection("wall", 0.8, wall_point_m=(2.0, 0.0), wall_normal=(1.0, 0.0)),
        )
    )
    delays, amps = s._paths(np.array([1.0, 0.0]), 0.0, np.zeros(2), 0.0)
    # image of the bow projector at (2.75, 0); H1 at (0, 0.15)
    assert delays[0, 0, 1] == pytest.approx(math.hypot(2.75, 0.15) * FS / s.sound_speed_true_mps)
    assert amps[0, 0, 1] == pytest.approx(0.8 / math.hypot(2.75, 0.15))
    ch = s.synthesize(np.array([1.0, 0.0]), 0.0, np.zeros(2), 0.0, np.random.default_rng(0))
    mf = np.fft.irfft(np.fft.rfft(ch[0, 0]) * np.conj(np.fft.rfft(s.replica)), n=s.nfft)
    direct, image = int(round(delays[0, 0, 0])), int(round(delays[0, 0, 1]))  # noqa: RUF046 - numpy 1.x rounds to a float
    assert mf[image] == pytest.approx(0.8 * 1.25 / math.hypot(2.75, 0.15) * mf[direct], rel=0.05)


# --- error bounds -------------------------------------------------------------------
def _jacobian_std(tdoa, toa, dtau, estimator="paper"):
    x0 = np.concatenate([tdoa, toa.ravel()])

    def f(x):
        m = estimate_from_delays(
            x[:2],
            x[2:].reshape(2, 2),
            hydrophone_base_m=D,
            projector_spacing_m=L,
            sound_speed_mps=V,
            sample_rate_hz=FS,
            estimator=estimator,
        )
        return np.array([float(m.azimuth_rad), float(m.range_m), float(m.heading_rad)])

    h = 1e-4
    J = np.stack([(f(x0 + h * e) - f(x0 - h * e)) / (2 * h) for e in np.eye(6)], axis=1)
    return np.sqrt((J**2) @ (np.full(6, dtau) ** 2))


@pytest.mark.parametrize("pose", [(3.0, 20.0, 70.0), (5.0, -50.0, 150.0), (4.0, 60.0, -30.0)])
def test_corrected_bounds_match_the_jacobian(pose):
    args = _pose(*pose)
    s = MLSSensor(MLSConfig(snr_db_at_1m=math.inf, estimator="paper", sample_rate_hz=FS))
    tdoa, toa = s.true_delays(*args)
    m = estimate_from_delays(
        tdoa, toa, hydrophone_base_m=D, projector_spacing_m=L, sound_speed_mps=V, sample_rate_hz=FS, estimator="paper"
    )
    dtau = 0.05
    b = mls_error_bounds(
        m.sub_azimuths_rad,
        m.sub_ranges_m,
        m.range_m,
        hydrophone_base_m=D,
        projector_spacing_m=L,
        sound_speed_mps=V,
        sample_rate_hz=FS,
        tdoa_std_samples=dtau,
    )
    assert np.array([float(x) for x in b]) == pytest.approx(_jacobian_std(tdoa, toa, dtau), rel=0.01)
    printed = mls_error_bounds(
        m.sub_azimuths_rad,
        m.sub_ranges_m,
        m.range_m,
        hydrophone_base_m=D,
        projector_spacing_m=L,
        sound_speed_mps=V,
        sample_rate_hz=FS,
        tdoa_std_samples=dtau,
        as_printed=True,
    )
    assert float(printed[0]) == pytest.approx(float(b[0]))  # eq. (11) is right
    assert float(printed[1]) == pytest.approx(4.0 * float(b[1]))  # eq. (12) is 4x too large


def test_ideal_timing_bound_is_cramer_rao_for_a_flat_band():
    s = MLSSensor(MLSConfig(band_hz=None, snr_db_at_1m=10.0))
    toa = np.full((2, 2), FS / s.sound_speed_true_mps)  # 1 m: unit amplitude
    _, s_toa = s.timing_std_samples(toa, interpolation="ideal")
    crb = math.sqrt(s.noise_sigma**2 * 3.0 / (math.pi**2 * s.n_chips))
    assert float(s_toa[0, 0]) == pytest.approx(crb, rel=0.02)


# --- signal level against the analytic mode -----------------------------------------
def test_analytic_agrees_with_signal_level_on_a_small_grid():
    rows = run_grid(ranges_m=(0.7, 3.0), azimuths_deg=(-60.0, 0.0, 60.0), n_signal=120, n_analytic=5000, seed=3)
    bad = [(r["range_m"], r["azimuth_deg"], np.round(r["ratio"], 2)) for r in rows if not r["pass"]]
    assert not bad, f"std ratio analytic/signal outside 25 %: {bad}"


def test_signal_delays_spread_as_modelled(sensor):
    args = _pose(2.5, 35.0, -100.0)
    _tdoa, toa = sensor.true_delays(*args)
    s_tdoa, s_toa = sensor.timing_std_samples(toa)
    rng = np.random.default_rng(11)
    tracker = PeakTracker()
    E = np.array(
        [
            np.concatenate([m.tdoa_samples, m.toa_samples.ravel()])
            for m in (sensor.measure_signal(*args, rng=rng, tracker=tracker) for _ in range(150))
        ]
    )
    ratio = E.std(axis=0) / np.concatenate([s_tdoa, s_toa.ravel()])
    assert np.all(np.abs(ratio - 1.0) < 0.25), ratio


# --- the tank experiment ------------------------------------------------------------
def test_short_tank_sweep_meets_the_headline_bounds():
    stats = statistics(run_sweep(n_events=61, seed=1, mode="signal"))
    checks = headline_checks(stats)
    assert all(checks.values()), (checks, stats)
    # the paper: errors near +-90 deg stay below 15 deg (azimuth)
    assert stats["azimuth_maxabs_near_90_deg"] < 15.0
    assert stats["range_std_mm"] < 10.0


def test_tank_sweep_analytic_mode_meets_the_headline_bounds():
    checks = headline_checks(statistics(run_sweep(n_events=301, seed=2, mode="analytic")))
    assert all(checks.values()), checks


# --- bad input ----------------------------------------------------------------------
@pytest.mark.parametrize(
    "kw, name",
    [
        (dict(sample_rate_hz=0.0), "sample_rate_hz"),
        (dict(sample_rate_hz=-96e3), "sample_rate_hz"),
        (dict(hydrophone_base_m=0.0), "hydrophone_base_m"),
        (dict(projector_spacing_m=float("nan")), "projector_spacing_m"),
        (dict(max_range_m=-1.0), "max_range_m"),
        (dict(mls_order=3), "mls_order"),
        (dict(mls_order=10.5), "mls_order"),
        (dict(band_hz=(4e3, 60e3)), "band_hz"),
        (dict(band_hz=(5e3, 1e3)), "band_hz"),
        (dict(band_hz=3.0), "band_hz"),
        (dict(snr_db_at_1m=float("nan")), "snr_db_at_1m"),
        (dict(depth_m=-1.0), "depth_m"),
        (dict(sync_jitter_s=-1e-6), "sync_jitter_s"),
        (dict(estimator="magic"), "estimator"),
        (dict(spline_halfwidth_samples=1), "spline_halfwidth_samples"),
    ],
)
def test_bad_config(kw, name):
    with pytest.raises(ValueError, match=name):
        MLSConfig(**kw)


def test_bad_reflection():
    with pytest.raises(ValueError, match="coefficient"):
        Reflection("surface", -1.5)
    with pytest.raises(ValueError, match="kind"):
        Reflection("bottom")


def test_range_too_short_or_too_long(sensor):
    with pytest.raises(ValueError, match="shorter than the array geometry allows"):
        sensor.measure_analytic(*_pose(0.35, 0.0, 0.0), rng=np.random.default_rng(0))
    with pytest.raises(ValueError, match="shorter than the array geometry allows"):
        sensor.measure_signal(*_pose(0.2, 30.0, 0.0), rng=np.random.default_rng(0))
    with pytest.raises(ValueError, match="max_range_m"):
        sensor.measure_analytic(*_pose(12.0, 0.0, 0.0), rng=np.random.default_rng(0))


def test_bad_call_arguments(sensor):
    args = _pose(1.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="exactly one of rng and normals"):
        sensor.measure_analytic(*args)
    with pytest.raises(ValueError, match="normals must have shape"):
        sensor.measure_analytic(*args, normals=np.zeros(7))
    with pytest.raises(ValueError, match="sender_pos_m"):
        sensor.measure_analytic(np.array([1.0, 0.0, 0.0]), 0.0, np.zeros(2), 0.0, rng=np.random.default_rng(0))
    with pytest.raises(ValueError, match="observer_heading_rad must be finite"):
        sensor.measure_analytic(np.array([1.0, 0.0]), 0.0, np.zeros(2), float("nan"), rng=np.random.default_rng(0))
    with pytest.raises(ValueError, match="channels must have shape"):
        sensor.process(np.zeros((2, 2, 10)))


# --- determinism --------------------------------------------------------------------
def test_signal_level_is_deterministic_with_a_seed(sensor):
    args = _pose(2.0, 15.0, 100.0)
    a = sensor.measure_signal(*args, rng=np.random.default_rng(7), tracker=PeakTracker())
    b = sensor.measure_signal(*args, rng=np.random.default_rng(7), tracker=PeakTracker())
    c = sensor.measure_signal(*args, rng=np.random.default_rng(8), tracker=PeakTracker())
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    assert float(a.azimuth_rad) != float(c.azimuth_rad)


def test_analytic_mode_takes_the_callers_normals(sensor):
    n = 50
    rng = np.random.default_rng(5)
    sp = rng.uniform(1.0, 4.0, (n, 2))
    sh = rng.uniform(-3.0, 3.0, n)
    op, oh = np.zeros((n, 2)), rng.uniform(-1.0, 1.0, n)
    a = sensor.measure_analytic(sp, sh, op, oh, rng=np.random.default_rng(9))
    z = np.random.default_rng(9).standard_normal((n, MLSSensor.N_NORMALS))
    b = sensor.measure_analytic(sp, sh, op, oh, normals=z)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    # row k of the batch is the single call with row k's normals
    k = 17
    one = sensor.measure_analytic(sp[k], sh[k], op[k], oh[k], normals=z[k])
    assert float(one.azimuth_rad) == float(b.azimuth_rad[k]) and float(one.heading_rad) == float(b.heading_rad[k])
    assert b.azimuth_rad.shape == (n,) and b.sub_ranges_m.shape == (n, 2)


@pytest.mark.parametrize("jitter_s", [0.0, 2e-5])
def test_measure_with_bounds_is_the_two_calls_bit_for_bit(sensor, jitter_s):
    """One geometry for a sending event's measurement and noise model (what the swarm
    simulator calls): identical to measure_analytic and error_bounds called apart."""
    s = sensor if jitter_s == 0.0 else MLSSensor(MLSConfig(sync_jitter_s=jitter_s))
    n = 40
    rng = np.random.default_rng(11)
    sp = rng.uniform(1.0, 4.0, (n, 2))
    sh = rng.uniform(-3.0, 3.0, n)
    op, oh = np.zeros((n, 2)), rng.uniform(-1.0, 1.0, n)
    z = rng.standard_normal((n, MLSSensor.N_NORMALS))
    for bias in (True, False):
        m, b = s.measure_analytic_with_bounds(sp, sh, op, oh, normals=z, interpolation_bias=bias)
        m0 = s.measure_analytic(sp, sh, op, oh, normals=z, interpolation_bias=bias)
        assert all(np.array_equal(x, y) for x, y in zip(m, m0))
    assert all(np.array_equal(x, y) for x, y in zip(b, s.error_bounds(sp, sh, op, oh)))
    m, _ = s.measure_analytic_with_bounds(sp, sh, op, oh, rng=np.random.default_rng(3))
    m0 = s.measure_analytic(sp, sh, op, oh, rng=np.random.default_rng(3))
    assert all(np.array_equal(x, y) for x, y in zip(m, m0))
    with pytest.raises(ValueError, match="exactly one of rng and normals"):
        s.measure_analytic_with_bounds(sp, sh, op, oh)


def test_a_randomized_depth_row_is_measured_by_its_own_depths_sensor():
    """With ``randomize_depth_m`` each row's MLS measurement comes from the sensor of its
    episode's depth: a row drawn at 50 m is the standalone 50 m scenario bit for bit. Until
    2026-12-04 one sensor at the scenario's ``depth_m`` (5 m) measured every row, so the
    50 m rows differed from the 50 m scenario (by ~1e-4 in the observation after a step)."""
    import coopnav_env
    from coopnav_env.core import make_simulator
    from coopnav_env.views import action_dim

    seeds = list(range(9000, 9016))
    sim = make_simulator(coopnav_env.make_config("swarm_mls", randomize_depth_m=(5.0, 50.0)), len(seeds))
    obs = sim.reset(seeds)
    deep_rows = [r for r, v in enumerate(sim.state.ep_variant) if sim.variants[v][1] == 50.0]
    assert deep_rows and len(deep_rows) < len(seeds)  # both depths drawn
    r = deep_rows[0]
    one = make_simulator(coopnav_env.make_config("swarm_mls", depth_m=50.0), 1)
    np.testing.assert_array_equal(obs[r], one.reset([seeds[r]])[0])
    rng = np.random.default_rng(1)
    for _ in range(6):
        actions = rng.uniform(-1.0, 1.0, (len(seeds), obs.shape[1], action_dim(sim)))
        res = sim.step(actions)
        np.testing.assert_array_equal(res.obs[r], one.step(actions[r : r + 1]).obs[0])


@pytest.mark.parametrize("depth_m", [5.0, 50.0])
def test_the_array_range_is_the_slant_range_the_filters_predict(depth_m):
    """The MLS range is a time of flight: with the school at 50 m and the sender at 5 m it is
    the slant range (hypot(30, 45) = 54.08 m at 30 m across), which is what the survey
    filters predict (eq. 7). Until 2026-12-04 the array sent the horizontal range (30 m),
    and the filters' gate rejected almost every range of the `deep_50m` shift."""
    import coopnav_env
    from coopnav_env.core import make_simulator
    from coopnav_env.core.measurements.mls_array import HEARD

    sim = make_simulator(coopnav_env.make_config("swarm_mls", depth_m=depth_m), 1)
    sim.reset([123])
    st = sim.state
    S = st.s_pos.shape[1]
    j = int(np.argmax(sim.sensor.heard_mask(st.cycle - 1)[0]))
    across = 30.0 + np.arange(S)  # each survey vehicle 30, 31, ... m east of the sender
    st.s_pos[0, :, 0] = st.b_pos[0, j, 0] + across
    st.s_pos[0, :, 1] = st.b_pos[0, j, 1]
    dz = depth_m - 5.0  # the sender at the scenario's beacon depth, 5 m
    assert np.allclose(st.s_pos[0, :, 2] - st.b_pos[0, j, 2], dz)
    m = sim.sensor.measure({"mls_n": np.zeros((1, S, 14))})  # noise-free
    assert (m.state[0, j] == HEARD).all()
    np.testing.assert_allclose(m.range_m[0, j], np.hypot(across, dz), atol=1e-2)
