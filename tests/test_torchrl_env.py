"""The TorchRL view of the batched core (coopnav_env/torchrl_env.py): TorchRL's spec check,
and that its transitions are the VecEnv's and the PettingZoo env's, exactly, for the same
seeds and actions (partial resets included)."""

import subprocess
import sys

import numpy as np
import pytest

from optional import require

require("torchrl")
import torch  # noqa: E402  (after the extra's check)
from torchrl.envs.utils import check_env_specs  # noqa: E402

import coopnav_env  # noqa: E402
from coopnav_env.torchrl_env import GROUP, SEED_STRIDE, CoopNavTorchEnv  # noqa: E402
from coopnav_env.vector import SEED_STRIDE as VEC_SEED_STRIDE  # noqa: E402
from coopnav_env.vector import CoopNavVecEnv  # noqa: E402

TWO_BY_TWO = dict(beacon_kinds=("beacon_auv", "asv"), n_survey=2)
OBS, ACT, REW = (GROUP, "observation"), (GROUP, "action"), (GROUP, "reward")


@pytest.mark.parametrize(
    "scenario, n_beacons, action_dim",
    [
        ("sousa_asv", 1, 2),  # a survey scenario: one ASV
        ("gao_team", 2, 2),  # a team: an ASV and a beacon AUV, two survey AUVs
        ("sousa_ping", 2, 3),  # the transmit decision: a third action component
        ("matos_moving_lbl", 2, 2),  # the moving network (its own simulator)
    ],
)
def test_check_env_specs_and_shapes(scenario, n_beacons, action_dim):
    env = CoopNavTorchEnv(scenario, n_envs=3, seed=5, max_cycles=4)
    check_env_specs(env, seed=0)
    assert env.batch_size == torch.Size([3])
    assert env.group_map == {GROUP: [f"beacon_{j}" for j in range(n_beacons)]}
    assert env.full_action_spec[ACT].shape == (3, n_beacons, action_dim)
    td = env.rollout(6, break_when_any_done=False)  # crosses an auto-reset (max_cycles 4)
    assert td[OBS].shape == (3, 6, n_beacons, env.obs_dim)
    assert td[("next", *REW)].shape == (3, 6, n_beacons, 1)
    assert td["state"].shape == (3, 6, env.sim.state_dim + n_beacons * env.obs_dim)
    assert td["next", "done"][:, 3].all() and not td["next", "done"][:, :3].any()
    assert td["next", "truncated"][:, 3].all() and not td["next", "terminated"].any()
    assert td["info", "survey_error_m_per_vehicle"].shape == (3, 6, env.sim.S)


def _pz_step(env, action_row):
    return env.step({f"beacon_{j}": a for j, a in enumerate(action_row)})


