"""The SB3 VecEnv over the batched core (coopnav_env/vector.py): its contract, and that
its transitions are the PettingZoo env's, exactly, for the same seeds."""

import copy

import gymnasium as gym
import numpy as np
import pytest

import coopnav_env
from coopnav_env.vector import REWARD_TERMS, SEED_STRIDE, CoopNavVecEnv
from coopnav_env.views import agent_infos

TWO_BY_TWO = dict(beacon_kinds=("beacon_auv", "asv"), n_survey=2)
EXTRA_KEYS = ("terminal_observation", "TimeLimit.truncated")


class RowView(gym.Env):
    """Row 0 of CoopNavVecEnv(n_envs=1) as a gymnasium.Env, for SB3's check_env."""

    def __init__(self, scenario, **kw):
        self.venv = CoopNavVecEnv(scenario, n_envs=1, seed=0, **kw)
        self.observation_space, self.action_space = self.venv.observation_space, self.venv.action_space

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        if seed is not None:
            self.venv.seed(seed)
        return self.venv.reset()[0], {}

    def step(self, action):
        obs, reward, done, infos = self.venv.step(np.asarray(action)[None])
        info = dict(infos[0])
        truncated = bool(info.pop("TimeLimit.truncated"))
        if done[0]:
            obs = info.pop("terminal_observation")[None]
        return obs[0], float(reward[0]), bool(done[0]) and not truncated, truncated, info


@pytest.mark.parametrize("scenario", ["sousa_asv", "gao_lawnmower"])
def test_sb3_check_env_on_a_batch_of_one_row(scenario):
    from stable_baselines3.common.env_checker import check_env

    check_env(RowView(scenario, max_cycles=8), warn=True)


def test_shapes_dtypes_and_spaces():
    venv = CoopNavVecEnv("gao_lawnmower", n_envs=3, seed=0, **TWO_BY_TWO)
    assert venv.num_envs == 6 and venv.n_envs == 3 and venv.n_beacons == 2
    obs = venv.reset()
    assert obs.shape == (6, venv.obs_dim) and obs.dtype == np.float32
    assert venv.observation_space.contains(obs[0]) and venv.action_space.shape == (2,)
    obs, reward, done, infos = venv.step(np.zeros((6, 2), dtype=np.float32))
    assert obs.shape == (6, venv.obs_dim) and obs.dtype == np.float32
    assert all(venv.observation_space.contains(o) for o in obs)
    assert reward.shape == (6,) and reward.dtype == np.float32
    assert done.shape == (6,) and done.dtype == bool
    assert isinstance(infos, list) and len(infos) == 6
    for info in infos:
        assert info["TimeLimit.truncated"] is False and "terminal_observation" not in info
        assert len(info["survey_error_m_per_vehicle"]) == 2
    assert infos[0] is not infos[1]  # the beacons of one environment get their own dicts
    assert venv.global_state().shape == (3, venv.sim.state_dim)


