"""What every trained policy shares (SB3, gated, RLlib): one observation in, one
action out, through ``act_batch``; and the scenario a run was trained on."""

from __future__ import annotations

from typing import Any

import numpy as np


class BatchPolicy:
    """What trained policies share: ``act`` on one observation through ``act_batch``
    (subclasses set ``obs_dim`` and implement ``act_batch`` and ``reset``)."""

    obs_dim: int
    obs_dtype = np.float64
    config: Any  # the ScenarioConfig it was trained on (None if unknown)
    name: str

    def reset(self, seed: int | None = None) -> None:
        raise NotImplementedError

    def act_batch(self, obs: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def act(self, obs: np.ndarray) -> np.ndarray:
        from coopnav_env.views import check_observation

        obs = check_observation(obs, self.obs_dim).astype(self.obs_dtype)  # shape and finite, one line
        return self.act_batch(obs[None])[0]

    def __call__(self, obs):
        return self.act(obs)

    def config_problem(self, config: Any) -> str | None:
        """Why this policy cannot drive ``config`` (a ScenarioConfig), or None: it can. A
        flat-observation policy takes one observation size; entity policies
        (``agents.entity.EntityPolicy``) say which teams they take."""
        from coopnav_env.obs_layout import obs_dim

        dim = obs_dim(config)
        if dim != self.obs_dim:
            return f"takes observations of size {self.obs_dim}; scenario {config.name!r} gives {dim}"
        return None

    def accepts(self, config: Any) -> bool:
        """Whether this policy can drive ``config`` (``config_problem`` is None)."""
        return self.config_problem(config) is None


def _trained_scenario(run_config: dict):
    """The ScenarioConfig a run trained on (its base scenario with the training overrides)."""
    from coopnav_env.scenarios import make_config

    args = run_config.get("args", {}) or {}
    name = args.get("scenario")
    if name is None:
        return None
    overrides = ((run_config.get("hyperparameters", {}) or {}).get("env", {}) or {}).get("overrides", {}) or {}
    try:
        return make_config(name, **overrides)
    except ValueError:
        return None
