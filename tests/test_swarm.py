"""swarm_mls: the MLS sensor's measurements inside the batched core (round robin,
range and bearing fusion, front/back unfolding), and the scenario's plumbing."""

import numpy as np
import pytest

import coopnav_env
from coopnav_env import make_config
from coopnav_env.core import make_simulator


def _sim(B=1, **overrides):
    c = make_config("swarm_mls", **overrides)
    sim = make_simulator(c, B)
    sim.reset(np.arange(B) + 11)
    return c, sim


def test_round_robin_one_sender_per_cycle():
    _c, sim = _sim(B=3, beacon_kinds=("beacon_auv", "beacon_auv"), beacon_start_distance_m=10.0)
    draws = sim._cycle_draws(sim.state.cycle)
    for cycle in range(4):
        sim.state.cycle = np.full(3, cycle + 1)  # the sensor measures after the counter advanced
        state, *_ = sim.sensor.measure(draws)
        senders = (state > 0).any(-1)  # (B, N)
        assert np.array_equal(senders, np.tile(np.arange(2) == cycle % 2, (3, 1)))


def test_senders_beyond_the_window_are_lost_not_fused():
    c, sim = _sim(B=2, mls_max_range_m=2.0)
    res = sim.step(np.zeros((2, 1, 2)))
    assert res.info["ranges_fused"].sum() == 0
    assert res.info["packets_lost"].sum() == 2 * c.n_survey  # the sender was silent to everyone


def test_range_and_bearing_pull_a_displaced_estimate_back():
    """One survey vehicle, the sender 20 m away: an estimate displaced 6 m ACROSS the line
    of sight (which a range alone barely corrects) is pulled back by the bearing, in
    the right direction; with the sign of the bearing wrong it would be pushed away."""
    _c, sim = _sim(
        B=1,
        n_survey=1,
        survey_path="stationary",
        beacon_start_distance_m=20.0,
        beacon_start_bearing_spread_deg=0.0,
        compass_bias_std_deg=0.0,
        current_speed_mps=0.0,
        current_speed_spread_mps=0.0,
        current_gm_std_mps=0.0,
    )
    st = sim.state
    los = st.b_pos[0, 0, :2] - st.s_pos[0, 0, :2]
    across = np.array([-los[1], los[0]]) / np.linalg.norm(los)
    st.s_est[0, 0, :2] = st.s_pos[0, 0, :2] + 6.0 * across
    st.s_P[0, 0, :2, :2] = np.eye(2) * 50.0
    res = sim.step(np.zeros((1, 1, 2)))
    err = sim.state.s_est[0, 0, :2] - sim.state.s_pos[0, 0, :2]
    assert res.info["ranges_fused"][0, 0] == 1
    assert abs(err @ across) < 1.5  # was 6 m
    assert np.linalg.norm(err) < 3.5  # what is left: mostly the sender's own ~1 m navigation error


def test_a_sender_behind_the_receiver_is_unfolded():
    """Two hydrophones fold a sender behind onto the front half-plane (azimuth 180 deg -
    bearing); the survey vehicle unfolds it with its estimate, so the bearing it fuses
    points astern, at the sender, and the estimate is corrected."""
    _c, sim = _sim(
        B=1,
        n_survey=1,
        survey_path="line",
        beacon_start_distance_m=20.0,
        beacon_start_bearing_deg=240.0,
        beacon_start_bearing_spread_deg=0.0,
        compass_bias_std_deg=0.0,
    )
    st = sim.state
    # the line runs east and the survey starts heading east: the sender (bearing 240 deg) is astern
    assert np.angle(st.s_heading[0, 0]) == pytest.approx(0.0, abs=1e-9)
    sim.state.cycle = np.ones(1, dtype=np.int64)
    state, rng_m, bearing, _var_r, _var_b = sim.sensor.measure(sim._cycle_draws(np.zeros(1, dtype=np.int64)))
    los = st.b_pos[0, 0, :2] - st.s_pos[0, 0, :2]
    true_bearing = np.arctan2(los[0], los[1])  # clockwise from north
    folded_error = np.degrees(abs((bearing[0, 0, 0] - true_bearing + np.pi) % (2 * np.pi) - np.pi))
    assert state[0, 0, 0] == 2 and folded_error < 3.0  # unfolded: ~0, folded it would be ~60 deg off
    assert rng_m[0, 0, 0] == pytest.approx(np.linalg.norm(los), abs=0.05)
    st.s_est[0, 0, :2] = st.s_pos[0, 0, :2] + np.array([0.0, 5.0])
    st.s_P[0, 0, :2, :2] = np.eye(2) * 50.0
    sim.state.cycle = np.zeros(1, dtype=np.int64)
    sim.step(np.zeros((1, 1, 2)))
    err = sim.state.s_est[0, 0, :2] - sim.state.s_pos[0, 0, :2]
    assert np.linalg.norm(err) < 3.0  # was 5 m


def test_school_navigates_better_than_dead_reckoning():
    from evaluation.episodes import run_episodes

    c = make_config("swarm_mls", max_cycles=120)
    eps, _ = run_episodes(c, "circle", range(4))
    err = np.mean([e["mean_error_m"] for e in eps])
    dr = np.mean([e["mean_dr_error_m"] for e in eps])
    assert err < 0.5 * dr


def test_mls_needs_the_survey_network():
    with pytest.raises(ValueError, match="acoustic_sensor='mls' needs network='survey_beacons'"):
        make_config("matos_moving_lbl", acoustic_sensor="mls")
    with pytest.raises(ValueError, match="unknown acoustic_sensor"):
        make_config("swarm_mls", acoustic_sensor="sonar")


def test_swarm_runs_under_the_vector_env():
    from coopnav_env.vector import CoopNavVecEnv

    venv = CoopNavVecEnv("swarm_mls", n_envs=4, seed=0, max_cycles=5)
    obs = venv.reset()
    assert obs.shape == (4, venv.obs_dim)
    for _ in range(6):
        obs, r, _done, _infos = venv.step(np.zeros((4, 2), dtype=np.float32))
        assert np.all(np.isfinite(r))
    assert coopnav_env.parallel_env("swarm_mls").config.n_survey == 3


@pytest.mark.parametrize(("pbb", "beacon_part"), [(np.diag([0.0, 100.0]), 0.0), (np.diag([100.0, 0.0]), 100.0)])
def test_an_mls_bearing_takes_the_senders_variance_across_the_line_of_sight(pbb, beacon_part):
    """The sender 50 m north of the survey estimate: its bearing R is the bearing's variance plus
    the sender's position variance across the line of sight (east) over the range squared
    (eq. N1's Pbb projected, ``consider.beacon_variance_los``). An error along the line of
    sight (north) does not turn the bearing: R = 0.01 rad^2. One across it (east, 100 m^2):
    R = 0.01 + 100 / 2500 = 0.05. A scalar Kalman update by hand on the east axis, P = 25 I:
    H = (-1/50, 0, 0), S = 25 / 2500 + R, P_ee <- 25 - (25 / 50)^2 / S."""
    from coopnav_env.core.measurements.mls_array import _bearing_update

    x, P = np.zeros(3), np.diag([25.0, 25.0, 1.0])
    assert _bearing_update(x, P, np.array([0.0, 50.0, 0.0]), pbb, 0.0, 0.01, np.inf, np.zeros(3))
    R = 0.01 + beacon_part / 2500.0
    assert P[0, 0] == pytest.approx(25.0 - 0.5**2 / (0.01 + R))
    assert P[1, 1] == 25.0
