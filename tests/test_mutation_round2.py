"""Mutation review, round 2: tests that kill the one-line bugs the existing tests let
through in the statistics, the EKF step and the information geometry, the reward terms,
the greedy planners and transmit schedules, the seeds, the counter-based random numbers
and the channel's slot logic. Each asserts a hand-computed value, a reference library's
answer, a geometry with a known answer or a Monte Carlo bound (the mutant each kills is
named in its docstring; the review's table is in its report)."""

from __future__ import annotations

import numpy as np
import pytest
from test_baselines import SURVEY  # where the hand-built survey vehicles sit
from test_channel import obs_view  # a stub observation with what the schedules read

# ------------------------------------------------------------------------------------
# the benchmark's statistics


def test_a_paired_interval_that_touches_zero_is_a_tie():
    """An interval [lo, 0] or [0, hi] holds 0: neither a win nor a loss (kills hi <= 0 and
    lo >= 0 in ``paired_verdict``)."""
    from evaluation.benchmark_stats import paired_verdict

    assert paired_verdict(-1.0, 0.0) == "tie"
    assert paired_verdict(0.0, 1.0) == "tie"
    assert paired_verdict(0.0, 0.0) == "tie"
    assert paired_verdict(-1.0, -1e-12) == "win" and paired_verdict(1e-12, 1.0) == "loss"


def test_the_best_planner_on_a_tie_is_the_first_listed():
    """Two planners with the same mean error: the best is the first of ``planners``, as
    ``lowest_mean`` (kills a tie-break that takes the last listed)."""
    from evaluation.benchmark_stats import compare_task, lowest_mean

    errors = {"fim_a": [1.0, 3.0], "fim_b": [2.0, 2.0], "circle": [5.0, 5.0]}
    assert compare_task(errors, ["fim_b", "fim_a", "circle"])["best_planner"] == "fim_b"
    assert compare_task(errors, ["fim_a", "fim_b", "circle"])["best_planner"] == "fim_a"
    task = compare_task(errors, ["fim_a", "fim_b"])
    assert lowest_mean(task["policies"], ["fim_b", "fim_a"]) == "fim_b"


def _summary_row(rel: float, hi: float) -> tuple:
    # (set, challenger, n, n/a, mean, best, rel, pooled, (lo, hi), w, t, l, official, greedy)
    return ("s", "ppo", 2, 0, 4.0 * (1.0 + rel), 4.0, rel, -0.5, (-1.0, hi), 1, 1, 0, True, None)


@pytest.mark.parametrize(
    "rel, hi, verdict",
    [
        (-0.25, -0.1, "met"),  # 25 % below the best planner, resolved
        (-0.20, -0.1, "met"),  # exactly 20 % below: "at least 20 %"
        (-0.25, 0.1, "not met (-25 %)"),  # 25 % below on the mean, but the interval holds 0
        (-0.10, -0.1, "not met (-10 %)"),  # resolved, but only 10 % below
        (0.10, 0.3, "not met (+10 %)"),  # worse than the best planner
    ],
)
def test_the_20_percent_aim_verdict(rel, hi, verdict):
    """benchmark_summary's aim column: met iff the mean is at least 20 % below the best
    planner's AND the pooled paired interval lies below 0 (kills ``or`` for ``and`` and a
    flipped comparison with AIM)."""
    from benchmarks import benchmark_summary

    table = benchmark_summary.markdown([_summary_row(rel, hi)])
    row = table.splitlines()[-1]
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[8] == verdict, row


# ------------------------------------------------------------------------------------
# evaluate.py's error statistics (evaluation/stats.py)

_EPISODE_KEYS = (
    "final_error_m",
    "mean_dr_error_m",
    "return",
    "ranges_fused",
    "outliers_rejected",
    "beacon_distance_m",
    "pings",
    "energy_J",
)


def _rows(episodes: list) -> tuple:
    """(step rows, episode rows) of episodes given as lists of per-step errors; the
    values as the CSV's text, as evaluate.py reads them back."""
    steps = [{"seed": str(s), "survey_error_m": str(e)} for s, errs in enumerate(episodes) for e in errs]
    eps = [dict.fromkeys(_EPISODE_KEYS, "0") | {"seed": str(s)} for s in range(len(episodes))]
    return steps, eps


