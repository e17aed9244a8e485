"""Baseline policies with the same interface as learned ones (see ``baselines.base``).

``fim_a`` and ``fim_b``: Sousa, Ferreira & Cruz's FIM guidance (approaches A and B);
``ellipse``: Gao & Chitre's range along the major axis of the error ellipse;
``perpendicular``, ``abeam``, ``river_escort``: the moving network's scripted boats (Matos & Cruz);
``horizon``: a receding-horizon planner (the cross-entropy method over the next pings), and
``oracle``, the same given the truth (the benchmark's reference): ``baselines.horizon`` for the
survey networks, ``baselines.boat_horizon`` for the boats;
``static``, ``circle``, ``random``: floors.
With ``channel_mode="decide"`` (scenario ``sousa_ping``) each combines with a
transmit schedule, ``make_policy("fim_a+tdma", env)`` (``baselines.schedule``:
``clock``, ``tdma``, ``event``).

A new planner is one module in this package with a ``Policy`` subclass decorated with
``@register_policy("name")``: every module here is imported with the package, so that
is the whole registration (a planner elsewhere registers when its module is imported).
"""

import importlib as _importlib
import pkgutil as _pkgutil

from .base import (
    BeaconContext,
    Policy,
    is_planner,
    list_policies,
    make_policy,
    motion_name,
    register_policy,
    split_spec,
    tell_truth,
    unregister_policy,
    waypoint_to_action,
)

# list_schedules: transmit schedules for channel_mode="decide", "<motion>+<schedule>"
from .schedule import list_schedules

for _module in _pkgutil.iter_modules(__path__):  # each planner module registers its planners
    _importlib.import_module(f"{__name__}.{_module.name}")

__all__ = [
    "BeaconContext",
    "Policy",
    "is_planner",
    "list_policies",
    "list_schedules",
    "make_policy",
    "motion_name",
    "register_policy",
    "split_spec",
    "tell_truth",
    "unregister_policy",
    "waypoint_to_action",
]
