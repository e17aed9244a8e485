"""Same seed + same actions = the same episode, bit for bit, at every step; the env
pickles mid-episode; and row b of a batch is the same environment as a batch of one."""

from __future__ import annotations

import copy
import pickle

import numpy as np
import pytest

import coopnav_env
from coopnav_env.core import make_simulator
from coopnav_env.core.sim import INFO_KEYS, Simulator
from coopnav_env.gym_env import CoopNavGymEnv

SCENARIOS = coopnav_env.list_scenarios()
MULTI = dict(beacon_kinds=("beacon_auv", "asv"), n_survey=2)
# every scenario, plus a two-beacon / two-survey roster (the N > 1 and S > 1 code paths)
CASES = [(sc, {}) for sc in SCENARIOS] + [("gao_lawnmower", MULTI)]
CASE_IDS = SCENARIOS + ["gao_lawnmower-2x2"]


def assert_same(a, b, where=""):
    """Exact equality of nested dicts / lists / arrays / scalars (dtype included for arrays)."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and a.keys() == b.keys(), f"{where}: keys {a.keys()} != {b.keys()}"
        for k in a:
            assert_same(a[k], b[k], f"{where}[{k!r}]")
    elif isinstance(a, (list, tuple)):
        assert type(a) is type(b) and len(a) == len(b), f"{where}: {a!r} != {b!r}"
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same(x, y, f"{where}[{i}]")
    elif isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray), f"{where}: {type(b)} is not an array"
        assert a.dtype == b.dtype and a.shape == b.shape, f"{where}: {a.dtype}{a.shape} != {b.dtype}{b.shape}"
        assert np.array_equal(a, b), f"{where}: arrays differ\n{a}\n{b}"
    else:
        assert type(a) is type(b) and a == b, f"{where}: {a!r} != {b!r}"


def action_sequence(n_agents, n_steps, seed):
    rng = np.random.default_rng(seed)
    return rng.uniform(-1.0, 1.0, size=(n_steps, n_agents, 2)).astype(np.float32)


def run_episode(env, seed, actions):
    """Reset with ``seed`` and play ``actions`` until the episode ends; every step's output."""
    obs, infos = env.reset(seed=seed)
    steps = [(obs, infos)]
    t = 0
    while env.agents:
        assert t < len(actions), "episode longer than the action sequence"
        out = env.step({a: actions[t, i] for i, a in enumerate(env.agents)})
        steps.append(out)
        t += 1
    return steps


@pytest.mark.parametrize("scenario, kw", CASES, ids=CASE_IDS)
def test_same_seed_same_episode(scenario, kw):
    env1 = coopnav_env.parallel_env(scenario, **kw)
    env2 = coopnav_env.parallel_env(scenario, **kw)
    n = env1.config.max_cycles
    acts = action_sequence(len(env1.possible_agents), n, seed=123)
    ep1 = run_episode(env1, 7, acts)
    ep2 = run_episode(env2, 7, acts)
    assert len(ep1) == len(ep2) >= 10, "episode too short to test determinism"
    for t, (s1, s2) in enumerate(zip(ep1, ep2)):
        assert_same(s1, s2, f"step {t}")
    # the episode really ended, by termination or truncation
    _, _, terms, truncs, _ = ep1[-1]
    assert all(terms.values()) or all(truncs.values())
    # the same env, reset with the same seed after an episode, replays it exactly
    ep3 = run_episode(env1, 7, acts)
    assert len(ep3) == len(ep1)
    for t, (s1, s3) in enumerate(zip(ep1, ep3)):
        assert_same(s1, s3, f"replay step {t}")


@pytest.mark.parametrize("scenario, kw", CASES, ids=CASE_IDS)
def test_different_seeds_differ(scenario, kw):
    env1 = coopnav_env.parallel_env(scenario, max_cycles=10, **kw)
    env2 = coopnav_env.parallel_env(scenario, max_cycles=10, **kw)
    acts = action_sequence(len(env1.possible_agents), 10, seed=5)
    ep1 = run_episode(env1, 1, acts)
    ep2 = run_episode(env2, 2, acts)
    first1, first2 = ep1[0][0]["beacon_0"], ep2[0][0]["beacon_0"]
    assert not np.array_equal(first1, first2), "different seeds gave the same initial observation"
    infos1 = [s[4]["beacon_0"]["survey_error_m"] for s in ep1[1:]]
    infos2 = [s[4]["beacon_0"]["survey_error_m"] for s in ep2[1:]]
    assert infos1 != infos2, "different seeds gave the same survey errors"
    assert not np.array_equal(env1.state(), env2.state())


def test_different_action_sequences_differ():
    """The actions matter (so the equal-episode test is not comparing constant outputs)."""
    env1 = coopnav_env.parallel_env("gao_lawnmower", max_cycles=5)
    env2 = coopnav_env.parallel_env("gao_lawnmower", max_cycles=5)
    ep1 = run_episode(env1, 3, action_sequence(1, 5, seed=1))
    ep2 = run_episode(env2, 3, action_sequence(1, 5, seed=2))
    assert_same(ep1[0], ep2[0], "reset")
    assert not np.array_equal(ep1[-1][0]["beacon_0"], ep2[-1][0]["beacon_0"])