def test_rollout_equals_the_vecenv_and_the_pettingzoo_envs():
    """Every row's observations, rewards, dones and infos are the VecEnv's (same seed,
    same actions, across auto-resets) and, over each row's first episode, the PettingZoo
    env's seeded seed + e; the first observation of the next episode is the VecEnv's."""
    seed, n, N = 77, 3, 2
    kw = dict(max_cycles=6, **TWO_BY_TWO)
    env = CoopNavTorchEnv("gao_lawnmower", n_envs=n, seed=seed, **kw)
    venv = CoopNavVecEnv("gao_lawnmower", n_envs=n, seed=seed, **kw)
    pz = [coopnav_env.parallel_env("gao_lawnmower", seed=seed + e, **kw) for e in range(n)]
    td = env.reset()
    v_obs = venv.reset()
    assert np.array_equal(td[OBS].numpy().reshape(n * N, -1), v_obs)
    for e, p in enumerate(pz):
        p_obs, _ = p.reset()
        assert all(np.array_equal(td[OBS][e, j].numpy(), p_obs[f"beacon_{j}"]) for j in range(N))
    rng = np.random.default_rng(1)
    ends = 0
    for t in range(13):
        a = rng.uniform(-1.3, 1.3, (n, N, 2)).astype(np.float32)  # some clipped
        td[ACT] = torch.from_numpy(a)
        out, td = env.step_and_maybe_reset(td)
        v_obs, v_rew, v_done, v_infos = venv.step(a.reshape(n * N, 2))
        nxt = out["next"]
        done = nxt["done"].numpy()[:, 0]
        assert np.array_equal(np.repeat(done, N), v_done)
        assert np.array_equal(nxt[REW].numpy().reshape(-1), v_rew)
        for e in range(n):
            for j in range(N):
                row = e * N + j
                final = v_infos[row]["terminal_observation"] if done[e] else v_obs[row]
                assert np.array_equal(nxt[OBS][e, j].numpy(), final)
                assert np.array_equal(td[OBS][e, j].numpy(), v_obs[row])  # after the auto-reset
                info = v_infos[row]
                assert bool(nxt["truncated"][e, 0]) == info["TimeLimit.truncated"]
                assert nxt["info", "survey_error_m"][e].item() == info["survey_error_m"]
                assert nxt["info", "ranges_fused"][e].item() == info["ranges_fused"]
                assert nxt["info", "range_ok"][e].item() == info["range_ok"]
                assert nxt["info", "dr_error_m_per_vehicle"][e].tolist() == info["dr_error_m_per_vehicle"]
                assert nxt["info", "survey_cov_en_m2"][e].tolist() == info["survey_cov_en_m2"]
                assert nxt[GROUP, "info", "beacon_error_m"][e, j].item() == info["beacon_error_m"]
            if t < 6:  # the first episode: the PettingZoo env seeded seed + e
                p_obs, p_rew, p_term, p_trunc, p_info = _pz_step(pz[e], a[e])
                for j in range(N):
                    agent = f"beacon_{j}"
                    assert np.array_equal(nxt[OBS][e, j].numpy(), p_obs[agent])
                    assert nxt[REW][e, j, 0].item() == np.float32(p_rew[agent])
                    assert bool(done[e]) == (p_term[agent] or p_trunc[agent])
                    assert nxt["info", "survey_error_m"][e].item() == p_info[agent]["survey_error_m"]
        ends += int(done.sum())
    assert ends == 2 * n  # two auto-resets per row in 13 steps of 6-cycle episodes
    assert np.array_equal(env.episode_seeds, venv.episode_seeds)
    assert list(env.episode_seeds) == [seed + e + 2 * SEED_STRIDE for e in range(n)]
    assert SEED_STRIDE == VEC_SEED_STRIDE


def test_partial_reset_restarts_only_the_masked_rows():
    """A "_reset" mask restarts its rows with their next episode's seed; the other rows
    carry on exactly as their PettingZoo envs."""
    seed, n = 300, 3
    env = CoopNavTorchEnv("sousa_asv", n_envs=n, seed=seed)
    pz = [coopnav_env.parallel_env("sousa_asv", seed=seed + e) for e in range(n)]
    td = env.reset()
    for p in pz:
        p.reset()
    rng = np.random.default_rng(2)

    def step(td):
        a = rng.uniform(-1, 1, (n, 1, 2)).astype(np.float32)
        td[ACT] = torch.from_numpy(a)
        td = env.step(td)["next"]
        for e, p in enumerate(pz):
            p_obs, *_ = _pz_step(p, a[e])
            assert np.array_equal(td[OBS][e, 0].numpy(), p_obs["beacon_0"])
        return td

    td = step(step(td))
    before = td[OBS].clone()
    td.set("_reset", torch.tensor([[False], [True], [False]]))
    td = env.reset(td)
    fresh, _ = coopnav_env.parallel_env("sousa_asv").reset(seed=seed + 1 + SEED_STRIDE)
    assert np.array_equal(td[OBS][1, 0].numpy(), fresh["beacon_0"])
    assert torch.equal(td[OBS][[0, 2]], before[[0, 2]])
    assert list(env.episode_seeds) == [seed, seed + 1 + SEED_STRIDE, seed + 2]
    pz[1].reset(seed=seed + 1 + SEED_STRIDE)
    step(step(td))  # every row, reset or not, is its PettingZoo env's again


