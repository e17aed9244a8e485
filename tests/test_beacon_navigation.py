"""The beacon AUV's own navigation: DVL dead reckoning that drifts with distance
travelled (compass error b0 + b1 sin(heading + phase), velocity scale error), the
variance it carries into the survey filters' R, GPS fixes at the surface and what a
surfacing costs (ascent, dwell, descent, away from the survey), bottom lock from the
altitude; the ASVs' command-following errors."""

from __future__ import annotations

import numpy as np
import pytest

import coopnav_env
from coopnav_env.core import make_simulator
from coopnav_env.core.beacon_nav import covariance_deviator_m2, heading_cycle_variance_m2

QUIET = dict(
    dvl_velocity_noise_mps=0.0,
    dvl_lock_loss_probability=0.0,
    beacon_dvl_heading_bias_std_deg=0.0,
    beacon_dvl_heading_cycle_deg=0.0,
    beacon_dvl_scale_error_std=0.0,
    beacon_surface_above_std_m=0.0,
    beacon_surface_every_s=0.0,
)
EAST = np.array([1.0, 0.0])  # velocity action: due east at full speed


def _drive_east(cycles, B=1, seed=0, setup=None, **overrides):
    c = coopnav_env.make_config("gao_sea", **{**QUIET, **overrides})
    sim = make_simulator(c, B)
    sim.reset(np.arange(B) + seed)
    if setup is not None:
        setup(sim.state)
    start = sim.state.b_pos[:, 0, :2].copy()
    err0 = sim.state.b_nav_err[:, 0, :2].copy()
    for _ in range(cycles):
        sim.step(np.broadcast_to(EAST, (B, 1, 2)))
    return c, sim, sim.state.b_pos[:, 0, :2] - start, sim.state.b_nav_err[:, 0, :2] - err0


def test_heading_bias_rotates_the_track_clockwise():
    """1 degree of compass bias on a 20-cycle eastward run: the error is the displacement
    turned clockwise by 1 degree minus the displacement, (e^{-i b0} - 1) d, i.e.
    2 sin(0.5 deg) |d| ~ 1.75 % of the distance, pointing mostly south."""

    def bias(st):
        st.b_dvl_heading_bias_rad[:] = np.radians(1.0)

    _, _, d, err = _drive_east(20, setup=bias)
    dz = d[0, 0] + 1j * d[0, 1]
    expect = (np.exp(-1j * np.radians(1.0)) - 1.0) * dz
    assert abs(dz) > 400  # 20 cycles of 20 s at ~1.35 m/s
    np.testing.assert_allclose(err[0], [expect.real, expect.imag], atol=1e-9)
    assert err[0, 1] < 0 and abs(err[0, 1]) > 50 * abs(err[0, 0])


def test_scale_error_stretches_the_track():
    def scale(st):
        st.b_dvl_scale_error[:] = 0.02

    _, _, d, err = _drive_east(10, setup=scale)
    np.testing.assert_allclose(err[0], 0.02 * d[0], atol=1e-9)


def test_one_cycle_heading_error_depends_on_the_heading():
    """b1 sin(heading + phase): eastward (bearing 90 deg) with phase 0 gives b1."""

    def phase(st):
        st.b_dvl_heading_phase_rad[:] = 0.0

    _, _, d, err = _drive_east(10, setup=phase, beacon_dvl_heading_cycle_deg=2.0)
    dz = d[0, 0] + 1j * d[0, 1]
    # the first cycle turns the vehicle onto east; its bearing varies a little there
    expect = (np.exp(-1j * np.radians(2.0)) - 1.0) * dz
    np.testing.assert_allclose(err[0], [expect.real, expect.imag], rtol=0.05, atol=0.05)


def test_carried_variance_matches_the_monte_carlo_error_on_a_straight_run():
    """Over many episodes (each its own bias, cycle phase, scale error and noise) the
    mean squared error equals twice the per-axis variance the beacon carries (straight
    run: the one-cycle part is a constant b1 sin(phase + 90 deg) there, E = b1^2 / 2)."""
    B = 4000
    overrides = dict(
        beacon_dvl_heading_bias_std_deg=0.5,
        beacon_dvl_heading_cycle_deg=1.0,
        beacon_dvl_scale_error_std=0.01,
        dvl_velocity_noise_mps=0.026,
    )
    _c, sim, _d, err = _drive_east(15, B=B, **overrides)
    mse = float((err**2).sum(-1).mean())
    # the carried variance minus the start fix's (err is measured from the start error)
    carried = float(2 * (sim.state.b_nav_var_m2[:, 0] - 1.0).mean())
    assert carried > 20.0
    assert mse == pytest.approx(carried, rel=0.08)


