"""Entity observations and policies (issue 23): the view's layout against hand-built
observations, the encoder's permutation and padding invariance, the mixed-team
VecEnv's seeds, the training config's checks, a tiny training run over randomized
teams, and an entity policy acting on every team size of every benchmark task."""

from typing import Any

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

import agents
from agents import formats, untrained_entity_policy
from agents.entity import ENCODERS, EntityEncoder, EntityPolicy
from agents.training import ConfigError, EntitySpec, EnvSpec, NormalizeSpec, PeriodicEvalSpec, TrainConfig
from coopnav_env import make_config
from coopnav_env.core import make_simulator
from coopnav_env.entity_obs import (
    ENTITY_DIM,
    KINDS,
    LAYOUT,
    MAX_BEACONS,
    MAX_SURVEY,
    entities,
    entity_observation,
    flatten_entities,
    unflatten_entities,
)
from coopnav_env.obs_layout import encode
from evaluation.tasks import TASK_SETS


def _one_hot(kind):
    return np.eye(len(KINDS))[KINDS.index(kind)]


# --- the view ------------------------------------------------------------------------
def test_layout_sizes_are_the_documented_table():
    # own 6 + 4 kinds + 3 indices; survey 9 + 2 waypoints x 2 + 4 kinds; beacon 2 + 4 kinds
    assert (LAYOUT.own_dim, LAYOUT.survey_dim, LAYOUT.beacon_dim) == (13, 17, 6)
    assert ENTITY_DIM == 13 + 5 * 17 + 5 + 2 * 6 + 2 == 117
    assert (MAX_SURVEY, MAX_BEACONS) == (5, 3)


def test_entities_of_a_hand_built_observation():
    """gao_team (an ASV and a beacon AUV, two survey AUVs), seen by beacon 1 (the AUV):
    every number from the metres given to obs_layout.encode."""
    config = make_config("gao_team")
    L, T = config.position_scale_m, config.ping_interval_s
    own = np.array([120.0, -40.0]) + (np.array(config.geofence_m[:2]) + np.array(config.geofence_m[2:])) / 2
    rel = np.array([[30.0, -60.0, 5.0], [-90.0, 15.0, 12.0]])
    peer = own + np.array([50.0, 80.0])
    wps = own + rel[:, None, :2] + np.array([[[10.0, 0.0], [20.0, 0.0]], [[0.0, -10.0], [0.0, -30.0]]])
    obs = encode(
        config, own, rel, major_m=[8.0, 4.0], minor_m=[2.0, 1.0], bearing_rad=[0.25, 1.0],
        reply_age_s=[40.0, 0.0], range_age_s=[20.0, 60.0], waypoints_en_m=wps, peers_en_m=[peer],
        speed_fraction=0.5, own_std_m=3.0,
    )  # fmt: skip
    e = entities(obs, config, agent=1)
    np.testing.assert_allclose(e.own[:2], (own - (np.array(config.geofence_m[:2]) + config.geofence_m[2:]) / 2) / L)
    np.testing.assert_allclose(e.own[4:6], [0.5, 0.3], atol=1e-6)
    np.testing.assert_array_equal(e.own[6:10], _one_hot("beacon_auv"))  # its kind: the role
    np.testing.assert_array_equal(e.own[10:13], [0, 1, 0])  # its index in the team
    np.testing.assert_array_equal(e.survey_mask, [True, True, False, False, False])
    np.testing.assert_allclose(e.survey[:2, :3], rel / [L, L, 100.0], atol=1e-6)
    np.testing.assert_allclose(e.survey[:2, 3:5], [[8 / 50, 2 / 50], [4 / 50, 1 / 50]], atol=1e-6)
    np.testing.assert_allclose(e.survey[0, 5:7], [np.cos(0.5), np.sin(0.5)], atol=1e-6)
    np.testing.assert_allclose(e.survey[:2, 7:9], [[40 / (10 * T), 20 / (10 * T)], [0, 60 / (10 * T)]], atol=1e-6)
    np.testing.assert_allclose(e.survey[1, 9:13], np.array([0, -10, 0, -30]) / L, atol=1e-5)
    np.testing.assert_array_equal(e.survey[:2, 13:], [_one_hot("survey_auv")] * 2)
    assert not e.survey[2:].any()  # padding: zeros
    np.testing.assert_array_equal(e.beacon_mask, [True, False])
    np.testing.assert_allclose(e.beacons[0, :2], [50 / L, 80 / L], atol=1e-6)
    np.testing.assert_array_equal(e.beacons[0, 2:], _one_hot("asv"))  # the other beacon is the ASV
    # beacon 0 (the ASV) sees itself as an ASV with index 0 and its peer as the AUV
    e0 = entities(obs, config, agent=0)
    np.testing.assert_array_equal(e0.own[6:13], np.r_[_one_hot("asv"), 1, 0, 0])
    np.testing.assert_array_equal(e0.beacons[0, 2:], _one_hot("beacon_auv"))


