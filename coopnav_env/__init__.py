"""coopnav: cooperative underwater navigation as a PettingZoo environment.

    import coopnav_env
    env = coopnav_env.parallel_env("gao_lawnmower", seed=0)

``parallel_env`` and ``env`` (AEC) take a scenario name and keyword overrides of
any scenario parameter; ``list_scenarios()`` names the scenarios. The batched
simulator is ``coopnav_env.core.sim.Simulator``. Heavy imports (matplotlib,
PettingZoo's wrappers) happen only when used.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from .scenarios import ScenarioConfig, list_scenarios, make_config, parameter_names

if TYPE_CHECKING:
    from pettingzoo import AECEnv

    from .pettingzoo_env import CoopNavParallelEnv

__all__ = ["ScenarioConfig", "env", "list_scenarios", "make_config", "parallel_env", "parameter_names", "raw_env"]


def parallel_env(scenario: str | ScenarioConfig = "gao_lawnmower", **kwargs: Any) -> CoopNavParallelEnv:
    """The PettingZoo ParallelEnv of ``scenario``. See ``CoopNavParallelEnv``."""
    from .pettingzoo_env import CoopNavParallelEnv

    return CoopNavParallelEnv(scenario, **kwargs)


def raw_env(scenario: str | ScenarioConfig = "gao_lawnmower", **kwargs: Any) -> AECEnv:
    """The unwrapped AEC environment (PettingZoo's ``raw_env`` convention): the
    parallel env seen through ``parallel_to_aec_wrapper`` (each action checked on its own
    agent's turn: ``pettingzoo_env.CoopNavAEC``), without the order check."""
    from .pettingzoo_env import CoopNavAEC

    return CoopNavAEC(parallel_env(scenario, **kwargs))


def env(scenario: str | ScenarioConfig = "gao_lawnmower", **kwargs: Any) -> AECEnv:
    """The AEC environment as PettingZoo's own envs return it: ``raw_env`` inside
    ``OrderEnforcingWrapper`` (which refuses ``step`` before ``reset`` and the like)."""
    from pettingzoo.utils.wrappers import OrderEnforcingWrapper

    return OrderEnforcingWrapper(raw_env(scenario, **kwargs))


def _register_gymnasium():
    try:
        from gymnasium.envs.registration import register, registry
    except ImportError:  # pragma: no cover
        return
    for name in list_scenarios():
        env_id = f"coopnav/{name}-v0"
        if make_config(name).n_beacons != 1:  # the Gymnasium view is one beacon's: parallel_env drives teams
            continue
        if env_id not in registry:
            register(id=env_id, entry_point="coopnav_env.gym_env:CoopNavGymEnv", kwargs={"scenario": name})


_register_gymnasium()
