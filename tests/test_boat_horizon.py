"""The boats' receding-horizon planner and oracle (``baselines.boat_horizon``): its kernel
against the survey planner's equations, the geometry it reaches, its registration beside
``baselines.horizon`` and its refusal of the paper's mission in the frame."""

from __future__ import annotations

import numpy as np
import pytest

import baselines
import coopnav_env
from baselines.boat_horizon import BoatHorizonPolicy, BoatModel, BoatOraclePolicy, _range_update, boat_plan_costs
from baselines.horizon import HorizonPolicy, OraclePolicy, _h1_update, _team_loop, _w_update
from coopnav_env.core.acoustics import packet_loss_probability

RIVER = coopnav_env.make_config("matos_river")


def _model(start, vehicle_v=(0.0, 0.0), P0=None, W0=None, shift=(0.0, 0.0), limits=None, R=1.0, grow=0.01):
    return BoatModel(
        start=np.asarray(start, float),
        vehicle_v=np.asarray(vehicle_v, float),
        dz=2.0,
        P0=np.eye(2) if P0 is None else np.asarray(P0, float),
        W0=np.zeros((2, 2)) if W0 is None else np.asarray(W0, float),
        with_error=W0 is not None,
        shift=np.asarray(shift, float),
        grow_m2=grow,
        R_m2=np.full(2, R),
        loss=np.array([0.05, 0.5, 1000.0]),
        limits=np.array([-1.0, 100.0, 1e9, -1.0, 1e9]) if limits is None else np.asarray(limits, float),
        bank=np.array([0.0, 0.0, 0.0, 1.0]),
        v_now=np.zeros((2, 2)),
        rides=False,
    )


def test_the_registry_keeps_one_class_per_name_and_network():
    assert type(baselines.make_policy("horizon", RIVER)) is BoatHorizonPolicy
    assert type(baselines.make_policy("oracle", RIVER, agent=1)) is BoatOraclePolicy
    assert type(baselines.make_policy("horizon", "gao_lawnmower")) is HorizonPolicy
    assert type(baselines.make_policy("oracle", "gao_lawnmower")) is OraclePolicy
    assert {"horizon", "oracle"} <= set(baselines.list_policies("moving_lbl"))
    assert {"horizon", "oracle"} <= set(baselines.list_policies(config=RIVER))


def test_both_moving_network_task_sets_carry_horizon_and_the_oracle():
    from evaluation.tasks import get_task_set

    for name in ("matos_moving_lbl", "matos_river"):
        ts = get_task_set(name)
        assert "horizon" in ts.planners and "horizon" not in ts.greedy_planners, name
        assert ts.references == ["oracle"], name


def test_a_mission_in_the_frame_gets_spread_plans_only():
    """On the paper's mission (in the frame) both boats keep the common transit and differ
    only along the baseline, B1 by -d and B2 by +d; (BH1) makes a stretch cost more."""
    lbl = coopnav_env.make_config("matos_moving_lbl")
    policy = BoatHorizonPolicy(lbl, seed=[1, 0])
    transit = np.array([0.0, -0.5])
    m = _model(np.array([[-50.0, -50.0], [50.0, -50.0]]))._replace(rides=True, v_now=np.stack([transit, transit]))
    v = policy.optimise(m) * lbl.boat_max_speed_mps
    np.testing.assert_allclose(v[0, :, 1], transit[1], atol=1e-12)
    np.testing.assert_allclose(v[1, :, 1], transit[1], atol=1e-12)
    np.testing.assert_allclose(v[0, :, 0], -v[1, :, 0], atol=1e-12)
    hold = np.repeat(np.repeat(m.v_now[None, :, None] / lbl.boat_max_speed_mps, 1, 0), 2, 2)
    stretch = hold.copy()
    stretch[:, 1, :, 0] += 0.2
    stretch[:, 0, :, 0] -= 0.2
    costs = np.empty(2)
    boat_plan_costs(np.concatenate([hold, stretch]), m, 3, policy.step_m, 2.0, costs)
    assert costs[1] > costs[0]


