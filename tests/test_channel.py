"""The acoustic channel as a shared resource (channel_mode="decide", core/channel.py):
its physics against hand-computed timelines, the energy bookkeeping, the default
scenarios unchanged bit for bit, and the new scenario through the API contracts."""

from __future__ import annotations

import functools
import importlib.util
from pathlib import Path

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test, parallel_seed_test

import coopnav_env
from coopnav_env.core import make_simulator
from coopnav_env.core.acoustics import mackenzie_sound_speed, travel_time
from coopnav_env.core.channel import packet_duration_s, reply_time_s, resolve_slot, transmit_energy_j
from coopnav_env.core.reward import TERM_WEIGHTS, weighted_reward
from coopnav_env.views import action_space, check_action

DATA = Path(__file__).resolve().parent / "data"
T_C, SAL = 10.0, 35.0
C0 = float(mackenzie_sound_speed(T_C, SAL, 0.0))  # every vehicle at the surface: one sound speed


def timeline(positions, starts, durations, velocities=None, max_range_m=1500.0):
    """One environment's slot: vehicles on the surface at ``positions`` (east, north)."""
    V = len(positions)
    pos = np.zeros((1, V, 3))
    pos[0, :, :2] = positions
    vel = np.zeros((1, V, 3)) if velocities is None else np.asarray(velocities, float).reshape(1, V, 3)
    start = np.array([np.nan if s is None else s for s in starts], float)[None]
    return resolve_slot(pos, vel, start, np.asarray(durations, float)[None], np.array([T_C]), SAL, max_range_m)


# --------------------------------------------------------------------------------------
# physics against hand-computed timelines


def test_packet_duration_is_bits_over_bit_rate():
    assert packet_duration_s(64, 80.0) == 0.8
    assert packet_duration_s(128, 80.0) == 1.6
    assert packet_duration_s(256, 5400.0) == pytest.approx(256 / 5400)
    sim = make_simulator(coopnav_env.make_config("sousa_ping", modem_bit_rate_bps=160.0, ping_packet_bits=40), 1)
    assert sim.channel.ping_s == 0.25 and sim.channel.reply_s == 0.8
    c = sim.config
    assert reply_time_s(c) == pytest.approx(0.25 + c.max_range_m / 1400.0 + c.turnaround_s)


def test_two_pings_that_overlap_at_the_receiver_are_both_lost():
    # beacons 150 m and 300 m from the survey vehicle (index 2), both send at t = 0 for 0.8 s:
    # arrivals [0.100, 0.900] and [0.200, 1.000] s overlap
    arrival, delivered, collided, deaf = timeline([(150, 0), (-300, 0), (0, 0)], [0.0, 0.0, None], [0.8, 0.8, 1.6])
    np.testing.assert_allclose(arrival[0, 0, 2], 150 / C0, rtol=1e-12)
    np.testing.assert_allclose(arrival[0, 1, 2], 300 / C0, rtol=1e-12)
    assert collided[0, 0, 2] and collided[0, 1, 2]
    assert not delivered[0, 0, 2] and not delivered[0, 1, 2]
    # each beacon also transmits while the other's ping reaches it: half-duplex
    assert deaf[0, 0, 1] and deaf[0, 1, 0]
    assert np.isnan(arrival[0, 2]).all()  # the silent vehicle sends nothing


def test_short_packets_that_do_not_overlap_both_arrive():
    # 0.05 s pings: [0.1003, 0.1503] and [0.2007, 0.2507] s at the survey vehicle
    _, delivered, collided, _ = timeline([(150, 0), (-300, 0), (0, 0)], [0.0, 0.0, None], [0.05, 0.05, 1.6])
    assert delivered[0, 0, 2] and delivered[0, 1, 2] and not collided[0].any()
    # the second sent later so that it arrives exactly as the first ends: touching is no overlap
    t1 = 150 / C0 + 0.05 - 300 / C0
    _, delivered, collided, _ = timeline([(150, 0), (-300, 0), (0, 0)], [0.0, t1 + 1e-9, None], [0.05, 0.05, 1.6])
    assert delivered[0, 0, 2] and delivered[0, 1, 2]


def test_a_receiver_that_transmits_while_a_packet_arrives_loses_it():
    # beacon 0 at 150 m pings at 0 (arrival [0.1003, 0.9003]); the survey vehicle sends at 0.05 s
    arrival, delivered, collided, deaf = timeline([(150, 0), (0, 0)], [0.0, 0.05], [0.8, 1.6])
    assert deaf[0, 0, 1] and not collided[0, 0, 1] and not delivered[0, 0, 1]
    # its packet reaches the beacon at 0.05 + 0.1003 s, while the beacon still sends (until 0.8 s)
    np.testing.assert_allclose(arrival[0, 1, 0], 0.05 + 150 / C0, rtol=1e-12)
    assert deaf[0, 1, 0] and not delivered[0, 1, 0]
    # sent after the ping has arrived (0.9003 s) it costs nothing, and its own reply arrives
    # at the beacon after the beacon's ping ended
    _, delivered, _, deaf = timeline([(150, 0), (0, 0)], [0.0, 0.91], [0.8, 1.6])
    assert delivered[0, 0, 1] and delivered[0, 1, 0] and not deaf.any()