def test_error_stats_pool_every_step_of_episodes_of_unequal_length():
    """The mean is the pooled mean over steps (summary.json's "all steps"), not the mean of
    the episode means: episodes of 1 step at 0 m and 3 steps at 10 m pool to 30 / 4 = 7.5
    (the mean of episode means would be 5). Every cluster-bootstrap draw is a ratio
    sum(errors) / sum(steps) of resampled episodes, a weighted mean of episode means, so
    the interval lies in [0, 10] (dividing by the sample's own step count instead gives
    60 / 4 = 15 for the draw of the long episode twice)."""
    from evaluation.stats import error_stats

    steps, eps = _rows([[0.0], [10.0, 10.0, 10.0]])
    st = error_stats(steps, eps)
    assert st["mean_error_m"] == pytest.approx(7.5)
    assert st["steps"] == 4 and st["episodes"] == 2
    lo, hi = st["ci95_error_m"]
    assert 0.0 <= lo <= 7.5 <= hi <= 10.0 + 1e-12
    assert hi == pytest.approx(10.0)  # the draw of the long episode twice (p = 1/4) is the top


def test_error_stats_bootstrap_interval_matches_the_normal_one_on_many_episodes():
    """400 one-step episodes of N(5, 1) errors: the cluster bootstrap of the mean is
    close to normal, so its 2.5 and 97.5 percentiles sit 1.96 standard errors either side
    (Monte Carlo error of a 2000-draw percentile there: ~0.06 se; the 5th percentile would
    be 1.645 se)."""
    from evaluation.stats import error_stats

    x = np.random.default_rng(7).normal(5.0, 1.0, 400)
    steps, eps = _rows([[v] for v in x])
    st = error_stats(steps, eps)
    se = x.std() / np.sqrt(len(x))  # the bootstrap's standard error of a mean (ddof 0)
    lo, hi = st["ci95_error_m"]
    assert st["mean_error_m"] == pytest.approx(x.mean())
    assert (st["mean_error_m"] - lo) / se == pytest.approx(1.96, abs=0.15)
    assert (hi - st["mean_error_m"]) / se == pytest.approx(1.96, abs=0.15)


def test_error_stats_bootstrap_resamples_every_episode():
    """20 one-step episodes, the last at 100 m and the rest at 0: the mean is 5 m and a
    draw holds the last episode K ~ Binomial(20, 1/20) times (value 5 K), so the upper end
    is far above the mean (K = 3 or 4 at the 97.5th percentile) and the lower end is 0
    (P(K = 0) = 0.36). A bootstrap that never draws the last episode gives [0, 0]."""
    from evaluation.stats import error_stats

    steps, eps = _rows([[0.0]] * 19 + [[100.0]])
    st = error_stats(steps, eps)
    lo, hi = st["ci95_error_m"]
    assert st["mean_error_m"] == pytest.approx(5.0)
    assert lo == 0.0 and 15.0 <= hi <= 20.0


def test_frame_error_stats_keep_the_axes_apart():
    """The x and y statistics of the moving frame come from their own columns: x errors
    1, -1, 3 (mean 1, spread > 0), y errors all 0 (mean 0, std 0)."""
    from evaluation.stats import frame_error_stats

    rows = [{"error_x_m": str(ex), "error_y_m": "0.0"} for ex in (1.0, -1.0, 3.0)]
    st = frame_error_stats(rows)
    assert st["error_x_mean_m"] == pytest.approx(1.0) and st["error_y_mean_m"] == 0.0
    assert st["error_y_std_m"] == 0.0 and st["error_x_std_m"] > 1.0
    assert frame_error_stats([{"survey_error_m": "1.0"}]) == {}


# ------------------------------------------------------------------------------------
# counter-based random numbers (coopnav_env/core/rng.py)


def test_uniforms_stay_inside_the_open_interval_when_the_hash_is_zero():
    """Uniforms are in (0, 1) (the inverse normal CDF of 0 is -inf): the 53-bit value
    0 maps to 2**-54, not 0. SplitMix64's finalizer maps 0 to 0, so the key below makes
    the first number of counter 0 hash to exactly 0."""
    from coopnav_env.core import rng

    stream = rng.STREAM_CYCLE
    stream_bits = np.uint64((stream * 0xD1B54A32D192ED03) & 0xFFFFFFFFFFFFFFFF)
    keys = np.array([rng._C_INDEX ^ stream_bits], dtype=np.uint64)  # base ^ 1 * C_INDEX == 0
    u = rng.uniform(keys, stream, np.zeros(1, np.int64), (1,))
    assert 0.0 < u[0, 0] < 1.0 and u[0, 0] == pytest.approx(2.0**-54, rel=1e-12)
    assert np.isfinite(rng.normal(keys, stream, np.zeros(1, np.int64), (1,))).all()