def test_carried_variance_without_bottom_lock_grows_with_the_square_of_the_time():
    """Bottom lock lost for good from the first cycle, and the told current's error
    sigma_c = 0.05 m/s per axis the only error: the beacon drifts by c T, so after 10 cycles
    of 20 s (T = 200 s) the per-axis variance it carries is (sigma_c T)^2 = 100 m^2 (a bias,
    not a walk: sigma_c^2 T would be 0.5), and 2000 episodes' mean squared error is twice that."""
    B = 2000
    c, sim, _d, err = _drive_east(
        10,
        B=B,
        beacon_current_estimate_error_mps=0.05,
        dvl_lock_model="fixed",
        dvl_lock_loss_probability=1.0,
        dvl_lock_regain_probability=0.0,
    )
    T = 10 * c.ping_interval_s
    assert T == 200.0 and not sim.state.b_dvl_lock.any()
    np.testing.assert_allclose(sim.state.b_nav_var_m2[:, 0] - 1.0, (0.05 * T) ** 2, rtol=1e-9)
    assert float((err**2).sum(-1).mean()) == pytest.approx(2.0 * (0.05 * T) ** 2, rel=0.08)


def _drive_orbit(cycles, B, degrees_per_cycle=30.0, **overrides):
    """The beacon on a polygonal orbit: its commanded velocity turns by ``degrees_per_cycle``
    every cycle (full speed); returns the simulator and the error grown since the start."""
    c = coopnav_env.make_config("gao_sea", **{**QUIET, **overrides})
    sim = make_simulator(c, B)
    sim.reset(np.arange(B))
    err0 = sim.state.b_nav_err[:, 0, :2].copy()
    for k in range(cycles):
        a = np.radians(degrees_per_cycle * k)
        sim.step(np.broadcast_to(np.array([np.cos(a), np.sin(a)]), (B, 1, 2)))
    return sim, sim.state.b_nav_err[:, 0, :2] - err0


@pytest.mark.parametrize("degrees_per_cycle", [30.0, 0.0])
def test_carried_variance_matches_the_monte_carlo_error_on_an_orbit(degrees_per_cycle):
    """Two whole orbits of 12 cycles (and, for contrast, the straight run): over episodes
    (each its own phase of the one-cycle compass error b1 = 1 deg, the only error here) the
    mean squared error is b1^2 (s^2 + |G|^2) / 4 with G = sum |d_k| e^{-2i theta_k}: about
    b1^2 s^2 / 4 on the orbit, where G nearly vanishes, twice that on the straight run. The
    straight-run formula (b1^2 s^2 / 2 whatever the path) was 2x the Monte Carlo on the orbit."""
    sim, err = _drive_orbit(24, 2000, degrees_per_cycle, beacon_dvl_heading_cycle_deg=1.0)
    st = sim.state
    mse = float((err**2).sum(-1).mean())
    carried = float(2 * (st.b_nav_var_m2[:, 0] - 1.0).mean())  # minus the start fix's variance
    s = float(st.b_travelled_m[:, 0].mean())
    b1 = np.radians(1.0)
    assert s > 500.0
    expected_total = b1**2 * s**2 / (4.0 if degrees_per_cycle else 2.0)
    assert mse == pytest.approx(expected_total, rel=0.1)  # the hand formula's two limits
    assert mse == pytest.approx(carried, rel=0.05)


def _leg_heading_deg(path, k):
    """The commanded heading (degrees from east, anticlockwise) of cycle k: due east, or a
    lawnmower of 6-cycle legs east and west joined by one cycle north."""
    if path == "straight":
        return 0.0
    phase = k % 14
    return 90.0 if phase in (6, 13) else (0.0 if phase < 6 else 180.0)


def _full_covariance_config():
    """``gao_sea`` with every beacon DVL error on and nothing else, ``beacon_covariance="full"``."""
    return coopnav_env.make_config(
        "gao_sea",
        **{
            **QUIET,
            "beacon_dvl_heading_bias_std_deg": 0.5,
            "beacon_dvl_heading_cycle_deg": 1.0,
            "beacon_dvl_scale_error_std": 0.01,
            "dvl_velocity_noise_mps": 0.026,
            "beacon_covariance": "full",
        },
    )


def _drive_legs(sim, path, k):
    """Step ``sim`` once at cycle k of ``path`` (``_leg_heading_deg``), full speed."""
    a = np.radians(_leg_heading_deg(path, k))
    sim.step(np.broadcast_to(np.array([np.cos(a), np.sin(a)]), (sim.state.batch_size, 1, 2)))


