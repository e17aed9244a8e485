"""The river version of the moving LBL network (``matos_river``, ``mission_frame="world"``):
the world mission through the boats' frame, the river's geometry and bank term, the
PettingZoo API, and that the boats' choices decide the outcome."""

import numpy as np
import pytest

import baselines
import coopnav_env
from coopnav_env import make_config
from coopnav_env.core import lbl, make_simulator, river
from coopnav_env.core.moving_network import OBS_DIM, RIVER_OBS_DIM, frame_waypoints
from coopnav_env.obs_layout import decode_boat, obs_dim
from coopnav_env.scenarios.matos import RIVER_PAPER_SETTINGS

# perfect boats: they go exactly where they are told (and stay where they are with zero actions)
STILL_BOATS = dict(boat_surge_noise_mps=0.0, boat_steering_noise_deg=0.0, boat_current_response=0.0)


def test_world_waypoint_to_frame_by_hand():
    """B1's GPS position (10, 20) (truth (8, 21) plus a GPS error (2, -1)), B2's 100 m from it
    on bearing atan2(0.6, 0.8) = 36.87 deg: x = (0.6, 0.8) (east, north), y 90 degrees
    clockwise = (0.8, -0.6). The waypoint B1 + 50 x + 30 y = (64, 42) is frame (50, 30); B1
    itself is (0, 0) and a point 100 m along y is (0, 100)."""
    b_pos = np.array([[[8.0, 21.0, 0.0], [70.0, 100.0, 0.0]]])
    gps_err = np.array([[[2.0, -1.0], [0.0, 0.0]]])
    wp = np.array([[64.0, 42.0, 2.0], [10.0, 20.0, 2.0], [90.0, -40.0, 2.0]])
    x, y = frame_waypoints(b_pos, gps_err, wp)
    np.testing.assert_allclose(x, [[50.0, 0.0, 0.0]], atol=1e-12)
    np.testing.assert_allclose(y, [[30.0, 0.0, 100.0]], atol=1e-12)


def test_the_simulator_gives_the_vehicle_its_world_mission_through_the_gps_frame():
    c = make_config("matos_river", max_cycles=5)
    sim = make_simulator(c, 2)
    sim.reset([3, 4])
    st = sim.state
    wp = np.asarray(c.waypoints_m)
    x, y = frame_waypoints(st.b_pos, st.b_gps_err, wp)
    np.testing.assert_array_equal(st.s_waypoints[:, 0, :, 0], x)
    np.testing.assert_array_equal(st.s_waypoints[:, 0, :, 1], y)
    # the boats start on a cross section half a baseline ahead: the vehicle 50 m from the middle
    # of the true baseline (the river has no curvature at the start), and the river's direction
    # points along -y; through the GPS (2.1 m per axis) to within metres
    xt, yt, _, _ = lbl.world_to_frame(st.b_pos[:, 0, :2], st.b_pos[:, 1, :2], wp[0, :2])
    np.testing.assert_allclose(xt, 50.0, atol=1.0)  # to the 25 m chords of the polyline
    np.testing.assert_allclose(yt, 50.0, atol=1.0)
    assert np.all(np.hypot(x[:, 0] - 50.0, y[:, 0] - 50.0) < 10.0)
    view = decode_boat(sim.observe()[0, 0], c)
    np.testing.assert_allclose(view.river_direction_xy, [0.0, -1.0], atol=0.1)
    # every cycle: recomputed through the boats' GPS positions at the cycle's start
    for _ in range(3):
        pos, err = st.b_pos.copy(), st.b_gps_err.copy()
        sim.step(np.zeros((2, 2, 2)))
        x, y = frame_waypoints(pos, err, wp)
        np.testing.assert_array_equal(st.s_waypoints[:, 0, :, 0], x)
        np.testing.assert_array_equal(st.s_waypoints[:, 0, :, 1], y)
        assert not np.array_equal(err, st.b_gps_err)


