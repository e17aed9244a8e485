"""The moving LBL network (Matos & Cruz): the fix, the signal exchange, the
moving-frame EKF, the boats' baselines and the scenario's reproduction figures."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import baselines
import coopnav_env
from coopnav_env import make_config
from coopnav_env.core import lbl, make_simulator
from coopnav_env.core.information import error_ellipse
from coopnav_env.core.navigation import frame_predict, joseph_update_batch
from coopnav_env.obs_layout import decode_boat
from coopnav_env.scenarios.matos import PAPER_SETTINGS

C = 1500.0


# --- the spherical fix ----------------------------------------------------------------
def test_spherical_fix_recovers_a_known_position():
    x, y = lbl.spherical_fix(50.0, np.hypot(70.0, 40.0), 100.0)  # vehicle at (30, 40)
    assert x == pytest.approx(30.0, abs=1e-12) and y == pytest.approx(40.0, abs=1e-12)
    xs, ys = lbl.spherical_fix([50.0, 50.0], [50.0, np.hypot(100.0, 50.0)], [100.0, 100.0])
    assert np.allclose(xs, [50.0, 0.0])
    assert np.allclose(ys, [0.0, 50.0])


@pytest.mark.parametrize("d1,d2,l", [(10.0, 115.0, 100.0), (115.0, 10.0, 100.0), (30.0, 40.0, 100.0)])
def test_spherical_fix_refuses_circles_that_do_not_meet(d1, d2, l):
    with pytest.raises(ValueError, match="circles do not meet"):
        lbl.spherical_fix(d1, d2, l)
    x, y, ok = lbl.spherical_fix_batch(d1, d2, l)
    assert not ok and np.isfinite(x) and np.isfinite(y)


def test_spherical_fix_bad_input():
    with pytest.raises(ValueError, match="baseline length must be > 0"):
        lbl.spherical_fix(50.0, 50.0, 0.0)
    with pytest.raises(ValueError, match="finite"):
        lbl.spherical_fix(np.nan, 50.0, 100.0)


def test_frame_conversions_are_inverse_and_clockwise():
    b1, b2 = np.array([[10.0, 20.0]]), np.array([[10.0 + 100.0, 20.0]])  # x axis points east
    x, y, phi, l = lbl.world_to_frame(b1, b2, np.array([[40.0, 0.0]]))  # 20 m south of B1+30
    assert phi[0] == pytest.approx(np.pi / 2) and l[0] == pytest.approx(100.0)
    # y is 90 degrees clockwise from x: from east that is south
    assert x[0] == pytest.approx(30.0) and y[0] == pytest.approx(20.0)
    back = lbl.frame_to_world(b1, phi, x, y)
    assert np.allclose(back, [[40.0, 0.0]])


# --- the exchange, against hand-computed instants -------------------------------------------
def _exchange(vehicle, vel=(0, 0, 0), c=C, cn=C, jitter=None, lost=None, tau=0.01, react=0.02):
    B = 1
    v3 = np.array([vehicle], dtype=float)
    z = np.zeros((B, 3))
    b1, b2 = np.zeros((B, 3)), np.array([[100.0, 0.0, 0.0]])
    jit = np.zeros((B, 7)) if jitter is None else np.array([jitter])
    lo = np.zeros((B, 7), dtype=bool) if lost is None else np.array([lost])
    return lbl.exchange(
        lbl.Movers(v3, np.array([vel], dtype=float), b1, z, b2, z),
        np.array([c]),
        np.array([cn]),
        jit,
        np.zeros((B, 7)),
        lo,
        tau,
        react,
        2.0,
    )


def test_exchange_static_geometry_gives_the_true_distances():
    ex = _exchange((30.0, 40.0, 0.0))
    d2 = np.hypot(70.0, 40.0)
    assert ex["d1"][0] == pytest.approx(50.0, abs=1e-9)
    assert ex["d2"][0] == pytest.approx(d2, abs=1e-9)
    assert ex["m"][0] == pytest.approx(50.0 + 100.0 + d2, abs=1e-9)
    assert ex["l"][0] == pytest.approx(100.0, abs=1e-9)
    # instants: S2 heard at t3 = 2 d1 / c + tau; S5 heard at t6 = t3 + react + 2 d2 / c + tau
    assert ex["t3"][0] == pytest.approx(100.0 / C + 0.01, abs=1e-12)
    assert ex["t6"][0] == pytest.approx(ex["t3"][0] + 0.02 + 2 * d2 / C + 0.01, abs=1e-12)
    assert ex["ok_l"][0] and ex["ok_track"][0]


def test_exchange_scales_with_the_assumed_sound_speed():
    ex = _exchange((30.0, 40.0, 0.0), c=1500.0, cn=1530.0)
    assert ex["d1"][0] == pytest.approx(50.0 * 1530.0 / 1500.0, rel=1e-9)


def test_exchange_propagates_sound_to_a_moving_vehicle():
    # the vehicle runs straight away from B1 at 2 m/s: the reply has further to go
    v = 2.0
    ex = _exchange((0.0, 50.0, 0.0), vel=(0.0, v, 0.0), tau=0.01)
    t1 = 50.0 / C + 0.01
    t3 = (t1 + 50.0 / C) / (1 - v / C)  # t3 = t1 + (50 + v t3) / c
    assert ex["t3"][0] == pytest.approx(t3, rel=1e-12)
    assert ex["d1"][0] == pytest.approx(C * (t3 - 0.01) / 2, rel=1e-12)
    assert ex["d1"][0] > 50.0


def test_exchange_losses_break_the_right_measurements():
    lost = [False, True, False, False, False, False, False]  # S2 not heard by the vehicle
    ex = _exchange((30.0, 40.0, 0.0), lost=lost)
    assert not ex["ok_d1"][0] and ex["ok_d2"][0] and not ex["ok_l"][0]
    assert ex["t3s"][0] == pytest.approx(2.0)  # it interrogated B2 at the timeout
    assert ex["d2"][0] == pytest.approx(np.hypot(70.0, 40.0), abs=1e-9)
    lost = [True] + [False] * 6  # B1 never heard S1: no S2, no S3
    ex = _exchange((30.0, 40.0, 0.0), lost=lost)
    assert not ex["ok_d1"][0] and not ex["ok_m"][0] and ex["ok_d2"][0]


def test_track_fix_places_the_vehicle_from_the_boats_instants():
    ex = _exchange((30.0, 40.0, 0.0), tau=0.01, react=0.02)
    fix, ok = lbl.track_fix(ex, np.zeros((1, 2)), np.array([[100.0, 0.0]]), 0.0, np.array([C]), 0.01, 0.02)
    # frame (30, 40) with x east, y clockwise from east (south)
    assert ok[0] and np.allclose(fix, [[30.0, -40.0]], atol=1e-6)


# --- the moving-frame EKF -----------------------------------------------------------------
def test_frame_predict_matches_the_integrated_covariance_equation():
    """Section VII: dE/dt = F, dP/dt = A P + P A^T + Q; the closed form against scipy's ODE solver."""
    rng = np.random.default_rng(1)
    E0 = np.array([20.0, 50.0, np.radians(80.0), 0.1, -0.3, 100.0])
    M = rng.standard_normal((6, 6))
    P0 = M @ M.T + np.eye(6)
    Q = np.diag([0.01, 0.02, 1e-6, 1e-4, 2e-4, 1e-3])
    v, theta, dt = 1.2, np.radians(95.0), 0.7

    def rhs(_, z):
        E, P = z[:6], z[6:].reshape(6, 6)
        rel = theta - E[2]
        F = np.array([v * np.cos(rel) + E[3], v * np.sin(rel) + E[4], 0, 0, 0, 0])
        A = np.zeros((6, 6))
        A[0, 2], A[0, 3], A[1, 2], A[1, 4] = v * np.sin(rel), 1.0, -v * np.cos(rel), 1.0
        return np.concatenate([F, (A @ P + P @ A.T + Q).ravel()])

    ref = solve_ivp(rhs, (0, dt), np.concatenate([E0, P0.ravel()]), rtol=1e-11, atol=1e-12).y[:, -1]
    E, P = E0.copy(), P0.copy()
    frame_predict(E, P, v, theta, dt, Q)
    assert np.allclose(E, ref[:6], atol=1e-9)
    assert np.allclose(P, ref[6:].reshape(6, 6), atol=1e-8)


