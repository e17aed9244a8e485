"""Physics and geometry of the coopnav core checked against hand-computed values.

Every expected number here is worked out independently of the code under test:
published check values, closed-form hand solutions, or an independent library
(scipy's ODE solver, scipy's rotations, numpy's eigen-decomposition, a numpy
random Generator). Where a value was computed by hand, the arithmetic is shown.
"""

import numpy as np
import pytest
from ping_harness import fuse_one_ping
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation
from scipy.stats import kstest

from coopnav_env.core import acoustics, dynamics, guidance, information, rng
from coopnav_env.scenarios import make_config


# ----------------------------------------------------------------------------------
# Mackenzie (1981) sound speed, shared/reference-values.md section 4
# ----------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "t, s, d, expected, tol",
    [
        # Published check values.
        (10.0, 35.0, 0.0, 1489.8, 0.05),  # the usual quoted value, 1489.8 m/s
        (25.0, 35.0, 1000.0, 1550.744, 5e-4),  # Mackenzie (1981)'s own check value
        # Computed by hand from the formula in reference-values.md section 4:
        # 25 C, 35 ppt, 0 m: 1448.96 + 4.591*25 - 5.304e-2*625 + 2.374e-4*15625
        #   = 1448.96 + 114.775 - 33.15 + 3.709375 = 1534.294375
        (25.0, 35.0, 0.0, 1534.294375, 1e-6),
        # 29 C, 30 ppt, 0 m: 1448.96 + 133.139 - 44.60664 + 5.7899486
        #   + 1.340*(-5) - 1.025e-2*29*(-5) = 1538.0685586 (ref-values: ~1538 m/s)
        (29.0, 30.0, 0.0, 1538.0685586, 1e-6),
        # 28 C, 30 ppt, 3 m (gao_lawnmower water): 1448.96 + 128.548 - 41.58336
        #   + 5.2114048 - 6.7 + 0.0489 + 1.675e-7*9 + 1.435 - 7.139e-13*28*27
        #   = 1535.9199463 (to 1e-7)
        (28.0, 30.0, 3.0, 1535.9199463, 1e-6),
    ],
)
def test_mackenzie_check_values(t, s, d, expected, tol):
    assert float(acoustics.mackenzie_sound_speed(t, s, d)) == pytest.approx(expected, abs=tol)


def test_mackenzie_broadcasts():
    t = np.array([10.0, 25.0])[:, None]
    d = np.array([0.0, 1000.0])[None, :]
    c = acoustics.mackenzie_sound_speed(t, 35.0, d)
    assert c.shape == (2, 2)
    assert c[0, 0] == pytest.approx(1489.8034, abs=1e-4)  # 1448.96+45.91-5.304+0.2374
    assert c[1, 0] == pytest.approx(1534.294375, abs=1e-6)
    assert c[1, 1] == pytest.approx(1550.744, abs=5e-4)


# ----------------------------------------------------------------------------------
# travel time between a fixed sender and a moving receiver
# ----------------------------------------------------------------------------------
C = 1500.0


def test_travel_time_static_receiver():
    # 3-4-5 triangle: 500 m at 1500 m/s is exactly 1/3 s.
    tau = acoustics.travel_time_s(np.zeros(3), np.array([300.0, 400.0, 0.0]), np.zeros(3), C)
    assert float(tau) == pytest.approx(1.0 / 3.0, rel=1e-14)


@pytest.mark.parametrize("v, rtol", [(2.0, 1e-10), (-2.0, 1e-10), (3.0, 1e-10), (10.0, 1e-8)])
def test_travel_time_radial_receiver(v, rtol):
    # Receiver moving radially (away for v > 0) at v: c tau = d + v tau, so tau = d / (c - v).
    # The code iterates a fixed point 3 times: its error shrinks by v/c per iteration, so
    # the relative error is ~(v/c)^4: 3e-12 at 2 m/s (1.5 nm of range), 2e-9 at 10 m/s.
    d = 500.0
    unit = np.array([0.6, 0.8, 0.0])
    tau = acoustics.travel_time_s(np.zeros(3), d * unit, v * unit, C)
    assert float(tau) == pytest.approx(d / (C - v), rel=rtol)


def test_travel_time_tangential_receiver():
    # Moving at right angles to the line of sight: (c tau)^2 = d^2 + (v tau)^2,
    # so tau = d / sqrt(c^2 - v^2).
    d, v = 800.0, 3.0
    tau = acoustics.travel_time_s(
        np.array([10.0, 20.0, 5.0]), np.array([10.0 + d, 20.0, 5.0]), np.array([0.0, v, 0.0]), C
    )
    assert float(tau) == pytest.approx(d / np.sqrt(C**2 - v**2), rel=1e-10)