def test_streams_counters_and_indices_draw_independent_uniforms():
    """Uniform (Kolmogorov-Smirnov), no repeated number within a draw, and other numbers
    for another stream, counter or environment (uncorrelated: |r| < 4 / sqrt(n))."""
    from scipy import stats

    from coopnav_env.core import rng

    keys = rng.env_keys(np.arange(8))
    c0 = np.zeros(8, np.int64)
    a = rng.uniform(keys, rng.STREAM_EPISODE, c0, (2000,))
    assert np.unique(a[0]).size == 2000 and np.unique(a).size == a.size
    assert stats.kstest(a.ravel(), "uniform").pvalue > 1e-3
    n = a.size
    for other in (
        rng.uniform(keys, rng.STREAM_CYCLE, c0, (2000,)),  # another stream, same counter
        rng.uniform(keys, rng.STREAM_EPISODE, c0 + 1, (2000,)),  # the next counter
        rng.uniform(rng.env_keys(np.arange(8) + 100), rng.STREAM_EPISODE, c0, (2000,)),  # other seeds
    ):
        assert not np.isin(other, a).any()
        assert abs(np.corrcoef(a.ravel(), other.ravel())[0, 1]) < 4.0 / np.sqrt(n)


# ------------------------------------------------------------------------------------
# transmit schedules (baselines/schedule.py)


def _sousa_ping(**kw):
    import coopnav_env

    return coopnav_env.make_config("sousa_ping", **kw)


def test_clock_schedule_transmits_in_the_slots_of_its_offset():
    """every=3, offset=1: slots 1, 4, 7 (k mod 3 == 1); every=1: every slot."""
    from baselines.schedule import ClockSchedule

    c = _sousa_ping()
    s = ClockSchedule(c, 0, every=3, offset=1)
    assert [k for k in range(9) if s.transmit(k, None)] == [1, 4, 7]
    assert [k for k in range(9) if ClockSchedule(c, 0, every=3).transmit(k, None)] == [0, 3, 6]
    assert all(ClockSchedule(c, 1).transmit(k, None) for k in range(5))


def test_tdma_beacons_take_their_own_turns():
    """Beacon j transmits in slots k with k mod F == j mod F: F = the number of beacons
    (2 on sousa_ping) by default, the scenario's tdma_frame_slots (3 here) when set;
    beacon 0 opens the frame (it owns slot 0)."""
    from baselines.schedule import TdmaSchedule

    c = _sousa_ping()
    assert c.n_beacons == 2
    turns = [[k for k in range(6) if TdmaSchedule(c, j).transmit(k, None)] for j in range(2)]
    assert turns == [[0, 2, 4], [1, 3, 5]]
    c3 = _sousa_ping(tdma_frame_slots=3)
    turns = [[k for k in range(6) if TdmaSchedule(c3, j).transmit(k, None)] for j in range(2)]
    assert turns == [[0, 3], [1, 4]]


def test_event_gain_sums_over_survey_vehicles_by_hand():
    """Two survey vehicles: one 50 m away along (0.6, 0.8) at the beacon's depth, one 30 m
    east and 40 m deeper (slant 50 m: h, the horizontal part of the unit slant vector, is
    (0.6, 0), not the horizontal unit vector (1, 0)). The gain is the sum of each one's
    log(1 + h'P'h / R), P' = P + q (age + T) I (not the largest of the two)."""
    from baselines.base import BeaconContext
    from baselines.schedule import predicted_gain_nats

    c = _sousa_ping()
    ctx = BeaconContext.from_config(c, 0)
    view = obs_view([[30.0, 40.0, 0.0], [30.0, 0.0, 40.0]], [np.diag([4.0, 1.0]), np.diag([9.0, 1.0])])
    q = c.process_noise_horizontal_m2ps * (5.0 + c.ping_interval_s)
    R = c.range_noise_std_m**2 + 0.25
    g1 = np.log1p((0.36 * (4.0 + q) + 0.64 * (1.0 + q)) / R)
    g2 = np.log1p(0.36 * (9.0 + q) / R)
    assert predicted_gain_nats(view, ctx) == pytest.approx(g1 + g2, rel=1e-12)


def test_event_schedule_transmits_only_when_the_gain_exceeds_the_threshold():
    """ "exceeds": a gain equal to the threshold stays silent, a hair above transmits;
    event_tdma transmits only in its own turn, whatever the gain."""
    from baselines.base import BeaconContext
    from baselines.schedule import EventSchedule, EventTdmaSchedule, predicted_gain_nats

    c = _sousa_ping()
    view = obs_view([[30.0, 40.0, 0.0]], [np.diag([4.0, 1.0])])
    g = predicted_gain_nats(view, BeaconContext.from_config(c, 0))
    assert g > 0.1
    assert not EventSchedule(c, 0, threshold_nats=g).transmit(0, view)
    assert EventSchedule(c, 0, threshold_nats=g * (1 - 1e-9)).transmit(0, view)
    both = EventTdmaSchedule(c, 1, threshold_nats=0.0)  # beacon 1: odd slots
    assert [k for k in range(4) if both.transmit(k, view)] == [1, 3]
    assert not EventTdmaSchedule(c, 1, threshold_nats=10 * g).transmit(1, view)