def test_out_of_range_packets_are_neither_heard_nor_harmful():
    arrival, delivered, collided, _ = timeline(
        [(150, 0), (-2000, 0), (0, 0)], [0.0, 0.0, None], [0.8, 0.8, 1.6], max_range_m=1500.0
    )
    assert np.isnan(arrival[0, 1, 2]) and not delivered[0, 1, 2]
    assert delivered[0, 0, 2] and not collided[0, 0, 2]


def test_the_time_of_flight_follows_the_moving_receiver():
    vel = [(0, 0, 0), (2.0, 1.0, 0.0)]
    arrival, *_ = timeline([(0, 0), (500, 0)], [0.5, None], [0.1, 0.1], velocities=vel)
    # the receiver is at (501, 0.5) when the packet leaves (0.5 s); then tau = |r + v tau| / c
    tau = arrival[0, 0, 1] - 0.5
    r = np.array([501.0, 0.5, 0.0]) + np.array([2.0, 1.0, 0.0]) * tau
    np.testing.assert_allclose(np.linalg.norm(r) / C0, tau, rtol=1e-12)
    assert tau == pytest.approx(
        travel_time(np.zeros(3), np.array([501.0, 0.5, 0.0]), np.array([2.0, 1.0, 0.0]), C0), rel=1e-12
    )
    assert tau > 501.0 / C0  # it flies away from the sender


# --------------------------------------------------------------------------------------
# the simulator in channel_mode="decide"


def _decide_sim(B=2, **kw):
    sim = make_simulator(coopnav_env.make_config("sousa_ping", **kw), B)
    sim.reset(np.arange(B) + 21)
    return sim


def _actions(B, transmit):
    a = np.zeros((B, len(transmit), 3))
    a[..., 2] = np.where(np.asarray(transmit), 1.0, -1.0)
    return a


def test_both_beacons_pinging_collide_at_the_survey_vehicle():
    sim = _decide_sim()
    res = sim.step(_actions(2, [True, True]))
    assert (res.beacon_info["pings"] == 1).all() and (res.beacon_info["collisions"] == 1).all()
    assert (res.info["ranges_fused"] == 0).all() and (res.info["packets_lost"] == 0).all()  # not random losses
    assert (res.terms["contact"] == 1.0).all() and (res.terms["ping"] == 1.0).all()
    assert (sim.state.k_age_s > 0).all()  # nothing decoded: no reply
    # one beacon alone: no collision; the survey vehicle replies
    res = sim.step(_actions(2, [True, False]))
    assert (res.beacon_info["collisions"] == 0).all()
    assert res.beacon_info["pings"].tolist() == [[1, 0], [1, 0]]
    assert (res.terms["contact"][:, 1] == 0.0).all()  # a silent beacon is not blamed for no contact
    heard = res.info["ranges_fused"][:, 0] + res.info["packets_lost"][:, 0] + res.info["outliers_rejected"][:, 0]
    assert (heard == 1).all()


def test_silent_beacons_measure_nothing_and_spend_nothing():
    sim = _decide_sim()
    res = sim.step(_actions(2, [False, False]))
    assert not res.info["range_ok"].any() and (res.info["packets_lost"] == 0).all()
    assert (res.beacon_info["energy_J"] == 0).all() and (res.terms["contact"] == 0).all()
    assert (res.terms["info_gain"] <= 0).all()  # prediction alone


def test_energy_sums_to_pings_times_power_times_duration():
    sim = _decide_sim(B=3, transmit_power_w=25.0)
    rng = np.random.default_rng(5)
    pings = energy = 0.0
    for _ in range(15):
        res = sim.step(rng.uniform(-1, 1, (3, 2, 3)))
        pings += res.beacon_info["pings"].sum()
        energy += res.beacon_info["energy_J"].sum()
    assert pings > 0
    assert energy == pytest.approx(pings * 25.0 * packet_duration_s(64, 80.0))
    assert transmit_energy_j(25.0, 0.8, 3) == pytest.approx(60.0)