def test_constructor_seed_and_unseeded_resets_are_reproducible():
    env1 = coopnav_env.parallel_env("gao_lawnmower", seed=42, max_cycles=3)
    env2 = coopnav_env.parallel_env("gao_lawnmower", seed=42, max_cycles=3)
    firsts = []
    for _ in range(3):  # a sequence of resets without a seed
        o1, _ = env1.reset()
        o2, _ = env2.reset()
        assert_same(o1, o2, "unseeded reset")
        firsts.append(o1["beacon_0"])
    # the constructor's seed is the first episode's seed
    env3 = coopnav_env.parallel_env("gao_lawnmower", max_cycles=3)
    assert_same(env3.reset(seed=42)[0]["beacon_0"], firsts[0])
    # later episodes are new episodes, not replays
    assert not np.array_equal(firsts[0], firsts[1])
    assert not np.array_equal(firsts[1], firsts[2])


def test_reset_seed_supersedes_constructor_seed():
    """After reset(seed=s), later unseeded resets follow s, whatever seed the constructor had."""
    a = coopnav_env.parallel_env("gao_lawnmower", seed=0, max_cycles=3)
    b = coopnav_env.parallel_env("gao_lawnmower", seed=1, max_cycles=3)
    c = coopnav_env.parallel_env("gao_lawnmower", max_cycles=3)
    for env in (a, b, c):
        env.reset(seed=5)
    nxt = [env.reset()[0]["beacon_0"] for env in (a, b, c)]
    assert_same(nxt[0], nxt[1], "a vs b")
    assert_same(nxt[0], nxt[2], "a vs c")
    fresh = coopnav_env.parallel_env("gao_lawnmower", max_cycles=3)
    assert not np.array_equal(nxt[0], fresh.reset(seed=0)[0]["beacon_0"]), "replayed the constructor's seed"


@pytest.mark.parametrize("scenario, kw", CASES, ids=CASE_IDS)
@pytest.mark.parametrize("render_mode", [None, "rgb_array"])
def test_pickle_mid_episode(scenario, kw, render_mode):
    env = coopnav_env.parallel_env(scenario, render_mode=render_mode, max_cycles=30, **kw)
    n_agents = len(env.possible_agents)
    acts = action_sequence(n_agents, 30, seed=9)
    env.reset(seed=21)
    for t in range(8):
        env.step({a: acts[t, i] for i, a in enumerate(env.agents)})
    clone = pickle.loads(pickle.dumps(env))
    assert clone.agents == env.agents
    assert_same(clone.state(), env.state(), "state after unpickling")
    t = 8
    while env.agents:
        step = {a: acts[t, i] for i, a in enumerate(env.agents)}
        out1 = env.step(step)
        out2 = clone.step(dict(step))
        assert_same(out1, out2, f"step {t} after unpickling")
        assert_same(env.state(), clone.state(), f"state at step {t}")
        t += 1
    assert not clone.agents
    assert t > 8
    if render_mode == "rgb_array":
        np.testing.assert_array_equal(env.render(), clone.render())


def test_pickle_copy_is_independent():
    env = coopnav_env.parallel_env("gao_lawnmower", max_cycles=10)
    env.reset(seed=1)
    env.step({"beacon_0": np.zeros(2, np.float32)})
    clone = pickle.loads(pickle.dumps(env))
    before = clone.state().copy()
    env.step({"beacon_0": np.ones(2, np.float32)})
    assert_same(clone.state(), before, "clone changed when the original stepped")


