"""The registry of named scenarios: ``register``, ``list_scenarios``, ``make_config``."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from ..names import closest
from .config import ScenarioConfig

_REGISTRY: dict = {}


def register(name: str, factory: Callable[[], ScenarioConfig] | ScenarioConfig) -> None:
    """Register a scenario under ``name``: a config, or a function that makes one."""
    if name in _REGISTRY:
        raise ValueError(f"scenario {name!r} is registered twice")
    _REGISTRY[name] = factory


def list_scenarios() -> list:
    """The names of the registered scenarios, sorted."""
    return sorted(_REGISTRY)


def make_config(scenario: str | ScenarioConfig = "gao_lawnmower", **overrides: Any) -> ScenarioConfig:
    """The named scenario's config with ``overrides`` applied (flat or dotted parameter
    names; an unknown scenario or parameter name is a ``ValueError`` with the closest)."""
    if isinstance(scenario, ScenarioConfig):
        base = scenario
    elif not isinstance(scenario, str):
        raise TypeError(f"scenario must be a scenario name (str) or a ScenarioConfig, got {type(scenario).__name__}")
    else:
        if scenario not in _REGISTRY:
            close = closest(scenario, list_scenarios())
            hint = f" (did you mean {close!r}?)" if close else ""
            raise ValueError(f"unknown scenario {scenario!r}{hint}; valid scenarios: {', '.join(list_scenarios())}")
        entry = _REGISTRY[scenario]
        base = entry() if callable(entry) else entry
    return base.replace(**overrides) if overrides else base


def resolve_config(env_or_config: Any) -> ScenarioConfig:
    """A ScenarioConfig from an env (any view with ``.config``), a simulator, a config
    or a scenario name."""
    if isinstance(env_or_config, ScenarioConfig):
        return env_or_config
    if isinstance(env_or_config, str):
        return make_config(env_or_config)
    for obj in (env_or_config, getattr(env_or_config, "unwrapped", None)):
        cfg = getattr(obj, "config", None)
        if isinstance(cfg, ScenarioConfig):
            return cfg
    raise TypeError(f"cannot find a scenario config in {type(env_or_config).__name__}")