# ------------------------------------------------------------------------------------
# the greedy planners (baselines/fim.py, baselines/ellipse.py)


def _asv(**kw):
    """tests/test_baselines.py's ASV scenario (round numbers: 2 m/s x 20 s, 10 m safety
    distance, a survey vehicle at rest 20 m down) with ``kw`` changed."""
    from test_baselines import ASV

    return ASV.replace(**kw)


def test_fim_a_sums_the_metric_over_survey_vehicles():
    """With several survey vehicles approach A's metric is summed over them: two vehicles
    at the same place give twice one vehicle's best det, at the same waypoint."""
    from baselines.base import BeaconContext
    from baselines.fim import fim_a_waypoint

    ctx = BeaconContext.from_config(_asv())
    own = SURVEY + [45.0, -20.0]
    wp1, v1 = fim_a_waypoint(ctx, own, SURVEY[None], [20.0])
    wp2, v2 = fim_a_waypoint(ctx, own, np.stack([SURVEY, SURVEY]), [20.0, 20.0])
    assert v2 == pytest.approx(2.0 * v1, rel=1e-9)
    np.testing.assert_allclose(wp2, wp1, atol=1e-6)


def test_fim_b_plans_for_the_vehicle_one_ping_ahead():
    """The survey vehicle moved 20 m north in one 20 s ping (1 m/s): approach B's p1 is
    where it is now and p2 where it will be one ping later, 20 m further north (the
    paper's eqs. 5-6). The planned waypoint and metric are fim_b_waypoint's for those
    hand-computed positions (not two pings ahead)."""
    from baselines import make_policy
    from baselines.fim import fim_b_waypoint
    from coopnav_env.obs_layout import decode, encode

    c = _asv(depth_m=0.0)
    policy = make_policy("fim_b", c)
    own = SURVEY + [60.0, 0.0]
    policy.act(encode(c, own_en_m=own, survey_rel_m=[[-60.0, 0.0, 0.0]]))
    obs = encode(c, own_en_m=own, survey_rel_m=[[-60.0, 20.0, 0.0]])
    policy.act(obs)
    p1, p2 = SURVEY + [0.0, 20.0], SURVEY + [0.0, 40.0]
    wp, val = fim_b_waypoint(policy.ctx, decode(obs, c).own_en_m, p1[None], [0.0], p2[None], [0.0])
    assert policy.last_metric == pytest.approx(val, rel=1e-6)
    np.testing.assert_allclose(policy.last_waypoint, wp, atol=1e-6)


def _ellipse_gain_by_hand(policy, survey_en, depth_below, P):
    """Gao & Chitre's expected information of a range from the planner's waypoint:
    P(arrive | d) log(1 + h'Ph / R), h the horizontal part of the unit slant vector,
    R the ranging noise plus the beacon's own position variance (2 m std here)."""
    c = policy.config
    d = np.asarray(policy.last_waypoint) - survey_en
    slant = np.sqrt(d @ d + depth_below**2)
    h = d / slant
    R = c.range_noise_std_m**2 + 2.0**2
    return float(policy.ctx.delivery_probability(slant)) * np.log1p(h @ P @ h / R)


def test_ellipse_metric_is_the_expected_information_of_the_grown_covariance():
    """A survey vehicle standing still, its reply 7 s old: the planner weighs the reported
    covariance (2-sigma ellipse 30 m x 4 m, major axis north: diag(4, 225)) grown by the
    process noise over the reply's age and one ping, P = P0 + q (7 + T) I, and the value
    it reports at its waypoint is the hand-computed expected information there."""
    from baselines.ellipse import EllipsePolicy
    from coopnav_env.obs_layout import encode

    c = _asv(depth_m=5.0)
    policy = EllipsePolicy(c)
    own = SURVEY + [25.0, 0.0]
    obs = encode(
        c, own_en_m=own, survey_rel_m=[[-25.0, 0.0, 5.0]], major_m=30.0, minor_m=4.0, bearing_rad=0.0, reply_age_s=7.0
    )
    policy.act(obs)
    q = c.process_noise_horizontal_m2ps
    assert q > 0
    P = np.diag([4.0, 225.0]) + q * (7.0 + c.ping_interval_s) * np.eye(2)
    assert policy.last_metric == pytest.approx(_ellipse_gain_by_hand(policy, SURVEY, 5.0, P), rel=1e-5)