def test_aec_env_pickles_and_deepcopies():
    acts = action_sequence(2, 20, seed=3)
    env = coopnav_env.env("gao_lawnmower", max_cycles=20, **MULTI)
    env.reset(seed=4)
    for k in range(6):
        env.step(acts[k // 2, k % 2])
    clones = [pickle.loads(pickle.dumps(env)), copy.deepcopy(env)]
    for k in range(6, 60):
        agent = env.agent_selection
        last = env.last()
        for c in clones:
            assert c.agent_selection == agent
            assert_same(c.last(), last, f"AEC step {k}")
        done = last[2] or last[3]
        action = None if done else acts[min(k // 2, 19), env.possible_agents.index(agent)]
        env.step(action)
        for c in clones:
            c.step(None if action is None else action.copy())
        if not env.agents:
            break
    assert not env.agents, "the AEC episode did not end"
    assert all(not c.agents for c in clones)


def test_gym_view_determinism_and_pickle():
    acts = action_sequence(1, 40, seed=8)[:, 0]
    e1, e2 = CoopNavGymEnv("gao_lawnmower", max_cycles=40), CoopNavGymEnv("gao_lawnmower", max_cycles=40)
    assert_same(e1.reset(seed=5), e2.reset(seed=5), "gym reset")
    for t in range(10):
        assert_same(e1.step(acts[t]), e2.step(acts[t]), f"gym step {t}")
    e3 = pickle.loads(pickle.dumps(e1))
    for t in range(10, 40):
        out1, out3 = e1.step(acts[t]), e3.step(acts[t])
        assert_same(out1, out3, f"gym step {t} after unpickling")
        if out1[2] or out1[3]:
            break
    o_a, _ = e1.reset(seed=6)
    o_b, _ = e2.reset(seed=7)
    assert not np.array_equal(o_a, o_b)


# --- the batched core: row b of a batch is the same environment as a batch of one ----
@pytest.mark.parametrize("scenario, kw", CASES, ids=CASE_IDS)
def test_batch_row_equals_batch_of_one(scenario, kw):
    config = coopnav_env.make_config(scenario, **kw)
    # the simulator that reads the config (the moving network's for matos_*: the survey network's
    # Simulator ran them as survey scenarios until their beacon sections became absent)
    big, one = make_simulator(config, batch_size=3), make_simulator(config, batch_size=1)
    obs3, obs1 = big.reset([5, 6, 7]), one.reset([6])
    assert obs3.shape == (3,) + obs1.shape[1:]
    np.testing.assert_array_equal(obs3[1], obs1[0])
    np.testing.assert_array_equal(big.global_state()[1], one.global_state()[0])
    rng = np.random.default_rng(17)
    n_steps = 60
    for t in range(n_steps):
        actions = rng.uniform(-1.0, 1.0, size=(3, config.n_beacons, 2))
        r3 = big.step(actions)
        r1 = one.step(actions[1:2].copy())
        np.testing.assert_array_equal(r3.obs[1], r1.obs[0], err_msg=f"obs, step {t}")
        np.testing.assert_array_equal(r3.reward[1], r1.reward[0], err_msg=f"reward, step {t}")
        assert r3.terminated[1] == r1.terminated[0], f"terminated, step {t}"
        assert r3.truncated[1] == r1.truncated[0], f"truncated, step {t}"
        assert set(r3.info) == set(r1.info)
        assert config.network != "survey_beacons" or set(r1.info) == set(INFO_KEYS)
        for key in r1.info:
            np.testing.assert_array_equal(r3.info[key][1], r1.info[key][0], err_msg=f"info {key}, step {t}")
        np.testing.assert_array_equal(big.global_state()[1], one.global_state()[0], err_msg=f"state, step {t}")
        if r1.terminated[0] or r1.truncated[0]:
            break
    # the three rows are different environments
    assert not np.array_equal(r3.obs[0], r3.obs[1]) and not np.array_equal(r3.obs[1], r3.obs[2])


def test_batch_row_equals_pettingzoo_env():
    """The PettingZoo env is the batch-of-one view: the same numbers as row 2 of a batch."""
    config = coopnav_env.make_config("gao_lawnmower", max_cycles=20)
    big = Simulator(config, batch_size=3)
    obs3 = big.reset([11, 12, 13])
    env = coopnav_env.parallel_env(config)
    obs, _ = env.reset(seed=13)
    np.testing.assert_array_equal(obs3[2, 0], obs["beacon_0"])
    rng = np.random.default_rng(0)
    while env.agents:
        actions = rng.uniform(-1.0, 1.0, size=(3, 1, 2))
        r3 = big.step(actions)
        obs, rewards, terms, truncs, infos = env.step({"beacon_0": actions[2, 0]})
        np.testing.assert_array_equal(r3.obs[2, 0], obs["beacon_0"])
        assert float(r3.reward[2, 0]) == rewards["beacon_0"]
        assert bool(r3.terminated[2]) == terms["beacon_0"] and bool(r3.truncated[2]) == truncs["beacon_0"]
        assert float(r3.info["survey_error_m"][2].mean()) == infos["beacon_0"]["survey_error_m"]
        np.testing.assert_array_equal(big.global_state()[2], env.state())


def test_partial_reset_keeps_other_rows():
    """Resetting one row of a batch (the vectorized trainer's auto-reset) leaves the others alone,
    and the reset row starts exactly like a fresh environment with that seed."""
    config = coopnav_env.make_config("gao_lawnmower")
    big = Simulator(config, batch_size=3)
    big.reset([5, 6, 7])
    rng = np.random.default_rng(1)
    for _ in range(4):
        big.step(rng.uniform(-1, 1, size=(3, 1, 2)))
    before = big.global_state().copy()
    obs = big.reset([99], mask=np.array([False, True, False]))
    after = big.global_state()
    np.testing.assert_array_equal(after[[0, 2]], before[[0, 2]])
    fresh = Simulator(config, batch_size=1)
    np.testing.assert_array_equal(obs[1], fresh.reset([99])[0])
    np.testing.assert_array_equal(after[1], fresh.global_state()[0])
    # and it then steps like the fresh one
    a = rng.uniform(-1, 1, size=(3, 1, 2))
    np.testing.assert_array_equal(big.step(a).obs[1], fresh.step(a[1:2]).obs[0])