def test_tdma_frame_slots_gates_the_transmit_decision():
    sim = _decide_sim(tdma_frame_slots=2)
    for k in range(4):
        res = sim.step(_actions(2, [True, True]))
        assert res.beacon_info["pings"][0].tolist() == ([1, 0] if k % 2 == 0 else [0, 1])
        assert (res.beacon_info["collisions"] == 0).all()


def test_the_ping_price_enters_the_reward():
    sim = _decide_sim(ping_penalty=0.3)
    assert sim.reward_weights["ping"] == -0.3 and TERM_WEIGHTS["ping"] == "ping_penalty"
    res = sim.step(_actions(2, [True, False]))
    np.testing.assert_allclose(res.reward, weighted_reward(res.terms, sim.reward_weights), atol=1e-12)
    assert res.reward[0, 0] == pytest.approx(
        res.reward[0, 1] - 0.3 - 0.2 * res.terms["contact"][0, 0] + 0.2 * res.terms["contact"][0, 1]
    )


def test_decide_mode_is_refused_where_it_cannot_work():
    with pytest.raises(ValueError, match="ranging_mode='owtt'"):
        coopnav_env.make_config("sousa_ping", ranging_mode="twtt")
    with pytest.raises(ValueError, match="cannot hold a ping and a reply"):
        coopnav_env.make_config("sousa_ping", ping_interval_s=2.0, substep_s=1.0)
    with pytest.raises(ValueError, match="unknown channel_mode"):
        coopnav_env.make_config("sousa_asv", channel_mode="aloha")


# --------------------------------------------------------------------------------------
# the existing scenarios: unchanged bit for bit (arrays recorded before the channel existed)


def test_default_scenarios_are_unchanged():
    """The fixed-clock scenarios replay the episodes recorded before the channel existed,
    within the cross-machine tolerance of tests/test_recorded.py (they were recorded on
    another CPU: bit for bit holds only on the recording machine)."""
    from test_recorded import close_enough

    spec = importlib.util.spec_from_file_location("record_default_scenarios", DATA / "record_default_scenarios.py")
    rec = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(rec)
    ref = np.load(rec.PATH)
    new = rec.record_all()
    assert set(new) == set(ref.files)
    bad = [key for key in ref.files if not close_enough(ref[key], new[key], 1e-9)]
    assert not bad, bad


@pytest.mark.parametrize("name", ["gao_lawnmower", "gao_sea", "sousa_asv", "swarm_mls", "matos_moving_lbl"])
def test_clock_scenarios_keep_their_spaces_terms_and_infos(name):
    env = coopnav_env.parallel_env(name)
    assert env.action_space("beacon_0").shape == (2,)
    assert env.config.channel_mode == "clock"
    sim = env.sim
    assert "ping" not in sim.reward_terms and "pings" not in sim.beacon_info_keys


# --------------------------------------------------------------------------------------
# the new scenario through the views and the contracts


def test_decide_action_space_and_action_check():
    env = coopnav_env.parallel_env("sousa_ping")
    assert env.action_space("beacon_1").shape == (3,) and action_space(env.sim).shape == (3,)
    assert action_space().shape == (2,)
    np.testing.assert_array_equal(check_action("b", [0.5, 2.0, -3.0], 3), [0.5, 1.0, -1.0])
    np.testing.assert_array_equal(check_action("b", [0.5, 0.1], 3), [0.5, 0.1, 1.0])  # motion alone: transmit
    with pytest.raises(ValueError, match=r"shape \(3,\)"):
        check_action("b", [0.1, 0.2, 0.3, 0.4], 3)
    with pytest.raises(ValueError, match=r"shape \(2,\)"):
        check_action("b", [0.1, 0.2, 0.3], 2)


def test_sousa_ping_parallel_api():
    parallel_api_test(coopnav_env.parallel_env("sousa_ping", max_cycles=12), num_cycles=17)


def test_sousa_ping_parallel_seed():
    parallel_seed_test(functools.partial(coopnav_env.parallel_env, "sousa_ping", max_cycles=12), num_cycles=12)


def test_sousa_ping_runs_through_the_protocol():
    from coopnav_env.core.contract import BatchedSimulator, StepResult

    config = coopnav_env.make_config("sousa_ping")
    sim = make_simulator(config, 3)
    assert isinstance(sim, BatchedSimulator)
    sim.reset(np.arange(3) + 40)
    assert (
        tuple(sim.reset_beacon_info())
        == tuple(sim.beacon_info_keys)
        == ("beacon_error_m", "beacon_away_s", "pings", "collisions", "energy_J")
    )
    # the protocol checks of every scenario (shapes, the reward as the weighted sum of
    # indicator terms, infos) run on sousa_ping in tests/test_contract.py; here what the
    # channel adds: the ping term and the channel's beacon infos
    res = sim.step(np.random.default_rng(0).uniform(-1, 1, (3, 2, 3)))
    assert isinstance(res, StepResult)
    assert tuple(res.terms) == tuple(sim.reward_terms) == ("info_gain", "safety", "geofence", "contact", "ping")
    assert tuple(res.beacon_info) == tuple(sim.beacon_info_keys)