def test_ellipse_plans_for_the_vehicle_one_ping_ahead():
    """The vehicle moved 20 m north in one 20 s ping: with the constant-velocity predictor
    the range is planned for where it will be at the next ping, 20 m further north."""
    from baselines.ellipse import EllipsePolicy
    from coopnav_env.obs_layout import encode

    c = _asv(depth_m=5.0)
    policy = EllipsePolicy(c, predictor="chord")
    own = SURVEY + [25.0, 0.0]
    policy.act(encode(c, own_en_m=own, survey_rel_m=[[-25.0, 0.0, 5.0]], major_m=30.0, minor_m=4.0))
    policy.act(encode(c, own_en_m=own, survey_rel_m=[[-25.0, 20.0, 5.0]], major_m=30.0, minor_m=4.0))
    P = np.diag([4.0, 225.0]) + c.process_noise_horizontal_m2ps * c.ping_interval_s * np.eye(2)  # reply age 0
    ahead = SURVEY + [0.0, 40.0]
    assert policy.last_metric == pytest.approx(_ellipse_gain_by_hand(policy, ahead, 5.0, P), rel=1e-5)


def _sin2(p, a, b):
    """sin^2 of the angle at p between the directions to a and to b (2-D)."""
    u, v = np.asarray(a) - p, np.asarray(b) - p
    cross = u[0] * v[1] - u[1] * v[0]
    return cross * cross / ((u @ u) * (v @ v))


def test_fim_b_metric_is_the_sum_of_both_positions_dets_by_hand():
    """At equal depth det I(p) of two ranges is sin^2 of the angle at p between the
    beacon's two positions, so approach B's value at its waypoint w is
    sin^2(own, w at p1) + sin^2(own, w at p2), for p1 and p2 apart."""
    from baselines.base import BeaconContext
    from baselines.fim import fim_b_waypoint

    ctx = BeaconContext.from_config(_asv(depth_m=0.0))
    own = SURVEY + [60.0, 0.0]
    p1, p2 = SURVEY, SURVEY + [0.0, 40.0]
    wp, val = fim_b_waypoint(ctx, own, p1[None], [0.0], p2[None], [0.0])
    assert val == pytest.approx(_sin2(p1, own, wp) + _sin2(p2, own, wp), rel=1e-9)
    # and it beats the point that is best for p1 alone (the tangent point of approach A)
    R, d = ctx.reach_m, 60.0
    phi = np.arcsin(R / d)
    for sign in (1.0, -1.0):
        tangent = p1 + np.sqrt(d * d - R * R) * np.array([np.cos(phi), sign * np.sin(phi)])
        assert val >= _sin2(p1, own, tangent) + _sin2(p2, own, tangent) - 1e-9


def test_fim_b_keeps_the_safety_distance_from_where_the_vehicle_will_be():
    """The waypoint is where the beacon is at the next ping, when the survey vehicle is at
    p2: approach B keeps the safety distance (25 m here) from p2. Beacon 40 m east of p2,
    p1 80 m south of the beacon: unconstrained, the best point lies 9 m from p2."""
    from baselines.base import BeaconContext
    from baselines.fim import fim_b_waypoint

    ctx = BeaconContext.from_config(_asv(depth_m=0.0, safety_distance_m=25.0))
    p2 = SURVEY
    own, p1 = SURVEY + [40.0, 0.0], SURVEY + [40.0, -80.0]
    wp, _ = fim_b_waypoint(ctx, own, p1[None], [0.0], p2[None], [0.0])
    assert np.linalg.norm(wp - own) <= ctx.reach_m + 1e-9
    assert np.linalg.norm(wp - p2) >= 25.0 - 1e-6


# ------------------------------------------------------------------------------------
# the survey EKF step and the information geometry


def test_the_gate_passes_an_innovation_exactly_at_its_threshold():
    """y^2 / S <= gate: P = 3 I, H = east, R = 1, so S = 4; y = 4 gives y^2 / S = 4.0
    exactly, fused at gate 4 and refused just below it; at gate 16 - 1e-9 it is fused
    (the gate is on y^2 / S = 4, not on y^2 = 16)."""
    from coopnav_env.core.navigation import gated_update_residual

    H = np.array([1.0, 0.0, 0.0])
    for gate, fused in ((4.0, True), (np.nextafter(4.0, 0.0), False), (16.0 - 1e-9, True)):
        x, P = np.zeros(3), 3.0 * np.eye(3)
        assert gated_update_residual(x, P, 4.0, H, 1.0, gate) is fused
        assert bool(x[0] == pytest.approx(3.0)) is fused  # K = 3 / 4: x moves by 3