def test_flatten_round_trip_and_batches():
    config = make_config("gao_sea", beacon_kinds=("asv", "beacon_auv", "beacon_auv"), n_survey=4)
    sim = make_simulator(config, 3)
    obs = sim.reset([11, 12, 13])  # (3, 3, D)
    agents_ = np.broadcast_to(np.arange(3), (3, 3))
    x = entity_observation(obs, config, agents_)
    assert x.shape == (3, 3, ENTITY_DIM) and x.dtype == np.float32
    back = flatten_entities(unflatten_entities(x))
    np.testing.assert_array_equal(back, x)
    one = entity_observation(obs[1, 2], config, 2)  # a single row equals its place in the batch
    np.testing.assert_array_equal(one, x[1, 2])
    e = unflatten_entities(x)
    assert e.survey_mask.sum(-1).tolist() == [[4] * 3] * 3 and e.beacon_mask.all()
    # beacon 2 (an AUV) lists the ASV then the other AUV; beacon 0 (the ASV) two AUVs
    np.testing.assert_array_equal(e.beacons[0, 2, :, 2:], [_one_hot("asv"), _one_hot("beacon_auv")])
    np.testing.assert_array_equal(e.beacons[0, 0, :, 2:], [_one_hot("beacon_auv")] * 2)


def test_the_view_refuses_what_it_cannot_read():
    with pytest.raises(ValueError, match=r"moving_lbl.*decode_boat"):
        entities(np.zeros(15), make_config("matos_moving_lbl"))
    with pytest.raises(ValueError, match=r"at most MAX_SURVEY=5"):
        entities(np.zeros(100), make_config("swarm_mls", n_survey=6))
    with pytest.raises(ValueError, match=r"at most MAX_BEACONS=3"):
        entities(np.zeros(100), make_config("gao_sea", beacon_kinds=("beacon_auv",) * 4))
    with pytest.raises(ValueError, match=r"agent must be beacon indices in \[0, 0\]"):
        entities(np.zeros(19), make_config("gao_sea"), agent=1)


# --- the encoder ---------------------------------------------------------------------
def _random_entities(rng, n_survey, n_peers, batch=3):
    x = rng.normal(size=(batch, ENTITY_DIM)).astype(np.float32)
    e = unflatten_entities(x)
    e.survey_mask[:] = np.arange(MAX_SURVEY) < n_survey
    e.beacon_mask[:] = np.arange(MAX_BEACONS - 1) < n_peers
    e.survey[~e.survey_mask] = 0.0
    e.beacons[~e.beacon_mask] = 0.0
    return e


def _encode(net, e):
    with torch.no_grad():
        return net(torch.as_tensor(flatten_entities(e))).numpy()


