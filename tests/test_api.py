"""The PettingZoo, Gymnasium and SB3 API contracts, on every scenario."""

from __future__ import annotations

import functools
import types
import warnings

import gymnasium
import numpy as np
import pytest
from pettingzoo.test import api_test, max_cycles_test, parallel_api_test, parallel_seed_test, seed_test, state_test

import coopnav_env

SCENARIOS = coopnav_env.list_scenarios()
SHORT = 12  # cycles per episode in the API checks: short, but long enough to see several steps
ONE_BEACON = [sc for sc in SCENARIOS if coopnav_env.make_config(sc).n_beacons == 1]


def test_list_scenarios_names_the_gao_scenarios():
    names = coopnav_env.list_scenarios()
    assert "gao_lawnmower" in names
    assert "gao_sea" in names
    assert names == sorted(set(names))


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_parallel_api(scenario):
    parallel_api_test(coopnav_env.parallel_env(scenario, max_cycles=SHORT), num_cycles=SHORT + 5)


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_aec_api(scenario):
    api_test(coopnav_env.env(scenario, max_cycles=SHORT), num_cycles=SHORT + 5)


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_parallel_seed(scenario):
    parallel_seed_test(functools.partial(coopnav_env.parallel_env, scenario, max_cycles=SHORT), num_cycles=SHORT)


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_aec_seed(scenario):
    seed_test(functools.partial(coopnav_env.env, scenario, max_cycles=SHORT), num_cycles=SHORT)


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_max_cycles(scenario):
    mod = types.SimpleNamespace(
        parallel_env=functools.partial(coopnav_env.parallel_env, scenario),
        env=functools.partial(coopnav_env.env, scenario),
    )
    max_cycles_test(mod)


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_state(scenario):
    par = coopnav_env.parallel_env(scenario, max_cycles=SHORT)
    state_test(coopnav_env.env(scenario, max_cycles=SHORT), par, num_cycles=SHORT)
    # the state is a real global state: inside its space, and it changes as the episode runs
    par.reset(seed=3)
    s0 = par.state()
    assert par.state_space.contains(s0)
    par.step({a: par.action_space(a).sample() for a in par.agents})
    s1 = par.state()
    assert par.state_space.contains(s1)
    assert not np.array_equal(s0, s1)


@pytest.mark.parametrize("scenario", ONE_BEACON)
def test_gymnasium_check_env(scenario):
    from gymnasium.utils.env_checker import check_env

    env = gymnasium.make(f"coopnav/{scenario}-v0", max_cycles=SHORT)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)  # a checker warning is a failure here
        check_env(env.unwrapped, skip_render_check=True)
    env.close()


@pytest.mark.parametrize("scenario", ONE_BEACON)
def test_sb3_check_env(scenario):
    from stable_baselines3.common.env_checker import check_env

    env = gymnasium.make(f"coopnav/{scenario}-v0", max_cycles=SHORT)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        check_env(env.unwrapped, warn=True)
    env.close()


def test_gymnasium_view_matches_beacon_0_of_parallel_env():
    """The Gymnasium view is the same env as beacon_0: same spaces and an episode that runs to its end."""
    genv = gymnasium.make("coopnav/gao_lawnmower-v0", max_cycles=5).unwrapped
    par = coopnav_env.parallel_env("gao_lawnmower")
    assert genv.observation_space == par.observation_space("beacon_0")
    assert genv.action_space == par.action_space("beacon_0")
    obs, info = genv.reset(seed=0)
    assert genv.observation_space.contains(obs)
    steps, done = 0, False
    while not done:
        obs, _reward, term, trunc, info = genv.step(genv.action_space.sample())
        steps += 1
        done = term or trunc
    assert steps == 5 and trunc
    for key in ("survey_error_m", "dr_error_m", "cov_logdet", "range_ok"):
        assert key in info


def test_keyword_override():
    env = coopnav_env.parallel_env("gao_lawnmower", ping_interval_s=10.0, current_speed_mps=0.3)
    assert env.config.ping_interval_s == 10.0
    assert env.config.current_speed_mps == 0.3
    assert env.config.name == "gao_lawnmower"
    # the override reaches the simulation: one step is now 10 s
    env.reset(seed=0)
    env.step({a: np.zeros(2, np.float32) for a in env.agents})
    assert env.sim.state.t_s[0] == pytest.approx(10.0)
    # and the registered scenario itself is untouched
    assert coopnav_env.make_config("gao_lawnmower").ping_interval_s == 20.0


def test_max_cycles_keyword_truncates():
    env = coopnav_env.parallel_env("gao_lawnmower", max_cycles=3)
    env.reset(seed=0)
    n = 0
    while env.agents:
        _, _, terms, truncs, _ = env.step({a: env.action_space(a).sample() for a in env.agents})
        n += 1
    assert n == 3
    assert all(truncs.values()) and not any(terms.values())