def test_fisher_information_weighs_each_range_by_its_inverse_variance():
    """J = sum_i u_i u_i^T / sigma_i^2 (Sousa et al. eq. 4): beacons due east and due
    north of the target with range std 2 m and 0.5 m give J = diag(1/4, 4), det 1."""
    from coopnav_env.core.information import fisher_information, range_information_det

    target = np.zeros(3)
    beacons = np.array([[10.0, 0.0, 0.0], [0.0, 10.0, 0.0]])
    J = fisher_information(target, beacons, np.array([2.0, 0.5]))
    np.testing.assert_allclose(J, np.diag([0.25, 4.0]), atol=1e-12)
    assert range_information_det(target, beacons, np.array([2.0, 0.5])) == pytest.approx(1.0)
    # one std for both: J = I / sigma^2, det 1 / sigma^4
    assert range_information_det(target, beacons, 2.0) == pytest.approx(1.0 / 16.0)


# ------------------------------------------------------------------------------------
# the reward terms


@pytest.mark.parametrize("name", ["gao_lawnmower", "matos_moving_lbl"])
def test_info_gain_is_positive_when_ranges_are_fused(name):
    """info_gain = log det P_before - log det P_after of the horizontal covariance over
    the cycle's range updates: every Joseph update of a range shrinks the covariance
    (det P+ = det P R / S for the state's, R < S), so a cycle that fused ranges gains
    information (> 0), on the survey network and on the moving network alike."""
    import coopnav_env
    from coopnav_env.core import make_simulator

    sim = make_simulator(coopnav_env.make_config(name), 2)
    sim.reset([3, 4])
    fused_steps = 0
    for _ in range(6):
        res = sim.step(np.zeros((2, sim.N, 2)))
        fused = np.asarray(res.info["ranges_fused"]).reshape(2, -1).sum(-1) > 0
        gain = res.terms["info_gain"][:, 0]
        assert (gain[fused] > 0).all(), (gain, fused)
        fused_steps += int(fused.sum())
    assert fused_steps >= 6


def test_training_signals_by_hand():
    """The training signals of one environment with two beacons and two survey vehicles:
    std = -mean_s sqrt(P_ee + P_nn) = -(sqrt(9 + 16) + sqrt(1 + 3)) / 2 = -3.5 (the trace,
    not an off-diagonal); logdet = -0.5 mean_s log det = -0.5 (2 + 4) / 2 = -1.5;
    error = -mean_s e = -2 (the mean over survey vehicles, not the sum); log_error =
    -ln(1 + 2); penalties = -(2 x safety + 3 x geofence) = -5 (contact is not a penalty)."""
    from types import SimpleNamespace

    from coopnav_env.core.reward import training_reward

    ones = np.ones((1, 2))
    terms = {"info_gain": 0.7 * ones, "safety": ones, "geofence": ones, "contact": ones}
    weights = {"info_gain": 1.0, "safety": -2.0, "geofence": -3.0, "contact": -0.5}
    info = {
        "survey_cov_en_m2": np.array([[[[9.0, 5.0], [5.0, 16.0]], [[1.0, 2.0], [2.0, 3.0]]]]),
        "cov_logdet": np.array([[2.0, 4.0]]),
        "survey_error_m": np.array([[1.0, 3.0]]),
    }
    res = SimpleNamespace(reward=np.full((1, 2), 0.25), terms=terms, info=info)
    expected = {"std": -3.5, "logdet": -1.5, "error": -2.0, "log_error": -np.log(3.0), "penalties": -5.0, "env": 0.25}
    for name, value in expected.items():
        np.testing.assert_allclose(training_reward({name: 1.0}, res, weights), np.full((1, 2), value), err_msg=name)
    mix = training_reward({"error": 2.0, "penalties": 0.5}, res, weights)
    np.testing.assert_allclose(mix, np.full((1, 2), 2.0 * -2.0 + 0.5 * -5.0))


# ------------------------------------------------------------------------------------
# the channel's slot logic (coopnav_env/core/channel.py)


def _decide_sim(B=1, **kw):
    """tests/test_channel.py's sousa_ping simulator, one environment by default."""
    from test_channel import _decide_sim as decide_sim

    return decide_sim(B=B, **kw)


def test_transmit_mask_needs_a_positive_third_component():
    """A beacon transmits when its third action component is > 0: 0 stays silent, the
    smallest positive value transmits; a motion-only action transmits every slot."""
    sim = _decide_sim()
    a = np.zeros((1, 2, 3))
    a[0, 1, 2] = 1e-6
    assert sim.channel.transmit_mask(a, np.array([0])).tolist() == [[False, True]]
    a[0, :, 2] = -1.0
    assert not sim.channel.transmit_mask(a, np.array([0])).any()
    assert sim.channel.transmit_mask(np.zeros((1, 2, 2)), np.array([0])).all()


def test_tdma_frame_slots_give_beacon_j_the_slots_k_mod_f_equal_j():
    """tdma_frame_slots F = 3: in slot k only beacon k mod 3 (if there is one) may transmit."""
    sim = _decide_sim(tdma_frame_slots=3)
    on = np.ones((1, 2, 3))
    got = [sim.channel.transmit_mask(on, np.array([k]))[0].tolist() for k in range(6)]
    assert got == [[True, False], [False, True], [False, False]] * 2