@pytest.mark.parametrize("encoder", ENCODERS)
@settings(max_examples=15, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    n_survey=st.integers(1, MAX_SURVEY),
    n_peers=st.integers(0, MAX_BEACONS - 1),
    perm=st.permutations(range(MAX_SURVEY)),
    peer_perm=st.permutations(range(MAX_BEACONS - 1)),
    garbage=st.floats(-1e3, 1e3),
)
def test_encoder_is_permutation_and_padding_invariant(encoder, seed, n_survey, n_peers, perm, peer_perm, garbage):
    """Permuting the survey vehicles (with their masks, padding slots included) or the
    other beacons, or filling the padded slots with anything, leaves the features
    unchanged to 1e-6."""
    torch.manual_seed(seed % 1000)
    net = EntityEncoder(encoder, embed_dim=16, heads=4).eval()
    rng = np.random.default_rng(seed)
    e = _random_entities(rng, n_survey, n_peers)
    y = _encode(net, e)
    p = unflatten_entities(flatten_entities(e))
    p.survey, p.survey_mask = p.survey[:, perm], p.survey_mask[:, perm]
    p.beacons, p.beacon_mask = p.beacons[:, peer_perm], p.beacon_mask[:, peer_perm]
    np.testing.assert_allclose(_encode(net, p), y, atol=1e-6)
    g = unflatten_entities(flatten_entities(e))
    g.survey[:, n_survey:] = garbage
    g.beacons[:, n_peers:] = -garbage
    np.testing.assert_allclose(_encode(net, g), y, atol=1e-6)


@pytest.mark.parametrize("encoder", ENCODERS)
def test_a_rows_features_do_not_depend_on_its_batch(encoder):
    """The encoder embeds only the slots some row of the batch fills (agents.entity._filled_slots):
    a row's features alone, in a batch of larger teams, and with every slot embedded (a row of
    five survey vehicles and two other beacons beside it) agree to 1e-6; and its gradients
    reach the weights the same way."""
    torch.manual_seed(3)
    net = EntityEncoder(encoder, embed_dim=16, heads=4)
    rng = np.random.default_rng(4)
    parts = [_random_entities(rng, n, p, batch=2) for n, p in ((1, 0), (2, 1), (MAX_SURVEY, MAX_BEACONS - 1))]
    x = torch.as_tensor(np.concatenate([flatten_entities(e) for e in parts]))
    together = net(x)
    for i in range(len(parts)):  # each team's rows alone: fewer filled slots than in the batch
        alone = net(x[2 * i : 2 * i + 2])
        torch.testing.assert_close(alone, together[2 * i : 2 * i + 2], atol=1e-6, rtol=0)
    small = x[:2]
    grads = torch.autograd.grad(net(small).sum(), list(net.parameters()), allow_unused=True)
    padded_grads = torch.autograd.grad(net(torch.cat([small, x[-1:]]))[:2].sum(), list(net.parameters()))
    for g, h in zip(grads, padded_grads):
        torch.testing.assert_close(torch.zeros_like(h) if g is None else g, h, atol=1e-5, rtol=1e-5)


@pytest.mark.parametrize("encoder", ENCODERS)
def test_encoder_sees_the_entities(encoder):
    """Not a constant: moving one survey vehicle or flipping a beacon's kind changes the features."""
    torch.manual_seed(0)
    net = EntityEncoder(encoder, embed_dim=16, heads=4).eval()
    e = _random_entities(np.random.default_rng(1), 2, 1)
    y = _encode(net, e)
    moved = unflatten_entities(flatten_entities(e))
    moved.survey[:, 1, :2] += 0.5
    assert np.abs(_encode(net, moved) - y).max() > 1e-4
    kind = unflatten_entities(flatten_entities(e))
    kind.beacons[:, 0, 2:] = _one_hot("asv")
    assert np.abs(_encode(net, kind) - y).max() > 1e-4
    role = unflatten_entities(flatten_entities(e))
    role.own[:, 10:13] = [0, 1, 0]  # the index: two symmetric ASVs act differently
    assert np.abs(_encode(net, role) - y).max() > 1e-4


def test_a_model_file_names_only_known_extractors():
    with pytest.raises(formats.PolicyFormatError, match=r"unknown features_extractor_class 'os.system'"):
        formats.policy_kwargs_python({"features_extractor_class": "os.system"}, "model")
    with pytest.raises(formats.PolicyFormatError, match=r"embed_dim must be an integer"):
        formats.policy_kwargs_python(
            {"features_extractor_class": "EntityExtractor", "features_extractor_kwargs": {"embed_dim": 10**9}}, "m"
        )
    with pytest.raises(formats.PolicyFormatError, match=r"not this code's"):
        formats.policy_kwargs_python(
            {"features_extractor_class": "EntityExtractor", "features_extractor_kwargs": {"layout": {"max_survey": 9}}},
            "m",
        )


