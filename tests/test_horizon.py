"""The receding-horizon planner (baselines/horizon.py) on toy cases with known optima.

The toy: a stationary survey vehicle at SURVEY at the beacon's depth (dz = 0), no
process noise, no packet loss, range variance R = 1 m^2 at every distance (the sound
speed known: no scale error), the beacon's own position exact, a 40 m reaching set
(2 m/s x 20 s) and a 3 m safety distance.

* One range from a unit horizontal direction h reduces the trace of P by
  h'P^2 h / (h'Ph + R). For P = diag(a, b) in the frame of its axes and
  x = cos^2 of the angle between h and the major axis, that is
  f(x) = (b^2 + (a^2 - b^2) x) / (b + R + (a - b) x), and
  f'(x) has the sign of (a - b)(ab + aR + bR) > 0 for a > b: the best range is along
  the major axis (Gao & Chitre's rule), the worst along the minor one.
* From an isotropic prior P0 = s I, two ranges at angle t between them give the
  information J = I/s + (u1 u1' + u2 u2')/R, tr J = 2/s + 2/R,
  det J = 1/s^2 + 2/(sR) + sin^2 t / R^2, and tr P = tr J / det J: smallest at
  t = 90 deg, where P = (sR/(s + R)) I. The beacon can always reach that geometry
  within one ping (its bearing from the survey vehicle may change by 90 deg). The
  first range's trace tr P1 does not depend on its direction, so the H = 2 plan
  (minimum of tr P1 + tr P2) puts its two ranges at right angles.
* From the elongated prior, the H = 2 optimum is not greedy: the first range is
  ~7 deg off the major axis, so that both ranges inform it (two ranges at +-t
  about the major axis of diag(a, b) would share it best at cos^2 t ~ 0.75 if only
  tr P2 counted; tr P1 pulls the first back towards the axis). Its reference value
  is a 0.1 deg grid over both directions (every direction pair is reachable: both
  reaching discs contain the survey vehicle, dz = 0).
"""

import re

import numpy as np
import pytest

import coopnav_env
from baselines import make_policy
from baselines.base import BeaconContext
from baselines.horizon import expected_covariances, horizon_cost
from coopnav_env.core.information import error_ellipse
from coopnav_env.obs_layout import encode

TOY = coopnav_env.make_config(
    "sousa_asv",
    survey_path="stationary",
    ping_interval_s=20.0,
    asv_max_speed_mps=2.0,
    safety_distance_m=3.0,
    packet_loss_near=0.0,
    packet_loss_far=0.0,
    process_noise_horizontal_m2ps=0.0,
    range_noise_std_m=1.0,
    temperature_uncertainty_c=0.0,
)
SURVEY = np.array([20.0, 10.0])
R = 1.0


def observe(own, P):
    major, minor, bearing = error_ellipse(P)
    rel = [[*(SURVEY - own), 0.0]]
    return encode(TOY, own_en_m=own, survey_rel_m=rel, major_m=major, minor_m=minor, bearing_rad=bearing, own_std_m=0.0)


def range_update(P, beacon):
    h = (SURVEY - beacon) / np.linalg.norm(SURVEY - beacon)
    Ph = P @ h
    return P - np.outer(Ph, Ph) / (h @ Ph + R)


def bearing_deg(beacon):
    d = beacon - SURVEY
    return np.degrees(np.arctan2(d[0], d[1])) % 360.0


def test_expected_covariance_is_the_kalman_update_weighted_by_arrival():
    """Eq. (H1) against a hand Kalman update, with a 30 % loss: E[P+] = 0.7 P_upd + 0.3 P."""
    c = TOY.replace(packet_loss_near=0.3, packet_loss_far=0.3)
    ctx = BeaconContext.from_config(c)
    P0 = np.array([[9.0, 2.0], [2.0, 4.0]])
    beacon = np.array([[[SURVEY[0] + 30.0, SURVEY[1] + 40.0]]])  # (N=1, H=1, 2)
    P, P_none = expected_covariances(beacon, SURVEY[None, None], np.zeros((1, 1)), P0[None], np.zeros((1, 1)), 0.0, ctx)
    want = 0.7 * range_update(P0, beacon[0, 0]) + 0.3 * P0
    np.testing.assert_allclose(P[0, 0, 0], [want[0, 0], want[0, 1], want[1, 1]], rtol=1e-12)
    np.testing.assert_allclose(P_none[0, 0], [9.0, 2.0, 4.0])
    assert horizon_cost(P, P_none)[0] == pytest.approx(np.trace(want) / 13.0)