def test_staggered_offsets_start_beacon_0_at_the_slot_start():
    """ "staggered": beacon j starts at j x (D_ping + max_range_m / 1400 m/s) = j x (5 s +
    1500 / 1400 s) on sousa_ping: 0 and 6.0714 s; "zero": both at 0."""
    sim = _decide_sim()
    d = sim._cycle_draws(sim.state.cycle)
    np.testing.assert_allclose(sim.channel.offsets_s(d), [[0.0, 5.0 + 1500.0 / 1400.0]], atol=1e-9)
    sim0 = _decide_sim(ping_offsets="zero")
    np.testing.assert_array_equal(sim0.channel.offsets_s(sim0._cycle_draws(sim0.state.cycle)), [[0.0, 0.0]])


def test_a_ping_costs_transmit_power_times_its_duration_on_the_range_link():
    """The range link's ping: transmit_power_w x ping_bits / modem_bit_rate_bps (the ping's
    bits, not the reply's)."""
    import coopnav_env
    from coopnav_env.core.channel import ping_energy_j

    c = coopnav_env.make_config("sousa_ping", link_model="range")
    assert c.ping_bits != c.reply_packet_bits
    assert ping_energy_j(c) == pytest.approx(c.transmit_power_w * c.ping_bits / c.modem_bit_rate_bps, rel=1e-12)


def test_kalman_gain_against_filterpy():
    """K = P H^T / S (eq. 12), S = H P H^T + R, as filterpy's ExtendedKalmanFilter computes
    it for one range: a correlated P, a slant range direction, R = 0.5."""
    from filterpy.kalman import ExtendedKalmanFilter

    from coopnav_env.core.navigation import innovation_variance, kalman_gain

    P = np.array([[4.0, 1.0, 0.2], [1.0, 9.0, -0.5], [0.2, -0.5, 1.0]])
    H = np.array([0.6, 0.64, 0.48])
    R = 0.5
    s_var = innovation_variance(P, H, R)
    assert s_var == pytest.approx(H @ P @ H + R, rel=1e-12)
    K = np.empty(3)
    kalman_gain(P, H, s_var, K)
    ekf = ExtendedKalmanFilter(dim_x=3, dim_z=1)
    ekf.x, ekf.P, ekf.R = np.zeros((3, 1)), P.copy(), np.array([[R]])
    ekf.update(np.array([[1.0]]), lambda x: H[None, :], lambda x: np.array([[0.0]]))
    np.testing.assert_allclose(K, ekf.K[:, 0], rtol=1e-12)


def test_geofence_term_reads_each_bound_on_its_own_axis():
    """gao_lawnmower's fence is east [-300, 430] x north [-300, 400] (not square): a beacon
    at east 415 m is inside (east beyond the north bound, 400, is still inside), at east
    445 m or north 415 m outside. The term is checked against the beacon's true position
    after the cycle, classified by hand."""
    import coopnav_env
    from coopnav_env.core import make_simulator

    config = coopnav_env.make_config("gao_lawnmower")
    e0, n0, e1, n1 = config.geofence_m
    assert (e1, n1) == (430.0, 400.0)
    sim = make_simulator(config, 3)
    sim.reset([3, 4, 5])
    sim.state.b_pos[:, 0, :2] = [[415.0, 0.0], [445.0, 0.0], [0.0, 415.0]]
    res = sim.step(np.zeros((3, 1, 2)))
    pos = sim.snapshot().beacon_true_m[:, 0, :2]
    outside = (pos[:, 0] < e0) | (pos[:, 0] > e1) | (pos[:, 1] < n0) | (pos[:, 1] > n1)
    assert outside.tolist() == [False, True, True], pos
    np.testing.assert_array_equal(res.terms["geofence"][:, 0], outside.astype(float))


# ------------------------------------------------------------------------------------
# the channel's slot, on the sonar link (the helpers of tests/test_channel.py)


def test_a_ping_is_decoded_when_its_uniform_is_at_least_one_minus_its_success_probability():
    """At 5 km the sonar link delivers with P = 0.60 (tests/test_channel.py by hand): lost if
    u < 1 - P = 0.40, so u = 0.45 decodes and u = 0.35 is lost (kills ``u >= P``, which
    would lose both; u = 0 and u near 1 cannot tell the two apart)."""
    from test_channel import _draws, _place, _tx

    sim = _decide_sim(B=2)
    _place(sim, [[5000.0, 0.0], [1e5, 0.0]], [[0.0, 0.0]])
    p = sim.channel.pings(_tx(2, [True, False]), _draws(sim))[1].outcome.p_success[0, 0, 2]
    assert p == pytest.approx(0.60, abs=0.01)
    ok, slot = sim.channel.pings(_tx(2, [True, False]), _draws(sim, acoustic_u0=[[[0.45]], [[0.35]]]))
    assert ok[:, 0, 0].tolist() == [True, False] and slot.lost[:, 0, 2].tolist() == [False, True]