# --- the views -----------------------------------------------------------------------
def test_mixed_team_env_seeds_rows_and_reproducibility():
    from coopnav_env.entity_views import EntityVecEnv, MixedTeamVecEnv
    from coopnav_env.vector import SEED_STRIDE, CoopNavVecEnv

    teams: list[dict[str, Any]] = [{}, {"n_survey": 2}, {"beacon_kinds": ["beacon_auv", "beacon_auv"]}]
    kw: dict[str, Any] = dict(teams=teams, n_envs=4, seed=7, max_cycles=3)
    a, b = MixedTeamVecEnv("gao_lawnmower", **kw), MixedTeamVecEnv("gao_lawnmower", **kw)
    assert a.team_envs == [2, 1, 1] and a.num_envs == 2 + 1 + 2  # environments x beacons
    obs = np.asarray(a.reset())
    np.testing.assert_array_equal(obs, b.reset())
    assert a.episode_seeds.tolist() == [7, 8, 9, 10]  # environment g: seed + g
    # environment 3 (the two-beacon team) is the standalone env of its team, seen as entities
    alone = EntityVecEnv(
        CoopNavVecEnv("gao_lawnmower", n_envs=1, seed=10, max_cycles=3, beacon_kinds=teams[2]["beacon_kinds"])
    )
    np.testing.assert_array_equal(obs[3:5], alone.reset())
    actions = np.random.default_rng(0).uniform(-1, 1, (3, a.num_envs, 2))
    for k in range(3):
        oa, ra, da, ia = a.step(actions[k])
        ob, rb, _, _ = b.step(actions[k])
        np.testing.assert_array_equal(oa, ob)
        np.testing.assert_array_equal(ra, rb)
    assert da.all() and ia[4]["terminal_observation"].shape == (ENTITY_DIM,)
    assert a.episode_seeds.tolist() == [7 + g + SEED_STRIDE for g in range(4)]
    assert a.get_attr("agent") == ["beacon_0", "beacon_0", "beacon_0", "beacon_0", "beacon_1"]
    with pytest.raises(ValueError, match=r"teams\[0\].*'depth_mm'.*did you mean 'depth_m'"):
        MixedTeamVecEnv("gao_lawnmower", teams=[{"depth_mm": 3.0}], n_envs=1)
    with pytest.raises(ValueError, match=r"teams\[1\].*ping_interval_s \(7.5\) must be a whole multiple"):
        MixedTeamVecEnv("gao_lawnmower", teams=[{}, {"ping_interval_s": 7.5}], n_envs=2)


def test_a_team_may_have_its_own_ping_interval():
    """A cycle length is one simulator's, so a second ping interval is a second team: its rows
    are the standalone env at that interval."""
    from coopnav_env.entity_views import EntityVecEnv, MixedTeamVecEnv
    from coopnav_env.vector import CoopNavVecEnv

    kw: dict[str, Any] = dict(teams=[{}, {"ping_interval_s": 10.0}], n_envs=2, seed=5)
    mixed = MixedTeamVecEnv("gao_sea", **kw)
    assert [c.ping_interval_s for c in mixed.configs] == [20.0, 10.0]
    obs = np.asarray(mixed.reset())
    alone = EntityVecEnv(CoopNavVecEnv("gao_sea", n_envs=1, seed=6, ping_interval_s=10.0))
    np.testing.assert_array_equal(obs[1:2], alone.reset())
    action = np.full((2, 2), 0.3)
    np.testing.assert_array_equal(mixed.step(action)[0][1:2], alone.step(action[1:2])[0])
    with pytest.raises(ValueError, match=r"at most MAX_SURVEY=5"):
        MixedTeamVecEnv("gao_lawnmower", teams=[{"n_survey": 6}], n_envs=1)