def direction_deg(beacon):
    """Bearing of the range direction, mod 180 (a range informs the same both ways)."""
    return bearing_deg(beacon) % 180.0


def angle_between_deg(x, y):
    d = abs(x - y) % 180.0
    return min(d, 180.0 - d)


def plan_pings(policy):
    """The planned ping positions (H, 2) of the policy's last decision."""
    v = policy.plan_v[policy.me]  # (H, 2) this beacon's part of the plan
    return policy.last_waypoint - policy.ctx.reach_m * v[0] + policy.ctx.reach_m * np.cumsum(v, 0)


def brute_force_two_pings(P0, step_deg=0.1, first_deg=None):
    """min over range directions (phi1, phi2) of tr P1 + tr P2 (the H = 2 cost up to its
    constant denominator), on a grid; the beacon can reach every direction pair.
    ``first_deg``: phi1 fixed there (the greedy first range)."""
    phi = np.radians(np.arange(0.0, 180.0, step_deg))
    h = np.stack([np.sin(phi), np.cos(phi)], -1)
    h1 = h if first_deg is None else np.array([[np.sin(np.radians(first_deg)), np.cos(np.radians(first_deg))]])

    def update(a, b, c, he, hn):
        ue, un = a * he + b * hn, b * he + c * hn
        k = 1.0 / (he * ue + hn * un + R)
        return a - k * ue * ue, b - k * ue * un, c - k * un * un

    a1, b1, c1 = update(P0[0, 0], P0[0, 1], P0[1, 1], h1[:, 0], h1[:, 1])  # (A,)
    a2, _b2, c2 = update(a1[:, None], b1[:, None], c1[:, None], h[None, :, 0], h[None, :, 1])  # (A, A)
    cost = (a1 + c1)[:, None] + a2 + c2
    i, j = np.unravel_index(np.argmin(cost), cost.shape)
    return np.degrees(phi[i]) if first_deg is None else first_deg, np.degrees(phi[j]), cost[i, j]


def elongated(major_bearing_deg, a=100.0, b=1.0):
    th = np.radians(major_bearing_deg)
    u = np.array([np.sin(th), np.cos(th)])
    w = np.array([u[1], -u[0]])
    return a * np.outer(u, u) + b * np.outer(w, w), w


@pytest.mark.parametrize("major_bearing_deg", [90.0, 30.0])
def test_one_ping_horizon_ranges_along_the_major_axis(major_bearing_deg):
    """H = 1, elongated prior (2-sigma axes 20 m and 2 m), the beacon 30 m from the survey
    vehicle at right angles to the major axis: the next ping is on the major axis."""
    P, w = elongated(major_bearing_deg)
    own = SURVEY + 30.0 * w
    policy = make_policy("horizon", TOY, seed=3, horizon=1)
    policy.act(observe(own, P))
    assert np.linalg.norm(policy.last_waypoint - own) <= policy.ctx.reach_m + 1e-6
    assert angle_between_deg(direction_deg(policy.last_waypoint), major_bearing_deg % 180.0) < 0.5


@pytest.mark.parametrize("seed", [0, 1])
def test_two_ping_plan_from_an_isotropic_prior_is_at_right_angles(seed):
    """H = 2, P0 = 100 I: the first range's direction is free, the second's is at right
    angles to it, and the plan's cost is the closed form (tr P1 + tr P2) / (2 tr P0)."""
    s = 100.0
    own = SURVEY + np.array([0.0, 30.0])
    policy = make_policy("horizon", TOY, seed=seed, horizon=2)
    policy.act(observe(own, s * np.eye(2)))
    b1, b2 = plan_pings(policy)
    np.testing.assert_allclose(b1, policy.last_waypoint)
    assert angle_between_deg(direction_deg(b1), direction_deg(b2)) == pytest.approx(90.0, abs=3.0)
    m = s * R / (s + R)
    assert policy.last_cost == pytest.approx(((s + m) + 2 * m) / (4 * s), rel=1e-3)