def test_travel_time_batched():
    d = np.array([100.0, 500.0, 1500.0])
    v = np.array([0.0, 1.5, -1.0])
    recv = np.stack([np.zeros(3), np.zeros(3), d], -1)  # straight down
    vel = np.stack([np.zeros(3), np.zeros(3), v], -1)
    tau = acoustics.travel_time_s(np.zeros(3), recv, vel, np.array([1480.0, 1500.0, 1520.0]))
    np.testing.assert_allclose(tau, d / (np.array([1480.0, 1500.0, 1520.0]) - v), rtol=1e-10)


# ----------------------------------------------------------------------------------
# packet loss
# ----------------------------------------------------------------------------------
def test_packet_loss_probability():
    near, far, rmax = 0.05, 0.5, 1500.0
    r = np.array([0.0, 750.0, 1500.0, 1500.01, 5000.0])
    p = acoustics.packet_loss_probability(r, near, far, rmax)
    # 0 m: near; half range: near + (far - near)/4 = 0.1625; max: far; beyond: 1
    np.testing.assert_allclose(p, [0.05, 0.1625, 0.5, 1.0, 1.0], atol=1e-15)
    # monotone in range up to max range
    rr = np.linspace(0, rmax, 101)
    assert np.all(np.diff(acoustics.packet_loss_probability(rr, near, far, rmax)) >= 0)


# ----------------------------------------------------------------------------------
# thrust model, Gao & Chitre eq. (1): m du/dt = T - k u^2
# ----------------------------------------------------------------------------------
# k = 1/2 Cd rho A = 0.5 * 0.42 * 1026 * 0.0284 = 6.119064 kg/m (ref-values section 1)
K_DRAG = 6.119064
MASS = 45.0


def test_drag_constant_and_terminal_speed():
    assert dynamics.drag_constant(0.42, 1026.0, 0.0284) == pytest.approx(K_DRAG, rel=1e-12)
    # T for 1.5 m/s: k * 1.5^2 = 13.767894 N (ref-values: "14 N at 1.5 m/s")
    assert float(dynamics.terminal_speed_mps(13.767894, K_DRAG)) == pytest.approx(1.5, rel=1e-12)
    # 14 N full thrust: sqrt(14 / 6.119064) = 1.5125910 m/s
    assert float(dynamics.terminal_speed_mps(14.0, K_DRAG)) == pytest.approx(1.5125910, abs=1e-7)
    # zero (and negative) thrust: no forward speed
    np.testing.assert_array_equal(dynamics.terminal_speed_mps(np.array([0.0, -3.0]), K_DRAG), [0.0, 0.0])


def _ode_speed(u0, thrust, times):
    sol = solve_ivp(
        lambda t, u: (thrust - K_DRAG * u * u) / MASS,
        (0.0, times[-1]),
        [u0],
        t_eval=times,
        method="DOP853",
        rtol=1e-12,
        atol=1e-12,
    )
    assert sol.success
    return sol.y[0]


@pytest.mark.parametrize(
    "u0, thrust",
    [
        (0.0, 8.4),  # from rest, 60 % of 14 N: approaches 1.1716 m/s from below
        (0.6, 13.767894),  # from below, 1.5 m/s terminal
        (2.5, 8.4),  # from above (coth branch)
        (1.5, 0.0),  # zero thrust: coasts down
        (1.5, 13.767894),  # at terminal speed: stays
    ],
)
def test_thrust_speed_profile_matches_ode(u0, thrust):
    times = np.linspace(0.5, 120.0, 60)
    got = dynamics.thrust_speed_profile(u0, thrust, K_DRAG, MASS, times)
    assert got.shape == (60,)
    np.testing.assert_allclose(got, _ode_speed(u0, thrust, times), rtol=1e-8, atol=1e-9)


def test_thrust_speed_profile_batched_and_limits():
    u0 = np.array([[0.0], [2.0]])  # (2,1)
    thrust = np.array([[0.0, 5.0, 14.0]])  # (1,3)
    times = np.array([1.0, 10.0, 1000.0])
    got = dynamics.thrust_speed_profile(u0, thrust, K_DRAG, MASS, times)
    assert got.shape == (2, 3, 3)
    for i in range(2):
        for j in range(3):
            np.testing.assert_allclose(got[i, j], _ode_speed(u0[i, 0], thrust[0, j], times), rtol=1e-8, atol=1e-9)
    # after 1000 s every thrusting case is at sqrt(T/k)
    np.testing.assert_allclose(got[:, 1:, -1], np.sqrt(np.array([5.0, 14.0]) / K_DRAG)[None, :].repeat(2, 0), rtol=1e-9)
    # zero thrust from 2 m/s: u = u0 / (1 + k u0 t / m), at t = 10 s: 2 / (1 + 6.119064*2*10/45)
    assert got[1, 0, 1] == pytest.approx(2.0 / (1.0 + K_DRAG * 2.0 * 10.0 / MASS), rel=1e-12)
    assert np.all(got[0, 0] == 0.0)  # at rest with no thrust stays at rest


