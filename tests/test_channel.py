"""The acoustic channel as a shared resource (channel_mode="decide", core/channel.py):
the wired link (sonar equation, capture, half duplex, offsets, energy) against
hand-computed cases through the simulator's channel, the range link's timelines,
the range link reproducing the earlier channel bit for bit, and the scenario through
the API contracts."""

from __future__ import annotations

import functools
import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test, parallel_seed_test

import coopnav_env
from coopnav_env.core import make_simulator
from coopnav_env.core.acoustics import mackenzie_sound_speed, travel_time
from coopnav_env.core.channel import link_params, ping_energy_j
from coopnav_env.core.link import SlotTransmissions, slot_timeline
from coopnav_env.core.link_framing import slot_timing
from coopnav_env.core.reward import TERM_WEIGHTS, weighted_reward
from coopnav_env.scenarios.sousa import SOUSA_PAPER_FILTER
from coopnav_env.scenarios.validate import SLOWEST_SOUND_SPEED_MPS
from coopnav_env.views import action_space, check_action

DATA = Path(__file__).resolve().parent / "data"
T_C, SAL = 10.0, 35.0
C0 = float(mackenzie_sound_speed(T_C, SAL, 0.0))  # every vehicle at the surface: one sound speed
RANGE_LINK = link_params(coopnav_env.make_config("sousa_ping", link_model="range"))


def timeline(positions, starts, durations, velocities=None, max_range_m=1500.0):
    """One environment's slot on the range link (``link_model="range"``): vehicles on
    the surface at ``positions`` (east, north). (arrival, delivered, collided, deaf)."""
    V = len(positions)
    pos = np.zeros((1, V, 3))
    pos[0, :, :2] = positions
    vel = np.zeros((1, V, 3)) if velocities is None else np.asarray(velocities, float).reshape(1, V, 3)
    start = np.array([np.nan if s is None else s for s in starts], float)[None]
    tx = SlotTransmissions(pos, vel, start, np.asarray(durations, float)[None], 185.0, 256)
    o = slot_timeline(tx, C0, RANGE_LINK._replace(hearing_range_m=max_range_m))
    return o.arrival_s, o.captured & ~o.deaf, o.overlapped & ~o.captured, o.deaf


# --------------------------------------------------------------------------------------
# the range link's timelines against hand-computed ones (the earlier channel's physics)


def test_range_link_packets_last_bits_over_bit_rate():
    c = coopnav_env.make_config(
        "sousa_ping", link_model="range", ping_offsets="zero", ping_interval_s=5.0, beacon_error_fusion="white"
    )  # the papers' ping: 64 bits, without the consider states' 20
    t = slot_timing(c, SLOWEST_SOUND_SPEED_MPS)
    assert (t.ping_s, t.reply_s, t.last_offset_s) == (0.8, 1.6, 0.0)
    assert t.reply_at_s == pytest.approx(0.8 + 1500.0 / 1400.0 + 0.015)
    assert t.need_s == pytest.approx(0.8 + 1.6 + 2 * 1500.0 / 1400.0 + 0.015)  # 4.557 s
    assert ping_energy_j(c) == pytest.approx(40.0 * 0.8)  # transmit_power_w x duration
    sim = make_simulator(c.replace(modem_bit_rate_bps=160.0), 1)
    assert sim.channel.ping_s == 0.4 and sim.channel.reply_s == 0.8


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


def _place(sim, beacons_m, survey_m, depth_m=5.0):
    """Every environment's vehicles at rest at (east, north) ``beacons_m`` and
    ``survey_m``, all at ``depth_m`` (so a path is the horizontal distance)."""
    st = sim.state
    for pos, xy in ((st.b_pos, beacons_m), (st.s_pos, survey_m)):
        pos[:] = depth_m
        pos[..., :2] = np.asarray(xy, float)
    st.b_vel[:] = 0.0
    st.s_vel_true[:] = 0.0