def test_flat_teams_vary_the_setting_not_the_makeup():
    """A flat policy takes one team makeup but may train over settings one simulator holds
    for all its rows (here the channel's loss): each team's rows are the standalone env with
    that setting, and a team that changes the observation's size is refused by name."""
    from coopnav_env.entity_views import MixedTeamVecEnv
    from coopnav_env.vector import CoopNavVecEnv

    lossy = {"packet_loss_near": 0.2, "packet_loss_far": 0.8}
    mixed = MixedTeamVecEnv("matos_moving_lbl", teams=[{}, lossy], n_envs=2, seed=3, observation="flat")
    assert [c.packet_loss_far for c in mixed.configs] == [0.5, 0.8]
    assert mixed.num_envs == 4
    assert mixed.observation_space == CoopNavVecEnv("matos_moving_lbl", n_envs=1).observation_space
    assert mixed.get_attr("agent") == ["beacon_0", "beacon_1", "beacon_0", "beacon_1"]
    configs = mixed.get_attr("config")
    assert configs[3].packet_loss_far == 0.8 and configs[1].packet_loss_far == 0.5
    obs = np.asarray(mixed.reset())
    alone = CoopNavVecEnv("matos_moving_lbl", n_envs=1, seed=4, **lossy)
    np.testing.assert_array_equal(obs[2:4], alone.reset())
    actions = np.random.default_rng(1).uniform(-1, 1, (30, 4, mixed.action_space.shape[0]))
    for k in range(30):  # long enough for the two channels to differ
        om, rm, _, _ = mixed.step(actions[k])
        oa, ra, _, _ = alone.step(actions[k, 2:4])
        np.testing.assert_array_equal(om[2:4], oa)
        np.testing.assert_array_equal(rm[2:4], ra)
    with pytest.raises(ValueError, match=r"flat observations differ in size"):
        MixedTeamVecEnv("gao_lawnmower", teams=[{}, {"n_survey": 2}], n_envs=2, observation="flat")
    with pytest.raises(ValueError, match=r"observation must be one of entities, flat"):
        MixedTeamVecEnv("gao_lawnmower", teams=[{}], n_envs=1, observation="entity")


def test_pettingzoo_entity_env_passes_the_api_test():
    from pettingzoo.test import parallel_api_test

    from coopnav_env.entity_views import entity_parallel_env

    env = entity_parallel_env("gao_team", seed=3, max_cycles=4)
    parallel_api_test(env, num_cycles=5)
    obs, _ = env.reset(seed=3)
    assert {a: o.shape for a, o in obs.items()} == {"beacon_0": (ENTITY_DIM,), "beacon_1": (ENTITY_DIM,)}
    np.testing.assert_array_equal(unflatten_entities(obs["beacon_1"]).own[6:10], _one_hot("beacon_auv"))


# --- the training config -------------------------------------------------------------
def _entity_config(**changes):
    base: dict[str, Any] = dict(
        scenario="gao_lawnmower",
        timesteps=1000,
        n_envs=4,
        env=EnvSpec(observation="entities", teams=[{}, {"n_survey": 2}]),
        normalize=NormalizeSpec(norm_obs=False),
    )
    base.update(changes)
    return TrainConfig(**base)


