"""The scenario description: a frozen dataclass in sections that the batched core reads.

A scenario is data. ``ScenarioConfig`` (``config.py``) holds every parameter of the
simulation (vehicles, sensors, acoustics, current, reward), grouped in sections
(``sections.py``) whose fields declare their unit, range and source (``params.py``);
a section that does not apply to a scenario is ``None``. ``scenarios/<name>.py``
files register named instances (``registry.py``). Overriding a parameter is
``make_config("gao_sea", ping_interval_s=10.0)`` (or ``**{"timing.ping_interval_s":
10.0}``). Unknown scenario or parameter names are a ``ValueError`` that names the
closest valid one, so a typo never passes silently (the VMAS habit).

This module keeps the names other code imports from it.
"""

from .config import (
    SECTIONS,
    ScenarioConfig,
    SectionSpec,
    bounds,
    check_overrides,
    default_of,
    flat_name,
    parameter_names,
    section_of,
)
from .params import COORDINATE_LIMIT_M, param, range_text
from .registry import list_scenarios, make_config, register, resolve_config
from .sections import (
    ACTION_MODES,
    AREA_LIMIT_M,
    BEACON_KINDS,
    CHANNEL_MODES,
    MAX_WAYPOINTS,
    NETWORKS,
    PAPER_FILTER,
    RANGING_MODES,
    SURVEY_PATHS,
)
from .sections_moving import MAX_RIVER_POINTS, MISSION_FRAMES
from .validate import SLOWEST_SOUND_SPEED_MPS, waypoint_count


def __getattr__(name: str) -> tuple:
    if name == "ACOUSTIC_SENSORS":  # the registry's, so a sensor registered later is valid
        from . import sections

        return sections.ACOUSTIC_SENSORS
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "ACOUSTIC_SENSORS",  # noqa: F822 - served by the module __getattr__ above
    "ACTION_MODES",
    "AREA_LIMIT_M",
    "BEACON_KINDS",
    "CHANNEL_MODES",
    "COORDINATE_LIMIT_M",
    "MAX_RIVER_POINTS",
    "MAX_WAYPOINTS",
    "MISSION_FRAMES",
    "NETWORKS",
    "PAPER_FILTER",
    "RANGING_MODES",
    "SECTIONS",
    "SLOWEST_SOUND_SPEED_MPS",
    "SURVEY_PATHS",
    "ScenarioConfig",
    "SectionSpec",
    "bounds",
    "check_overrides",
    "default_of",
    "flat_name",
    "list_scenarios",
    "make_config",
    "param",
    "parameter_names",
    "range_text",
    "register",
    "resolve_config",
    "section_of",
    "waypoint_count",
]