def test_river_geometry_offsets_and_cross_section():
    pts, cum = river.centerline_of(((0.0, 0.0), (100.0, 0.0), (100.0, -100.0)))  # east, then south
    off, tan = river.offsets(np.array([[50.0, -10.0], [50.0, 10.0], [90.0, -50.0], [120.0, -50.0]]), pts, cum)
    # right of east is south (+), right of south is west (+)
    np.testing.assert_allclose(off, [10.0, -10.0, 10.0, -20.0])
    np.testing.assert_allclose(tan, [1.0, 1.0, -1j, -1j])
    b1, b2, phi = river.cross_section_at(50.0, pts, cum, 1.0, 100.0)
    # going east, B1 on the left (north), B2 on the right (south); x axis B1 -> B2 points south
    np.testing.assert_allclose(b1, [50.0, 50.0])
    np.testing.assert_allclose(b2, [50.0, -50.0])
    assert phi == pytest.approx(np.pi)


def test_bank_penalty_fires_outside_the_river_only():
    c = make_config("matos_river", max_cycles=5, **STILL_BOATS)
    sim = make_simulator(c, 1)
    sim.reset([0])
    st = sim.state
    pts, cum = river.centerline_of(c.river_centerline_m)
    pe, pn, te, tn = river.point_at(400.0, pts, cum)
    right = np.array([tn, -te])  # the tangent turned 90 degrees clockwise
    st.b_pos[0, 0, :2] = np.array([pe, pn]) + (0.5 * c.river_width_m + 5.0) * right  # 5 m beyond the right bank
    st.b_pos[0, 1, :2] = np.array([pe, pn]) - (0.5 * c.river_width_m - 5.0) * right  # 5 m inside the left bank
    res = sim.step(np.zeros((1, 2, 2)))
    np.testing.assert_array_equal(res.terms["bank"], [[1.0, 0.0]])
    assert sim.reward_weights["bank"] == -c.bank_penalty
    assert res.terms["rotation"].sum() == 0.0  # no rotation term on a world mission


def test_matos_river_passes_the_pettingzoo_parallel_api_test():
    from pettingzoo.test import parallel_api_test

    env = coopnav_env.parallel_env("matos_river", seed=0, max_cycles=30)
    parallel_api_test(env, num_cycles=40)
    assert env.observation_space("beacon_0").shape == (OBS_DIM + RIVER_OBS_DIM,)


def test_observation_of_the_frame_mission_is_unchanged_and_the_river_adds_five():
    assert obs_dim(make_config("matos_moving_lbl")) == OBS_DIM == 15
    assert obs_dim(make_config("matos_river")) == OBS_DIM + RIVER_OBS_DIM == 20
    assert decode_boat(np.zeros(OBS_DIM), make_config("matos_moving_lbl")).river_direction_xy is None
    assert make_simulator(make_config("matos_moving_lbl")).reward_terms[-1] == "contact"


@pytest.mark.parametrize(
    "override,message",
    [
        (dict(mission_frame="earth"), "mission_frame 'earth'; valid: frame, world"),
        (dict(river_centerline_m=()), "river_centerline_m must hold 2 to"),
        (dict(river_centerline_m=((0.0, 0.0), (0.0, 0.0))), "river_centerline_m must not repeat"),
        (dict(river_width_m=0.0), "river_width_m must be in [1, 10000]"),
    ],
)
def test_river_parameters_are_validated(override, message):
    with pytest.raises(
        ValueError, match=message.replace("(", r"\(").replace(")", r"\)").replace("[", r"\[").replace("]", r"\]")
    ):
        make_config("matos_river", **override)
    # the river section applies only to world missions, the moving network's only to moving_lbl
    with pytest.raises(ValueError, match=r"river_centerline_m belongs to section 'river'.*mission_frame='world'"):
        make_config("matos_moving_lbl", river_centerline_m=((0.0, 0.0), (1.0, 0.0)))
    with pytest.raises(ValueError, match=r"mission_frame belongs to section 'moving'.*network='moving_lbl'"):
        make_config("gao_lawnmower", mission_frame="world")


def test_every_moving_network_policy_runs_on_the_river():
    env = coopnav_env.parallel_env("matos_river", seed=0, max_cycles=5)
    for name in ("static", "random", "perpendicular", "abeam", "river_escort"):
        obs, _ = env.reset(seed=1)
        pols = {a: baselines.make_policy(name, env, seed=0, agent=a) for a in env.agents}
        while env.agents:
            actions = {a: pols[a].act(obs[a]) for a in env.agents}
            for a in actions.values():
                assert a.shape == (2,) and np.all(np.isfinite(a)) and np.all(np.abs(a) <= 1.0)
            obs, *_ = env.step(actions)