@pytest.mark.parametrize("path", ["straight", "lawnmower"])
def test_carried_covariance_matrix_matches_the_monte_carlo_error(path):
    """Eq. N1 (``beacon_nav.covariance_deviator_m2``, ``beacon_covariance="full"``): the heading
    errors displace the beacon across its track, so its error covariance is not isotropic. Over 4000 episodes (each its
    own compass bias, one-cycle phase, scale error and noise) the error's 2x2 covariance E[e e^T]
    equals the carried [[m + a, c], [c, m - a]] (minus the start fix's I2), entry by entry,
    within 8 % of its largest entry; the isotropic m alone is off by 1.3x or more across the track
    and 0.7x along it (here 1.41x and 0.62x straight, where the white walk is a larger share,
    1.93x and 0.08x on the lawnmower, as a review measured: 1.9x and 0.07x)."""
    B = 4000
    c = _full_covariance_config()
    sim = make_simulator(c, B)
    sim.reset(np.arange(B) + 31000)
    err0 = sim.state.b_nav_err[:, 0, :2].copy()
    for k in range(28):
        _drive_legs(sim, path, k)
    st = sim.state
    e = st.b_nav_err[:, 0, :2] - err0
    mc = e.T @ e / B
    m, dev = st.b_nav_var_m2[:, 0] - 1.0, st.b_nav_dev_m2[:, 0]
    carried = np.array([[np.mean(m + dev.real), np.mean(dev.imag)], [np.mean(dev.imag), np.mean(m - dev.real)]])
    assert np.abs(mc - carried).max() < 0.08 * np.abs(carried).max(), (mc, carried)
    # across the track (north-south on these east-west legs) the isotropic m is far off
    assert mc[1, 1] / np.mean(m) > 1.3 and mc[0, 0] / np.mean(m) < 0.7, (mc, np.mean(m))
    # the default, "isotropic", carries and sends m alone: the same m, no deviator
    iso = make_simulator(c.replace(beacon_covariance="isotropic"), 8)
    iso.reset(np.arange(8) + 31000)
    for k in range(28):
        _drive_legs(iso, path, k)
    np.testing.assert_array_equal(iso.state.b_nav_var_m2, st.b_nav_var_m2[:8])
    assert np.all(iso.state.b_nav_dev_m2 == 0.0)


def test_cross_covariance_between_pings_matches_the_monte_carlo_error():
    """Eq. N2 (``consider.error_model_covariance``): the covariance of the beacon's error at two
    pings 14 cycles apart on the lawnmower, one leg east and one west between them (its heading
    errors' part turned with the track), from the error model's state the pings carry, against
    the Monte Carlo E[e2 e1^T] over 4000 episodes, entry by entry within 8 % of the largest.
    Eq. C7's random walk would have it Sigma1, the first ping's covariance: across these legs
    (north) that is 12.4 m^2 where the errors share 25.8 m^2, as a bias that grew."""
    from coopnav_env.core.consider import error_model_covariance
    from coopnav_env.core.measurements.modem import ModemRanging

    B = 4000
    c = _full_covariance_config()
    sim = make_simulator(c, B)
    sim.reset(np.arange(B) + 52000)
    model = ModemRanging(sim).params.error_model

    def state_now():
        st = sim.state
        d = st.b_pos[:, 0, 0] + st.b_nav_err[:, 0, 0] + 1j * (st.b_pos[:, 0, 1] + st.b_nav_err[:, 0, 1])
        d = d - st.b_fix_est[:, 0]
        g = st.b_turn_sum_m[:, 0]
        m = [d.real, d.imag, st.b_travelled_m[:, 0], g.real, g.imag, st.b_unlocked_s[:, 0], st.b_walk_var_m2[:, 0]]
        return np.stack(m, axis=1), st.b_nav_err[:, 0, :2].copy()

    saved = {}
    for k in range(26):
        _drive_legs(sim, "lawnmower", k)
        if k in (10, 24):
            saved[k] = state_now()
    (m1, e1), (m2, e2) = saved[10], saved[24]
    mc = e2.T @ e1 / B  # rows: the later ping's east, north
    model_c = np.mean([error_model_covariance(m2[i], m1[i], model) for i in range(B)], axis=0).reshape(2, 2)
    assert np.abs(mc - model_c).max() < 0.08 * np.abs(model_c).max(), (mc, model_c)
    # eq. C7's random walk (phi = 1) takes Cov(b2, b1) for Sigma1, the covariance at the first ping
    sigma1 = np.mean([error_model_covariance(m1[i], m1[i], model) for i in range(B)], axis=0).reshape(2, 2)
    assert np.abs(mc - sigma1).max() > 0.3 * np.abs(model_c).max(), (mc, sigma1)