# ----------------------------------------------------------------------------------
# attitude: eq. (4)-(5), body (forward, starboard, down) -> nav (east, north, down)
# ----------------------------------------------------------------------------------
def _scipy_body_to_nav(b, p, r):
    # Intrinsic Z-Y-X (yaw, pitch, roll) in NED; rows reordered to (east, north, down)
    R_ned = Rotation.from_euler("ZYX", [b, p, r]).as_matrix()
    return R_ned[[1, 0, 2]]


def test_body_to_nav_matrix_matches_scipy():
    g = np.random.default_rng(7)
    angles = np.stack([g.uniform(-np.pi, np.pi, 50), g.uniform(-1.4, 1.4, 50), g.uniform(-np.pi, np.pi, 50)], -1)
    M = dynamics.body_to_nav_matrix(angles[:, 0], angles[:, 1], angles[:, 2])
    assert M.shape == (50, 3, 3)
    for a, m in zip(angles, M):
        np.testing.assert_allclose(m, _scipy_body_to_nav(*a), atol=1e-12)
    # orthogonal, left-handed (rows swapped from a right-handed NED triad)
    np.testing.assert_allclose(M @ np.swapaxes(M, -1, -2), np.broadcast_to(np.eye(3), M.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(M), -1.0, atol=1e-12)
    # forward_axis is the first column, whatever the roll
    F = dynamics.forward_axis(angles[:, 0], angles[:, 1])
    np.testing.assert_allclose(F, M[:, :, 0], atol=1e-12)


def test_forward_axis_hand_values():
    # bearing 90 deg, level: due east
    np.testing.assert_allclose(dynamics.forward_axis(np.pi / 2, 0.0), [1.0, 0.0, 0.0], atol=1e-15)
    # bearing 0, level: due north
    np.testing.assert_allclose(dynamics.forward_axis(0.0, 0.0), [0.0, 1.0, 0.0], atol=1e-15)
    # bearing 180, 30 deg nose up: south and up (depth decreasing): (0, -cos30, -sin30)
    np.testing.assert_allclose(dynamics.forward_axis(np.pi, np.radians(30.0)), [0.0, -np.sqrt(3) / 2, -0.5], atol=1e-15)
    # heading east, rolled 90 deg starboard-down: the starboard axis points down and the
    # body's down axis points to port, which is north
    M = dynamics.body_to_nav_matrix(np.pi / 2, 0.0, np.pi / 2)
    np.testing.assert_allclose(M[:, 0], [1.0, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(M[:, 1], [0.0, 0.0, 1.0], atol=1e-15)
    np.testing.assert_allclose(M[:, 2], [0.0, 1.0, 0.0], atol=1e-15)


def test_bearing_unit_round_trip():
    b = np.array([0.0, np.pi / 2, np.pi, -np.pi / 2, 0.3])
    h = dynamics.bearing_to_unit(b)
    np.testing.assert_allclose(h, [1j, 1.0, -1j, -1.0, np.sin(0.3) + 1j * np.cos(0.3)], atol=1e-15)
    np.testing.assert_allclose(dynamics.unit_to_bearing(h), [0.0, np.pi / 2, np.pi, -np.pi / 2, 0.3], atol=1e-15)


# ----------------------------------------------------------------------------------
# turning
# ----------------------------------------------------------------------------------
def _bearing_diff(a, b):
    return np.angle(np.exp(1j * (a - b)))


def test_turn_towards_limit_and_direction():
    limit = 0.1
    h = dynamics.bearing_to_unit(0.0)  # north
    target = 5.0 * dynamics.bearing_to_unit(np.pi / 2)  # east; magnitude does not matter
    # one step: bearing 0 -> 0.1 (clockwise, the short way)
    h1 = dynamics.turn_towards(h, target, limit)
    assert float(dynamics.unit_to_bearing(h1)) == pytest.approx(0.1, abs=1e-14)
    assert abs(h1) == pytest.approx(1.0, abs=1e-14)
    # repeat: reaches east after ceil((pi/2)/0.1) = 16 steps, never more than 0.1 per step
    bearings = [0.0]
    for _ in range(20):
        h = dynamics.turn_towards(h, target, limit)
        bearings.append(float(dynamics.unit_to_bearing(h)))
    steps = np.abs(_bearing_diff(np.array(bearings[1:]), np.array(bearings[:-1])))
    assert np.all(steps <= limit + 1e-12)
    assert int(np.argmax(np.abs(_bearing_diff(np.array(bearings), np.pi / 2)) < 1e-12)) == 16
    assert bearings[-1] == pytest.approx(np.pi / 2, abs=1e-12)
    # the short way round: from 10 deg to 350 deg turns anticlockwise (bearing decreases)
    h2 = dynamics.turn_towards(
        dynamics.bearing_to_unit(np.radians(10.0)), dynamics.bearing_to_unit(np.radians(350.0)), np.radians(5.0)
    )
    assert float(np.degrees(dynamics.unit_to_bearing(h2))) == pytest.approx(5.0, abs=1e-10)
    # zero desired vector: keep heading
    h3 = dynamics.turn_towards(dynamics.bearing_to_unit(1.0), 0j, 0.5)
    assert float(dynamics.unit_to_bearing(h3)) == pytest.approx(1.0, abs=1e-14)
    # a limit of half a turn or more is no limit (before the cap, 2 pi wrapped to a limit of 0)
    for big in (np.pi, 1.5 * np.pi, 2.0 * np.pi):
        h4 = dynamics.turn_towards(dynamics.bearing_to_unit(0.0), dynamics.bearing_to_unit(np.pi), big)
        assert float(abs(dynamics.unit_to_bearing(h4))) == pytest.approx(np.pi, abs=1e-12)


def test_beacon_kernel_turns_at_the_limit_then_goes_straight():
    """A beacon heading north, told to go east at 1 m/s, turning 30 deg per 1 s sub-step:
    three sub-steps of turning (bearings 30, 60, 90 deg), then straight east."""
    from coopnav_env.core.substeps import integrate_beacons

    pos = np.zeros((1, 1, 3))
    heading = np.array([[dynamics.bearing_to_unit(0.0)]])
    vel = np.zeros((1, 1, 3))
    turn = np.radians(30.0)
    integrate_beacons(
        pos, heading, vel, np.array([[1.0 + 0.0j]]), np.array([np.cos(turn)]), np.array([np.sin(turn)]), 5, 1.0
    )
    # hand sum: sin30+sin60+1+1+1 east, cos30+cos60+0+0+0 north
    assert pos[0, 0, 0] == pytest.approx(0.5 + np.sqrt(3) / 2 + 3.0, abs=1e-12)
    assert pos[0, 0, 1] == pytest.approx(np.sqrt(3) / 2 + 0.5, abs=1e-12)
    assert float(dynamics.unit_to_bearing(heading[0, 0])) == pytest.approx(np.pi / 2, abs=1e-12)
    np.testing.assert_allclose(vel[0, 0, :2], [1.0, 0.0], atol=1e-12)
    # commanded to stop: it stays and keeps its heading
    integrate_beacons(pos, heading, vel, np.array([[0.0j]]), np.array([np.cos(turn)]), np.array([np.sin(turn)]), 5, 1.0)
    assert pos[0, 0, 0] == pytest.approx(0.5 + np.sqrt(3) / 2 + 3.0, abs=1e-12)
    assert float(dynamics.unit_to_bearing(heading[0, 0])) == pytest.approx(np.pi / 2, abs=1e-12)


def test_turn_towards_step_by_step_reaches_targets_the_short_way():
    b0 = np.array([0.0, 1.0, -2.0, 3.0])
    bd = np.array([np.pi / 2, 1.0 - 0.3, 2.5, -3.0])  # +90 deg; -0.3; across +/-pi; the short way across pi
    h = dynamics.bearing_to_unit(b0)
    prev = b0
    for _ in range(40):  # total turns needed: pi/2, 0.3, 1.783, 0.283 rad; all <= 0.05 * 40
        h = dynamics.turn_towards(h, dynamics.bearing_to_unit(bd), 0.05)
        bear = dynamics.unit_to_bearing(h)
        assert np.all(np.abs(_bearing_diff(bear, prev)) <= 0.05 + 1e-12)
        prev = bear
    np.testing.assert_allclose(np.abs(h), 1.0, atol=1e-12)
    np.testing.assert_allclose(_bearing_diff(dynamics.unit_to_bearing(h), bd), 0.0, atol=1e-12)


# ----------------------------------------------------------------------------------
# Gauss-Markov current
# ----------------------------------------------------------------------------------
def test_gauss_markov_stationary_variance():
    g = np.random.default_rng(12345)
    std, tau, dt = 0.02, 600.0, 20.0
    a = np.exp(-dt / tau)
    n_chain, n_steps = 20000, 300
    v = np.zeros(n_chain)
    v10 = None
    for k in range(n_steps):
        v_prev = v
        v = dynamics.gauss_markov_step(v, dt, tau, std, g.standard_normal(n_chain))
        if k == 9:
            v10 = v.copy()
    # transient from 0: var after n steps = std^2 (1 - a^(2n)); n = 10: 0.4866 std^2
    assert np.var(v10) == pytest.approx(std**2 * (1 - a**20), rel=0.04)
    # stationary after 300 steps (a^600 ~ 2e-9): variance std^2 (sampling error ~1 %)
    assert np.var(v) == pytest.approx(std**2, rel=0.04)
    assert np.mean(v) == pytest.approx(0.0, abs=4 * std / np.sqrt(n_chain))
    # lag-one correlation a = exp(-1/30) = 0.96722
    assert np.corrcoef(v_prev, v)[0, 1] == pytest.approx(a, abs=0.005)
    # complex values (east + 1j north, as the simulator uses) work per component
    z = dynamics.gauss_markov_step(
        np.full(n_chain, 0.01 + 0.0j), dt, tau, std, g.standard_normal(n_chain) + 1j * g.standard_normal(n_chain)
    )
    assert np.mean(z.real) == pytest.approx(0.01 * a, abs=4 * std * np.sqrt(1 - a * a) / np.sqrt(n_chain))
    assert np.std(z.imag) == pytest.approx(std * np.sqrt(1 - a * a), rel=0.04)


# ----------------------------------------------------------------------------------
# line-of-sight guidance (Matos & Cruz Fig. 5)
# ----------------------------------------------------------------------------------
def test_los_target_hand_geometry_east_segment():
    start, end, est = 0 + 0j, 100 + 0j, 30 + 10j  # P = (30, 0)
    for alpha, q_expected in [(0.0, 100 + 0j), (1.0, 30 + 0j), (0.5, 65 + 0j)]:
        q, along, length = guidance.los_target(est, start, end, alpha)
        assert q == pytest.approx(q_expected, abs=1e-12)
        assert along == pytest.approx(30.0, abs=1e-12)
        assert length == pytest.approx(100.0, abs=1e-12)


def test_los_target_hand_geometry_tilted_segment():
    # W0 = (10, 20), W1 = (70, 100): length 100, direction t = (0.6, 0.8), normal n = (-0.8, 0.6).
    # V = W0 + 50 t + 10 n = (32, 66), so P = W0 + 50 t = (40, 60).
    w0, w1, v = 10 + 20j, 70 + 100j, 32 + 66j
    cases = [
        (0.0, 70 + 100j),
        (1.0, 40 + 60j),
        (0.25, 62.5 + 90j),
    ]  # along 0.25*50 + 0.75*100 = 87.5 -> (10+52.5, 20+70)
    for alpha, q_expected in cases:
        q, along, _length = guidance.los_target(np.array([v]), np.array([w0]), np.array([w1]), alpha)
        assert q[0] == pytest.approx(q_expected, abs=1e-12)
        assert along[0] == pytest.approx(50.0, abs=1e-12)
        # |W1 Q| = alpha |W1 P|
        assert abs(w1 - q[0]) == pytest.approx(alpha * abs(w1 - (40 + 60j)), abs=1e-12)


def test_build_path_lawnmower():
    cfg = make_config("gao_lawnmower")
    assert cfg.survey_area_m == (130.0, 100.0) and cfg.lawnmower_spacing_m == 20.0
    wp, hover = guidance.build_path(cfg)
    assert not hover
    # tracks at north = 0, 20, ..., 100: 6 tracks, 2 waypoints each
    assert wp.shape == (12, 3)
    np.testing.assert_allclose(wp[0], [0.0, 0.0, cfg.depth_m])
    np.testing.assert_allclose(wp[1], [130.0, 0.0, cfg.depth_m])
    np.testing.assert_allclose(wp[2], [130.0, 20.0, cfg.depth_m])
    np.testing.assert_allclose(wp[-1], [0.0, 100.0, cfg.depth_m])  # 6th track runs west
    np.testing.assert_allclose(wp[:, 2], cfg.depth_m)
    # 6 tracks of 130 m and 5 cross legs of 20 m: 780 + 100 = 880 m
    assert guidance.path_length_m(wp) == pytest.approx(880.0, abs=1e-9)
    # a second survey vehicle: the same pattern shifted north by survey_spacing_m
    wp1, _ = guidance.build_path(cfg, vehicle_index=1)
    np.testing.assert_allclose(wp1 - wp, np.broadcast_to([0.0, cfg.survey_spacing_m, 0.0], wp.shape))
    # flown there and back: twice the length, ending at the start
    wp2, _ = guidance.build_path(cfg.replace(path_repeats=2))
    assert guidance.path_length_m(wp2) == pytest.approx(1760.0, abs=1e-9)
    np.testing.assert_allclose(wp2[-1], wp[0])


# ----------------------------------------------------------------------------------
# error ellipse and Fisher information
# ----------------------------------------------------------------------------------
def test_error_ellipse_hand_values():
    P = np.array(
        [
            [[9.0, 0.0], [0.0, 4.0]],  # major along east: 2*3 = 6, minor 2*2 = 4
            [[1.0, 0.0], [0.0, 4.0]],  # major along north
            [[2.0, 1.0], [1.0, 2.0]],
        ]
    )  # eigenvalues 3 (along NE, bearing 45 deg), 1
    major, minor, bearing = information.error_ellipse(P)
    np.testing.assert_allclose(major, [6.0, 4.0, 2 * np.sqrt(3.0)], atol=1e-12)
    np.testing.assert_allclose(minor, [4.0, 2.0, 2.0], atol=1e-12)
    np.testing.assert_allclose(bearing, [np.pi / 2, 0.0, np.pi / 4], atol=1e-12)


def test_error_ellipse_matches_eigh():
    g = np.random.default_rng(3)
    A = g.normal(size=(300, 3, 3)) * g.uniform(0.1, 20.0, size=(300, 1, 1))
    P = A @ np.swapaxes(A, -1, -2) + 0.01 * np.eye(3)  # random SPD 3x3; the ellipse uses the E/N block
    for n_sigma in (1.0, 2.0, 3.0):
        major, minor, bearing = information.error_ellipse(P, n_sigma=n_sigma)
        w, V = np.linalg.eigh(P[:, :2, :2])  # ascending
        np.testing.assert_allclose(major, n_sigma * np.sqrt(w[:, 1]), rtol=1e-9)
        np.testing.assert_allclose(minor, n_sigma * np.sqrt(w[:, 0]), rtol=1e-7, atol=1e-9)
        v = V[:, :, 1]  # major-axis eigenvector, (east, north)
        expected = np.arctan2(v[:, 0], v[:, 1])  # bearing: clockwise from north
        diff = np.mod(bearing - expected, np.pi)
        assert np.all(np.minimum(diff, np.pi - diff) < 1e-7)
        assert np.all((bearing >= 0) & (bearing < np.pi))


def test_fisher_information_right_angle_and_collinear():
    target = np.array([12.0, -7.0, 3.0])
    right = target + np.array([[25.0, 0.0, 0.0], [0.0, -60.0, 0.0]])  # beacons east and south
    J = information.fisher_information(target, right, 1.0)
    np.testing.assert_allclose(J, np.eye(2), atol=1e-15)
    assert float(information.det2(J)) == pytest.approx(1.0, abs=1e-15)
    assert float(np.linalg.det(J)) == pytest.approx(1.0, abs=1e-15)
    collinear = target + np.array([[25.0, 0.0, 0.0], [-40.0, 0.0, 0.0]])
    assert abs(float(information.det2(information.fisher_information(target, collinear, 1.0)))) < 1e-15
    # also at right angles along a diagonal, sigma 2: J = I/4, det 1/16
    diag = target + np.array([[10.0, 10.0, 0.0], [-5.0, 5.0, 0.0]])
    assert float(information.det2(information.fisher_information(target, diag, 2.0))) == pytest.approx(
        1 / 16, abs=1e-15
    )


def test_fisher_information_slant_and_batch():
    # a beacon 3 m east and 4 m deeper than the target: u = (-0.6, 0, -0.8)
    target = np.zeros(3)
    beacon = np.array([[3.0, 0.0, 4.0]])
    np.testing.assert_allclose(
        information.fisher_information(target, beacon, 1.0), [[0.36, 0.0], [0.0, 0.0]], atol=1e-15
    )
    np.testing.assert_allclose(
        information.fisher_information(target, beacon, 2.0, horizontal=False),
        np.array([[0.36, 0, 0.48], [0, 0, 0], [0.48, 0, 0.64]]) / 4,
        atol=1e-15,
    )
    # batch (B, M, 3) with per-beacon sigmas
    targets = np.zeros((2, 3))
    beacons = np.array([[[1.0, 0, 0], [0, 1.0, 0]], [[1.0, 0, 0], [0, 1.0, 0]]])
    J = information.fisher_information(targets, beacons, np.array([[1.0, 2.0], [0.5, 1.0]]))
    np.testing.assert_allclose(J, [np.diag([1.0, 0.25]), np.diag([4.0, 1.0])], atol=1e-15)


def test_logdet_horizontal_matches_slogdet():
    g = np.random.default_rng(5)
    A = g.normal(size=(50, 3, 3))
    P = A @ np.swapaxes(A, -1, -2) + 0.1 * np.eye(3)
    np.testing.assert_allclose(information.logdet_horizontal(P), np.linalg.slogdet(P[:, :2, :2])[1], rtol=1e-10)


# ----------------------------------------------------------------------------------
# counter-based random numbers
# ----------------------------------------------------------------------------------
def test_rng_normal_moments():
    keys = rng.env_keys(np.arange(64))
    x = rng.normal(keys, 4, np.arange(64), (2000,))
    assert x.shape == (64, 2000)
    n = x.size
    assert abs(x.mean()) < 4 / np.sqrt(n)  # 4 standard errors
    assert x.std() == pytest.approx(1.0, abs=4 * np.sqrt(0.5 / n))
    assert kstest(x.ravel(), "norm").pvalue > 1e-3
    u = rng.uniform(keys, 5, np.zeros(64, dtype=np.int64), (1000,))
    assert np.all((u > 0) & (u < 1))
    assert u.mean() == pytest.approx(0.5, abs=4 * np.sqrt(1 / 12 / u.size))


def test_rng_row_equals_seed_alone():
    seeds = np.array([0, 1, 2, 3, 4, 5, 6, 7, 1234, -5])
    counters = np.arange(10) * 3
    batch = rng.normal(rng.env_keys(seeds), 2, counters, (4, 5))
    for b, (s, c) in enumerate(zip(seeds, counters)):
        alone = rng.normal(rng.env_keys([s]), 2, np.array([c]), (4, 5))
        np.testing.assert_array_equal(batch[b], alone[0])
    # a different stream, counter or seed gives different (uncorrelated) numbers
    keys = rng.env_keys(np.arange(200))
    a = rng.normal(keys, 1, np.zeros(200), (50,)).ravel()
    for other in (
        rng.normal(keys, 2, np.zeros(200), (50,)),
        rng.normal(keys, 1, np.ones(200), (50,)),
        rng.normal(rng.env_keys(np.arange(200) + 200), 1, np.zeros(200), (50,)),
    ):
        assert abs(np.corrcoef(a, other.ravel())[0, 1]) < 4 / np.sqrt(a.size)


def test_survey_kernel_dead_reckons_along_eq5_forward_axis():
    """The sub-step kernel's dead-reckoning step is u_model * tau * forward_axis(measured
    bearing, measured pitch): eq. (4) with the rotation of eq. (5), in the kernel's complex form."""
    from coopnav_env.core.kernel_records import SurveyParams, SurveyView
    from coopnav_env.core.substeps import integrate_survey

    depth = 10.0
    pos = np.array([[[0.0, 0.0, depth]]])
    est, dr = pos.copy(), pos.copy()
    waypoints = np.array([[[[0.0, 0.0, depth], [1000.0, 0.0, depth]]]])
    u, thrust = 1.2, 1.2**2 * 6.0  # cruising: thrust = k u^2 with k = 6
    bias, compass_noise, pitch_noise = np.radians(2.0), np.radians(0.7), np.radians(1.5)
    sv = SurveyView(
        pos=pos,
        est=est,
        P=np.zeros((1, 1, 3, 3)),
        dr=dr,
        heading=np.array([[1.0 + 0.0j]]),  # due east
        wp_index=np.array([[1]]),
        done=np.array([[False]]),
        vel_true=np.zeros((1, 1, 3)),
        vel_est=np.zeros((1, 1, 3)),
        speed_model=np.array([[u]]),
        waypoints=waypoints,
        n_waypoints=np.array([[2]]),
        hover=np.array([[False]]),
        thrust_n=np.array([[thrust]]),
        speed_scale=np.array([[1.0]]),
        compass_bias_rad=np.array([[bias]]),
        current_est=np.array([[0.0j]]),
        last_range_t_s=np.zeros((1, 1)),
        rejected_streak=np.zeros((1, 1), dtype=np.int64),
    )
    prm = SurveyParams(
        substep_s=1.0,
        ping_interval_s=1.0,
        drag_k=6.0,
        mass_kg=45.0,
        los_alpha=0.5,
        acceptance_m=3.0,
        turn_cos=np.cos(0.2),
        turn_sin=np.sin(0.2),
        max_pitch_rad=np.radians(20.0),
        depth_gain_per_m=0.2,
        depth_noise_m=0.0,
        gps_noise_m=0.0,
        gps_max_depth_m=0.0,
        nan_probability=0.0,
        loss_near=0.0,
        loss_far=0.0,
        max_range_m=1.0,
        position_scale_m=1.0,
        observed_waypoints=1,
        beacon_max_speed=np.ones(1),
        fence_center=np.zeros(2),
    )
    integrate_survey(sv, np.array([[[compass_noise]]]), np.array([[[pitch_noise]]]), np.array([0.0j]), prm)
    expected = u * 1.0 * dynamics.forward_axis(np.pi / 2 + bias + compass_noise, pitch_noise)
    np.testing.assert_allclose(dr[0, 0] - [0.0, 0.0, depth], expected, atol=1e-12)
    np.testing.assert_allclose(est[0, 0], dr[0, 0], atol=1e-12)  # no current told: EKF and DR move alike
    np.testing.assert_allclose(pos[0, 0, :2], [u, 0.0], atol=1e-12)  # the truth goes straight east


# ----------------------------------------------------------------------------------
# Two-way ranging to a moving beacon: each leg from its own geometry (issue 21 bug)
# ----------------------------------------------------------------------------------
# Survey still at the origin, beacon 1500 m east moving east at 2 m/s, c = 1500 m/s,
# turnaround TAT = 0.015 s. The interrogation reaches the beacon at tau1 with
# 1500 tau1 = 1500 + 2 tau1, tau1 = 1500 / 1498 = 1.0013351 s; the reply leaves it at
# 1500 + 2 (tau1 + TAT) = 1502.0327 m, so 1500 tau2 = 1502.0327 and
# r = 1500 (tau1 + tau2) / 2 = (1502.0027 + 1502.0327) / 2 = 1502.0177 m. A prediction
# with the beacon at its t = 0 position for both legs says 1500 m: 2.02 m (4 sigma of a
# 0.5 m range) too short.
TWTT_TAU1 = 1500.0 / 1498.0
TWTT_RANGE = 0.5 * (1500.0 * TWTT_TAU1 + 1500.0 + 2.0 * (TWTT_TAU1 + 0.015))


def test_two_way_range_and_its_prediction_follow_each_legs_geometry():
    from coopnav_env.core.measurements.modem import modem_range
    from coopnav_env.core.navigation import moving_range_prediction

    survey, beacon, zero = np.zeros(3), np.array([1500.0, 0.0, 0.0]), np.zeros(3)
    u = np.array([2.0, 0.0, 0.0])
    delays = np.zeros((2, 2))
    r = modem_range(survey, zero, beacon, u, 1500.0, 1500.0, 0.0, 0.0, True, 0.015, 0.0, delays)
    assert r == pytest.approx(TWTT_RANGE, abs=1e-6)
    assert r - 1500.0 == pytest.approx(2.0177, abs=1e-4)
    h, H = moving_range_prediction(survey, zero, beacon, u, delays)
    assert h == pytest.approx(TWTT_RANGE, abs=1e-4)  # the legs' times estimated as (t_rt - TAT) / 2
    np.testing.assert_allclose(H, [-1.0, 0.0, 0.0], atol=1e-12)
    # one-way: the beacon sends at t = 0 from where it is then; the survey hears it at tau
    delays1 = np.zeros((2, 1))
    r1 = modem_range(survey, zero, beacon, u, 1500.0, 1500.0, 0.0, 0.0, False, 0.0, 0.0, delays1)
    assert r1 == pytest.approx(1500.0, abs=1e-9)
    assert moving_range_prediction(survey, zero, beacon, u, delays1)[0] == pytest.approx(1500.0, abs=1e-9)
    # one-way to a survey moving away at 2 m/s: it hears the ping at tau = 1500 / 1498 s, 2 tau
    # further off, r = 1500 tau = 1502.0027 m; the prediction places it there (v times the
    # leg's time, delays1[0, 0] = r / c), not where it was at t = 0 (1500 m, 4 sigma short)
    v = np.array([-2.0, 0.0, 0.0])
    r1 = modem_range(survey, v, beacon, u, 1500.0, 1500.0, 0.0, 0.0, False, 0.0, 0.0, delays1)
    assert r1 == pytest.approx(1500.0 * 1500.0 / 1498.0, abs=1e-6)
    assert moving_range_prediction(survey, v, beacon, u, delays1)[0] == pytest.approx(r1, abs=1e-6)


def test_two_way_range_from_a_moving_beacon_is_fused_without_bias():
    """The simulator's modem model end to end: the survey filter sits on the truth; a
    noiseless two-way range from the beacon of the hand case above must not move it
    (the old prediction, both legs from the beacon's t = 0 position, pushed it away
    from the beacon by K y, y = 2.02 m: 1.99 m before the fix)."""
    from coopnav_env.core import make_simulator

    c = make_config(
        "gao_sea",
        ranging_mode="twtt",
        turnaround_s=0.015,
        max_range_m=5000.0,
        water_temperature_c=20.0,
        temperature_uncertainty_c=0.0,
        range_noise_std_m=0.5,
    )
    sim = make_simulator(c, 1)
    sim.reset(np.array([0]))
    st = sim.state
    st.s_pos[0, 0] = [0.0, 0.0, st.s_pos[0, 0, 2]]
    # the beacon at the same depth: the hand case's horizontal line
    out = fuse_one_ping(
        sim, st.s_pos[0, 0].copy(), np.diag([4.0, 4.0, 0.01]), [1500.0, 0.0, st.s_pos[0, 0, 2]], [2.0, 0.0, 0.0]
    )
    assert out.fused[0, 0, 0]
    assert abs(st.s_est[0, 0, 0] - st.s_pos[0, 0, 0]) < 0.01  # 1.99 m off with the t = 0 geometry (before the fix)


@pytest.mark.parametrize(("mode", "expected"), [("owtt", 0.3), ("twtt", 1.0 - 0.7**2)])
def test_a_two_way_range_is_lost_when_either_leg_is(mode, expected):
    """The modem's range-loss curve at 30 % whatever the range (``packet_loss_near`` =
    ``packet_loss_far``): a one-way ping is lost 30 % of the time; a two-way range needs the
    interrogation and the reply both, 1 - 0.7^2 = 51 %. 640 pings each (64 environments, 10
    cycles; std of the fraction about 0.02)."""
    from coopnav_env import make_config
    from coopnav_env.core import make_simulator

    c = make_config(
        "gao_sea",
        ranging_mode=mode,
        packet_loss_near=0.3,
        packet_loss_far=0.3,
        outlier_probability=0.0,
        beacon_surface_every_s=0.0,
        beacon_surface_above_std_m=0.0,
    )
    B = 64
    sim = make_simulator(c, B)
    sim.reset(np.arange(B))
    lost = used = 0
    for _ in range(10):
        info = sim.step(np.zeros((B, 1, 2))).info
        lost += info["packets_lost"].sum()
        used += info["ranges_fused"].sum() + info["outliers_rejected"].sum() + info["nan_rejected"].sum()
    assert lost + used == B * 10
    assert lost / (lost + used) == pytest.approx(expected, abs=0.06)
