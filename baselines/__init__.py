"""Baseline policies with the same interface as learned ones (see ``baselines.base``).

``fim_a`` and ``fim_b``: Sousa, Ferreira & Cruz's FIM guidance (approaches A and B);
``ellipse``: Gao & Chitre's range along the major axis of the error ellipse;
``perpendicular``, ``abeam``: the moving network's scripted boats (Matos & Cruz);
``static``, ``circle``, ``random``: floors.
With ``channel_mode="decide"`` (scenario ``sousa_ping``) each combines with a
transmit schedule, ``make_policy("fim_a+tdma", env)`` (``baselines.schedule``:
``clock``, ``tdma``, ``event``).

A new planner is one module with a ``Policy`` subclass decorated with
``@register_policy("name")`` plus one import line here.
"""

from . import ellipse, fim, moving_lbl, simple  # noqa: F401  (each registers its planners)
from .base import BeaconContext, Policy, list_policies, make_policy, waypoint_to_action
from .schedule import list_schedules  # transmit schedules for channel_mode="decide": "<motion>+<schedule>"

__all__ = ["BeaconContext", "Policy", "list_policies", "list_schedules", "make_policy", "waypoint_to_action"]