def test_covariance_deviator_hand_values():
    """Eq. N1 by hand. A straight run north of s = 100 m (D = 100i, G = s) with only the one-cycle
    compass error b1: Sigma_xx = b1^2 s^2 / 2 (all of it across the track, east), Sigma_yy = 0,
    so a = b1^2 s^2 / 4 = m and c = 0. The constant errors on D = 100 (east) with sigma_k = 0.02,
    sigma_b0 = 0.01: along the track sigma_k^2 |D|^2 = 4, across sigma_b0^2 |D|^2 = 1, so
    a = (4 - 1) / 2 = 1.5. On whole orbits (G = 0) the one-cycle part is isotropic."""
    b1 = np.radians(1.0)
    dev = covariance_deviator_m2(0.0, 100j, b1, 100.0, 100.0 + 0j)
    assert dev.real == pytest.approx(b1**2 * 100.0**2 / 4.0) and dev.imag == 0.0
    assert heading_cycle_variance_m2(b1, 100.0, 100.0 + 0j) == pytest.approx(dev.real)  # m = a: Sigma_yy = 0
    dev = covariance_deviator_m2(0.02**2 - 0.01**2, 100.0 + 0j, 0.0, 100.0, 100.0 + 0j)
    assert dev == pytest.approx(1.5)
    # at 45 degrees the along/across difference turns into the correlation c
    dev = covariance_deviator_m2(0.02**2 - 0.01**2, 100.0 * np.exp(1j * np.pi / 4), 0.0, 100.0, 0j)
    assert dev.real == pytest.approx(0.0, abs=1e-12) and dev.imag == pytest.approx(1.5)
    assert covariance_deviator_m2(0.0, 0j, b1, 300.0, 0j) == 0.0


def test_surfacing_on_a_clock_resets_to_a_gps_fix():
    overrides = dict(beacon_dvl_heading_bias_std_deg=2.0, beacon_surface_every_s=100.0, beacon_surfacing="instant")
    c = coopnav_env.make_config("gao_sea", **{**QUIET, **overrides})
    sim = make_simulator(c, 64)
    sim.reset(np.arange(64))
    for k in range(1, 11):
        sim.step(np.broadcast_to(EAST, (64, 1, 2)))
        st = sim.state
        surfaced = k % 5 == 0  # every 100 s = 5 cycles of 20 s
        assert bool(st.b_surfacings.all()) == surfaced and not (st.b_surfacings.any() and not surfaced)
        if surfaced:
            np.testing.assert_allclose(st.b_nav_var_m2, c.gps_noise_m**2)
            err = np.hypot(st.b_nav_err[:, 0, 0], st.b_nav_err[:, 0, 1])
            assert np.sqrt((err**2).mean() / 2) == pytest.approx(c.gps_noise_m, rel=0.25)
        elif k > 5:  # after the first fix the variance grows from the GPS's again
            assert (st.b_nav_var_m2 > c.gps_noise_m**2).all()


def test_surfacing_when_the_own_std_exceeds_the_threshold():
    overrides = dict(beacon_dvl_heading_bias_std_deg=2.0, beacon_surface_above_std_m=4.0, beacon_surfacing="instant")
    c = coopnav_env.make_config("gao_sea", **{**QUIET, **overrides})
    sim = make_simulator(c, 8)
    sim.reset(np.arange(8))
    surfaced = 0
    for _ in range(60):
        sim.step(np.broadcast_to(EAST, (8, 1, 2)))
        assert (sim.state.b_nav_var_m2 <= 4.0**2 + 1e-9).all()  # never carried above the threshold
        surfaced += int(sim.state.b_surfacings.sum())
    assert surfaced > 8


def test_the_lake_trial_beacon_has_gps_every_cycle():
    c = coopnav_env.make_config("gao_lawnmower")
    assert c.beacon_surface_every_s == c.ping_interval_s
    sim = make_simulator(c, 4)
    sim.reset(np.arange(4))
    sim.step(np.zeros((4, 1, 2)))
    np.testing.assert_allclose(sim.state.b_nav_var_m2, c.gps_noise_m**2)


# ----------------------------------------------------------------------------------
# What surfacing costs (core/beacon_nav.py)
# ----------------------------------------------------------------------------------
def test_a_timed_surfacing_hand_timeline():
    """Beacon at 2 m, 0.5 m/s up and down, 30 s dwell, no ranging above 1 m, a fix due
    every 100 s, 20 s cycles. Due at the end of cycle 5 (100 s since the start fix): the
    ascent begins. From there: at the surface at 4 s, fix at 34 s, back at 2 m at 38 s;
    above 1 m from 2 s to 36 s. Cycle 6 covers 0-20 s: away 18 s, at the surface at its
    end (no ping, no reply); cycle 7 covers 20-40 s: away 16 s, the fix, back at depth.
    The next fix is due 100 s after it (cycle 12), taken at cycle 14: a fix every 140 s
    (25.7 an hour) where the instant model took one every 100 s (36 an hour)."""
    B = 16
    c = coopnav_env.make_config(
        "gao_sea",
        **{
            **QUIET,
            "beacon_dvl_heading_bias_std_deg": 2.0,
            "beacon_surface_every_s": 100.0,
            "beacon_auv_depth_m": 2.0,
            "beacon_vertical_speed_mps": 0.5,
            "beacon_surface_dwell_s": 30.0,
            "beacon_ranging_min_depth_m": 1.0,
            "beacon_start_distance_m": 30.0,
            "packet_loss_near": 0.0,
            "packet_loss_far": 0.0,
        },
    )
    sim = make_simulator(c, B)
    sim.reset(np.arange(B))
    away, fixes, depth, fused, age = [], [], [], [], []  # fused: ranges fused or gated out
    for _ in range(15):
        res = sim.step(np.zeros((B, 1, 2)))  # holds station near the survey start
        st = sim.state
        away.append(res.beacon_info["beacon_away_s"][:, 0].copy())
        fixes.append(st.b_surfacings[:, 0].copy())
        depth.append(st.b_pos[:, 0, 2].copy())
        fused.append(res.info["ranges_fused"].sum(-1) + res.info["outliers_rejected"].sum(-1))
        age.append(st.k_age_s[:, 0, 0].copy())
    away, fixes, depth, fused, age = map(np.array, (away, fixes, depth, fused, age))  # (cycle, B)
    expect_away = np.zeros(15)
    expect_away[[5, 12]] = 18.0  # cycles 6 and 13 (index = cycle - 1)
    expect_away[[6, 13]] = 16.0
    np.testing.assert_allclose(away, np.repeat(expect_away[:, None], B, 1), atol=1e-9)
    np.testing.assert_array_equal(fixes.sum(1) > 0, np.isin(np.arange(1, 16), [7, 14]))
    assert (fixes[[6, 13]] == 1).all()
    np.testing.assert_allclose(depth[[5, 12]], 0.0)
    np.testing.assert_allclose(np.delete(depth, [5, 12], 0), 2.0)
    assert (fused[[5, 12]] == 0).all()  # away: its pings are not sent
    assert (fused[[4, 6, 11, 13]] > 0).all()  # at depth, without losses: every ping arrives
    assert (age[5] == age[4] + c.ping_interval_s).all()  # away: no reply heard