def test_training_config_checks_the_entity_keys():
    _entity_config().check()
    with pytest.raises(ConfigError, match=r"needs normalize.norm_obs: false"):
        _entity_config(normalize=NormalizeSpec()).check()
    with pytest.raises(ConfigError, match=r"unknown env.observation 'entity'; did you mean 'entities'"):
        _entity_config(env=EnvSpec(observation="entity")).check()
    with pytest.raises(ConfigError, match=r"env.teams\[0\].n_survey: a flat-observation policy takes one team makeup"):
        TrainConfig(scenario="gao_lawnmower", env=EnvSpec(teams=[{"n_survey": 2}])).check()
    TrainConfig(scenario="matos_moving_lbl", env=EnvSpec(teams=[{}, {"packet_loss_far": 0.8}])).check()
    with pytest.raises(ConfigError, match=r"unknown env.teams\[1\] key 'packet_loss'; did you mean"):
        TrainConfig(scenario="matos_moving_lbl", env=EnvSpec(teams=[{}, {"packet_loss": 0.8}])).check()
    with pytest.raises(ConfigError, match=r"env.teams\[1\].n_survey must be an integer in \[1, 5\], got 6"):
        _entity_config(env=EnvSpec(observation="entities", teams=[{}, {"n_survey": 6}])).check()
    with pytest.raises(ConfigError, match=r"unknown env.teams\[0\] key 'n_surveys'; did you mean 'n_survey'"):
        _entity_config(env=EnvSpec(observation="entities", teams=[{"n_surveys": 2}])).check()
    with pytest.raises(ConfigError, match=r"1-3 beacon kinds"):
        _entity_config(env=EnvSpec(observation="entities", teams=[{"beacon_kinds": ["asv"] * 4}])).check()
    with pytest.raises(ConfigError, match=r"env.teams\[1\].ping_interval_s must be a number of seconds"):
        _entity_config(env=EnvSpec(observation="entities", teams=[{}, {"ping_interval_s": "10 s"}])).check()
    _entity_config(env=EnvSpec(observation="entities", teams=[{}, {"ping_interval_s": 10.0}])).check()
    with pytest.raises(ConfigError, match=r"lists a team twice"):
        _entity_config(env=EnvSpec(observation="entities", teams=[{}, {}])).check()
    with pytest.raises(ConfigError, match=r"n_envs \(1\) must be at least the number of env.teams \(2\)"):
        _entity_config(n_envs=1).check()
    with pytest.raises(ConfigError, match=r"entity: embed_dim .* multiple of heads"):
        _entity_config(entity=EntitySpec(embed_dim=30, heads=4)).check()
    with pytest.raises(ConfigError, match=r"encoder must be one of deepsets, attention"):
        _entity_config(entity=EntitySpec(encoder="gnn")).check()
    from agents.training.config import ImitateSpec

    _entity_config(imitate=ImitateSpec(planner="ellipse")).check()  # entity policies can clone a planner
    from agents.training import RLlibConfig

    with pytest.raises(ConfigError, match=r"is for the SB3 trainer"):
        RLlibConfig(scenario="gao_lawnmower", env=EnvSpec(observation="entities")).check()
    from agents.training.common import prepare_job

    with pytest.raises(ConfigError, match=r"moving_lbl"):
        prepare_job(_entity_config(scenario="matos_moving_lbl", env=EnvSpec(observation="entities")))
    with pytest.raises(ConfigError, match=r"env.teams\[1\]: beacon_kinds: the kind .boat. belongs"):
        prepare_job(_entity_config(env=EnvSpec(observation="entities", teams=[{}, {"beacon_kinds": ["boat"]}])))


# --- a tiny training run, and every task of the benchmark ------------------------------
def test_tiny_training_over_randomized_teams(tmp_path):
    """A few thousand steps on three teams at once (<30 s): the run saves and loads through
    the safe format, validates every team, and the policy then drives teams it never saw."""
    from agents.training import sb3

    config = _entity_config(
        timesteps=2000,
        seed=2,
        ppo={"n_steps": 64, "batch_size": 160, "n_epochs": 2, "policy_kwargs": {"net_arch": [32]}},
        env=EnvSpec(
            overrides={"max_cycles": 8},
            observation="entities",
            teams=[{}, {"n_survey": 2}, {"beacon_kinds": ["beacon_auv", "beacon_auv"]}],
        ),
        eval=PeriodicEvalSpec(every_steps=1000, episodes=2, baselines=[]),
        entity=EntitySpec(encoder="deepsets", embed_dim=16),
        checkpoint_every_steps=1000,
    )
    out = tmp_path / "entity_run"
    assert sb3.train(config, out) == 0
    import json

    last = json.loads((out / "evaluations.jsonl").read_text().splitlines()[-1])
    assert set(last["per_cell"]) == {"team=scenario", "n_survey=2", "beacon_kinds=beacon_auv+beacon_auv"}
    with pytest.warns(UserWarning, match=r"trained on 'gao_lawnmower', used on 'swarm_mls'"):
        policy = agents.load(out, scenario="swarm_mls")
    assert isinstance(policy, EntityPolicy) and policy.config.n_survey == 3
    team = make_config("gao_lawnmower", n_survey=5, beacon_kinds=("asv", "beacon_auv", "beacon_auv"))
    third = agents.make_policy(out, team, agent=2)
    assert isinstance(third, EntityPolicy) and third.agent == 2 and third.act(np.zeros(third.obs_dim)).shape == (2,)
    with pytest.raises(ValueError, match=r"acts with 2 numbers; scenario 'sousa_ping' takes 3"):
        agents.load(out, scenario="sousa_ping")
    reloaded = agents.load(out / "model.safetensors")
    assert isinstance(reloaded, EntityPolicy) and reloaded.config.max_cycles == 8  # the run's config.yml