def _draws(sim, acoustic_u0=None, message_u=None):
    """This cycle's draws, with the ping's and the messages' uniforms set if given."""
    d = dict(sim._cycle_draws(sim.state.cycle))
    if acoustic_u0 is not None:
        d["acoustic_u"] = d["acoustic_u"].copy()
        d["acoustic_u"][..., 0] = acoustic_u0
    if message_u is not None:
        d["message_u"] = np.full_like(d["message_u"], message_u)
    return d


def _tx(B, transmit):
    return np.broadcast_to(np.asarray(transmit, bool), (B, len(transmit))).copy()


def snr_by_hand(r_m, noise_db):
    """185 dB - (20 log10 r + 6.1048051 r / 1000) - noise: spherical spreading, Thorp at 25 kHz."""
    return 185.0 - (20.0 * math.log10(r_m) + 6.1048051 * r_m / 1000.0) - noise_db


def p_success_by_hand(snr_db, bits=256):
    """exp(-thr / SNR) (Rayleigh, thr 3 dB) x (1 - PER), BER = exp(-Eb/N0 / 2) / 2, Eb/N0 = SNR 4000 / 80."""
    ber = 0.5 * math.exp(-0.5 * 10.0 ** (snr_db / 10.0) * 4000.0 / 80.0)
    return math.exp(-(10.0 ** ((3.0 - snr_db) / 10.0))) * (1.0 - ber) ** bits


def test_snr_and_loss_against_range_through_the_wired_channel():
    ranges = np.array([500.0, 1000.0, 3000.0, 5000.0, 6000.0, 8000.0])
    B = len(ranges)
    sim = _decide_sim(B=B)
    # beacon 0 at range r east of the survey vehicle, beacon 1 silent far away
    _place(sim, np.stack([np.c_[ranges, np.zeros(B)], np.full((B, 2), 1e5)], 1), np.zeros((B, 1, 2)))
    noise_db = sim.channel.noise_db
    # the band noise: NL(25 kHz) = 38.549 dB re 1 uPa^2/Hz (tests/test_link.py) + 10 log10(4000) = 74.570 flat
    assert noise_db == pytest.approx(38.549 + 36.0206, abs=0.05)
    _, slot = sim.channel.pings(_tx(B, [True, False]), _draws(sim))
    o = slot.outcome
    np.testing.assert_allclose(o.range_m[:, 0, 2], ranges, rtol=1e-9)
    snr = [snr_by_hand(r, noise_db) for r in ranges]
    np.testing.assert_allclose(o.snr_db[:, 0, 2], snr, atol=1e-6)
    # 1 km: SNR = 185 - 66.1048 - 74.57 = 44.3 dB, P = 0.9999; 5 km: 185 - 104.5034 - 74.57 = 5.93 dB,
    # P = exp(-10^-0.293) = 0.60 (40 % lost); 8 km: SNR -8.9 dB, P = exp(-15.6) ~ 0
    p = o.p_success[:, 0, 2]
    np.testing.assert_allclose(p, [p_success_by_hand(x) for x in snr], atol=1e-9)
    assert p[1] == pytest.approx(0.9999, abs=1e-4) and p[3] == pytest.approx(0.60, abs=0.01) and p[5] < 1e-6
    assert np.all(np.diff(p) < 0)  # loss grows with range
    assert not slot.collided.any() and not slot.deaf[:, 0, 2].any()


def test_the_link_loses_pings_with_the_modems_own_uniform_and_counts_them():
    sim = _decide_sim(B=2)
    _place(sim, [[1000.0, 0.0], [1e5, 0.0]], [[0.0, 0.0]])
    p = 1.0 - sim.channel.pings(_tx(2, [True, False]), _draws(sim))[1].outcome.p_success[0, 0, 2]
    # lost if u < 1 - P (P = 0.99993 at 1 km): u = 0 loses it, u = 1 - P/2 keeps it
    ok, slot = sim.channel.pings(_tx(2, [True, False]), _draws(sim, acoustic_u0=[[[0.0]], [[1.0 - p / 2]]]))
    assert ok[:, 0, 0].tolist() == [False, True] and slot.lost[:, 0, 2].tolist() == [True, False]
    # through a step: the lost ping is counted in packets_lost, not measured
    orig = sim._cycle_draws

    def lossy(cycle):
        d = dict(orig(cycle))
        d["acoustic_u"] = d["acoustic_u"].copy()
        d["acoustic_u"][..., 0] = 0.0
        return d

    sim._cycle_draws = lossy
    res = sim.step(_actions(2, [True, False]))
    assert (res.info["packets_lost"][:, 0] == 1).all() and (res.info["ranges_fused"] == 0).all()