def test_bad_actions_get_the_views_one_line_errors():
    env = CoopNavTorchEnv("gao_lawnmower", n_envs=2, seed=0, **TWO_BY_TWO)
    td = env.reset()
    bad = torch.zeros(2, 2, 2)
    bad[1, 1, 0] = float("nan")
    with pytest.raises(ValueError, match=r"action for env 1 beacon_1 must be finite"):
        env.step(td.set(ACT, bad))
    with pytest.raises(ValueError, match=r"must have shape \(2, 2, 2\).*got shape \(2, 2, 3\)"):
        env.step(td.set(ACT, torch.zeros(2, 2, 3)))
    with pytest.raises(ValueError, match="finite"):
        env.step(td.set(ACT, torch.full((2, 2, 2), float("inf"))))
    # finite out-of-range actions are clipped, as check_action does
    twin = CoopNavTorchEnv("gao_lawnmower", n_envs=2, seed=0, **TWO_BY_TWO)
    wild = torch.tensor([[[5.0, -7.0], [0.5, 3.0]], [[-2.0, 0.1], [1e9, -1e9]]])
    env.set_seed(0)  # restart the episode count: the same episodes as twin
    a = env.step(env.reset().set(ACT, wild))[("next", *OBS)]
    b = twin.step(twin.reset().set(ACT, wild.clamp(-1, 1)))[("next", *OBS)]
    assert torch.equal(a, b)
    fresh = CoopNavTorchEnv("sousa_asv", n_envs=1, seed=0)
    with pytest.raises(RuntimeError, match="reset"):
        fresh.step(fresh.full_action_spec.rand())


def test_bad_arguments():
    with pytest.raises(ValueError, match="n_envs"):
        CoopNavTorchEnv("sousa_asv", n_envs=0)
    with pytest.raises(ValueError, match="unknown scenario"):
        CoopNavTorchEnv("nope")
    with pytest.raises(ValueError, match=r"unknown state 'truth'; valid: privileged, observations"):
        CoopNavTorchEnv("sousa_asv", state="truth")
    with pytest.raises(ValueError, match="unknown reward term 'errror'"):
        CoopNavTorchEnv("sousa_asv", reward_terms={"errror": 1.0})
    with pytest.raises(ValueError, match=r"takes n_envs=64, not batch_size="):  # TorchRL's word for it
        CoopNavTorchEnv("sousa_asv", batch_size=64)


def test_transmit_decision_and_the_motion_alone():
    """sousa_ping: a (B, N, 2) action means "transmit every slot", the third component 1."""
    a2 = torch.tensor([[[0.3, -0.2], [0.1, 0.9]]])
    a3 = torch.cat([a2, torch.ones(1, 2, 1)], -1)
    runs = []
    for a in (a2, a3):
        env = CoopNavTorchEnv("sousa_ping", n_envs=1, seed=4)
        nxt = env.step(env.reset().set(ACT, a))["next"]
        assert nxt[GROUP, "info", "pings"].tolist() == [[1, 1]]  # both beacons transmitted
        runs.append(nxt[OBS])
    assert torch.equal(runs[0], runs[1])
    env = CoopNavTorchEnv("sousa_ping", n_envs=1, seed=4)
    silent = torch.cat([a2, -torch.ones(1, 2, 1)], -1)
    assert env.step(env.reset().set(ACT, silent))["next", GROUP, "info", "pings"].tolist() == [[0, 0]]


def test_state_and_training_reward():
    """ "state": the core's global_state then every observation (privileged), or the
    observations alone; ``reward_terms`` gives the VecEnv's training reward."""
    terms = {"error": 1.0, "penalties": 0.5}
    env = CoopNavTorchEnv("gao_lawnmower", n_envs=2, seed=3, reward_terms=terms, **TWO_BY_TWO)
    venv = CoopNavVecEnv("gao_lawnmower", n_envs=2, seed=3, reward_terms=terms, **TWO_BY_TWO)
    td = env.reset()
    venv.reset()
    gs = env.sim.global_state()
    assert torch.equal(td["state"], torch.cat([torch.from_numpy(gs), td[OBS].reshape(2, -1)], -1))
    a = np.full((2, 2, 2), 0.5, dtype=np.float32)
    r = env.step(td.set(ACT, torch.from_numpy(a)))[("next", *REW)]
    assert np.array_equal(r.numpy().reshape(-1), venv.step(a.reshape(4, 2))[1])
    plain = CoopNavTorchEnv("gao_lawnmower", n_envs=2, seed=3, state="observations", infos=False, **TWO_BY_TWO)
    td = plain.reset()
    assert torch.equal(td["state"], td[OBS].reshape(2, -1)) and "info" not in td.keys()  # noqa: SIM118 - TensorDict has no `in`