def test_a_batch_row_equals_the_standalone_env():
    rng = np.random.default_rng(2)
    actions = rng.uniform(-1, 1, (8, 3, 2, 3))
    big = _decide_sim(B=3)
    big.reset([7, 8, 9])
    one = _decide_sim(B=1)
    one.reset([8])
    for a in actions:
        rb, r1 = big.step(a), one.step(a[1:2])
        assert np.array_equal(rb.obs[1:2], r1.obs) and np.array_equal(rb.reward[1:2], r1.reward)
        for k in rb.beacon_info:
            assert np.array_equal(rb.beacon_info[k][1:2], r1.beacon_info[k])


def test_reset_infos_have_the_step_keys_in_decide_mode():
    env = coopnav_env.parallel_env("sousa_ping", max_cycles=3)
    _, reset_infos = env.reset(seed=1)
    _, _, _, _, step_infos = env.step({a: env.action_space(a).sample() for a in env.agents})
    for agent in env.possible_agents:
        assert set(reset_infos[agent]) == set(step_infos[agent]) >= {"pings", "collisions", "energy_J"}
        assert reset_infos[agent]["pings"] == 0.0


def test_vecenv_takes_three_component_actions():
    from coopnav_env.vector import CoopNavVecEnv

    venv = CoopNavVecEnv("sousa_ping", n_envs=2, seed=0)
    assert venv.action_space.shape == (3,)
    venv.reset()
    _, reward, _, infos = venv.step(np.tile([0.0, 0.0, 1.0], (4, 1)))
    assert reward.shape == (4,) and infos[0]["pings"] == 1.0 and infos[0]["collisions"] == 1.0
    with pytest.raises(ValueError, match=r"shape \(4, 3\)"):
        venv.step(np.zeros((4, 4)))


# --------------------------------------------------------------------------------------
# the transmit schedules


def _episode(name, seed=3, cycles=24):
    from baselines import make_policy

    env = coopnav_env.parallel_env("sousa_ping", max_cycles=cycles)
    obs, _ = env.reset(seed=seed)
    pols = {a: make_policy(name, env, seed=0, agent=a) for a in env.agents}
    pings = collisions = 0.0
    while env.agents:
        actions = {a: pols[a].act(obs[a]) for a in env.agents}
        for a in actions.values():
            assert a.shape == (3,) and np.all(np.abs(a) <= 1.0)
        obs, _, _, _, infos = env.step(actions)
        pings += sum(i["pings"] for i in infos.values())
        collisions += sum(i["collisions"] for i in infos.values())
    return pings, collisions


def test_schedules_combine_with_the_planners():
    assert _episode("fim_a+clock") == (48, 48)  # the fixed clock: two beacons always collide
    assert _episode("fim_b+tdma") == (24, 0)  # turns: one ping a slot, no collision
    assert _episode("circle+clock") == (48, 48)
    p, c = _episode("fim_a+event_tdma")
    assert c == 0 and 0 < p <= 24
    assert _episode("fim_a") == (24, 0)  # a plain planner gets the default schedule, tdma


def test_schedules_are_refused_on_the_fixed_clock():
    from baselines import make_policy

    with pytest.raises(ValueError, match="channel_mode='decide'"):
        make_policy("fim_a+tdma", "sousa_asv")
    with pytest.raises(ValueError, match="valid schedules"):
        make_policy("fim_a+aloha", "sousa_ping")
    assert make_policy("fim_a", "sousa_asv").act(
        np.zeros(coopnav_env.parallel_env("sousa_asv").sim.obs_dim, np.float32)
    ).shape == (2,)


def test_event_gain_by_hand():
    from baselines.schedule import predicted_gain_nats
    from coopnav_env.obs_layout import ObsView

    config = coopnav_env.make_config("sousa_ping")
    view = ObsView.__new__(ObsView)
    view.survey_rel_m = np.array([[30.0, 40.0, 0.0]])
    view.cov_m2 = np.array([[[4.0, 0.0], [0.0, 1.0]]])
    view.reply_age_s = np.array([5.0])
    view.own_std_m = np.float64(0.5)
    q = config.process_noise_horizontal_m2ps * (5.0 + 5.0)
    h = np.array([0.6, 0.8])
    expected = np.log1p(h @ (np.diag([4.0, 1.0]) + q * np.eye(2)) @ h / (config.range_noise_std_m**2 + 0.25))
    assert predicted_gain_nats(view, config) == pytest.approx(expected)