def test_monte_carlo_delivery_matches_the_success_probability():
    B = 1000
    sim = _decide_sim(B=B)
    _place(sim, np.broadcast_to([[5000.0, 0.0], [1e5, 0.0]], (B, 2, 2)), np.zeros((B, 1, 2)))
    ok, slot = sim.channel.pings(_tx(B, [True, False]), _draws(sim))
    p = slot.outcome.p_success[0, 0, 2]
    assert p == pytest.approx(0.60, abs=0.01)
    # binomial: std sqrt(0.6 x 0.4 / 1000) = 0.0155; 4 sigma
    assert abs(ok[:, 0, 0].mean() - p) < 4 * math.sqrt(p * (1 - p) / B)


def test_the_planners_delivery_model_is_the_wired_sonar_link():
    """The planners weigh a range by the probability that its ping arrives
    (``BeaconContext.delivery_probability``). On the sonar link that is the channel's
    own P(decode) of a lone ping, not the modem's range-loss curve (which the channel
    switches off): before, the planners saw every ping arrive, and on a weak link (a
    130 dB source in a loud sea) ``ellipse`` stood 310 m off where 1 ping in 200 is
    decoded at 200 m."""
    from baselines.base import BeaconContext

    weak = dict(source_level_db=130.0, noise_wind_mps=15.0, noise_shipping=1.0)
    ranges = np.array([20.0, 60.0, 100.0, 200.0, 1000.0])
    B = len(ranges)
    for kw in ({}, weak):
        sim = _decide_sim(B=B, **kw)
        _place(sim, np.stack([np.c_[ranges, np.zeros(B)], np.full((B, 2), 1e5)], 1), np.zeros((B, 1, 2)))
        wired = sim.channel.pings(_tx(B, [True, False]), _draws(sim))[1].outcome.p_success[:, 0, 2]
        planners = BeaconContext.from_config(sim.config).delivery_probability(ranges)
        np.testing.assert_allclose(planners, wired, rtol=1e-9, atol=1e-12)
    # by hand on the weak link: NL = band noise at 25 kHz with 15 m/s wind and full shipping
    noise_db = sim.channel.noise_db
    snr = [130.0 - (20.0 * math.log10(r) + 6.1048051 * r / 1000.0) - noise_db for r in ranges]
    np.testing.assert_allclose(planners, [p_success_by_hand(x) for x in snr], atol=1e-9)
    assert planners[0] > 0.95 and planners[3] < 0.01  # 20 m nearly always, 200 m almost never


def test_capture_a_near_ping_survives_a_far_one_in_the_wired_channel():
    # beacons 100 m and 1000 m from the survey vehicle, both at t = 0 (ping_offsets="zero"), 5 s packets:
    # [0.067, 5.067) and [0.67, 5.67) overlap; SIR = TL(1000) - TL(100) = 20 + 6.1048 x 0.9 = +25.49 dB
    sim = _decide_sim(B=1, ping_offsets="zero")
    _place(sim, [[100.0, 0.0], [-1000.0, 0.0]], [[0.0, 0.0]])
    ok, slot = sim.channel.pings(_tx(1, [True, True]), _draws(sim, acoustic_u0=0.5))
    o = slot.outcome
    assert o.overlapped[0, 0, 2] and o.overlapped[0, 1, 2]
    assert o.sir_db[0, 0, 2] == pytest.approx(25.4943, abs=1e-3)
    assert o.sir_db[0, 1, 2] == pytest.approx(-25.4943, abs=1e-3)
    assert ok[0, :, 0].tolist() == [True, False]  # the near one captured, the far one collided
    assert slot.collided[0, :2, 2].tolist() == [False, True]
    # the range link (the earlier channel): any overlap loses both, the near ping too
    sim = _decide_sim(B=1, link_model="range", ping_offsets="zero", ping_interval_s=5.0)
    _place(sim, [[100.0, 0.0], [-1000.0, 0.0]], [[0.0, 0.0]])
    ok, slot = sim.channel.pings(_tx(1, [True, True]), _draws(sim))
    assert ok[0, :, 0].tolist() == [False, False] and slot.collided[0, :2, 2].all()


