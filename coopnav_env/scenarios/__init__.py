"""Named scenarios. Importing this package registers every scenario file."""

from . import gao  # noqa: F401  (registers gao_lawnmower, gao_sea)
from . import matos  # noqa: F401  (registers matos_moving_lbl)
from . import ping  # noqa: F401  (registers sousa_ping)
from . import sousa  # noqa: F401  (registers sousa_asv)
from . import swarm  # noqa: F401  (registers swarm_mls)
from .base import ScenarioConfig, list_scenarios, make_config, parameter_names, register, resolve_config

__all__ = ["ScenarioConfig", "list_scenarios", "make_config", "parameter_names", "register", "resolve_config"]
