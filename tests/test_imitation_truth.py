"""Imitation of a privileged planner (the oracle): the clone's data records the oracle's
decisions made with its row's truth, as the evaluation tells it, not ``horizon``'s (what the
oracle falls back to without a snapshot)."""

from __future__ import annotations

import numpy as np


def test_collect_tells_the_oracle_its_rows_truth():
    from stable_baselines3.common.vec_env import VecNormalize

    from agents.training.imitation import collect
    from baselines import make_policy, tell_truth
    from coopnav_env.core import make_simulator
    from coopnav_env.vector import CoopNavVecEnv

    seed, k = 21, 6
    raw = CoopNavVecEnv("gao_lawnmower", n_envs=2, seed=seed)
    assert raw.get_attr("env_index") == [0, 1]
    data = collect(VecNormalize(raw, norm_reward=False), raw, "oracle", steps=2 * k, seed=3)
    obs, acts = data["obs"], data["actions"]
    # the same two episodes stepped by hand: environment e's first episode is seeded seed + e
    config = raw.config
    sim = make_simulator(config, 2)
    sim.reset(np.array([seed, seed + 1]))
    oracles = [[make_policy("oracle", config, seed=(3, r), agent="beacon_0")] for r in range(2)]
    blind = [make_policy("oracle", config, seed=(3, r), agent="beacon_0") for r in range(2)]  # never told
    differs = False
    for t in range(k):
        tell_truth(oracles, sim)
        told = np.stack([oracles[r][0].act(obs[t, r]) for r in range(2)])
        np.testing.assert_allclose(acts[t], told, rtol=1e-6, atol=1e-6)
        differs |= not np.allclose(told, np.stack([blind[r].act(obs[t, r]) for r in range(2)]), atol=1e-4)
        sim.step(told[:, None, :])
    assert differs  # the truth changes the oracle's decisions: the test can tell it was given