def _mean_error(policy, seeds, max_cycles):
    c = make_config("matos_river", max_cycles=max_cycles)
    B = len(seeds)
    sim = make_simulator(c, B)
    obs = sim.reset(seeds)
    pols = [[baselines.make_policy(policy, c, agent=j, seed=s) for j in range(2)] for s in seeds]
    alive, err, bank = np.ones(B, dtype=bool), [], []
    while alive.any():
        res = sim.step(np.array([[pols[b][j].act(obs[b, j]) for j in range(2)] for b in range(B)]))
        obs = res.obs
        err.append(np.where(alive, res.info["survey_error_m"][:, 0], np.nan))
        bank.append(np.where(alive[:, None], res.terms["bank"], np.nan))
        alive &= ~(res.terminated | res.truncated)
    return np.nanmean(err, 0), np.nanmean(bank)


def test_static_boats_lose_the_vehicle_and_the_escort_keeps_it():
    """Four seeded episodes down the whole river (seeds 100-103). Measured: river_escort 0.74-0.93 m
    mean error, never on the bank; static boats, which the vehicle passes after ~40 s and leaves
    ever further behind (the fix's geometry degrades, then the ranges beyond max_range_m are
    lost), 10.6-25.2 m: at least 13 times the escort's in every episode. (With the paper's
    filter, before the boats' telemetry of issue 21, the escort's were 1.69-1.79 m and the static
    boats' filter ran off to 171-1877 m; with the frame's bearing and motion telemetered, phi
    and the frame's velocity stay known and the static boats' error grows with the geometry.)"""
    seeds = [100, 101, 102, 103]
    escort, escort_bank = _mean_error("river_escort", seeds, 900)
    static, _ = _mean_error("static", seeds, 900)
    assert np.all(escort < 1.5) and escort_bank == 0.0
    assert np.all(static > 10.0 * escort) and np.all(static > 8.0)


def river_nees_runs(B=50, seed0=0, policy="river_escort", **overrides):
    """B episodes of ``policy`` boats on matos_river in one simulator: per cycle (T, B) the NEES
    of the filter's (x, y) against the truth in the true frame (NaN after an episode ended),
    the (x, y) error and the phi error (deg). The numbers of docs/scenarios/matos-cruz.md#river."""
    from coopnav_env.core import lbl

    c = make_config("matos_river", **overrides)
    sim = make_simulator(c, B)
    obs = sim.reset(np.arange(B) + seed0)
    pols = [[baselines.make_policy(policy, c, agent=j, seed=b) for j in range(2)] for b in range(B)]
    alive, n2, err, phi = np.ones(B, dtype=bool), [], [], []
    while alive.any():
        res = sim.step(np.array([[pols[b][j].act(obs[b, j]) for j in range(2)] for b in range(B)]))
        obs, st = res.obs, sim.state
        x, y, _, _ = lbl.world_to_frame(st.b_pos[:, 0, :2], st.b_pos[:, 1, :2], st.s_pos[:, 0, :2])
        e = np.stack([st.f_E[:, 0] - x, st.f_E[:, 1] - y], -1)
        nan = np.where(alive, 1.0, np.nan)
        n2.append(nan * np.einsum("bi,bi->b", e, np.linalg.solve(st.f_P[:, :2, :2], e[..., None])[..., 0]))
        err.append(nan * np.hypot(e[:, 0], e[:, 1]))
        phi.append(nan * res.info["phi_error_deg"][:, 0])
        alive &= ~(res.terminated | res.truncated)
    return np.array(n2), np.array(err), np.array(phi)