def test_joseph_update_batch_matches_filterpy_with_correlated_noise():
    from filterpy.kalman import KalmanFilter

    rng = np.random.default_rng(2)
    x0 = rng.standard_normal(6)
    M = rng.standard_normal((6, 6))
    P0 = M @ M.T + np.eye(6)
    H = rng.standard_normal((2, 6))
    R = np.array([[1.0, -1.0], [-1.0, 6.0]])
    z = rng.standard_normal(2)
    kf = KalmanFilter(dim_x=6, dim_z=2)
    kf.x, kf.P, kf.H, kf.R = x0.copy()[:, None], P0.copy(), H, R
    kf.update(z[:, None])
    x, P, nis = joseph_update_batch(x0[None], P0[None], (z - H @ x0)[None], H[None], R, np.array([True]))
    assert np.allclose(x[0], kf.x[:, 0], atol=1e-10)
    assert np.allclose(P[0], kf.P, atol=1e-10)
    y = z - H @ x0
    assert nis[0] == pytest.approx(y @ np.linalg.solve(H @ P0 @ H.T + R, y))
    x2, P2, _ = joseph_update_batch(x0[None], P0[None], y[None], H[None], R, np.array([False]))
    assert np.array_equal(x2[0], x0) and np.array_equal(P2[0], P0)


