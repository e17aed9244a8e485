"""The beacon AUV's own navigation: DVL dead reckoning that drifts with distance
travelled (compass error b0 + b1 sin(heading + phase), velocity scale error), the
variance it carries into the survey filters' R, and GPS fixes at the surface."""

from __future__ import annotations

import numpy as np
import pytest

import coopnav_env
from coopnav_env.core import make_simulator

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


def test_surfacing_on_a_clock_resets_to_a_gps_fix():
    overrides = dict(beacon_dvl_heading_bias_std_deg=2.0, beacon_surface_every_s=100.0)
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
    overrides = dict(beacon_dvl_heading_bias_std_deg=2.0, beacon_surface_above_std_m=4.0)
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
