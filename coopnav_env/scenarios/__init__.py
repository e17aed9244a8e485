"""Named scenarios. Importing this package registers every scenario file."""

from . import gao  # noqa: F401  (registers gao_lawnmower, gao_sea)
from . import sousa  # noqa: F401  (registers sousa_asv)
from .base import ScenarioConfig, list_scenarios, make_config, parameter_names, register

__all__ = ["ScenarioConfig", "list_scenarios", "make_config", "parameter_names", "register"]