def _run(config, B, seed0, actions_fn=None, policy="perpendicular"):
    """Run B episodes; returns per-step info arrays (steps, B) of the named keys."""
    sim = make_simulator(config, B)
    obs = sim.reset(np.arange(B) + seed0)
    pols = [[baselines.make_policy(policy, config, agent=j) for j in range(2)] for _ in range(B)]
    out = {k: [] for k in ("phi_error_deg", "baseline_error_m", "error_x_m", "error_y_m", "vehicle_y_m")}
    alive = np.ones(B, dtype=bool)
    while alive.any():
        a = np.array([[pols[b][j].act(obs[b, j]) for j in range(2)] for b in range(B)])
        if actions_fn is not None:
            a = actions_fn(sim, a)
        res = sim.step(a)
        obs = res.obs
        for k in out:
            out[k].append(np.where(alive, res.info[k][:, 0], np.nan))
        alive &= ~(res.terminated | res.truncated)
    return {k: np.array(v) for k, v in out.items()}


# the boats following their commands exactly (the boat_* noise off), and the filter tuned to
# them (the frame_q_* defaults of ScenarioConfig: phi and c nearly constant)
PERFECT_BOATS = dict(
    boat_surge_noise_mps=0.0,
    boat_steering_noise_deg=0.0,
    boat_current_response=0.0,
    frame_q_position_m2ps=0.01,
    frame_q_orientation_rad2ps=1e-6,
    frame_q_current_m2ps3=1e-4,
    frame_q_baseline_m2ps=0.02,
)

# stated in the README: within 75 cycles (150 s) |phi error| < 4 deg. What is left is not
# lag: the filter sees theta_compass - phi, so it estimates phi plus the compass bias
# (std 1 deg), and the steady-state rms is ~2.4 deg
PHI_CONVERGENCE_CYCLES = 75


def test_frame_orientation_converges_after_a_30_degree_error():
    c = make_config(
        "matos_moving_lbl",
        initial_frame_orientation_error_deg=30.0,
        initial_frame_orientation_std_deg=30.0,
        max_cycles=150,
        **PERFECT_BOATS,
    )
    out = _run(c, 8, 100)
    phi = np.abs(out["phi_error_deg"])
    assert np.mean(phi[0]) > 20.0  # 30 deg off plus the prior draw (std 30 deg)
    assert np.nanmax(phi[PHI_CONVERGENCE_CYCLES:]) < 4.0