@pytest.mark.parametrize("major_bearing_deg", [90.0, 30.0])
def test_two_ping_plan_matches_the_brute_force_optimum(major_bearing_deg):
    """H = 2, the elongated prior: the first range is NOT along the major axis (the greedy
    answer) but about 7 deg off it, so that the two ranges share the major axis (a grid
    over both directions finds it); the planner finds that optimum, and its cost is
    below the greedy plan's (first range on the major axis, the second at its best)."""
    P, w = elongated(major_bearing_deg)
    own = SURVEY + 30.0 * w
    phi1, _phi2, best = brute_force_two_pings(P)
    policy = make_policy("horizon", TOY, seed=2, horizon=2)
    policy.act(observe(own, P))
    b1, _b2 = plan_pings(policy)
    mirror = (2 * major_bearing_deg - phi1) % 180.0  # the optimum mirrored in the major axis
    got = direction_deg(b1)
    assert min(angle_between_deg(got, phi1), angle_between_deg(got, mirror)) < 1.5, (got, phi1, mirror)
    assert 4.0 < angle_between_deg(got, major_bearing_deg % 180.0) < 12.0
    assert policy.last_cost * 2 * np.trace(P) == pytest.approx(best, rel=2e-3)
    greedy = brute_force_two_pings(P, first_deg=major_bearing_deg)[2]
    assert best < greedy and policy.last_cost * 2 * np.trace(P) < greedy


def test_deterministic_given_the_seed_and_warm_started():
    """Same seed, same actions; the plan is kept (M = 1 beacon, H, 2) for the next decision's warm start."""
    obs = observe(SURVEY + np.array([0.0, 30.0]), np.diag([50.0, 5.0]))
    a = make_policy("horizon", TOY, seed=7)
    b = make_policy("horizon", TOY, seed=7)
    np.testing.assert_array_equal(a.act(obs), b.act(obs))
    assert a.plan_v.shape == (1, a.horizon, 2)
    with pytest.raises(ValueError, match="criterion"):
        make_policy("horizon", TOY, criterion="volume")


def test_expected_errors_with_the_error_unknown_are_eq_h1():
    """Eq. (H3) with W0 = P0 (the filter's own belief as the error's second moment) is eq.
    (H1): the Joseph form at the optimal gain, over 3 pings of 2 beacons with 30 % loss."""
    from baselines.horizon import team_expected_covariances, team_expected_errors

    c = TOY.replace(packet_loss_near=0.3, packet_loss_far=0.3)
    ctx = BeaconContext.from_config(c)
    rng = np.random.default_rng(3)
    beacons = SURVEY + rng.uniform(-60.0, 60.0, (5, 2, 3, 2))  # (N, M, H, 2)
    survey = np.broadcast_to(SURVEY, (3, 1, 2))
    P0 = np.array([[[9.0, 2.0], [2.0, 4.0]]])
    grow, var2, dz = np.full((3, 1), 0.5), np.array([0.0, 3.0]), np.zeros((2, 3, 1))  # R = 1 and 4 m^2
    P, P_none = team_expected_covariances(beacons, survey, dz, P0, grow, var2, ctx)
    W, W_none = team_expected_errors(beacons, survey, dz, P0, grow, var2, ctx, P0)
    np.testing.assert_allclose(W, P, rtol=1e-12)
    np.testing.assert_allclose(W_none, P_none)


