"""Named scenarios. Importing this package registers every scenario file; the names are
``list_scenarios()`` (the generated docs page ``reference/scenarios.md`` lists each with
its sections and the values that differ from the defaults)."""

from . import gao, matos, ping, sousa, swarm  # noqa: F401  (each file registers its scenarios)
from .base import (
    PAPER_FILTER,
    ScenarioConfig,
    list_scenarios,
    make_config,
    parameter_names,
    register,
    resolve_config,
)

__all__ = [
    "PAPER_FILTER",
    "ScenarioConfig",
    "list_scenarios",
    "make_config",
    "parameter_names",
    "register",
    "resolve_config",
]