def test_baseline_estimate_tracks_a_boat_speed_mismatch():
    """B2 runs 0.05 m/s faster along the baseline than B1: l grows by 3 m a minute."""
    c = make_config("matos_moving_lbl", max_cycles=300)
    extra = 0.05 / c.boat_max_speed_mps

    def mismatch(sim, a):
        st = sim.state
        base = st.b_pos[:, 1, :2] - st.b_pos[:, 0, :2]
        unit = base / np.linalg.norm(base, axis=-1, keepdims=True)
        a = a.copy()
        a[:, 1] += extra * unit
        return a

    out = _run(c, 6, 200, mismatch)
    l_err = out["baseline_error_m"]
    steps = np.flatnonzero(np.isfinite(l_err).all(1))
    late = l_err[steps[len(steps) // 2 :]]
    # the baseline grew by ~0.05 m/s x 600 s = 30 m; the random-walk model of l follows the
    # ramp with a lag of rate x T / K ~ 1.3 m (K ~ 0.075 at steady state), not 30 m
    assert np.sqrt(np.mean(late**2)) < 2.0
    assert np.abs(np.mean(late)) < 2.0


def test_perpendicular_policy_moves_both_boats_perpendicular_to_the_baseline():
    env = coopnav_env.parallel_env("matos_moving_lbl", seed=3)
    obs, _ = env.reset(seed=3)
    c = env.config
    for j, agent in enumerate(env.agents):
        view = decode_boat(obs[agent], c)
        assert bool(view.is_b1) == (j == 0)
        x_axis = np.array([np.sin(np.radians(c.frame_orientation_deg)), np.cos(np.radians(c.frame_orientation_deg))])
        assert np.allclose(view.x_axis_en, x_axis, atol=0.1)  # the GPS frame's bearing (2 m GPS noise)
        # in the frame: nothing along the baseline, the transit speed across it
        a = baselines.make_policy("perpendicular", env, agent=agent).act(obs[agent])
        assert np.allclose(a * c.boat_max_speed_mps, [0.0, c.boat_transit_speed_mps], atol=1e-6)
        # the same boats in east/north actions: perpendicular to the baseline
        env_en = coopnav_env.parallel_env("matos_moving_lbl", seed=3, action_mode="velocity")
        obs_en, _ = env_en.reset(seed=3)
        a = baselines.make_policy("perpendicular", env_en, agent=agent).act(obs_en[agent])
        assert abs(float(a @ x_axis)) < 0.05
        assert np.linalg.norm(a) * c.boat_max_speed_mps == pytest.approx(abs(c.boat_transit_speed_mps), rel=0.05)


def test_scenario_rejects_a_roster_it_cannot_simulate():
    with pytest.raises(ValueError, match="beacon_kinds=\\('boat', 'boat'\\)"):
        make_config("matos_moving_lbl", beacon_kinds=("boat",))
    with pytest.raises(ValueError, match="y > 0"):
        make_config("matos_moving_lbl", waypoints_m=((0.0, -5.0, 2.0), (100.0, 50.0, 2.0)))
    with pytest.raises(ValueError, match="belongs to network='moving_lbl'"):
        make_config("gao_lawnmower", beacon_kinds=("boat",))
    with pytest.raises(ValueError, match="frame_velocity' belongs to network='moving_lbl'"):
        make_config("gao_lawnmower", action_mode="frame_velocity")


def test_ellipse_infos_are_two_sigma_semi_axes_of_the_filter_covariance():
    """ellipse_major_m / ellipse_minor_m mean 2-sigma semi-axes, as in the observations and
    evaluate.py: 2 sqrt of the eigenvalues of the filter's (x, y) covariance."""
    from coopnav_env.core.information import ELLIPSE_N_SIGMA

    assert ELLIPSE_N_SIGMA == 2.0
    c = make_config("matos_moving_lbl", max_cycles=20)
    B = 3
    sim = make_simulator(c, B)
    sim.reset(np.arange(B) + 11)
    for _ in range(5):
        res = sim.step(np.zeros((B, 2, 2)))
        w = np.linalg.eigvalsh(sim.state.f_P[:, :2, :2])  # ascending
        np.testing.assert_allclose(res.info["ellipse_major_m"][:, 0], 2.0 * np.sqrt(w[:, 1]), rtol=1e-9)
        np.testing.assert_allclose(res.info["ellipse_minor_m"][:, 0], 2.0 * np.sqrt(w[:, 0]), rtol=1e-7)
        # the same numbers evaluate.py writes to its steps.csv columns of these names
        major, minor, _ = error_ellipse(res.info["survey_cov_en_m2"])
        assert np.array_equal(res.info["ellipse_major_m"], major)
        assert np.array_equal(res.info["ellipse_minor_m"], minor)


def test_evaluate_reports_moving_frame_errors(tmp_path):
    import json

    from evaluation.cli import main

    out = tmp_path / "ev"
    rc = main(
        [
            "--scenario",
            "matos_moving_lbl",
            "--policies",
            "perpendicular,static",
            "--episodes",
            "2",
            "--set",
            "max_cycles=40",
            "--out",
            str(out),
        ]
    )
    assert rc == 0
    s = json.loads((out / "summary.json").read_text())
    for p in ("perpendicular", "static"):
        assert 0.05 < s["policies"][p]["error_x_std_m"] < 5.0
        assert 0.05 < s["policies"][p]["error_y_std_m"] < 5.0
    assert (out / "frame_errors.png").exists()


# --- the boats' imperfect motion (boat_* parameters) and the filter tuned to it ------------
def _perpendicular_actions(c, B):
    """The ``perpendicular`` policy's action for every boat of B environments (frame_velocity:
    nothing along the baseline, the transit speed across it; checked against the policy above)."""
    a = np.zeros((B, 2, 2))
    a[..., 1] = c.boat_transit_speed_mps / c.boat_max_speed_mps
    return a


def _autocorrelation(x, lag):
    """Over axis 0 (time) of x (T, n), pooled over the columns."""
    x = x - x.mean()
    return float(np.sum(x[lag:] * x[:-lag]) / np.sum(x * x) * len(x) / (len(x) - lag))


def test_boat_speed_and_course_fluctuate_as_gauss_markov():
    """Ground speed minus commanded speed, and course over ground minus commanded course, of
    200 boats over 300 cycles: stationary std boat_surge_noise_mps / boat_steering_noise_deg and
    the correlation exp(-lag T / tau) of a first-order Gauss-Markov process sampled every cycle."""
    c = make_config("matos_moving_lbl", boat_current_response=0.0, max_cycles=300)
    B, T, tau = 100, c.ping_interval_s, c.boat_noise_time_constant_s
    sim = make_simulator(c, B)
    sim.reset(np.arange(B) + 300)
    a = _perpendicular_actions(c, B)
    speed, course = [], []
    for _ in range(300):
        cmd = sim.command_velocity(a)  # what the boats were told, this cycle (GPS frame)
        sim.step(a)
        v = sim.state.b_vel[..., 0] + 1j * sim.state.b_vel[..., 1]
        # in the command's axes: (|cmd| + s) exp(-1j delta); signed, for the rare (3.3 sigma) cycle
        # in which the fluctuation exceeds the 0.5 m/s transit and the boat drifts backwards
        u = v / cmd * np.abs(cmd)
        sign = np.sign(u.real)
        speed.append((sign * np.abs(u) - np.abs(cmd)).ravel())
        course.append(-np.angle(sign * u).ravel())  # a positive complex angle is anticlockwise
    speed, course = np.array(speed), np.degrees(np.array(course))
    # 60,000 samples with ~1,000 correlation times: the std to ~3 %, the correlations to ~0.03
    assert np.mean(speed) == pytest.approx(0.0, abs=0.01)
    assert np.std(speed) == pytest.approx(c.boat_surge_noise_mps, rel=0.05)
    assert np.std(course) == pytest.approx(c.boat_steering_noise_deg, rel=0.05)
    for lag in (1, 15):  # one cycle: exp(-2/30) = 0.936; 30 s: exp(-1) = 0.368
        expected = np.exp(-lag * T / tau)
        assert _autocorrelation(speed, lag) == pytest.approx(expected, abs=0.04)
        assert _autocorrelation(course, lag) == pytest.approx(expected, abs=0.04)


def test_perfect_boats_follow_their_commands_and_the_current_response_adds_to_them():
    c = make_config(
        "matos_moving_lbl", boat_surge_noise_mps=0.0, boat_steering_noise_deg=0.0, current_speed_mps=0.4, max_cycles=20
    )
    B = 4
    for response in (0.0, c.boat_current_response, 1.0):
        sim = make_simulator(c.replace(boat_current_response=response), B)
        sim.reset(np.arange(B) + 40)
        a = _perpendicular_actions(c, B)
        for _ in range(10):
            cmd = sim.command_velocity(a)
            cur = sim.state.current_mean + sim.state.current_gm  # this cycle's water current
            p0 = sim.state.b_pos[..., :2].copy()
            sim.step(a)
            v = sim.state.b_vel[..., 0] + 1j * sim.state.b_vel[..., 1]
            # the boats are on course after the first cycle: velocity = command + response x current
            np.testing.assert_allclose(v, cmd + response * cur[:, None], atol=1e-12)
            moved = sim.state.b_pos[..., :2] - p0
            np.testing.assert_allclose(moved[..., 0] + 1j * moved[..., 1], v * c.ping_interval_s, atol=1e-9)


def _frame_current(st, eps=1e-3):
    """What the filter's (c_x, c_y) stand for: the velocity, in the moving frame, of the water at
    the vehicle (the current minus the frame's motion, its rotation included), by finite difference."""
    b1, b2, v = st.b_pos[:, 0, :2], st.b_pos[:, 1, :2], st.s_pos[:, 0, :2]
    cur = st.current_mean + st.current_gm
    x0, y0, _, _ = lbl.world_to_frame(b1, b2, v)
    x1, y1, _, _ = lbl.world_to_frame(
        b1 + eps * st.b_vel[:, 0, :2], b2 + eps * st.b_vel[:, 1, :2], v + eps * np.stack([cur.real, cur.imag], -1)
    )
    return (x1 - x0) / eps, (y1 - y0) / eps


def _nees_runs(B=100, seed0=0, restarts=None, **overrides):
    """B episodes of the perpendicular boats in one simulator, on the paper's channel
    (``PAPER_SETTINGS``) unless overrides say otherwise: per cycle (T, B) the NEES of (x, y) and
    of all six states (NaN after an episode ended), and the (x, y) error; the restarts per
    cycle (T, B) are appended to the list ``restarts`` if one is given."""
    c = make_config("matos_moving_lbl", **{**PAPER_SETTINGS, **overrides})
    sim = make_simulator(c, B)
    sim.reset(np.arange(B) + seed0)
    a = _perpendicular_actions(c, B)
    n2, n6, err = [], [], []
    alive = np.ones(B, dtype=bool)
    while alive.any():
        res = sim.step(a)
        st = sim.state
        x, y, phi, length = lbl.world_to_frame(st.b_pos[:, 0, :2], st.b_pos[:, 1, :2], st.s_pos[:, 0, :2])
        cx, cy = _frame_current(st)
        e = np.stack(
            [
                st.f_E[:, 0] - x,
                st.f_E[:, 1] - y,
                np.angle(np.exp(1j * (st.f_E[:, 2] - phi))),
                st.f_E[:, 3] - cx,
                st.f_E[:, 4] - cy,
                st.f_E[:, 5] - length,
            ],
            -1,
        )
        nan = np.where(alive, 1.0, np.nan)
        n2.append(nan * np.einsum("bi,bi->b", e[:, :2], np.linalg.solve(st.f_P[:, :2, :2], e[:, :2, None])[..., 0]))
        n6.append(nan * np.einsum("bi,bi->b", e, np.linalg.solve(st.f_P, e[..., None])[..., 0]))
        err.append(nan * np.hypot(e[:, 0], e[:, 1]))
        if restarts is not None:
            restarts.append(np.where(alive, np.asarray(res.info["filter_restarts"]).reshape(B, -1).sum(1), 0))
        alive &= ~(res.terminated | res.truncated)
    return np.array(n2), np.array(n6), np.array(err)


def test_filter_is_consistent_at_the_default_boat_noise():
    """100 Monte Carlo runs at the boat_* defaults, on the paper's channel (PAPER_SETTINGS): the
    run-average NEES of (x, y) and of all six states lies in the two-sided 95 % chi-square band
    (N = 100 runs: chi2(100 n) / 100) on average over the mission and at most cycles
    (Bar-Shalom, Li & Kirubarajan, sec. 5.4)."""
    from scipy.stats import chi2

    B = 100
    n2, n6, _ = _nees_runs(B)
    full = np.isfinite(n2).sum(1) >= 0.9 * B  # the cycles before episodes start ending
    for nees, dof in ((n2, 2), (n6, 6)):
        lo, hi = chi2.ppf([0.025, 0.975], dof * B) / B
        avg = np.nanmean(nees[full], 1)
        assert lo < np.mean(avg) < hi, (dof, np.mean(avg), lo, hi)
        assert np.mean((avg > lo) & (avg < hi)) > 0.8, (dof, np.mean((avg > lo) & (avg < hi)))


def test_filter_does_not_diverge_at_twice_the_boat_noise():
    """0.3 m/s of boat speed fluctuation with the filter tuned to 0.15: over-confident (NEES ~3
    for (x, y)) but bounded. A diverged filter runs off by tens to hundreds of metres (without the
    lockout restart of ``cycle`` it did, at 0.15 m/s); here 95 % of the final errors stay below
    4 m (three times the 1.2 m std of one LBL fix at the line's ends) and fewer than 2 % of all
    cycles exceed 5 m."""
    n2, _, err = _nees_runs(100, boat_surge_noise_mps=0.3)
    final = np.array([e[np.isfinite(e)][-1] for e in err.T])
    assert np.percentile(final, 95) < 4.0
    assert np.nanmean(err > 5.0) < 0.02
    assert np.nanmean(n2) < 5.0


# --- on the project's channel: multipath outliers and range-dependent losses (issue 21) --------
CHANNEL = {"outlier_probability": 0.03, "packet_loss_near": 0.05, "packet_loss_far": 0.5}


def test_the_scenarios_default_to_the_projects_channel_and_the_paper_settings_switch_it_off():
    for name in ("matos_moving_lbl", "matos_river"):
        c = make_config(name)
        assert (c.outlier_probability, c.packet_loss_near, c.packet_loss_far) == (0.03, 0.05, 0.5)
        p = make_config(name, **PAPER_SETTINGS)
        assert (p.outlier_probability, p.packet_loss_near, p.packet_loss_far) == (0.0, 0.0, 0.0)


def test_fix_covariance_matches_monte_carlo_fixes():
    """Eq. F2 of core/moving_network/recovery.py: the fix's covariance J R J^T, R = sigma_r^2
    EXCHANGE_COVARIANCE, against 20000 fixes from noisy (d1, d2, l) at a point 30 m off the
    baseline (a GDOP of ~2 in y), 2 m below the boats: each entry within 5 % of the diagonal."""
    from coopnav_env.core.lbl import ExchangeResult
    from coopnav_env.core.moving_network import EXCHANGE_COVARIANCE
    from coopnav_env.core.moving_network.recovery import fix_with_covariance

    x, y, L, dz, s2 = 30.0, 30.0, 100.0, 2.0, 1.0
    d1, d2 = np.sqrt(x * x + y * y + dz * dz), np.sqrt((L - x) ** 2 + y * y + dz * dz)

    def ex_of(a, b, c):
        z = 0.0
        return ExchangeResult(a, z, b, c, True, True, True, True, z, z, z, z, z, z, True, 0)

    r, S = np.empty(3), np.empty((3, 3))
    assert fix_with_covariance(ex_of(d1, d2, L), dz, s2, r, S)
    np.testing.assert_allclose(r, (x, y, L), atol=1e-9)
    noise = np.random.default_rng(5).multivariate_normal(np.zeros(3), s2 * EXCHANGE_COVARIANCE, 20000)
    fixes = np.empty((len(noise), 3))
    rr, SS = np.empty(3), np.empty((3, 3))
    for i, (n1, n2, nl) in enumerate(noise):
        assert fix_with_covariance(ex_of(d1 + n1, d2 + n2, L + nl), dz, s2, rr, SS)
        fixes[i] = rr
    mc = np.cov(fixes.T)
    scale = np.sqrt(np.outer(np.diag(S), np.diag(S)))
    assert np.all(np.abs(mc - S) < 0.05 * scale), (mc, S)


def _window(W=8):
    """A Filter record of one environment with an empty window of W fixes."""
    from coopnav_env.core.moving_network import Filter

    return Filter(
        np.zeros((1, 6)),
        np.eye(6)[None].copy(),
        np.zeros((1, 3), dtype=np.int64),
        np.zeros((1, W, 3)),
        np.zeros((1, W, 3, 3)),
        np.full((1, W), -1, dtype=np.int64),
    )


def test_line_fit_sets_an_outlying_fix_aside_and_recovers_the_error_and_its_velocity():
    """Eqs. F4-F5: eight fixes on the line r = e - U a (present error e = (6, -4) m, velocity
    error U = (0.5, 0.2) m per cycle), 1 m of noise each, and the newest one 25 m off (a
    multipath excess, l too): the fit keeps six or seven of the seven, never the outlier, finds
    e within 3 sigma of its covariance and the velocity error within 3 sigma (the fit's prior
    on it, frame_restart_velocity_std_mps, pulls it towards 0); the old restart took that newest fix."""
    from coopnav_env.core.moving_network.recovery import line_fit
    from coopnav_env.core.moving_network.state import cycle_params

    f = _window()
    rng = np.random.default_rng(3)
    e, U = np.array([6.0, -4.0]), np.array([0.5, 0.2])
    for k in range(8):
        f.window_age[0, k] = k
        f.window_r[0, k, :2] = e - U * k + rng.normal(0.0, 1.0, 2)
        f.window_r[0, k, 2] = rng.normal(0.0, 1.0)
        f.window_S[0, k] = np.eye(3)
    f.window_r[0, 0] += (25.0, 10.0, -12.0)
    p = cycle_params(make_config("matos_moving_lbl"), 6.63, 9.21)
    theta, cov = np.empty(4), np.empty((4, 4))
    n, l_mean, var_l = line_fit(f, 0, p, theta, cov)
    assert n >= 6  # the outlier never; a good fix may fall outside the 99 % gate
    d = theta[:2] - e
    assert d @ np.linalg.solve(cov[:2, :2], d) < 11.8  # chi2(2) 99.7 %
    assert np.all(np.abs(theta[2:] - U) < 3.0 * np.sqrt(np.diag(cov)[2:]))
    assert abs(l_mean) < 3.0 * np.sqrt(var_l)


def test_too_few_consistent_fixes_do_not_restart():
    """Three fixes only (frame_restart_min_fixes = 4): no fit, whatever they say."""
    from coopnav_env.core.moving_network.recovery import line_fit
    from coopnav_env.core.moving_network.state import cycle_params

    f = _window()
    for k in range(3):
        f.window_age[0, k] = k
        f.window_S[0, k] = np.eye(3)
        f.window_r[0, k, :2] = (20.0, 20.0)
    p = cycle_params(make_config("matos_moving_lbl"), 6.63, 9.21)
    assert line_fit(f, 0, p, np.empty(4), np.empty((4, 4)))[0] == 0


def test_filter_consensus_by_hand():
    """Eq. F4b: fixes of covariance I (x, y, l), P_xy = I, P_ll = 1, so each residual is tested
    against 2 I: (3, 0, 0) has NIS 9 / 2 = 4.5 <= 9.21 (2 dof) and counts; (5, 0, 0) has 12.5
    and does not; (0, 0, 3.5): l's 12.25 / 2 = 6.1 <= 6.63 (1 dof), counts; (0, 0, 4): 8 > 6.63,
    does not; empty slots never count. With P = 100 I all four count."""
    from coopnav_env.core.moving_network.recovery import filter_consensus
    from coopnav_env.core.moving_network.state import cycle_params

    f = _window()
    for k, r in enumerate([(3.0, 0.0, 0.0), (5.0, 0.0, 0.0), (0.0, 0.0, 3.5), (0.0, 0.0, 4.0)]):
        f.window_age[0, k] = 0
        f.window_S[0, k] = np.eye(3)
        f.window_r[0, k] = r
    p = cycle_params(make_config("matos_moving_lbl"), 6.63, 9.21)
    assert filter_consensus(f, 0, np.eye(6), p) == 2
    assert filter_consensus(f, 0, 100.0 * np.eye(6), p) == 4  # a grown P agrees with anything


def _locked_out(P_xy_var, fixes_e):
    """A filter at E = 0 whose d2 has been gated out REINIT_AFTER_CYCLES - 1 cycles, P_xy =
    P_xy_var I, and eight stored fixes of noise 0.25 I at the residual fixes_e (x, y) (ages 1-8,
    no velocity error); ``recover`` then runs for a cycle whose d2 is gated out again (no new
    fix). Returns (restarted, E)."""
    from coopnav_env.core.lbl import ExchangeResult
    from coopnav_env.core.moving_network.recovery import recover
    from coopnav_env.core.moving_network.state import REINIT_AFTER_CYCLES, cycle_params

    f = _window()
    f.P[0] = np.eye(6)
    f.P[0, 0, 0] = f.P[0, 1, 1] = P_xy_var
    f.rejected_cycles[0, 1] = REINIT_AFTER_CYCLES - 1
    for k in range(8):
        f.window_age[0, k] = k
        f.window_S[0, k] = 0.25 * np.eye(3)
        f.window_r[0, k, :2] = fixes_e
    p = cycle_params(make_config("matos_river"), 6.63, 9.21)
    status = np.array([[True, True], [True, False], [False, False]])
    ex = ExchangeResult(0.0, 0.0, 0.0, 0.0, True, False, True, False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, False, 0)
    E, P = f.E[0], f.P[0]
    restarted = recover(E, P, f, 0, status, np.zeros(3), ex, 2.0, 1.0, p)
    return restarted, E.copy(), P.copy()


def test_a_consistent_but_sharper_window_restarts_a_grown_filter_and_not_a_sharp_one():
    """Eq. F4c: eight fixes 2 m off in x, each 0.5 m std. A filter of P_xy = 9 I (it has refused
    ranges for cycles) agrees with them (NIS 4 / 9.03 < 9.21) but knows less than they do: it
    restarts onto them (x += ~2, P_xx < 1). A filter of P_xy = 0.01 I knows more; the fixes then
    disagree with it (NIS ~ 4 / 0.04 = 100) and its consensus (eq. F4b) is 0, so it restarts too
    - while fixes at 0.05 m agree with the sharp filter and it holds. Before eq. F4c the grown
    filter held, and kept refusing the ranges (seed 730044: 20 m)."""
    restarted, E, P = _locked_out(9.0, (2.0, 0.0))
    assert restarted == 1 and abs(E[0] - 2.0) < 0.3 and P[0, 0] < 1.0
    restarted, E, _ = _locked_out(0.01, (2.0, 0.0))
    assert restarted == 1 and abs(E[0] - 2.0) < 0.3
    restarted, E, _ = _locked_out(0.01, (0.05, 0.0))
    assert restarted == 0 and E[0] == 0.0


def test_restarts_land_near_the_vehicle_with_an_honest_covariance():
    """The lock-out restart on the project's channel (40 runs, seeds 0-39): no restart leaves the
    filter more than 5 m off or its (x, y) NEES above the 99.9 % point (13.8). The old restart
    re-fixed from the triggering cycle's own spherical fix, unchecked, with P = 4 sigma_r^2: that
    cycle is the likeliest to hold a multipath excess, and (issue 21) 19 % of its restarts
    landed more than 5 m off; on these seeds it failed this test."""
    restarts = []
    n2, _, err = _nees_runs(40, 0, restarts, **CHANNEL)
    hit = np.array(restarts) > 0
    assert np.all(err[hit] < 5.0), np.sort(err[hit])[-5:]
    assert np.all(n2[hit] < 13.8), np.sort(n2[hit])[-5:]


def _per_cycle(n2, err, B):
    """The per-cycle figures of benchmarks/nees_per_cycle.py from (T, B) NEES and errors: the
    mean and its band, the fraction of run-cycles in the per-cycle 95 % band, the fraction
    above the 99.9 % point, the largest error."""
    from scipy.stats import chi2

    v = n2[np.isfinite(n2)]
    lo, hi = chi2.ppf([0.025, 0.975], 2 * B) / B
    band = chi2.ppf([0.025, 0.975], 2)
    in_band = np.mean((v >= band[0]) & (v <= band[1]))
    return v.mean(), (lo, hi), in_band, np.mean(v > chi2.ppf(0.999, 2)), np.nanmax(err)


def test_filter_per_cycle_nees_on_the_projects_channel():
    """30 runs of the perpendicular boats at the scenario's defaults (outliers 3 %, losses
    5-50 %; seeds 0-29): the mean (x, y) NEES inside the 95 % band of a mean of 30 chi2(2),
    at least 90 % of run-cycles inside the per-cycle 95 % band, at most 5x the nominal 0.1 %
    above the 99.9 % point, and no error above 20 m. 100-run figures: the slow test below and
    docs/scenarios/matos-cruz.md#channel."""
    n2, _, err = _nees_runs(30, 0, **CHANNEL)
    mean, (lo, hi), in_band, above, worst = _per_cycle(n2, err, 30)
    assert lo < mean < hi, (mean, lo, hi)
    assert in_band > 0.90, in_band
    assert above < 0.005, above
    assert worst < 20.0, worst


@pytest.mark.slow
def test_filter_per_cycle_nees_on_the_projects_channel_100_runs():
    """The same over 100 runs (seeds 1000-1099)."""
    n2, _, err = _nees_runs(100, 1000, **CHANNEL)
    mean, (lo, hi), in_band, above, worst = _per_cycle(n2, err, 100)
    assert lo < mean < hi, (mean, lo, hi)
    assert in_band > 0.90, in_band
    assert above < 0.005, above
    assert worst < 20.0, worst