def test_a_dwell_ending_at_a_cycles_end_fixes_in_that_cycle():
    """The fix falls in (t0, t1]: with 20 s cycles, a 10 m ascent at 1 m/s and a 10 s dwell
    the fix is at 20 s, the end of the excursion's first cycle, and is taken there (not a
    cycle late, as an open interval would have it); the second cycle (20-40 s) has none. Up at
    10 s, back at depth at 30 s; above the 5 m ranging depth from 5 s to 25 s."""
    from coopnav_env.core.beacon_nav import _surface, nav_params, surfacing_times

    c = coopnav_env.make_config(
        "gao_sea",
        **{
            **QUIET,
            "beacon_vertical_speed_mps": 1.0,
            "beacon_surface_dwell_s": 10.0,
            "beacon_ranging_min_depth_m": 5.0,
        },
    )
    prm = nav_params(c, 20)
    assert prm.T == 20.0
    times = tuple(float(t[0]) for t in surfacing_times([10.0], 1.0, 10.0, 5.0))
    assert times == (10.0, 20.0, 30.0, 5.0, 25.0)
    fix, away_s, on, t0, depth, away = _surface(True, 0.0, False, times, 10.0, prm)
    assert fix and away_s == 15.0 and on and t0 == 20.0 and depth == 0.0 and away
    fix, away_s, on, t0, depth, away = _surface(True, 20.0, False, times, 10.0, prm)
    assert not fix and away_s == 5.0 and not on and depth == 10.0 and not away


def test_a_beacon_at_the_surface_with_no_dwell_takes_its_fix():
    """A beacon AUV at 0 m with a 0 s dwell (both allowed) has its fix at the excursion's
    start: before, a fix in (t0, t1] never came, so it began a surfacing every cycle and was
    never fixed (a review). Now: due every 100 s, fixed at the first cycle of each excursion."""
    c = coopnav_env.make_config(
        "gao_sea",
        **{**QUIET, "beacon_surface_every_s": 100.0, "beacon_auv_depth_m": 0.0, "beacon_surface_dwell_s": 0.0},
    )
    sim = make_simulator(c, 2)
    sim.reset(np.arange(2))
    fixes = []
    for _ in range(15):
        sim.step(np.zeros((2, 1, 2)))
        fixes.append(sim.state.b_surfacings[:, 0].copy())
    fixes = np.array(fixes)
    assert (fixes == fixes[:, :1]).all()
    got = np.flatnonzero(fixes[:, 0]) + 1  # the cycles with a fix
    assert len(got) >= 2 and np.all(np.diff(got) >= 100.0 / c.ping_interval_s), got


def test_an_instant_surfacing_keeps_the_old_model():
    c = coopnav_env.make_config("gao_sea", **{**QUIET, "beacon_surface_every_s": 100.0, "beacon_surfacing": "instant"})
    sim = make_simulator(c, 2)
    sim.reset(np.arange(2))
    for k in range(1, 11):
        res = sim.step(np.zeros((2, 1, 2)))
        assert (sim.state.b_surfacings[:, 0] == (k % 5 == 0)).all()
        assert (res.beacon_info["beacon_away_s"] == 0).all()
        np.testing.assert_allclose(sim.state.b_pos[:, 0, 2], c.beacon_auv_depth_m)