def test_near_far_a_near_interferer_drowns_a_far_ping_unless_staggered():
    # beacon 0 at 1.4 km, beacon 1 at 200 m: at the same start, SIR of the far ping
    # -(20 log10(7) + 6.1048 x 1.2) = -(16.902 + 7.326) = -24.23 dB: lost; staggered (6.07 s
    # apart: the far ping has ended at 5 + 0.94 s when the near one arrives at 6.07 + 0.13 s)
    # both decoded
    for offsets, expect in (("zero", [False, True]), ("staggered", [True, True])):
        sim = _decide_sim(B=1, ping_offsets=offsets)
        _place(sim, [[1400.0, 0.0], [0.0, 200.0]], [[0.0, 0.0]])
        ok, slot = sim.channel.pings(_tx(1, [True, True]), _draws(sim, acoustic_u0=0.5))
        assert ok[0, :, 0].tolist() == expect, offsets
        if offsets == "zero":
            assert slot.outcome.sir_db[0, 0, 2] == pytest.approx(-(20.0 * math.log10(7.0) + 6.1048051 * 1.2), abs=1e-3)


def test_half_duplex_in_the_wired_channel():
    # zero offsets: the two beacons (800 m apart) transmit together and each is deaf to the other
    sim = _decide_sim(B=1, ping_offsets="zero")
    _place(sim, [[400.0, 0.0], [-400.0, 0.0]], [[0.0, 300.0]])
    reply_ok, peer_ok, o = sim.channel.replies(_tx(1, [True, True]), np.ones((1, 1), bool), _draws(sim, message_u=0.5))
    assert o.deaf[0, 0, 1] and o.deaf[0, 1, 0] and not peer_ok[0, 0, 1] and not peer_ok[0, 1, 0]
    # staggered: B starts at 6.07 s, after A's ping left it (arrival 0.55 s, end 5.55 s), and A has
    # finished sending when B's reaches it: both hear each other
    sim = _decide_sim(B=1)
    _place(sim, [[400.0, 0.0], [-400.0, 0.0]], [[0.0, 300.0]])
    reply_ok, peer_ok, o = sim.channel.replies(_tx(1, [True, True]), np.ones((1, 1), bool), _draws(sim, message_u=0.5))
    assert not o.deaf[0].any() and peer_ok[0, 0, 1] and peer_ok[0, 1, 0] and reply_ok.all()
    # the survey vehicle replies at 6.0714 + 5 + 1.0714 + 0.015 = 12.158 s; B's ping from 2.5 km
    # arrives at 6.07 + 2500 / c = 7.8 s and lasts until 12.8 s: the replying vehicle is deaf to it
    t = sim.channel.timing
    assert t.reply_at_s == pytest.approx(2 * (5.0 + 1500.0 / 1400.0) + 0.015)
    _place(sim, [[400.0, 0.0], [-2500.0, 0.0]], [[0.0, 0.0]])
    _, _, o = sim.channel.replies(_tx(1, [True, True]), np.ones((1, 1), bool), _draws(sim))
    assert o.deaf[0, 1, 2] and not o.deaf[0, 0, 2] and o.p_success[0, 1, 2] == 0.0