def _act_on(policy, config, seed=0):
    sim = make_simulator(config, 1)
    obs = sim.reset([seed])
    for j in range(config.n_beacons):
        action = policy.for_config(config, j).act(obs[0, j])
        assert action.shape == (policy.action_dim,) and np.isfinite(action).all()


def test_an_entity_policy_acts_on_every_team_size_of_every_task():
    """One untrained entity policy per action size (2; 3 for sousa_ping's transmit
    decision) acts on every task of every task set on the survey-beacon networks, team
    tasks included; the moving network's boats are refused with the reason."""
    policies = {2: untrained_entity_policy(2, seed=1), 3: untrained_entity_policy(3, seed=1)}
    teams = set()
    for ts in TASK_SETS.values():
        for task in ts.tasks:
            config = task.config(ts.scenario)
            if config.network == "moving_lbl":
                assert "decode_boat" in str(policies[2].config_problem(config))
                continue
            from coopnav_env.views import action_dim

            policy = policies[action_dim(config)]
            assert policy.config_problem(config) is None, (ts.name, task.name)
            _act_on(policy, config)
            teams.add((config.n_survey, config.beacon_kinds))
    assert {(2, ("beacon_auv",)), (5, ("beacon_auv",)), (1, ("beacon_auv", "beacon_auv"))} <= teams
    assert len(teams) >= 6


def test_the_benchmark_plans_no_na_for_an_entity_policy(tmp_path, monkeypatch):
    """evaluation's n/a comes from the policy (check_policy asks its config_problem): an
    entity policy is n/a on none of gao_lawnmower's tasks, team tasks included (plan
    only: no episodes run)."""
    from evaluation import episodes
    from evaluation.benchmark import plan_benchmark

    entity = untrained_entity_policy(2, seed=3)
    real = episodes.make_policy

    def fake(name, config, seed, agent):
        return entity.for_config(config, agent) if name == "entity" else real(name, config, seed, agent)

    monkeypatch.setattr(episodes, "make_policy", fake)
    monkeypatch.setattr("evaluation.config.resolve_trained", lambda *a, **k: {"shipped": None, "model": "entity"})
    plan = plan_benchmark("gao_lawnmower", "entity", out=str(tmp_path / "b"), check_out=False)
    assert all(not c for c in plan.sets[0].cannot.values())
    assert "two_beacons" in plan.sets[0].configs and "two_surveys" in plan.sets[0].configs


def test_a_run_without_observation_normalization_saves_and_restores(tmp_path):
    """norm_obs: false (required by entity runs): SB3's VecNormalize then has no obs_rms;
    its file holds the identity's statistics and restores into such a VecNormalize (this
    raised AttributeError before)."""
    from stable_baselines3.common.vec_env import VecNormalize

    from coopnav_env.entity_views import EntityVecEnv
    from coopnav_env.vector import CoopNavVecEnv

    venv = VecNormalize(EntityVecEnv(CoopNavVecEnv("gao_lawnmower", n_envs=2, seed=5)), norm_obs=False)
    venv.ret_rms.mean, venv.ret_rms.count = np.full((), 0.25), 7.0
    formats.save_vecnormalize(venv, tmp_path / "v.safetensors")
    stats = formats.read_vecnormalize(tmp_path / "v.safetensors")
    assert stats["norm_obs"] is False and stats["obs_mean"].shape == (ENTITY_DIM,) and not stats["obs_mean"].any()
    other = VecNormalize(EntityVecEnv(CoopNavVecEnv("gao_lawnmower", n_envs=2, seed=5)), norm_obs=False)
    formats.restore_vecnormalize(other, stats)
    assert (float(other.ret_rms.mean), other.ret_rms.count) == (0.25, 7.0)