def test_a_survey_vehicle_replies_when_it_decoded_any_ping_not_only_when_it_decoded_all():
    """Beacon 0 at 1 km and beacon 1 100 km away both ping: the survey vehicle decodes only
    beacon 0's and replies, so the slot it is resolved in holds its reply, which reaches
    beacon 0 (kills ``.all`` for ``.any`` over the beacons, which keeps it silent)."""
    from test_channel import _draws, _place, _tx

    sim = _decide_sim(B=1)
    _place(sim, [[1000.0, 0.0], [1e5, 0.0]], [[0.0, 0.0]])
    ok, slot = sim.channel.pings(_tx(1, [True, True]), _draws(sim, acoustic_u0=0.5))
    assert ok[0, :, 0].tolist() == [True, False]
    reply_arrival = slot.outcome.arrival_s[0, 2, 0]  # [sender: the survey vehicle, receiver: beacon 0]
    assert np.isfinite(reply_arrival) and reply_arrival == pytest.approx(
        sim.channel.timing.reply_at_s + 1000.0 / 1500.0, abs=0.05
    )


def test_random_offsets_span_the_last_beacons_stagger_not_one_step():
    """``ping_offsets="random"``: each beacon's start is u x the last staggered offset,
    (N - 1) x step (kills u x step, the same only for two beacons). Three ASVs need a
    longer slot: 40 s."""
    sim = _decide_sim(B=2, ping_offsets="random", beacon_kinds=("asv", "asv", "asv"), ping_interval_s=40.0)
    t = sim.channel.timing
    assert t.last_offset_s == pytest.approx(2 * t.step_s)
    d = dict(sim._cycle_draws(sim.state.cycle))
    d["ping_offset_u"] = np.full_like(d["ping_offset_u"], 0.75)
    np.testing.assert_allclose(sim.channel.offsets_s(d), 0.75 * 2 * (5.0 + 1500.0 / 1400.0), rtol=1e-12)


def test_a_beacon_deaf_to_the_other_while_sending_loses_its_message_but_the_other_does_not():
    """Staggered pings of two beacons 2 km apart: A sends over [0, 5] s, B over [6.07, 11.07] s.
    A's ping reaches B over [1.33, 6.33] s, while B has begun sending: B is deaf to it. B's
    reaches A at 7.4 s, after A finished: A hears it. So peer_ok [receiver, sender] is
    [A, B] True, [B, A] False (kills the [sender, receiver] deafness read unswapped)."""
    from test_channel import _draws, _place, _tx

    sim = _decide_sim(B=1)
    _place(sim, [[1000.0, 0.0], [-1000.0, 0.0]], [[0.0, 300.0]])
    _, peer_ok, o = sim.channel.replies(_tx(1, [True, True]), np.ones((1, 1), bool), _draws(sim, message_u=0.5))
    assert o.deaf[0, 0, 1] and not o.deaf[0, 1, 0]  # [sender, receiver]: B deaf to A's ping only
    assert peer_ok[0, 0, 1] and not peer_ok[0, 1, 0]


def test_a_ping_whose_reception_ends_exactly_at_the_reply_time_is_replied_to():
    """``ended`` is end <= reply time: a reception that ends at the reply time itself has
    ended (CH5, the last channel mutant: ``<`` keeps the survey vehicle silent). The reply
    time is set to the ping's own end, so the tie is exact; the reply then starts as the
    reception ends, which is no overlap: the ping is still decoded and the reply reaches
    beacon 0 after its flight of 1 km."""
    from test_channel import _draws, _place, _tx

    sim = _decide_sim(B=1)
    _place(sim, [[1000.0, 0.0], [1e5, 0.0]], [[0.0, 0.0]])
    ch = sim.channel
    end_s = float(ch.pings(_tx(1, [True, False]), _draws(sim, acoustic_u0=0.5))[1].outcome.end_s[0, 0, 2])
    assert np.isfinite(end_s) and end_s < ch.reply_at_s  # 5 s + 1 km / c, before the laid-out reply time
    ch.reply_at_s = end_s
    ok, slot = ch.pings(_tx(1, [True, False]), _draws(sim, acoustic_u0=0.5))
    assert ok[0, 0, 0] and slot.ended[0, 0, 2]
    assert slot.outcome.arrival_s[0, 2, 0] == pytest.approx(end_s + 1000.0 / 1500.0, abs=0.05)