def test_dvl_lock_probabilities_from_the_altitude_hand_values():
    """a_max 20 m, the last 20 % (4 m) fading: at 18 m altitude the ramp is (18 - 16) / 4
    = 0.5, p_loss = 0.02 + 0.98 x 0.5 = 0.51, p_regain = 0.5 x 0.5 = 0.25; at 10 m the
    base 0.02 and 0.5; above 20 m or below 0.05 m no lock (1, 0)."""
    from coopnav_env.core.beacon_nav import dvl_lock_probabilities

    loss, regain = dvl_lock_probabilities(np.array([18.0, 10.0, 16.0, 20.0, 25.0, 0.01]), 0.05, 20.0, 0.2, 0.02, 0.5)
    np.testing.assert_allclose(loss, [0.51, 0.02, 0.02, 1.0, 1.0, 1.0])
    np.testing.assert_allclose(regain, [0.25, 0.5, 0.5, 0.0, 0.0, 0.0])


def test_bottom_lock_is_lost_near_the_dvls_range_limit():
    """The simulator's lock after one cycle from lock at 18 m altitude (20 m water, beacon
    at 2 m, a 20 m DVL): lost with probability 0.51 (hand value above); with 1000 m of
    water (out of range) always; with the old fixed model 0.02 whatever the altitude."""
    B = 4000

    def lost_fraction(**overrides):
        c = coopnav_env.make_config("gao_sea", **{**QUIET, "dvl_lock_loss_probability": 0.02, **overrides})
        sim = make_simulator(c, B)
        sim.reset(np.arange(B))
        sim.step(np.zeros((B, 1, 2)))
        return 1.0 - sim.state.b_dvl_lock.mean()

    sd = np.sqrt(0.25 / B)
    near = dict(water_depth_m=20.0, beacon_auv_depth_m=2.0, dvl_max_altitude_m=20.0, dvl_lock_fade_fraction=0.2)
    assert abs(lost_fraction(**near) - 0.51) < 4 * sd
    assert lost_fraction(water_depth_m=1000.0) == 1.0
    assert abs(lost_fraction(water_depth_m=1000.0, dvl_lock_model="fixed") - 0.02) < 4 * np.sqrt(0.02 * 0.98 / B)


# ----------------------------------------------------------------------------------
# The ASVs follow their commands as the boats do (dynamics.disturb_boats)
# ----------------------------------------------------------------------------------
def _asv_cycle(B=1, **overrides):
    c = coopnav_env.make_config("sousa_asv", **overrides)
    sim = make_simulator(c, B)
    sim.reset(np.arange(B))
    return c, sim


def test_asv_surge_and_course_errors_hand_values():
    """Commanded due east at full speed v = 2 m/s from a standstill: with only the surge
    error s0 (its start value) the ASV makes good an extra s0 h T along its heading h over
    the 20 s cycle; with only a course error delta it makes good v e^{-i delta}, i.e.
    v (e^{-i delta} - 1) T off the commanded track."""
    east = np.array([[[1.0, 0.0]]])
    quiet = dict(current_speed_mps=0.0, current_speed_spread_mps=0.0, current_gm_std_mps=0.0)
    c, ref = _asv_cycle(**quiet, asv_surge_noise_mps=0.0, asv_steering_noise_deg=0.0)
    p0 = ref.state.b_pos[0, 0, :2].copy()
    ref.step(east)
    commanded = ref.state.b_pos[0, 0, :2] - p0
    h = ref.state.b_heading[0, 0]
    T = c.ping_interval_s

    _, sim = _asv_cycle(**quiet, asv_surge_noise_mps=0.3, asv_steering_noise_deg=0.0)
    s0 = sim.state.b_surge[0, 0]
    assert s0 != 0.0
    sim.step(east)
    got = sim.state.b_pos[0, 0, :2] - p0
    np.testing.assert_allclose(got - commanded, [s0 * h.real * T, s0 * h.imag * T], atol=1e-9)

    _, sim = _asv_cycle(**quiet, asv_surge_noise_mps=0.0, asv_steering_noise_deg=5.0)
    d0 = sim.state.b_steer[0, 0]
    sim.step(east)
    got = sim.state.b_pos[0, 0, :2] - p0
    v = ref.state.b_vel[0, 0, 0] + 1j * ref.state.b_vel[0, 0, 1]
    off = v * (np.exp(-1j * d0) - 1.0) * T
    np.testing.assert_allclose(got - commanded, [off.real, off.imag], atol=1e-9)