def test_infos_are_the_views_agent_infos():
    venv = CoopNavVecEnv("gao_sea", n_envs=4, seed=3, **TWO_BY_TWO)
    venv.reset()
    for _ in range(3):
        venv.step_async(np.random.default_rng(0).uniform(-1, 1, (8, 2)))
        # the same batch step, straight from a copy of the core, for the reference infos
        ref = copy.deepcopy(venv.sim).step(venv._actions)
        _, _, _, infos = venv.step_wait()
        for row, info in enumerate(infos):
            expect = agent_infos(ref.info, row // 2, ref.beacon_info, row % 2)
            got = {k: v for k, v in info.items() if k not in EXTRA_KEYS}
            assert set(got) == set(expect)
            for k in expect:
                assert np.array_equal(got[k], expect[k]), k


def _pz_actions(a, n_beacons, e):
    return {f"beacon_{j}": a[e * n_beacons + j] for j in range(n_beacons)}


def _compare_with_pettingzoo(venv, envs, steps, rng):
    """Step venv and the PettingZoo envs (one per environment) with the same actions;
    resets each PettingZoo env with the VecEnv's episode seed when its episode ends.
    Returns the number of episode ends seen."""
    N = venv.n_beacons
    ends = 0
    for _ in range(steps):
        a = rng.uniform(-1.3, 1.3, (venv.num_envs, 2)).astype(np.float32)  # some clipped
        obs, reward, done, infos = venv.step(a)
        for e, env in enumerate(envs):
            p_obs, p_rew, p_term, p_trunc, p_info = env.step(_pz_actions(a, N, e))
            for j in range(N):
                row, agent = e * N + j, f"beacon_{j}"
                final = infos[row]["terminal_observation"] if done[row] else obs[row]
                assert np.array_equal(final, p_obs[agent])
                assert reward[row] == np.float32(p_rew[agent])
                assert done[row] == (p_term[agent] or p_trunc[agent])
                assert infos[row]["TimeLimit.truncated"] == (p_trunc[agent] and not p_term[agent])
                got = {k: v for k, v in infos[row].items() if k not in EXTRA_KEYS}
                assert set(got) == set(p_info[agent])
                assert all(np.array_equal(got[k], p_info[agent][k]) for k in got)
            if done[e * N]:
                ends += 1
                assert not env.agents
                p_obs, _ = env.reset(seed=int(venv.episode_seeds[e]))
                for j in range(N):
                    assert np.array_equal(obs[e * N + j], p_obs[f"beacon_{j}"])
    return ends


def test_row_0_equals_the_pettingzoo_env_over_whole_episodes():
    """CoopNavVecEnv(n_envs=1, seed=s) row 0 == parallel_env(seed=s): identical
    observations, rewards, dones and infos over a whole episode and the next."""
    seed = 1234
    venv = CoopNavVecEnv("sousa_asv", n_envs=1, seed=seed)
    env = coopnav_env.parallel_env("sousa_asv", seed=seed)
    obs = venv.reset()
    p_obs, _ = env.reset()
    assert np.array_equal(obs[0], p_obs["beacon_0"])
    steps = venv.config.max_cycles
    assert _compare_with_pettingzoo(venv, [env], 2 * steps, np.random.default_rng(0)) == 2
    assert venv.episode_seeds[0] == seed + 2 * SEED_STRIDE


def test_every_row_of_a_batch_equals_its_pettingzoo_env():
    seed = 77
    venv = CoopNavVecEnv("gao_lawnmower", n_envs=3, seed=seed, max_cycles=6, **TWO_BY_TWO)
    envs = [coopnav_env.parallel_env("gao_lawnmower", seed=seed + e, max_cycles=6, **TWO_BY_TWO) for e in range(3)]
    obs = venv.reset()
    for e, env in enumerate(envs):
        p_obs, _ = env.reset()
        assert np.array_equal(obs[2 * e + 1], p_obs["beacon_1"])
    assert _compare_with_pettingzoo(venv, envs, 13, np.random.default_rng(1)) == 6


def test_rows_of_a_large_batch_equal_their_pettingzoo_envs():
    """At 64 environments and more the core may switch to threaded kernels: the rows
    must still be the batch-of-one transitions."""
    seed, n = 500, 64
    venv = CoopNavVecEnv("sousa_asv", n_envs=n, seed=seed)
    venv.reset()
    picked = [0, 63]
    envs = [coopnav_env.parallel_env("sousa_asv", seed=seed + e) for e in picked]
    for env in envs:
        env.reset()
    rng = np.random.default_rng(4)
    for _ in range(5):
        a = rng.uniform(-1, 1, (n, 2)).astype(np.float32)
        obs, reward, _, _ = venv.step(a)
        for e, env in zip(picked, envs):
            p_obs, p_rew, *_ = env.step({"beacon_0": a[e]})
            assert np.array_equal(obs[e], p_obs["beacon_0"]) and reward[e] == np.float32(p_rew["beacon_0"])


def test_truncation_sets_time_limit_truncated_and_terminal_observation():
    venv = CoopNavVecEnv("gao_lawnmower", n_envs=2, seed=0, max_cycles=4)
    first = venv.reset()
    for t in range(4):
        obs, _, done, infos = venv.step(np.zeros((2, 2)))
        assert done.all() == (t == 3) and done.any() == (t == 3)
    for info in infos:
        assert info["TimeLimit.truncated"] is True
        term = info["terminal_observation"]
        assert term.shape == (venv.obs_dim,) and term.dtype == np.float32
    assert not np.array_equal(obs, np.stack([i["terminal_observation"] for i in infos]))
    assert not np.array_equal(obs, first)  # a new episode, with a new seed
    assert list(venv.episode_seeds) == [SEED_STRIDE, 1 + SEED_STRIDE]


def test_step_infos_false_gives_infos_only_where_episodes_end():
    full = CoopNavVecEnv("gao_lawnmower", n_envs=3, seed=0, max_cycles=3, **TWO_BY_TWO)
    lean = CoopNavVecEnv("gao_lawnmower", n_envs=3, seed=0, max_cycles=3, step_infos=False, **TWO_BY_TWO)
    full.reset(), lean.reset()
    for t in range(3):
        a = np.full((6, 2), 0.2)
        o1, r1, d1, i1 = full.step(a)
        o2, r2, d2, i2 = lean.step(a)
        assert np.array_equal(o1, o2) and np.array_equal(r1, r2) and np.array_equal(d1, d2)
        if t < 2:
            assert i2 == [{}] * 6
    for a, b in zip(i1, i2):
        assert a.keys() == b.keys()
        assert np.array_equal(a.pop("terminal_observation"), b.pop("terminal_observation")) and a == b


def test_termination_is_not_a_time_limit():
    ping = coopnav_env.make_config("sousa_asv").ping_interval_s
    venv = CoopNavVecEnv("sousa_asv", n_envs=2, seed=0, mission_duration_s=3 * ping, max_cycles=50)
    venv.reset()
    for _ in range(3):
        _, _, done, infos = venv.step(np.zeros((2, 2)))
    assert done.all()
    assert all(i["TimeLimit.truncated"] is False and "terminal_observation" in i for i in infos)


def test_the_same_seed_reproduces_and_seed_restarts_the_count():
    def run(venv):
        out = [venv.reset()]
        for _ in range(8):
            out.append(venv.step(np.full((2, 2), 0.3))[0])
        return np.stack(out)

    a = CoopNavVecEnv("gao_lawnmower", n_envs=2, seed=9, max_cycles=3)
    b = CoopNavVecEnv("gao_lawnmower", n_envs=2, seed=9, max_cycles=3)
    c = CoopNavVecEnv("gao_lawnmower", n_envs=2, seed=10, max_cycles=3)
    ra = run(a)
    assert np.array_equal(ra, run(b))
    assert not np.array_equal(ra, run(c))
    assert not np.array_equal(ra, run(a))  # reset() without seed(): the next episodes
    assert a.seed(9) == [9, 10]
    assert np.array_equal(ra, run(a))


def test_bad_actions():
    venv = CoopNavVecEnv("gao_lawnmower", n_envs=2, seed=0, **TWO_BY_TWO)
    venv.reset()
    bad = np.zeros((4, 2))
    bad[3, 1] = np.nan
    with pytest.raises(ValueError, match="env 1 beacon_1"):
        venv.step(bad)
    with pytest.raises(ValueError, match="shape"):
        venv.step(np.zeros((2, 2)))
    with pytest.raises(ValueError, match="finite"):
        venv.step(np.full((4, 2), np.inf))
    with pytest.raises(ValueError, match="numeric"):
        venv.step([["a", "b"]] * 4)
    # finite out-of-range actions are clipped, as check_action does
    twin = CoopNavVecEnv("gao_lawnmower", n_envs=2, seed=0, **TWO_BY_TWO)
    twin.reset()
    venv.seed(0)  # restart the episode count: the same episodes as twin
    venv.reset()
    wild = np.array([[5.0, -7.0], [0.5, 3.0], [-2.0, 0.1], [1e9, -1e9]])
    assert np.array_equal(venv.step(wild)[0], twin.step(np.clip(wild, -1, 1))[0])


def test_step_before_reset_is_an_error():
    venv = CoopNavVecEnv("gao_lawnmower", n_envs=1, seed=0)
    with pytest.raises(RuntimeError, match="reset"):
        venv.step(np.zeros((1, 2)))


def test_bad_arguments():
    with pytest.raises(ValueError, match="n_envs"):
        CoopNavVecEnv("gao_lawnmower", n_envs=0)
    with pytest.raises(ValueError, match="unknown scenario"):
        CoopNavVecEnv("nope")
    with pytest.raises(ValueError, match="unknown scenario parameter"):
        CoopNavVecEnv("gao_lawnmower", depth=3)
    with pytest.raises(ValueError, match="randomize_depth_m"):
        CoopNavVecEnv("sousa_asv", n_envs=2, randomize_depth_m=(-5.0,))
    with pytest.raises(ValueError, match="unknown reward term 'errror'"):
        CoopNavVecEnv("sousa_asv", n_envs=1, reward_terms={"errror": 1.0})
    with pytest.raises(ValueError, match="finite"):
        CoopNavVecEnv("sousa_asv", n_envs=1, reward_terms={"error": float("nan")})


def test_sb3_helpers_and_wrappers():
    from stable_baselines3.common.vec_env import VecCheckNan, VecMonitor, VecNormalize

    venv = CoopNavVecEnv("gao_lawnmower", n_envs=2, seed=0, max_cycles=5, **TWO_BY_TWO)
    assert venv.get_attr("render_mode") == [None] * 4
    assert venv.get_attr("agent") == ["beacon_0", "beacon_1", "beacon_0", "beacon_1"]
    assert venv.get_attr("config", indices=[3])[0].n_beacons == 2
    assert venv.env_is_wrapped(gym.Wrapper) == [False] * 4
    with pytest.raises(AttributeError):
        venv.get_attr("no_such_thing")
    venv.set_attr("note", "x")
    assert venv.get_attr("note", indices=1) == ["x"]
    with pytest.raises(ValueError):
        venv.set_attr("note", "y", indices=[0])
    assert venv.env_method("seed", 4, indices=[0, 1]) == [[4, 4, 5, 5]] * 2
    wrapped = VecNormalize(VecMonitor(VecCheckNan(venv, raise_exception=True)), gamma=0.99)
    wrapped.reset()
    episodes = 0
    for _ in range(11):
        _, _, _done, infos = wrapped.step(np.random.default_rng(0).uniform(-1, 1, (4, 2)))
        episodes += sum("episode" in i for i in infos)
    assert episodes == 8  # two episodes of two environments, two beacons each
    wrapped.close()


DR = dict(
    randomize_depth_m=(1.0, 5.0, 20.0, 50.0),
    randomize_survey_path=("stationary", "lawnmower", "circle", "spiral"),
    randomize_noise_scale=(0.75, 1.25),
)


def test_per_episode_randomization_is_the_cores_in_one_simulator():
    """Randomization comes from the scenario's randomize_* parameters: one Simulator,
    and every row still equals the PettingZoo env of the same scenario and seed,
    across the auto-reset (which draws a new cell from the new seed)."""
    seed = 40
    venv = CoopNavVecEnv("sousa_asv", n_envs=16, seed=seed, max_cycles=3, mission_duration_s=0.0, **DR)
    assert isinstance(venv.sim, coopnav_env.core.sim.Simulator) and len(venv.sim.variants) == 16
    venv.reset()
    cells = venv.episode_cells()
    assert len(set(cells)) > 4  # 16 environments draw several of the 16 cells
    assert venv.get_attr("episode_cell", indices=[5]) == [cells[5]]
    assert [c[1] for c in cells] == [float(d) for d in venv.sim.state.s_pos[:, 0, 2]]  # each at its depth
    picked = [3, 11]
    envs = [
        coopnav_env.parallel_env("sousa_asv", seed=seed + e, max_cycles=3, mission_duration_s=0.0, **DR) for e in picked
    ]
    for env in envs:
        env.reset()
    assert _compare_with_pettingzoo(_Only(venv, picked), envs, 7, np.random.default_rng(2)) == 4
    assert venv.episode_cells() != cells  # the next episodes drew again


def test_training_reward_terms():
    """reward_terms replaces the reward by a weighted sum of training signals; the
    observations, dones and infos stay the environment's."""
    kw = dict(n_envs=3, seed=8, max_cycles=4)
    plain = CoopNavVecEnv("gao_lawnmower", **kw, **TWO_BY_TWO)
    shaped = CoopNavVecEnv(
        "gao_lawnmower", reward_terms={"error": 2.0, "env": 1.0, "penalties": 0.5}, **kw, **TWO_BY_TWO
    )
    plain.reset(), shaped.reset()
    for _ in range(4):
        a = np.random.default_rng(0).uniform(-1, 1, (6, 2))
        o1, r1, d1, _i1 = plain.step(a)
        o2, r2, d2, i2 = shaped.step(a)
        assert np.array_equal(o1, o2) and np.array_equal(d1, d2)
        st, c = shaped.sim.state, shaped.config
        dist = np.linalg.norm(st.s_pos[:, None, :, :] - st.b_pos[:, :, None, :], axis=-1)
        penalties = -(c.safety_penalty * (dist < c.safety_distance_m).any(-1))  # (B, N); inside the fence here
        for row in range(6):
            e, j = divmod(row, 2)
            err = np.mean(i2[row]["survey_error_m_per_vehicle"]) if not d2[row] else None
            if err is not None:
                expect = r1[row] + 2.0 * (-err) + 0.5 * penalties[e, j]
                assert r2[row] == pytest.approx(expect, rel=1e-5, abs=1e-5)
    for term in REWARD_TERMS:  # every term gives a finite reward of the right shape
        venv = CoopNavVecEnv("sousa_asv", n_envs=2, seed=0, reward_terms={term: 1.0})
        venv.reset()
        r = venv.step(np.zeros((2, 2)))[1]
        assert r.shape == (2,) and np.isfinite(r).all()
    err_only = CoopNavVecEnv("sousa_asv", n_envs=2, seed=0, reward_terms={"error": 1.0})
    err_only.reset()
    _, r, _, infos = err_only.step(np.zeros((2, 2)))
    assert np.allclose(r, [-i["survey_error_m"] for i in infos])
    # log_error: -ln(1 + e / 1 m) of the same step's error
    log_only = CoopNavVecEnv("sousa_asv", n_envs=2, seed=0, reward_terms={"log_error": 1.0})
    log_only.reset()
    _, r, _, infos = log_only.step(np.zeros((2, 2)))
    assert np.allclose(r, [-np.log(1.0 + i["survey_error_m"]) for i in infos]) and np.all(r < 0)
    # rejected: minus the ranges the survey filter gated out; every range a 200 m multipath here
    for prob, expect in ((1.0, -1.0), (0.0, 0.0)):
        rej = CoopNavVecEnv(
            "sousa_asv",
            n_envs=2,
            seed=0,
            reward_terms={"rejected": 1.0},
            outlier_probability=prob,
            outlier_mean_excess_m=200.0,
        )
        rej.reset()
        for _ in range(3):
            _, r, _, infos = rej.step(np.zeros((2, 2)))
            assert np.array_equal(r, [-i["outliers_rejected"] for i in infos]) and np.all(r == expect)


class _Only:
    """Drive a VecEnv with random actions and show some of its environments as if alone."""

    def __init__(self, venv, envs):
        self.venv, self.envs, self.n_beacons = venv, list(envs), venv.n_beacons
        self.num_envs = len(self.envs) * venv.n_beacons
        self.rows = np.concatenate([np.arange(e * venv.n_beacons, (e + 1) * venv.n_beacons) for e in self.envs])

    @property
    def episode_seeds(self):
        return self.venv.episode_seeds[self.envs]

    def step(self, a):
        full = np.zeros((self.venv.num_envs, 2), dtype=np.float32)
        full[self.rows] = a
        obs, r, d, infos = self.venv.step(full)
        return obs[self.rows], r[self.rows], d[self.rows], [infos[i] for i in self.rows]