@pytest.mark.parametrize("p", [1.0, 0.6])
def test_range_update_is_eqs_h1_and_h3(p):
    rng = np.random.default_rng(3)
    A, B = rng.standard_normal((2, 2)), rng.standard_normal((2, 2))
    P, W = A @ A.T + np.eye(2), B @ B.T
    h = np.array([0.6, -0.8])
    P1, W1 = P.copy(), W.copy()
    _range_update(P1, W1, h[0], h[1], p, 2.0, True)
    a, b, c = _h1_update(P[0, 0], P[0, 1], P[1, 1], h[0], h[1], p, 2.0)
    wa, wb, wc = _w_update(W[0, 0], W[0, 1], W[1, 1], P[0, 0], P[0, 1], P[1, 1], h[0], h[1], p, 2.0)
    np.testing.assert_allclose(P1, [[a, b], [b, c]], rtol=1e-12)
    np.testing.assert_allclose(W1, [[wa, wb], [wb, wc]], rtol=1e-12)
    # by hand, arriving for sure: the Kalman update P - P h h' P / (h'Ph + R)
    Ph = P @ h
    expected = P - np.outer(Ph, Ph) / (h @ Ph + 2.0)
    P2 = P.copy()
    _range_update(P2, W.copy(), h[0], h[1], 1.0, 2.0, False)
    np.testing.assert_allclose(P2, expected, rtol=1e-12)


class _Channel:
    """The exchange's two-way arrival, as ``_team_loop``'s channel."""

    @staticmethod
    def delivery_probability(d):
        a = 1.0 - np.vectorize(packet_loss_probability)(d, 0.05, 0.5, 1000.0)
        return a * a

    @staticmethod
    def range_variance_m2(d, var):
        """The boats' R, the same at every distance (``boat_horizon``'s R_m2): here the
        'variance' passed is that R."""
        return var + np.zeros(np.shape(d))


@pytest.mark.parametrize("with_error", [False, True])
def test_kernel_cost_is_the_survey_planners_loop_on_the_boats_ranges(with_error):
    """The kernel's eq. (H2)/(H4) equals ``baselines.horizon._team_loop`` fed the same two
    boats' positions relative to the moving vehicle, cycle by cycle (no constraint active)."""
    rng = np.random.default_rng(7)
    start = np.array([[-50.0, -60.0], [50.0, -60.0]])
    v_s = np.array([0.4, 0.9])
    W0 = np.array([[4.0, 1.0], [1.0, 2.0]]) if with_error else None
    shift = np.array([1.5, -2.0]) if with_error else np.zeros(2)
    m = _model(start, v_s, P0=[[2.0, 0.3], [0.3, 1.0]], W0=W0, shift=shift)
    K, blocks, T, step = 3, 2, 2.0, 2.5 * 2.0
    v = baselines.boat_horizon._disc(rng.uniform(-1, 1, (5, 2, blocks, 2)))
    out = np.empty(5)
    boat_plan_costs(v, m, K, step, T, out)
    n = K * blocks
    per_cycle = np.repeat(v, K, axis=2)  # (N, 2, n, 2)
    boats = start[None, :, None, :] + step * np.cumsum(per_cycle, axis=2)
    veh = v_s[None, :] * T * np.arange(1, n + 1)[:, None]  # (n, 2)
    rel = boats - veh[None, None]  # boats relative to the vehicle: the vehicle at the origin
    dz = np.full((2, n, 1), 2.0)
    P, Wm = _team_loop(
        rel,
        np.zeros((n, 1, 2)),
        dz,
        m.P0[None],
        np.full((n, 1), m.grow_m2),
        np.ones(2),  # R = 1 m^2 for both boats, as m.R_m2
        _Channel,
        None if W0 is None else W0[None],
        None if W0 is None else shift[None],
    )
    total = P[..., 0] + P[..., 2]
    tr0 = np.trace(m.P0) + 2 * m.grow_m2 * np.arange(1, n + 1)
    if with_error:
        total = total + Wm[..., 0] + Wm[..., 2]
        tr0 = tr0 + np.trace(W0) + 2 * m.grow_m2 * np.arange(1, n + 1)
    np.testing.assert_allclose(out, total.sum((1, 2)) / tr0.sum(), rtol=1e-10)