def test_expected_error_of_a_known_error_by_hand():
    """Eq. (H3), one range with a 30 % loss, the error now e0 known: E[W+] =
    0.7 (A e0 e0' A' + R K K') + 0.3 e0 e0', K from the filter's covariance P0."""
    from baselines.horizon import team_expected_errors

    c = TOY.replace(packet_loss_near=0.3, packet_loss_far=0.3)
    ctx = BeaconContext.from_config(c)
    P0 = np.array([[9.0, 2.0], [2.0, 4.0]])
    e0 = np.array([3.0, -1.0])
    beacon = np.array([[[[SURVEY[0] + 30.0, SURVEY[1] + 40.0]]]])  # (N=1, M=1, H=1, 2)
    W, _ = team_expected_errors(
        beacon,
        SURVEY[None, None],
        np.zeros((1, 1, 1)),
        P0[None],
        np.zeros((1, 1)),
        np.array([0.0]),  # the beacon's own variance: R = range_noise_std_m^2 = 1
        ctx,
        np.outer(e0, e0)[None],
    )
    h = (SURVEY - beacon[0, 0, 0]) / 50.0
    K = P0 @ h / (h @ P0 @ h + R)
    A = np.eye(2) - np.outer(K, h)
    want = 0.7 * (A @ np.outer(e0, e0) @ A.T + R * np.outer(K, K)) + 0.3 * np.outer(e0, e0)
    np.testing.assert_allclose(W[0, 0, 0], [want[0, 0], want[0, 1], want[1, 1]], rtol=1e-12)


@pytest.mark.parametrize("error_en", [(6.0, 0.0), (0.0, 6.0)])
def test_oracle_ranges_along_the_error_it_is_told(error_en):
    """An isotropic covariance (25 m^2 each way) gives horizon no preferred bearing; the
    oracle, told the filter's error e0, ranges along it: |e0 - K h'e0|^2 is least for h
    parallel to e0 (K = P h / (h'Ph + R) is along h). From 30 m north of the survey
    vehicle the beacon can reach either axis in one ping."""
    from types import SimpleNamespace

    own, P = SURVEY + np.array([0.0, 30.0]), np.diag([25.0, 25.0])
    est = np.array([*SURVEY, 0.0])
    snap = SimpleNamespace(
        beacon_est_m=np.array([[[*own, 0.0]]]),
        beacon_true_m=np.array([[[*own, 0.0]]]),
        survey_est_m=est[None, None],
        survey_true_m=(est - [*error_en, 0.0])[None, None],
        survey_cov_en_m2=P[None, None],
    )
    oracle = make_policy("oracle", TOY, seed=4, horizon=1)
    oracle.observe_truth(snap, 0)
    oracle.act(observe(own, P))
    axis = 90.0 if error_en[0] else 0.0  # the error's axis: east-west or north-south
    assert angle_between_deg(direction_deg(oracle.last_waypoint), axis) < 5.0


def test_oracle_gets_the_truth_in_run_episodes_and_is_never_a_best_planner():
    from evaluation.episodes import run_episodes
    from evaluation.tasks import TASK_SETS

    calls = []
    config = coopnav_env.make_config("gao_lawnmower", max_cycles=3)
    from baselines.horizon import OraclePolicy

    orig = OraclePolicy.observe_truth
    try:
        OraclePolicy.observe_truth = lambda self, snap, row: calls.append(row) or orig(self, snap, row)
        rows, _ = run_episodes(config, "oracle", [11, 12])
    finally:
        OraclePolicy.observe_truth = orig
    assert len(rows) == 2 and sorted(set(calls)) == [0, 1] and len(calls) == 6
    assert all("oracle" not in ts.planners for ts in TASK_SETS.values())


def test_planned_steps_tells_the_oracle_the_truth(monkeypatch):
    """baselines.rollout.planned_steps (the NEES and range-model scripts' rollout) gives a
    privileged planner the truth before every step of every run, as the evaluation does."""
    from baselines.horizon import OraclePolicy
    from baselines.rollout import planned_steps

    calls = []
    orig = OraclePolicy.observe_truth
    monkeypatch.setattr(
        OraclePolicy, "observe_truth", lambda self, snap, row: calls.append(row) or orig(self, snap, row)
    )
    steps = list(planned_steps("gao_lawnmower", "oracle", {"max_cycles": 3}, 2, 11))
    assert len(steps) == 3 and sorted(calls) == [0, 0, 0, 1, 1, 1]