def test_a_survey_vehicle_measures_no_ping_it_is_deaf_to_while_replying():
    """The pings a survey vehicle fuses are those of the slot with its own reply in it (a
    review found them taken from the silent slot): staggered, A at 400 m, B at 2.5 km,
    beyond ``max_range_m`` for which the reply time (12.158 s) is laid out. B's ping
    arrives at 6.07 + 2500 / c = 7.7 s (c about 1536 m/s) and lasts until 12.7 s: the
    vehicle, replying to A's, is deaf to it, so it measures A's range only (before: both).
    With A silent, B's ping is the only one and had not ended by the reply time, so no
    reply is sent and it is measured."""
    sim = _decide_sim(B=1)
    _place(sim, [[400.0, 0.0], [-2500.0, 0.0]], [[0.0, 0.0]])
    ok, slot = sim.channel.pings(_tx(1, [True, True]), _draws(sim, acoustic_u0=0.5))
    assert slot.ended[0, 0, 2] and not slot.ended[0, 1, 2]
    assert slot.outcome.end_s[0, 1, 2] == pytest.approx(6.0714 + 2500.0 / 1536.0 + 5.0, abs=0.01)
    assert sim.channel.reply_at_s == pytest.approx(12.158, abs=1e-3)
    assert ok[0, :, 0].tolist() == [True, False] and slot.deaf[0, 1, 2] and not slot.lost[0, 1, 2]
    ok, slot = sim.channel.pings(_tx(1, [False, True]), _draws(sim, acoustic_u0=0.5))
    assert ok[0, :, 0].tolist() == [False, True] and not slot.deaf[0].any()
    assert not (ok & slot.ended[:, :2, 2:]).any()  # nothing to reply to at 12.158 s
    # through a step: A and B both ping, one range is fused; B alone: its range is fused
    # and the beacons hear no reply (their report of the survey vehicle ages by the slot)
    for transmit, fused in (([True, True], 1), ([False, True], 1)):
        sim = _decide_sim(B=1)
        _place(sim, [[400.0, 0.0], [-2500.0, 0.0]], [[0.0, 0.0]])
        age = sim.state.k_age_s.copy()
        res = sim.step(_actions(1, transmit))
        assert res.info["ranges_fused"].sum() == fused, transmit
        replied = sim.state.k_age_s[0, :, 0] < age[0, :, 0] + sim.config.ping_interval_s
        assert replied.all() == transmit[0], (transmit, sim.state.k_age_s[0, :, 0], age[0, :, 0])


def test_a_batch_row_resolves_its_slot_as_the_environment_alone():
    """Whether a slot is resolved again with the replies in it is decided for the batch; a
    review found a row's late ping, lost by its draw alone, counted deaf beside a row that
    needed the second pass. Row 0: A at 400 m and B at 2.5 km, both decoded (B's late).
    Row 1: the same with B's draw losing it. Each row's pings, losses and deafness are those
    of the environment alone."""
    geometry = [[400.0, 0.0], [-2500.0, 0.0]]
    u0 = np.array([[[0.5], [0.5]], [[0.5], [0.0]]])  # (B, N, S): row 1 loses B's ping by its draw
    sim = _decide_sim(B=2)
    _place(sim, np.broadcast_to(geometry, (2, 2, 2)), np.zeros((2, 1, 2)))
    ok, slot = sim.channel.pings(_tx(2, [True, True]), _draws(sim, acoustic_u0=u0))
    for row in range(2):
        alone = _decide_sim(B=1)
        _place(alone, geometry, [[0.0, 0.0]])
        ok1, slot1 = alone.channel.pings(_tx(1, [True, True]), _draws(alone, acoustic_u0=u0[row : row + 1]))
        assert np.array_equal(ok[row], ok1[0]), row
        for name in ("delivered", "lost", "deaf", "collided", "ended"):
            assert np.array_equal(getattr(slot, name)[row], getattr(slot1, name)[0]), (row, name)
    assert slot.deaf[1, 1, 2] and not slot.lost[1, 1, 2]  # replying to A's, deaf to B's: not a loss