def test_filter_is_consistent_on_the_river():
    """50 runs of river_escort boats (~6 s) on the paper's channel with the paper's filter
    (RIVER_PAPER_SETTINGS: no telemetry, the Q that filter needs on the river): the
    run-average (x, y) NEES, over the cycles in which >= 90 % of the runs are alive, averages
    inside the two-sided 95 % band chi2(2 B) / B and lies in it at most cycles. Measured: 2.22
    and 88 % (seeds 0-49), 2.25 and 84 % (1000-1049)."""
    from scipy.stats import chi2

    B = 50
    n2, err, _ = river_nees_runs(B, **RIVER_PAPER_SETTINGS)
    full = np.isfinite(n2).sum(1) >= 0.9 * B
    lo, hi = chi2.ppf([0.025, 0.975], 2 * B) / B
    avg = np.nanmean(n2[full], 1)
    assert lo < np.mean(avg) < hi
    assert np.mean((avg > lo) & (avg < hi)) > 0.75
    assert np.nanmean(err) < 2.0


def _river_per_cycle(B, seed0):
    """B river_escort runs at the scenario's defaults (outliers 3 %, losses 5-50 %): the
    per-cycle figures of benchmarks/nees_per_cycle.py (mean NEES, fraction of run-cycles in the
    per-cycle 95 % band, fraction above the 99.9 % point, runs whose error ever exceeds 20 m)."""
    from scipy.stats import chi2

    n2, err, _ = river_nees_runs(B, seed0)
    v = n2[np.isfinite(n2)]
    band = chi2.ppf([0.025, 0.975], 2)
    in_band = np.mean((v >= band[0]) & (v <= band[1]))
    return v.mean(), in_band, np.mean(v > chi2.ppf(0.999, 2)), int(np.sum(np.nanmax(err, 0) > 20.0))


def test_river_per_cycle_nees_on_the_projects_channel():
    """Issue 21's target on the river with outliers and losses, 20 runs (seeds 0-19, ~10 s): the
    mean (x, y) NEES inside the band of a mean of 20 chi2(2), at least 90 % of run-cycles inside
    the per-cycle 95 % band, at most 5x the nominal 0.1 % above the 99.9 % point, no run's error
    above 20 m. Measured: 2.03, 94.5 %, 0.18 %, worst 4.0 m. With the paper's filter (before the
    boats' telemetry) 9 of these runs passed 20 m (mean NEES 2580, 88 %, 4.4 %); with the telemetry but the recovery's
    velocity prior at 0.3 m/s, run 11 did (27.9 m: two outlier fixes of one multipath kind
    restarted a filter that was right; docs/scenarios/matos-cruz.md#channel)."""
    from scipy.stats import chi2

    mean, in_band, above, above_20 = _river_per_cycle(20, 0)
    lo, hi = chi2.ppf([0.025, 0.975], 40) / 20
    assert lo < mean < hi, mean
    assert in_band > 0.90, in_band
    assert above < 0.005, above
    assert above_20 == 0, above_20


@pytest.mark.slow
def test_river_meets_issue_21s_target_on_the_projects_channel():
    """100 runs (seeds 1000-1099): the mean (x, y) NEES inside the band of a mean of 100
    chi2(2) and no run's error above 20 m. Measured: 2.02, 94.8 % in the per-cycle band, 0 runs."""
    from scipy.stats import chi2

    mean, _, _, above_20 = _river_per_cycle(100, 1000)
    lo, hi = chi2.ppf([0.025, 0.975], 200) / 100
    assert lo < mean < hi and above_20 == 0, (mean, above_20)


# --- the boats' telemetry in the filter (issue 21): the frame's bearing and its motion ----------
def test_bearing_variance_by_hand():
    """Eq. B1: GPS errors of 2.1 m per axis at both boats, 100 m apart: var = 2 x 2.1^2 / 100^2
    = 8.82e-4 rad^2, 1.70 deg; at 50 m four times it."""
    from coopnav_env.core.moving_network.filter import bearing_variance_rad2

    assert bearing_variance_rad2(2.1, 100.0) == pytest.approx(8.82e-4)
    assert np.degrees(np.sqrt(bearing_variance_rad2(2.1, 100.0))) == pytest.approx(1.7016, abs=1e-4)
    assert bearing_variance_rad2(2.1, 50.0) == pytest.approx(4 * 8.82e-4)