def test_oracle_under_a_transmit_schedule_still_gets_the_truth():
    """On a slotted channel (``sousa_ping``) every planner is wrapped with a transmit
    schedule (``baselines.schedule.ScheduledPolicy``); the wrapper hid the oracle's
    ``privileged`` flag, so the benchmark never passed it the truth and its results were
    horizon's to the digit (benchmark v4, 2026-12-03)."""
    from baselines.horizon import OraclePolicy
    from evaluation.episodes import run_episodes

    config = coopnav_env.make_config("sousa_ping", max_cycles=2)
    policy = make_policy("oracle", config, seed=1)
    assert type(policy).__name__ == "ScheduledPolicy" and policy.privileged
    assert not make_policy("horizon", config, seed=1).privileged
    calls = []
    orig = OraclePolicy.observe_truth
    try:
        OraclePolicy.observe_truth = lambda self, snap, row: calls.append(row) or orig(self, snap, row)
        run_episodes(config, "oracle", [11])
    finally:
        OraclePolicy.observe_truth = orig
    assert len(calls) == 2 * config.n_beacons  # every decision of every ASV


# two beacons (ASVs, both at the survey vehicle's depth) and the stationary survey vehicle of TOY
TEAM = TOY.replace(beacon_kinds=("asv", "asv"))


def observe_team(own, peer, P):
    major, minor, bearing = error_ellipse(P)
    rel = [[*(SURVEY - own), 0.0]]
    return encode(
        TEAM,
        own_en_m=own,
        survey_rel_m=rel,
        major_m=major,
        minor_m=minor,
        bearing_rad=bearing,
        own_std_m=0.0,
        peers_en_m=[peer],
    )


def test_joint_team_plan_puts_two_simultaneous_ranges_at_right_angles():
    """Two beacons 6 m apart, both 30 m north of the survey vehicle, P0 = 100 I, one ping
    ahead: the two ranges of the ping give tr P = tr J / det J with
    det J = 1/s^2 + 2/(sR) + sin^2 t / R^2 (module docstring), smallest at t = 90 deg,
    where tr P / tr P0 = R / (s + R) = 1/101. The joint plan reaches it (each beacon can
    move its bearing by 90 deg in one ping); each beacon, planning from its own
    observation with the episode's common random numbers, applies its own part, and the
    two applied positions are at right angles. Planning around the other held at its
    reported position (team="peers"), each moves to be at right angles to where the
    other WAS: both move, and the geometry they reach is poor."""
    s = 100.0
    b = [SURVEY + np.array([0.0, 30.0]), SURVEY + np.array([6.0, 30.0])]
    P = s * np.eye(2)
    joint = [make_policy("horizon", TEAM, seed=(5, j), agent=j, horizon=1, team="joint") for j in range(2)]
    for j, pol in enumerate(joint):
        pol.act(observe_team(b[j], b[1 - j], P))
        assert pol.planned == [0, 1] and pol.me == j and pol.plan_v.shape == (2, 1, 2)
        assert pol.last_cost == pytest.approx(R / (s + R), rel=1e-3)
        ping = np.stack(b) + pol.step_m[:, None] * pol.plan_v[:, 0]  # the plan's ping positions of both beacons
        assert angle_between_deg(direction_deg(ping[0]), direction_deg(ping[1])) == pytest.approx(90.0, abs=2.0)
    applied = [pol.last_waypoint for pol in joint]
    assert angle_between_deg(direction_deg(applied[0]), direction_deg(applied[1])) == pytest.approx(90.0, abs=0.5)
    held = [make_policy("horizon", TEAM, seed=(5, j), agent=j, horizon=1, team="peers") for j in range(2)]
    for j, pol in enumerate(held):
        pol.act(observe_team(b[j], b[1 - j], P))
    apart = angle_between_deg(direction_deg(held[0].last_waypoint), direction_deg(held[1].last_waypoint))
    assert apart < 20.0, apart  # ~11 deg: each turned 90 deg from where the other was