def test_two_pings_in_one_slot_do_not_collide():
    """Both beacons ping every slot on sousa_ping's default channel: staggered, neither
    collides and both are heard (the earlier channel sent both at t = 0: always a collision)."""
    sim = _decide_sim()
    for _ in range(3):
        res = sim.step(_actions(2, [True, True]))
        assert (res.beacon_info["pings"] == 1).all() and (res.beacon_info["collisions"] == 0).all()
        heard = res.info["ranges_fused"] + res.info["packets_lost"] + res.info["outliers_rejected"]
        assert (heard == 2).all()
    # at the same start (ping_offsets="zero") the two ASVs' pings overlap at the survey vehicle
    sim = _decide_sim(ping_offsets="zero")
    res = sim.step(_actions(2, [True, True]))
    assert (res.beacon_info["collisions"].sum(-1) >= 1).all()


def test_random_offsets_are_drawn_over_the_stagger_span():
    sim = _decide_sim(B=3, ping_offsets="random")
    t = sim.channel.timing
    seen = []
    for _ in range(3):
        d = sim._cycle_draws(sim.state.cycle)
        off = sim.channel.offsets_s(d)
        np.testing.assert_array_equal(off, d["ping_offset_u"] * t.last_offset_s)
        assert ((off >= 0) & (off < 5.0 + 1500.0 / 1400.0)).all()
        seen.append(off)
        sim.step(_actions(3, [True, True]))
    assert not np.array_equal(seen[0], seen[1])


def test_silent_beacons_measure_nothing_and_spend_nothing():
    sim = _decide_sim()
    res = sim.step(_actions(2, [False, False]))
    assert not res.info["range_ok"].any() and (res.info["packets_lost"] == 0).all()
    assert (res.beacon_info["energy_J"] == 0).all() and (res.terms["contact"] == 0).all()
    assert (res.terms["info_gain"] <= 0).all()  # prediction alone


def test_energy_per_ping_from_source_level_and_efficiency():
    # SL 185 dB: 10^((185 - 170.8) / 10) = 26.30 W acoustic, / 0.25 = 105.2 W, x 5.0 s = 526.05 J
    sim = _decide_sim(B=3)
    assert sim.channel.ping_s == pytest.approx(1.0 + 0.5 + 0.2 + 0.1 + 3.2)
    assert sim.channel.ping_energy_j == pytest.approx(526.05, abs=0.01)
    rng = np.random.default_rng(5)
    pings = energy = 0.0
    for _ in range(6):
        res = sim.step(rng.uniform(-1, 1, (3, 2, 3)))
        pings += res.beacon_info["pings"].sum()
        energy += res.beacon_info["energy_J"].sum()
    assert pings > 0 and energy == pytest.approx(pings * 526.05, abs=0.01 * pings)
    # 180 dB at 50 % efficiency: 10^0.92 / 0.5 x 5 = 83.18 J
    assert ping_energy_j(sim.config.replace(source_level_db=180.0, transmit_efficiency=0.5)) == pytest.approx(
        83.18, abs=0.01
    )


def test_the_slot_must_hold_the_exchange_and_the_validator_names_the_minimum():
    # staggered: 6.0714 (B's offset) + 5 + 1.0714 + 0.015 + 5 + 1.0714 = 18.229 s
    assert slot_timing(coopnav_env.make_config("sousa_ping"), SLOWEST_SOUND_SPEED_MPS).need_s == pytest.approx(
        18.229, abs=1e-3
    )
    with pytest.raises(ValueError, match=r"minimum is 18\.229 s"):
        coopnav_env.make_config("sousa_ping", ping_interval_s=18.0)
    assert coopnav_env.make_config("sousa_ping", ping_interval_s=19.0).ping_interval_s == 19.0
    # all at t = 0: 5 + 1.0714 + 0.015 + 5 + 1.0714 = 12.158 s
    with pytest.raises(ValueError, match=r"minimum is 12\.158 s"):
        coopnav_env.make_config("sousa_ping", ping_offsets="zero", ping_interval_s=12.0)
    # the earlier 5 s slot is refused with real packets, accepted on the range link
    with pytest.raises(ValueError, match="cannot hold the exchange"):
        coopnav_env.make_config("sousa_ping", ping_interval_s=5.0)
    coopnav_env.make_config("sousa_ping", link_model="range", ping_offsets="zero", ping_interval_s=5.0)