def test_the_constraints_are_metres_outside_their_limits():
    """A boat 4 m inside the safety distance, the baseline 10 m too long and the vehicle 5 m
    too near its line: 4 + 10 + 5 metres, over one cycle, times PENALTY_PER_M."""
    from baselines.base import PENALTY_PER_M

    start = np.array([[-4.0, 0.0], [106.0, 0.0]])  # the vehicle at the origin, 2 m below
    d = np.hypot(4.0, 2.0)
    limits = np.array([d + 4.0, 100.0, 0.0, 5.0, 1e9])
    m, m_free = _model(start, limits=limits), _model(start)
    v = np.zeros((1, 2, 1, 2))
    out, free = np.empty(1), np.empty(1)
    boat_plan_costs(v, m, 1, 1.0, 2.0, out)
    boat_plan_costs(v, m_free, 1, 1.0, 2.0, free)
    assert out[0] - free[0] == pytest.approx(PENALTY_PER_M * (4.0 + 10.0 + 5.0))


def test_the_plan_reaches_the_right_angle_fix_of_a_static_vehicle():
    """A static vehicle, both boats 100 m apart on one side of it in a line (the worst
    geometry: both lines of sight parallel). The best two-range fix is at right angles,
    which a 100 m baseline gives with the vehicle 50 m from its middle (Thales); applying
    each plan's first velocity for 40 cycles brings the boats there."""
    policy = BoatHorizonPolicy(RIVER, seed=[5, 0])
    start = np.array([[60.0, 0.0], [160.0, 0.0]])
    limits = np.array([12.0, 100.0, 5.0, 17.0, 1e9])
    for _ in range(40):
        m = _model(start, limits=limits, R=1.0, grow=0.01)
        v = policy.optimise(m)
        start = start + policy.step_m * v[:, 0]
    h = -start / np.linalg.norm(start, axis=1, keepdims=True)  # lines of sight to the vehicle
    angle = np.degrees(np.arccos(abs(h[0] @ h[1])))
    assert angle > 80.0, start
    assert abs(np.linalg.norm(start[1] - start[0]) - 100.0) <= 5.5


def test_both_boats_find_the_same_plan_and_the_oracle_gets_the_truth():
    from evaluation.episodes import run_episodes

    config = coopnav_env.make_config("matos_river", max_cycles=12)
    calls = []
    orig = BoatOraclePolicy.observe_truth
    try:
        BoatOraclePolicy.observe_truth = lambda self, snap, row: calls.append(row) or orig(self, snap, row)
        rows, _ = run_episodes(config, "oracle", [3, 4])
    finally:
        BoatOraclePolicy.observe_truth = orig
    assert len(rows) == 2 and sorted(set(calls)) == [0, 1] and len(calls) == 2 * 2 * 12
    # the same seed gives the same episode
    again, _ = run_episodes(config, "horizon", [3])
    once, _ = run_episodes(config, "horizon", [3])
    assert again[0]["mean_error_m"] == once[0]["mean_error_m"]
    b1, b2 = BoatHorizonPolicy(RIVER, 0, seed=[9, 0]), BoatHorizonPolicy(RIVER, 1, seed=[9, 1])
    m = _model(np.array([[-50.0, -50.0], [50.0, -50.0]]), (0.5, 0.8))
    np.testing.assert_array_equal(b1.optimise(m), b2.optimise(m))