def test_horizon_cost_criteria_and_terminal_weight_by_hand():
    """Two pings, one survey vehicle: traces 8 and 2 with ranges, 18 and 32 without.
    trace: (8 + 2) / (18 + 32) = 0.2; the last ping counted twice (terminal_weight=1):
    (8 + 4) / (18 + 64); sqrt_trace: (sqrt 8 + sqrt 2) / (sqrt 18 + sqrt 32) = 3/7."""
    P = np.array([[[[4.0, 0.0, 4.0]], [[1.0, 0.0, 1.0]]]])  # (N=1, H=2, S=1, 3)
    P_none = np.array([[[9.0, 0.0, 9.0]], [[16.0, 0.0, 16.0]]])
    assert horizon_cost(P, P_none)[0] == pytest.approx(0.2)
    assert horizon_cost(P, P_none, terminal_weight=1.0)[0] == pytest.approx(12.0 / 82.0)
    assert horizon_cost(P, P_none, "sqrt_trace")[0] == pytest.approx(3.0 / 7.0)
    assert horizon_cost(P, P_none, "logdet")[0] == pytest.approx(np.log(16 / 81) + np.log(1 / 256))
    with pytest.raises(ValueError, match="criterion must be one of"):
        horizon_cost(P, P_none, "volume")


def test_default_horizon_looks_30_s_ahead_in_4_to_6_pings():
    from baselines.horizon import default_horizon

    assert [default_horizon(t) for t in (20.0, 10.0, 7.5, 5.0, 2.0)] == [4, 4, 4, 6, 6]
    assert make_policy("horizon", TOY).horizon == 4  # TOY pings every 20 s
    assert make_policy("horizon", coopnav_env.make_config("sousa_asv")).horizon == 6  # every 5 s
    assert make_policy("horizon", TOY, horizon=3).horizon == 3


def test_mls_window_in_the_planners_channel_and_the_oracle_hears_at_the_true_distance():
    """The MLS array hears every sender within ``mls_max_range_m`` and none beyond, so the
    planners' delivery probability is that window (before, the modem's loss curve over
    1500 m: on ``swarm_mls`` at 0.3 m/s the oracle sat 130 m away, ellipse 71 m). The
    oracle's channel is at the true distance, its update at the filter's geometry: a
    survey estimate 50 m from the beacon whose truth is 70 m away gets no range."""
    from baselines.horizon import _team_loop

    mls = BeaconContext.from_config(coopnav_env.make_config("swarm_mls"))
    assert mls.acoustic_range_m == 60.0
    np.testing.assert_array_equal(mls.delivery_probability(np.array([5.0, 60.0, 60.01, 200.0])), [1, 1, 0, 0])
    modem = BeaconContext.from_config(coopnav_env.make_config("gao_sea"))
    assert modem.acoustic_range_m == coopnav_env.make_config("gao_sea").max_range_m
    assert 0.4 < float(modem.delivery_probability(np.array([200.0]))[0]) < 1.0
    beacon = np.zeros((1, 1, 1, 2))
    survey = np.array([[[50.0, 0.0]]])  # (H, S, 2): the estimate, 50 m east
    P0 = np.diag([25.0, 25.0])[None]
    args = (beacon, survey, np.zeros((1, 1, 1)), P0, np.zeros((1, 1)), np.array([1.0]), mls)
    heard, _ = _team_loop(*args)
    assert heard[0, 0, 0, 0] < 2.0  # east variance 25 -> ~0.96 after one range along east
    unheard, _ = _team_loop(*args, channel_shift=np.array([[20.0, 0.0]]))  # truly 70 m away
    np.testing.assert_allclose(unheard[0, 0, 0], [25.0, 0.0, 25.0])