def test_the_range_link_reproduces_the_earlier_channel_bit_for_bit():
    """sousa_ping on link_model="range" with every ping at t = 0 and the 5 s slot replays the
    episodes recorded before the sonar link (tests/data/sousa_ping_range_link.npz, copied
    from all_scenarios.npz's sousa_ping/default at the commit before): the same channel."""
    from test_recorded import close_enough

    spec = importlib.util.spec_from_file_location("record_all_scenarios", DATA / "record_all_scenarios.py")
    rec = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(rec)
    ref = np.load(DATA / "sousa_ping_range_link.npz")
    earlier = {"link_model": "range", "ping_offsets": "zero", "ping_interval_s": 5.0}
    earlier |= {"asv_surge_noise_mps": 0.0, "asv_steering_noise_deg": 0.0}  # the ASVs followed commands exactly
    earlier |= dict(SOUSA_PAPER_FILTER)  # and the survey filter was the papers' (white Q 0.05)
    for batch, seeds in rec.RUNS:
        new = rec.record("sousa_ping", batch, seeds, earlier)
        recorded = {k.split("/", 1)[1] for k in ref.files if k.startswith(f"B{batch}/")}
        assert set(new) - recorded <= {"beacon.beacon_away_s"}, set(new) ^ recorded  # the one key added since
        bad = [k for k in recorded if not close_enough(ref[f"B{batch}/{k}"], new[k], rec.RTOL)]
        assert not bad, bad


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
    with pytest.raises(ValueError, match="cannot hold the exchange"):
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
    assert reward.shape == (4,) and infos[0]["pings"] == 1.0 and infos[0]["collisions"] == 0.0  # staggered
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
    assert _episode("fim_a+clock") == (48, 0)  # the fixed clock: both beacons every slot, staggered
    assert _episode("fim_b+tdma") == (24, 0)  # turns: one ping a slot, no collision
    assert _episode("circle+clock") == (48, 0)
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


def obs_view(rel, cov, age=5.0, own_std=0.5):
    """A beacon's decoded observation with only what the transmit schedules read: the survey
    vehicles' positions relative to it, their reported covariances, the replies' age and the
    beacon's own position std."""
    from coopnav_env.obs_layout import ObsView

    view = ObsView.__new__(ObsView)
    view.survey_rel_m = np.asarray(rel, float)
    view.cov_m2 = np.asarray(cov, float)
    view.reply_age_s = np.full(len(view.survey_rel_m), age)
    view.own_std_m = np.float64(own_std)
    return view


def test_event_gain_by_hand():
    from baselines.base import BeaconContext
    from baselines.schedule import predicted_gain_nats
    from coopnav_env.core.acoustics import mackenzie_sound_speed

    config = coopnav_env.make_config("sousa_ping")
    view = obs_view([[30.0, 40.0, 0.0]], [np.diag([4.0, 1.0])])
    q = config.process_noise_horizontal_m2ps * (5.0 + config.ping_interval_s)  # the reply's age + one slot
    h = np.array([0.6, 0.8])
    # R by hand: the ranging noise and the beacon's variance; R(d) adds the sound speed's
    # scale error over the 50 m slant (Mackenzie's dc/dT at the mid-depth, times the uncertainty)
    depth = 0.5 * config.depth_m  # halfway between the ASV at 0 m and the survey vehicle
    c0 = float(mackenzie_sound_speed(config.water_temperature_c, config.salinity_psu, depth))
    c1 = float(mackenzie_sound_speed(config.water_temperature_c + 1.0, config.salinity_psu, depth))
    rel = config.temperature_uncertainty_c * (c1 - c0) / c0
    ctx = BeaconContext.from_config(config, 0)
    for model, R in [
        ("constant", config.range_noise_std_m**2 + 0.25),  # the default: one R at every distance
        ("filter", config.range_noise_std_m**2 + 0.25 + (50.0 * rel) ** 2),  # the survey filter's R(d)
    ]:
        expected = np.log1p(h @ (np.diag([4.0, 1.0]) + q * np.eye(2)) @ h / R)
        assert predicted_gain_nats(view, ctx.with_range_model(model)) == pytest.approx(expected, rel=1e-12)