def test_infos_have_documented_keys_every_step():
    env = coopnav_env.parallel_env("gao_lawnmower", max_cycles=4)
    env.reset(seed=0)
    while env.agents:
        _, rewards, _, _, infos = env.step({a: env.action_space(a).sample() for a in env.agents})
        for a, info in infos.items():
            assert np.isfinite(rewards[a])
            for key in (
                "survey_error_m",
                "dr_error_m",
                "cov_logdet",
                "range_ok",
                "ranges_fused",
                "outliers_rejected",
                "nan_rejected",
                "packets_lost",
            ):
                assert key in info, key
                assert key + "_per_vehicle" in info, key
            assert isinstance(info["range_ok"], bool)
            assert np.isfinite(info["survey_error_m"]) and info["survey_error_m"] >= 0
            assert np.isfinite(info["dr_error_m"]) and info["dr_error_m"] >= 0
            assert np.isfinite(info["cov_logdet"])


def test_render_rgb_array():
    env = coopnav_env.parallel_env("gao_lawnmower", render_mode="rgb_array", max_cycles=3)
    env.reset(seed=0)
    while env.agents:
        env.step({a: env.action_space(a).sample() for a in env.agents})
    frame = env.render()
    assert isinstance(frame, np.ndarray)
    assert frame.ndim == 3 and frame.shape[2] == 3
    assert frame.shape[0] > 50 and frame.shape[1] > 50
    assert frame.dtype == np.uint8
    assert frame.min() < frame.max()  # something was drawn
    env.close()


def test_render_human_draws_into_a_pyplot_window():
    import matplotlib
    import matplotlib.pyplot as plt

    if matplotlib.get_backend().lower() != "agg":
        plt.switch_backend("agg")  # headless
    before = set(plt.get_fignums())
    env = coopnav_env.parallel_env("gao_lawnmower", render_mode="human", max_cycles=2)
    env.reset(seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # Agg cannot show windows, and says so
        while env.agents:
            env.step({a: env.action_space(a).sample() for a in env.agents})  # human mode renders each step
        assert env.render() is None
    opened = set(plt.get_fignums()) - before
    assert len(opened) == 1, "human rendering must draw into exactly one pyplot figure"
    fig = plt.figure(opened.pop())
    assert fig.axes and fig.axes[0].lines, "the window is empty"
    env.close()
    assert set(plt.get_fignums()) == before, "close() must close the window"


def test_render_without_mode_returns_none():
    env = coopnav_env.parallel_env("gao_lawnmower", max_cycles=2)
    env.reset(seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert env.render() is None


MULTI = dict(beacon_kinds=("beacon_auv", "asv"), n_survey=2)


def test_two_beacons_two_surveys_parallel_api():
    env = coopnav_env.parallel_env("gao_lawnmower", max_cycles=SHORT, **MULTI)
    assert env.possible_agents == ["beacon_0", "beacon_1"]
    parallel_api_test(env, num_cycles=SHORT + 5)


def test_two_beacons_two_surveys_infos_per_vehicle():
    env = coopnav_env.parallel_env("gao_lawnmower", max_cycles=5, **MULTI)
    obs, _ = env.reset(seed=0)
    assert set(obs) == {"beacon_0", "beacon_1"}
    steps = 0
    while env.agents:
        obs, _rewards, _, _, infos = env.step({a: env.action_space(a).sample() for a in env.agents})
        steps += 1
        assert set(infos) == {"beacon_0", "beacon_1"}
        for info in infos.values():
            for key in (
                "survey_error_m",
                "dr_error_m",
                "cov_logdet",
                "range_ok",
                "ranges_fused",
                "outliers_rejected",
                "nan_rejected",
                "packets_lost",
            ):
                per = info[key + "_per_vehicle"]
                assert isinstance(per, list) and len(per) == 2, key
            assert info["survey_error_m"] == pytest.approx(np.mean(info["survey_error_m_per_vehicle"]))
            assert info["ranges_fused"] == sum(info["ranges_fused_per_vehicle"])
            assert info["range_ok"] == any(info["range_ok_per_vehicle"])
        # the two beacons see different things (own position differs)
        assert not np.array_equal(obs["beacon_0"], obs["beacon_1"])
    assert steps == 5


def test_gymnasium_view_refuses_two_beacons():
    from coopnav_env.gym_env import CoopNavGymEnv

    with pytest.raises(ValueError, match="one beacon"):
        CoopNavGymEnv("gao_lawnmower", beacon_kinds=("beacon_auv", "asv"))


def test_raw_env_is_the_unwrapped_aec_env():
    """PettingZoo's convention: ``raw_env`` the AEC env without wrappers, ``env`` it
    inside OrderEnforcingWrapper (which refuses a step before reset)."""
    from pettingzoo import AECEnv
    from pettingzoo.utils.wrappers import BaseWrapper, OrderEnforcingWrapper

    raw = coopnav_env.raw_env("gao_lawnmower", max_cycles=3)
    assert isinstance(raw, AECEnv) and not isinstance(raw, BaseWrapper)
    wrapped = coopnav_env.env("gao_lawnmower", max_cycles=3)
    assert isinstance(wrapped, OrderEnforcingWrapper)
    with pytest.raises(Exception, match="reset"):
        wrapped.step(np.zeros(2, dtype=np.float32))
    raw.reset(seed=0)
    wrapped.reset(seed=0)
    assert raw.observe("beacon_0").tolist() == wrapped.observe("beacon_0").tolist()