def test_planners_weigh_a_range_by_the_filters_variance_at_its_distance():
    """With ``range_model="filter"`` the planners' R is the survey filter's R(d)
    (``measurements.range_variance_m2``, the ufunc the modem kernel calls): the ranging
    noise, the beacon's own variance and the sound speed's scale error (d std(c)/c)^2,
    which grows with the distance. By hand on ``gao_sea`` with a 2 degC temperature
    uncertainty: Mackenzie's dc/dT at the mid-depth, and eq. (H1) from a beacon 1,200 m
    away (the default, ``"constant"``: R the same at every distance, 1 m^2 + the beacon's
    variance, here less than half of R(1,200 m))."""
    from coopnav_env.core.acoustics import mackenzie_sound_speed

    c = coopnav_env.make_config("gao_sea", temperature_uncertainty_c=2.0, packet_loss_near=0.0, packet_loss_far=0.0)
    constant = BeaconContext.from_config(c)
    np.testing.assert_array_equal(
        constant.range_variance_m2(np.array([10.0, 1200.0]), 0.3), c.range_noise_std_m**2 + 0.3
    )
    ctx = constant.with_range_model("filter")
    depth = 0.5 * (c.beacon_auv_depth_m + c.depth_m)
    c0 = float(mackenzie_sound_speed(c.water_temperature_c, c.salinity_psu, depth))
    dc_dT = float(mackenzie_sound_speed(c.water_temperature_c + 1.0, c.salinity_psu, depth)) - c0
    rel = 2.0 * dc_dT / c0
    d = np.array([10.0, 1200.0])
    R_hand = c.range_noise_std_m**2 + 0.3 + (d * rel) ** 2
    np.testing.assert_allclose(ctx.range_variance_m2(d, 0.3), R_hand, rtol=1e-12)
    assert R_hand[1] > 2.0 * (c.range_noise_std_m**2 + 0.3)
    # (H1) with that R: a beacon 1,200 m east of the survey vehicle, at its depth
    P0 = np.diag([400.0, 100.0])
    beacon = np.array([[[1200.0, 0.0]]])  # (N=1, H=1, 2)
    P, _ = expected_covariances(beacon, np.zeros((1, 1, 2)), np.zeros((1, 1)), P0[None], np.zeros((1, 1)), 0.3, ctx)
    want_east = 400.0 - 400.0**2 / (400.0 + R_hand[1])
    np.testing.assert_allclose(P[0, 0, 0], [want_east, 0.0, 100.0], rtol=1e-12)


def test_range_model_reaches_the_planners_and_is_checked():
    """``range_model`` is a keyword of ``ellipse``, ``horizon`` (so ``oracle``) and the event
    schedules; with a schedule it goes to both, and is dropped for a motion planner that
    weighs no range (``fim_a``). A bad value is refused by name."""
    assert make_policy("ellipse", "gao_sea", range_model="filter").ctx.range_model == "filter"
    h = make_policy("horizon", "gao_team", range_model="filter")
    assert h.ctx.range_model == "filter" and all(bc.range_model == "filter" for bc in h.team_ctx)
    assert make_policy("oracle", "gao_sea").ctx.range_model == "constant"
    p = make_policy("fim_a+event", "sousa_ping", range_model="filter")
    assert p.schedule.ctx.range_model == "filter"
    with pytest.raises(ValueError, match="range_model must be one of"):
        make_policy("ellipse", "gao_sea", range_model="d2")


@pytest.mark.parametrize(
    ("knob", "value", "what"),
    [
        ("horizon", 2.5, "horizon must be a whole number in [1, 50]"),
        ("horizon", True, "horizon must be a whole number"),
        ("horizon", 10**9, "horizon must be a whole number in [1, 50]"),
        ("n_samples", 10**8, "n_samples must be a whole number in [1, 4096]"),
        ("refine_iters", -1, "refine_iters must be a whole number in [0, 100]"),
        ("init_std", float("nan"), "init_std must be a finite number > 0"),
        ("terminal_weight", float("nan"), "terminal_weight must be a finite number >= 0"),
    ],
)
def test_the_planners_search_settings_are_refused_outside_their_range(knob, value, what):
    """A float, a bool, NaN, a negative count or 1e9 was taken (truncated) or planned for
    hours (an input audit ran ``--policies horizon:horizon=1e9`` into a timeout); the boats'
    planner shares the check (``check_search_settings``)."""
    with pytest.raises(ValueError, match=re.escape(what)):
        make_policy("horizon", TOY, **{knob: value})
    if knob not in ("horizon", "terminal_weight"):
        with pytest.raises(ValueError, match=re.escape(what)):
            make_policy("horizon", coopnav_env.make_config("matos_river"), **{knob: value})
    with pytest.raises(ValueError, match="n_elite must be at most n_samples"):
        make_policy("horizon", TOY, n_samples=4, n_elite=5)
