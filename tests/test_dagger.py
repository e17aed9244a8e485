"""DAgger rounds of the imitation (``imitate.dagger_rounds``): the clone drives, the planner
labels the states the clone reaches, and the clone is fitted again on all the data."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml


def test_a_driven_collection_records_the_planners_labels_of_the_drivers_states():
    """With a driver, the environment follows the driver's actions and the recorded actions are
    the planner's decisions on the states reached (here a driver that stands still)."""
    from stable_baselines3.common.vec_env import VecNormalize

    from agents.training.imitation import collect
    from baselines import make_policy
    from coopnav_env.core import make_simulator
    from coopnav_env.vector import CoopNavVecEnv

    seed, k = 41, 5
    raw = CoopNavVecEnv("gao_lawnmower", n_envs=2, seed=seed)
    still = collect(
        VecNormalize(raw, norm_reward=False), raw, "ellipse", 2 * k, 3, driver=lambda o: np.zeros((len(o), 2))
    )
    # the same two episodes stepped by hand, standing still: environment e's first episode is seed + e
    sim = make_simulator(raw.config, 2)
    obs = sim.reset(np.array([seed, seed + 1]))
    planners = [make_policy("ellipse", raw.config, seed=(3, r), agent="beacon_0") for r in range(2)]
    for t in range(k):
        np.testing.assert_allclose(still["obs"][t], obs[:, 0], rtol=1e-6, atol=1e-4)
        want = np.stack([planners[r].act(still["obs"][t, r]) for r in range(2)])
        np.testing.assert_allclose(still["actions"][t], want, rtol=1e-6, atol=1e-6)
        obs = sim.step(np.zeros((2, 1, 2))).obs
    assert np.abs(still["actions"]).max() > 0.1  # the planner wanted to move: its labels are not the driver's
    raw2 = CoopNavVecEnv("gao_lawnmower", n_envs=2, seed=seed)
    driven = collect(VecNormalize(raw2, norm_reward=False), raw2, "ellipse", 2 * k, 3)
    assert not np.allclose(still["obs"][-1], driven["obs"][-1])  # the planner driving reaches other states


ENTITY_TEAMS = {  # the entity clone's path: teams of one and two beacons, the clone reads entities
    "observation": "entities",
    "teams": [{}, {"beacon_kinds": ["beacon_auv", "beacon_auv"]}],
}


@pytest.mark.parametrize(
    "scenario, env, rows",
    [("sousa_asv", {}, 4), ("gao_lawnmower", ENTITY_TEAMS, 6)],  # rows: the VecEnv's rows of 4 environments
    ids=["flat", "entity_teams"],
)
def test_dagger_rounds_refit_on_the_clones_own_states(tmp_path, scenario, env, rows):
    """A tiny run with one DAgger round: the record has the round, with the clone's error on its
    own states before the refit, and the data of both collections; flat, and an entity policy
    driving teams of other numbers of beacons (``MixedTeamVecEnv``)."""
    from agents.training import cli

    out = tmp_path / "dagger"
    config = {
        "policy": "MlpPolicy",
        "n_envs": 4,
        "ppo": {"n_steps": 64, "batch_size": 128, "n_epochs": 1, "policy_kwargs": {"net_arch": [32, 32]}},
        "env": {"overrides": {"max_cycles": 12}, **env},
        **({"entity": {"embed_dim": 16, "heads": 2}, "normalize": {"norm_obs": False}} if env else {}),
        "imitate": {
            "planner": "circle",
            "steps": 400,
            "epochs": 3,
            "batch_size": 128,
            "dagger_rounds": 1,
            "dagger_steps": 200,
        },
        "eval": {"every_steps": 0, "episodes": 1},
        "checkpoint_every_steps": 0,
    }
    path = tmp_path / "c.yml"
    path.write_text(yaml.safe_dump(config))
    argv = ["--scenario", scenario, "--timesteps", "256", "--seed", "0", "--out", str(out), "--config", str(path)]
    assert cli.main([*argv, "--no-progress"]) == 0
    record = yaml.safe_load((out / "config.yml").read_text())["imitation"]
    whole = -(-200 // rows) * rows  # collect's whole steps of every row
    assert [r["steps"] for r in record["dagger"]] == [whole]
    assert record["steps"] == -(-400 // rows) * rows + whole
    assert 0 < record["dagger"][0]["action_rms_error_before"] < 2.0
    json.dumps(record)


@pytest.mark.parametrize("bad", [-1, 1.5, True, "2"])
def test_bad_dagger_settings_are_one_line(bad):
    from agents.training.config import ConfigError, TrainConfig, from_dict

    with pytest.raises(ConfigError, match=r"imitate\.dagger_rounds"):
        from_dict(TrainConfig, {"imitate": {"planner": "circle", "dagger_rounds": bad}}).check()
