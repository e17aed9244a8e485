"""The RLlib ``PPOConfig`` of a coopnav job (``agents.training.rllib``'s part 1): the
environment's config, the algorithm's settings from the job's YAML, and the record of
what was built. Ray is imported inside the functions."""

from __future__ import annotations

import enum
import inspect
from typing import Any

import numpy as np

from .config import ConfigError, RLlibConfig, unknown_key_message


def training_keywords() -> set:
    """The keywords PPOConfig.training accepts (its own and AlgorithmConfig's)."""
    from ray.rllib.algorithms.algorithm_config import AlgorithmConfig
    from ray.rllib.algorithms.ppo import PPOConfig

    names = set()
    for fn in (PPOConfig.training, AlgorithmConfig.training):
        names |= {
            n
            for n, p in inspect.signature(fn).parameters.items()
            if n != "self" and p.kind not in (p.VAR_KEYWORD, p.VAR_POSITIONAL)
        }
    return names


def env_config(config: RLlibConfig, seed: int) -> dict:
    from coopnav_env.vector import check_reward_terms

    return {
        "scenario": config.scenario,
        "overrides": dict(config.env.overrides),
        "seed": int(seed),
        "reward_terms": check_reward_terms(config.reward),
        "num_envs_per_env_runner": int(config.env_runners.get("num_envs_per_env_runner", 1) or 1),
    }


def build_config(config: RLlibConfig, seed: int | None = None) -> Any:
    """(PPOConfig, beacon -> module map) of a job: the adapter env, one module per
    beacon kind, the config's ``ppo``/``model``/``env_runners``/``learners`` sections.
    ``seed``: the run's (default ``config.seed``). Bad sections are a ``ConfigError``."""
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.core.rl_module.multi_rl_module import MultiRLModuleSpec
    from ray.rllib.core.rl_module.rl_module import RLModuleSpec

    from coopnav_env.rllib_env import (
        CoopNavRLlibEnv,
        KindMapping,
        SurveyErrorMetrics,
        mean_std_filter,
        module_ids,
        module_map,
    )

    seed = config.seed if seed is None else int(seed)
    valid = training_keywords()
    for key in config.ppo:
        if key not in valid:
            raise ConfigError(unknown_key_message(key, valid, "ppo key (PPOConfig.training keyword)"))
    env_cfg = env_config(config, seed)
    mapping = module_map(config.scenario, env_cfg["overrides"])
    runners = {"num_env_runners": 0, **config.env_runners}
    if config.normalize_obs:
        runners["env_to_module_connector"] = mean_std_filter
    try:
        algo_config = (
            PPOConfig()
            .environment(CoopNavRLlibEnv, env_config=env_cfg, disable_env_checking=True)
            .env_runners(**runners)
            .learners(**config.learners)
            .training(**config.ppo)
            .multi_agent(
                policies=set(module_ids(mapping)),
                policy_mapping_fn=KindMapping(mapping),
                policies_to_train=module_ids(mapping),
            )
            .rl_module(
                rl_module_spec=MultiRLModuleSpec(
                    rl_module_specs={m: RLModuleSpec(model_config=dict(config.model)) for m in module_ids(mapping)}
                )
            )
            .callbacks(SurveyErrorMetrics)
            .debugging(seed=seed, log_level="ERROR")
            .reporting(metrics_num_episodes_for_smoothing=100)
        )
        algo_config.validate()
    except (TypeError, ValueError, KeyError, AssertionError) as err:
        raise ConfigError(
            f"bad RLlib hyperparameters: {' '.join(str(err).split())[:300] or type(err).__name__}"
        ) from None
    return algo_config, mapping


def config_record(algo_config: Any) -> dict:
    """The AlgorithmConfig as plain YAML-able values (callables and classes by name)."""

    def clean(v):
        if isinstance(v, enum.Enum):
            return clean(v.value)
        if isinstance(v, dict):
            return {str(k): clean(x) for k, x in v.items()}
        if isinstance(v, (list, tuple, set)):
            return [clean(x) for x in v]
        if v is None or isinstance(v, (bool, int, float, str)):
            return v
        if isinstance(v, (np.integer, np.floating)):
            return v.item()
        if isinstance(v, type) or callable(v):
            return f"{getattr(v, '__module__', '?')}.{getattr(v, '__qualname__', type(v).__name__)}"
        return repr(v)

    d = algo_config.to_dict()
    return clean({k: v for k, v in d.items() if not k.startswith("_") or k in ("_rl_module_spec",)})


def cpus_per_trial(algo_config: Any) -> int:
    runners = int(algo_config.num_env_runners or 0)
    return int(np.ceil(runners * float(algo_config.num_cpus_per_env_runner or 1))) + 1