def test_bearing_update_by_hand_and_wrapped():
    """A scalar Kalman update on phi: P_phiphi = 0.01, R = 0.01, phi_hat = 0.1, z = 0.2: gain
    1/2, phi = 0.15, P_phiphi = 0.005; x, correlated with phi by P_x,phi = 0.005, moves by
    0.005 / 0.02 x 0.1 = 0.025 and its variance drops by 0.005^2 / 0.02 = 1.25e-3. Across the
    +-pi seam (phi_hat = 3.1, z = -3.1) the innovation is 2 pi - 6.2 = 0.0832, not -6.2."""
    from coopnav_env.core.moving_network.filter import filter_work, update_phi

    E = np.array([10.0, 20.0, 0.1, 0.0, 0.0, 100.0])
    P = np.diag([1.0, 1.0, 0.01, 0.1, 0.1, 1.0])
    P[0, 2] = P[2, 0] = 0.005
    update_phi(E, P, 0.2, 0.01, filter_work())
    assert E[2] == pytest.approx(0.15)
    assert P[2, 2] == pytest.approx(0.005)
    assert E[0] == pytest.approx(10.025)
    assert P[0, 0] == pytest.approx(1.0 - 1.25e-3)
    assert E[1] == 20.0 and E[5] == 100.0
    E = np.array([0.0, 50.0, 3.1, 0.0, 0.0, 100.0])
    P = np.diag([1.0, 1.0, 0.01, 0.1, 0.1, 1.0])
    update_phi(E, P, -3.1, 0.01, filter_work())
    assert E[2] == pytest.approx(3.1 + 0.5 * (2 * np.pi - 6.2))


def test_telemetry_covariance_by_hand():
    """Eq. M3 for sigma_v = 0.05 m/s over T = 2 s at l = 100 m: sigma_v^2 T^2 = 0.01 m^2;
    var(d_x) = var(d_y) = 0.01, var(dphi) = 2 x 0.01 / 100^2 = 2e-6, var(dl) = 0.02,
    cov(d_y, dphi) = -1e-4, cov(d_x, dl) = -0.01, the rest 0."""
    from coopnav_env.core.moving_network.frame_motion import telemetry_covariance

    S = np.empty((4, 4))
    telemetry_covariance(0.05, 2.0, 100.0, S)
    want = np.array([[0.01, 0, 0, -0.01], [0, 0.01, -1e-4, 0], [0, -1e-4, 2e-6, 0], [-0.01, 0, 0, 0.02]])
    np.testing.assert_allclose(S, want, rtol=1e-12, atol=1e-15)


def test_move_frame_by_hand():
    """Eq. M1 with the frame turned 90 deg clockwise after B1 moved (1, 2) in it: (x, y) = (10,
    20) -> (x - 1, y - 2) = (9, 18) -> x' = 18, y' = -9 (a point on the frame's y side is met by
    the turning x axis); c = (0.3, 0) -> (0, -0.3); phi + pi / 2, l + 0.5. With P = I and no
    telemetry error, P' = J J^T = I. Then eq. M2 at dphi = 0 with var(dphi) = 1e-4 alone: x'
    gains y'^2 1e-4 = 0.04 (y' = 20), y' gains x'^2 1e-4 = 0.01, cov(x', y') = -x' y' 1e-4 = -0.02."""
    from coopnav_env.core.moving_network.frame_motion import move_frame

    E = np.array([10.0, 20.0, 0.5, 0.3, 0.0, 100.0])
    P = np.eye(6)
    moved = move_frame(E, P, np.array([1.0, 2.0, np.pi / 2, 0.5]), np.zeros((4, 4)))
    np.testing.assert_allclose(E, [18.0, -9.0, 0.5 + np.pi / 2, 0.0, -0.3, 100.5], atol=1e-12)
    np.testing.assert_allclose(P, np.eye(6), atol=1e-12)
    np.testing.assert_allclose(moved, [2.0, -1.0], atol=1e-12)  # d = (1, 2) in the new frame
    E = np.array([10.0, 20.0, 0.5, 0.0, 0.0, 100.0])
    P = np.zeros((6, 6))
    S = np.zeros((4, 4))
    S[2, 2] = 1e-4
    move_frame(E, P, np.zeros(4), S)
    assert (P[0, 0], P[1, 1], P[0, 1], P[2, 2]) == pytest.approx((0.04, 0.01, -0.02, 1e-4))