def test_state_survey_slots_give_teams_of_other_sizes_one_layout():
    """``state_survey_slots``: a one-survey team's state laid out for two survey vehicles is its
    own state with zeros at the second vehicle's indices, and every other value sits where a
    two-survey team's sits (the beacons' block after 2 x 10 values, each observation's other
    beacons after its two survey blocks)."""
    from coopnav_env.core.observation import OWN_DIM, PER_SURVEY_FIXED
    from coopnav_env.core.sim import SURVEY_STATE_DIM

    one = CoopNavTorchEnv("gao_lawnmower", n_envs=2, seed=5, beacon_kinds=["beacon_auv", "asv"])
    padded = CoopNavTorchEnv(
        "gao_lawnmower", n_envs=2, seed=5, beacon_kinds=["beacon_auv", "asv"], state_survey_slots=2
    )
    two = CoopNavTorchEnv("gao_lawnmower", n_envs=2, seed=5, state_survey_slots=2, **TWO_BY_TWO)
    block, D1 = PER_SURVEY_FIXED + 2 * one.config.observed_waypoints, one.flat_obs_dim  # a survey vehicle's
    assert padded.state_dim == two.state_dim == one.state_dim + SURVEY_STATE_DIM + 2 * block
    s1, sp = one.reset()["state"], padded.reset()["state"]
    assert sp.shape == (2, two.state_dim) and two.reset()["state"].shape == sp.shape
    G1 = one.sim.state_dim
    # the indices the second survey vehicle takes: its 10 state values after the first's,
    # and in each beacon's observation its block after the first's
    zeros = list(range(SURVEY_STATE_DIM, 2 * SURVEY_STATE_DIM))
    G2, D2 = G1 + SURVEY_STATE_DIM, D1 + block
    for j in range(2):
        zeros += list(range(G2 + j * D2 + OWN_DIM + block, G2 + j * D2 + OWN_DIM + 2 * block))
    keep = [i for i in range(two.state_dim) if i not in set(zeros)]
    assert torch.equal(sp[:, keep], s1) and not sp[:, zeros].any()
    with pytest.raises(ValueError, match="state_survey_slots must be an int >= the team's 2 survey"):
        CoopNavTorchEnv("gao_lawnmower", state_survey_slots=1, **TWO_BY_TWO)
    with pytest.raises(ValueError, match="moving network's state has one survey vehicle"):
        CoopNavTorchEnv("matos_moving_lbl", state_survey_slots=2)
    same = CoopNavTorchEnv("gao_lawnmower", n_envs=2, seed=5, state_survey_slots=1)
    assert same.state_dim == CoopNavTorchEnv("gao_lawnmower", n_envs=2, seed=5).state_dim