def test_disturb_boats_turns_the_command_not_the_current_by_hand():
    """``dynamics.disturb_boats`` with a course error and a current at once: commanded 2 m/s
    east (v = 2), course off by delta = 10 degrees clockwise, current c = 0.5 + 0.3i m/s of
    which r = 0.4 is not cancelled. Made good: v e^{-i delta} + r c = 2 (cos 10, -sin 10) +
    (0.2, 0.12) = (2.16962, -0.22729) m/s, the current's share not turned with the course
    (turned, it would be (2.18741, -0.26385)); over T = 20 s the position moves by the
    difference from the command, (3.3923, -4.5459) m."""
    from coopnav_env.core.dynamics import disturb_boats

    pos, vel = np.zeros((1, 1, 3)), np.array([[[2.0, 0.0, 0.0]]])
    delta = np.radians(10.0)
    disturb_boats(
        pos, np.array([[1.0 + 0j]]), vel, np.zeros((1, 1)), np.array([[delta]]), np.array([[0.5 + 0.3j]]), 0.4, 20.0
    )
    made_good = 2.0 * np.exp(-1j * delta) + 0.4 * (0.5 + 0.3j)
    np.testing.assert_allclose(vel[0, 0, :2], [made_good.real, made_good.imag], atol=1e-12)
    np.testing.assert_allclose(vel[0, 0, :2], [2.16962, -0.22729], atol=1e-5)
    np.testing.assert_allclose(pos[0, 0, :2], [(made_good.real - 2.0) * 20.0, made_good.imag * 20.0], atol=1e-12)
    np.testing.assert_allclose(pos[0, 0, :2], [3.3923, -4.5459], atol=1e-4)


def test_asv_errors_are_the_boats_gauss_markov_processes():
    """Over many ASVs and cycles the surge error's std is asv_surge_noise_mps and its
    one-cycle correlation exp(-T / tau) = exp(-20 / 30) = 0.513 (20 s cycles here)."""
    B = 2000
    _, sim = _asv_cycle(B, ping_interval_s=20.0)
    s = []
    for _ in range(6):
        sim.step(np.zeros((B, 1, 2)))
        s.append(sim.state.b_surge[:, 0].copy())
    s = np.array(s)
    assert s.std() == pytest.approx(0.15, rel=0.05)
    rho = np.mean(s[1:] * s[:-1]) / np.mean(s**2)
    assert rho == pytest.approx(np.exp(-20.0 / 30.0), abs=0.03)


def test_a_beacon_away_sends_no_mls_ping_either():
    """swarm_mls's beacon at 5 m, 2 s cycles, a fix due every 10 s: the ascent begins at
    the end of cycle 5; above 1 m from 8 s to 42 s into it (fix at 40 s), so away at the
    ends of cycles 10 to 25, when nothing is fused from it."""
    B = 4
    c = coopnav_env.make_config("swarm_mls", beacon_surface_every_s=10.0)
    assert c.ping_interval_s == 2.0 and c.beacon_auv_depth_m == 5.0
    sim = make_simulator(c, B)
    sim.reset(np.arange(B))
    fused, away = [], []
    for _ in range(27):
        res = sim.step(np.zeros((B, c.n_beacons, 2)))
        fused.append(res.info["ranges_fused"].sum(-1))
        away.append(sim.state.b_away[:, 0].copy())
    fused, away = np.array(fused), np.array(away)
    np.testing.assert_array_equal(away.all(1), np.isin(np.arange(1, 28), np.arange(10, 26)))
    assert (fused[9:25] == 0).all()
    assert fused[:8].sum() > 0


def test_a_turn_limit_of_half_a_turn_or_more_per_substep_is_no_limit():
    """The limit per sub-step is rate x sub-step, at most pi: at 360 deg/s and 1 s sub-steps
    its cosine and sine were those of 0, and the vehicle never turned (a review). Now it
    points straight at the target, as any limit of pi or more should; the defaults are
    unchanged."""
    from coopnav_env.core.dynamics import max_turn_per_substep_rad, turn_toward

    assert max_turn_per_substep_rad(360.0, 1.0) == np.pi
    assert max_turn_per_substep_rad(30.0, 1.0) == np.radians(30.0)  # the ASVs' default, exactly
    a = float(max_turn_per_substep_rad(360.0, 1.0))
    heading, desired = 1j, -1j  # north, and a target due south
    assert turn_toward(heading, desired, np.cos(a), np.sin(a)) == -1j
    c = coopnav_env.make_config("sousa_asv", asv_max_turn_rate_dps=360.0)
    sim = make_simulator(c, 1)
    sim.reset([0])
    assert sim._beacon_turn_cos[0] == -1.0