def test_move_frame_follows_the_boats_in_the_world():
    """The boats move and turn the frame (B1 (0, 0) -> (3, -1), B2 (100, 0) -> (101, -12),
    east-north): a point fixed in the world, at its frame coordinates before, lands by eq. M1
    (the motion as the simulator computes it, without GPS velocity error) on its frame
    coordinates after; the frame's bearing and length change as the boats' GPS gives them."""
    from coopnav_env.core.moving_network import MovingNetworkSimulator
    from coopnav_env.core.moving_network.frame_motion import move_frame

    sim = MovingNetworkSimulator(make_config("matos_river", boat_velocity_noise_mps=0.0), 1)
    sim.reset([0])
    start = np.array([[[0.0, 0.0], [100.0, 0.0]]])
    end = np.array([[[3.0, -1.0], [101.0, -12.0]]])
    draws = {"motion": np.zeros((1, 2, 2))}
    motion = sim._frame_motion(start, end, draws)[0]
    p = np.array([[40.0, -55.0]])
    x0, y0, phi0, l0 = lbl.world_to_frame(start[:, 0], start[:, 1], p)
    x1, y1, phi1, l1 = lbl.world_to_frame(end[:, 0], end[:, 1], p)
    E = np.array([x0[0], y0[0], phi0[0], 0.0, 0.0, l0[0]])
    move_frame(E, np.eye(6), motion, np.zeros((4, 4)))
    np.testing.assert_allclose(E[[0, 1, 2, 5]], [x1[0], y1[0], phi1[0], l1[0]], atol=1e-9)


def test_telemetered_motion_errors_match_eq_m3():
    """The simulator's telemetered motion (``_frame_motion``) minus the true one, over 20000
    draws of the boats' GPS velocity errors: its covariance is eq. M3's (sigma_v = 0.05 m/s,
    T = 2 s, l = 100 m) within 5 % of the diagonal."""
    from coopnav_env.core.moving_network import MovingNetworkSimulator
    from coopnav_env.core.moving_network.frame_motion import telemetry_covariance

    B = 20000
    sim = MovingNetworkSimulator(make_config("matos_river"), 1)
    sim.batch_size = B  # _frame_motion reads only the config and the batch size
    start = np.broadcast_to(np.array([[0.0, 0.0], [0.0, 100.0]]), (B, 2, 2))  # frame x along north
    end = start + np.array([[1.0, 2.0], [1.5, 2.0]])
    draws = {"motion": np.random.default_rng(5).standard_normal((B, 2, 2))}
    truth = sim._frame_motion(start, end, {"motion": np.zeros((B, 2, 2))})
    err = sim._frame_motion(start, end, draws) - truth
    S = np.empty((4, 4))
    telemetry_covariance(0.05, 2.0, 100.0, S)
    scale = np.sqrt(np.outer(np.diag(S), np.diag(S)))
    assert np.all(np.abs(np.cov(err.T) - S) < 0.05 * scale)


def test_paper_settings_keep_the_papers_filter():
    """The river defaults to the telemetry; PAPER_SETTINGS / RIVER_PAPER_SETTINGS switch it off
    (and restore the Q of the paper's filter on the river); matos_moving_lbl keeps the paper's
    filter. With them, the boats' telemetered motion is zero and the filter's (x, y, c) evolve
    as the paper's (the prediction plus the range updates alone)."""
    from coopnav_env.core.moving_network import MovingNetworkSimulator
    from coopnav_env.scenarios.matos import PAPER_SETTINGS

    c = make_config("matos_river")
    assert c.frame_bearing_fusion and c.frame_motion_telemetry
    for name, settings in (("matos_river", RIVER_PAPER_SETTINGS), ("matos_moving_lbl", PAPER_SETTINGS)):
        p = make_config(name, **settings)
        assert not p.frame_bearing_fusion and not p.frame_motion_telemetry
    assert not make_config("matos_moving_lbl").frame_motion_telemetry
    assert make_config("matos_river", **RIVER_PAPER_SETTINGS).frame_q_position_m2ps == 0.5
    sim = MovingNetworkSimulator(make_config("matos_river", **RIVER_PAPER_SETTINGS), 1)
    sim.reset([0])
    start = np.array([[[0.0, 0.0], [100.0, 0.0]]])
    moved = sim._frame_motion(start, start + 5.0, {"motion": np.ones((1, 2, 2))})
    assert np.all(moved == 0.0)