def test_imitation_drives_each_flat_team_with_its_own_scenario():
    """The clone's data (agents.training.imitation.collect) over flat teams: each row's
    planner is made for its team's scenario and beacon, so the recorded actions of the
    second team are the planner's for that team (here a shorter baseline, which moves abeam's
    targets), not the first team's."""
    from stable_baselines3.common.vec_env import VecNormalize

    from agents.training.imitation import collect
    from baselines import make_policy
    from coopnav_env.entity_views import MixedTeamVecEnv

    teams: list[dict[str, Any]] = [{}, {"baseline_target_m": 50.0}]
    raw = MixedTeamVecEnv("matos_moving_lbl", teams=teams, n_envs=2, seed=11, observation="flat")
    data = collect(VecNormalize(raw, norm_reward=False), raw, "abeam", steps=40, seed=3)
    obs, acts = data["obs"], data["actions"]
    k = 5  # a few steps in: both boats moving
    configs, agents = raw.get_attr("config"), raw.get_attr("agent")
    for r in (2, 3):
        own = make_policy("abeam", configs[r], seed=(3, r), agent=agents[r])
        other = make_policy("abeam", raw.configs[0], seed=(3, r), agent=agents[r])
        for t in range(k + 1):
            a_own, a_other = own.act(obs[t, r]), other.act(obs[t, r])
        np.testing.assert_allclose(acts[k, r], a_own, rtol=1e-6, atol=1e-6)
        assert not np.allclose(acts[k, r], a_other, atol=1e-3)


def test_imitation_records_entity_rows_and_the_planners_flat_decisions():
    """collect() over entity rows: the policy's data are the entity observations, and the planners
    decide on each row's flat vector underneath, so the recorded actions are those of a flat run
    of the same episodes; over a mixed team each team's planner reads its own team's vector."""
    from stable_baselines3.common.vec_env import VecNormalize

    from agents.training.imitation import collect
    from coopnav_env.entity_views import EntityVecEnv, MixedTeamVecEnv
    from coopnav_env.vector import CoopNavVecEnv

    flat = CoopNavVecEnv("gao_lawnmower", n_envs=2, seed=31)
    ent = EntityVecEnv(CoopNavVecEnv("gao_lawnmower", n_envs=2, seed=31))
    a = collect(VecNormalize(flat, norm_obs=False, norm_reward=False), flat, "ellipse", steps=12, seed=3)
    b = collect(VecNormalize(ent, norm_obs=False, norm_reward=False), ent, "ellipse", steps=12, seed=3)
    np.testing.assert_array_equal(a["actions"], b["actions"])
    assert b["obs"].shape[-1] == ent.observation_space.shape[0] != a["obs"].shape[-1]
    for t in range(a["obs"].shape[0]):
        np.testing.assert_allclose(b["obs"][t], ent.convert(a["obs"][t].astype(np.float64)), atol=1e-6)
    teams: list[dict[str, Any]] = [{}, {"beacon_kinds": ["beacon_auv", "beacon_auv"]}]
    mixed = MixedTeamVecEnv("gao_lawnmower", teams=teams, n_envs=2, seed=5)
    c = collect(VecNormalize(mixed, norm_obs=False, norm_reward=False), mixed, "ellipse", steps=9, seed=3)
    assert c["actions"].shape == (3, 3, 2) and np.isfinite(c["actions"]).all()
    assert mixed.get_attr("flat_observation")[0].shape != mixed.get_attr("flat_observation")[1].shape


def test_mixed_get_attr_keeps_the_rows_order_with_one_call_per_team():
    """MixedTeamVecEnv.get_attr asks each team once for its rows, and hands the values back in
    the order of ``indices``, however the rows of the teams interleave there."""
    from coopnav_env.entity_views import MixedTeamVecEnv

    teams: list[dict[str, Any]] = [{}, {"beacon_kinds": ["beacon_auv", "beacon_auv"]}]
    mixed = MixedTeamVecEnv("gao_lawnmower", teams=teams, n_envs=2, seed=5)
    mixed.reset()
    assert mixed.num_envs == 3  # a row of the first team, two of the second
    order = [2, 0, 1]  # the second team's rows around the first's
    one_by_one = [mixed.get_attr("agent", [i])[0] for i in order]
    assert mixed.get_attr("agent", order) == one_by_one
    flat = mixed.get_attr("flat_observation", order)
    for i, v in zip(order, flat):
        np.testing.assert_array_equal(v, mixed.get_attr("flat_observation", [i])[0])
    assert len({v.shape for v in flat}) == 2  # both teams' rows are there, each its own size