def _error_model_draws(legs_deg, n, rng, sk, sb0, b1, sc, unlocked_s, walk1, walk2):
    """The beacon AUV's dead-reckoning error model written out per cycle, as ``_navigate``
    draws it, over ``n`` episodes: each cycle's displacement d (20 m at bearing theta) becomes
    ((1 + k) e^{-i beta} - 1) d with beta = b0 + b1 sin(theta + phase), plus the told current's
    error c times the time without lock, plus a white part (per-axis variance walk1 at the
    first ping, walk2 at the second; the increments independent). Returns the error at the
    middle of the track and at its end (complex, east + i north), and the error-model states
    (D, s, G, T, w) the pings would carry there."""
    k = sk * rng.standard_normal(n)
    b0 = sb0 * rng.standard_normal(n)
    phase = rng.uniform(0.0, 2.0 * np.pi, n)
    c = sc * (rng.standard_normal(n) + 1j * rng.standard_normal(n))
    u1 = np.sqrt(walk1) * (rng.standard_normal(n) + 1j * rng.standard_normal(n))
    u12 = np.sqrt(walk2 - walk1) * (rng.standard_normal(n) + 1j * rng.standard_normal(n))
    half = len(legs_deg) // 2
    z, D, s, G, out = np.zeros(n, complex), 0j, 0.0, 0j, []
    for i, theta in enumerate(np.radians(legs_deg), start=1):
        d = 20.0 * (np.sin(theta) + 1j * np.cos(theta))  # bearing theta from north, clockwise
        z = z + ((1.0 + k) * np.exp(-1j * (b0 + b1 * np.sin(theta + phase))) - 1.0) * d
        D, s, G = D + d, s + 20.0, G + 20.0 * np.exp(-2j * theta)  # G = sum |d| e^{-2i theta}
        if i in (half, len(legs_deg)):
            T, w = (unlocked_s[0], walk1) if i == half else (unlocked_s[1], walk2)
            noise = u1 if i == half else u1 + u12
            out.append((z + c * T + noise, np.array([D.real, D.imag, s, G.real, G.imag, T, w])))
    return out


def test_the_error_model_on_a_curved_track_matches_its_own_monte_carlo():
    """Eqs. N1 and N2 on a track that is neither north-south nor east-west (legs at bearings
    45-250 degrees, so G is complex and the track turns), with every error at once: against
    the model's own Monte Carlo (200,000 episodes of the per-cycle error ``_navigate`` draws,
    written out here), the carried covariance [[m + a, c], [c, m - a]] at a ping and the
    cross-covariance Cov(b2, b1) of two pings, entry by entry within 3 % of the largest. The
    earlier Monte Carlo tests drove axis-aligned legs, where G is real: there a conjugate
    slipped onto G (eq. N1's b1^2 s G / 4, or N2's s2 G1 + G2 s1) or a factor lost on the told
    current's 2 sigma_c^2 T2 T1 changed nothing they measured (a mutation review, 2026-12-07)."""
    from coopnav_env.core.beacon_nav import error_model
    from coopnav_env.core.consider import error_model_covariance

    sk, sb0_deg, b1_deg, sc = 0.02, 0.3, 2.0, 0.02
    cfg = _full_covariance_config().replace(
        beacon_dvl_scale_error_std=sk,
        beacon_dvl_heading_bias_std_deg=sb0_deg,
        beacon_dvl_heading_cycle_deg=b1_deg,
        beacon_current_estimate_error_mps=sc,
    )
    model = error_model(cfg)
    assert model.sigma2_sum == pytest.approx(sk**2 + np.radians(sb0_deg) ** 2)
    legs = [45.0] * 5 + [120.0, 165.0, 210.0, 250.0, 250.0]
    rng = np.random.default_rng(20261207)
    walk1, walk2, unlocked = 0.1, 0.2, (60.0, 120.0)
    (e1, m1), (e2, m2) = _error_model_draws(
        legs, 200_000, rng, sk, np.radians(sb0_deg), np.radians(b1_deg), sc, unlocked, walk1, walk2
    )

    def cov(a, b):  # E[a b^T] of two complex errors as 2x2 (rows: a's east, north)
        A, B = np.stack([a.real, a.imag]), np.stack([b.real, b.imag])
        return A @ B.T / a.size

    for e, m in ((e1, m1), (e2, m2)):  # eq. N1: the covariance each ping carries
        D, s, G, T, w = m[0] + 1j * m[1], m[2], m[3] + 1j * m[4], m[5], m[6]
        b1 = np.radians(b1_deg)
        var = w + (sc * T) ** 2 + 0.5 * model.sigma2_sum * abs(D) ** 2 + heading_cycle_variance_m2(b1, s, G)
        dev = covariance_deviator_m2(model.sigma2_diff, D, b1, s, G)
        carried = np.array([[var + dev.real, dev.imag], [dev.imag, var - dev.real]])
        mc = cov(e, e)
        assert abs(dev.imag) > 0.1 * abs(carried).max(), carried  # a correlation a slipped conjugate flips
        assert np.abs(mc - carried).max() < 0.03 * np.abs(carried).max(), (mc, carried)
        np.testing.assert_allclose(np.reshape(error_model_covariance(m, m, model), (2, 2)), carried, rtol=1e-12)
    mc = cov(e2, e1)
    model_c = np.reshape(error_model_covariance(m2, m1, model), (2, 2))
    assert np.abs(mc - model_c).max() < 0.03 * np.abs(model_c).max(), (mc, model_c)
    # the told current's share is large enough that half of it would show: 2 sc^2 T2 T1 / 2 per axis
    assert (sc**2 * unlocked[0] * unlocked[1]) > 0.1 * np.abs(model_c).max()