def test_state_beacon_slots_give_teams_of_other_numbers_of_beacons_one_layout():
    """``state_beacon_slots``: a one-beacon team's state laid out for two beacons is its own
    state with zeros at the second beacon's indices (its 7 state values after the first's, the
    first beacon's entry for a peer at the end of its observation, the second beacon's whole
    observation), and it has the two-beacon team's size."""
    from coopnav_env.core.sim import BEACON_STATE_DIM, SURVEY_STATE_DIM

    one = CoopNavTorchEnv("gao_lawnmower", n_envs=2, seed=5)
    padded = CoopNavTorchEnv("gao_lawnmower", n_envs=2, seed=5, state_beacon_slots=2)
    two = CoopNavTorchEnv("gao_lawnmower", n_envs=2, seed=5, beacon_kinds=["beacon_auv", "asv"])
    assert one.n_beacons == 1 and two.n_beacons == 2
    D1, D2 = one.flat_obs_dim, two.flat_obs_dim
    assert D2 == D1 + 2 and padded.state_dim == two.state_dim == one.state_dim + BEACON_STATE_DIM + D2 + 2
    s1, sp = one.reset()["state"], padded.reset()["state"]
    G1 = one.sim.state_dim
    b0 = SURVEY_STATE_DIM + BEACON_STATE_DIM  # the second beacon's block starts after the first's
    zeros = list(range(b0, b0 + BEACON_STATE_DIM))
    G2 = G1 + BEACON_STATE_DIM
    zeros += [G2 + D1, G2 + D1 + 1]  # beacon 0's observation: its peer's entry
    zeros += list(range(G2 + D2, G2 + 2 * D2))  # beacon 1's observation
    keep = [i for i in range(two.state_dim) if i not in set(zeros)]
    assert sp.shape == (2, two.state_dim) and torch.equal(sp[:, keep], s1) and not sp[:, zeros].any()
    both = CoopNavTorchEnv("gao_lawnmower", n_envs=2, seed=5, state_survey_slots=2, state_beacon_slots=2)
    assert both.state_dim == CoopNavTorchEnv("gao_lawnmower", n_envs=2, seed=5, **TWO_BY_TWO).state_dim
    observed = CoopNavTorchEnv("gao_lawnmower", n_envs=2, seed=5, state="observations", state_beacon_slots=3)
    assert observed.reset()["state"].shape == (2, 3 * (D1 + 4))
    with pytest.raises(ValueError, match="state_beacon_slots must be an int >= the team's 2 beacons"):
        CoopNavTorchEnv("gao_lawnmower", state_beacon_slots=1, beacon_kinds=["beacon_auv", "asv"])
    with pytest.raises(ValueError, match="moving network's state has its two boats"):
        CoopNavTorchEnv("matos_moving_lbl", state_beacon_slots=3)


def test_importing_coopnav_env_does_not_import_torch():
    code = (
        "import sys, coopnav_env; torch = 'torch' in sys.modules; import coopnav_env.vector; "
        "print(torch, 'torchrl' in sys.modules, 'tensordict' in sys.modules)"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["False", "False", "False"]  # nor do the other views import torchrl


def _replay(actions):
    """A rollout policy that plays ``actions`` (steps first) in order."""
    step = iter(actions)

    def policy(td):
        td.set(ACT, next(step))
        return td

    return policy


@pytest.mark.parametrize("team", [{}, TWO_BY_TWO])
def test_the_entity_observation_is_the_entity_form_of_the_flat_one(team):
    """observation="entities": TorchRL's spec check passes, and each step's group observation
    is entity_obs.entity_observation of the flat observation of the same seeds and actions
    (beacon j with role j), bit for bit; the state and rewards are the flat env's."""
    from coopnav_env.entity_obs import ENTITY_DIM, entity_observation

    entity = CoopNavTorchEnv("gao_sea", n_envs=3, seed=5, max_cycles=4, observation="entities", **team)
    flat = CoopNavTorchEnv("gao_sea", n_envs=3, seed=5, max_cycles=4, **team)
    check_env_specs(entity, seed=0)
    N = flat.n_beacons
    actions = torch.linspace(-0.9, 0.9, 6 * 3 * N * 2).reshape(6, 3, N, 2)
    rollouts = []
    for env in (entity, flat):
        env.set_seed(5)
        rollouts.append(env.rollout(6, _replay(actions), break_when_any_done=False))
    e, f = rollouts
    assert e[("next", *OBS)].shape == (3, 6, N, ENTITY_DIM) and entity.obs_dim == ENTITY_DIM
    want = entity_observation(f[("next", *OBS)].double().numpy(), flat.config, np.arange(N))
    np.testing.assert_array_equal(e[("next", *OBS)].numpy(), want)
    assert np.unique(e[("next", *OBS)][..., 10:13].argmax(-1)).tolist() == list(range(N))  # the role one-hot
    torch.testing.assert_close(e["next", "state"], f["next", "state"], rtol=0, atol=0)
    torch.testing.assert_close(e[("next", *REW)], f[("next", *REW)], rtol=0, atol=0)
    with pytest.raises(ValueError, match="entity view does not read"):
        CoopNavTorchEnv("matos_moving_lbl", observation="entities")
    with pytest.raises(ValueError, match=r"unknown observation 'entity'; did you mean 'entities'\? valid: flat"):
        CoopNavTorchEnv("gao_sea", observation="entity")
