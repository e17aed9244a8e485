"""Baseline policies with the same interface as learned ones (see ``baselines.base``).

``fim_a`` and ``fim_b``: Sousa, Ferreira & Cruz's FIM guidance (approaches A and B);
``ellipse``: Gao & Chitre's range along the major axis of the error ellipse;
``perpendicular``, ``abeam``: the moving network's scripted boats (Matos & Cruz);
``static``, ``circle``, ``random``: floors.

A new planner is one module with a ``Policy`` subclass decorated with
``@register_policy("name")`` plus one import line here.
"""

from . import ellipse, fim, moving_lbl, simple  # noqa: F401  (each registers its planners)
from .base import BeaconContext, Policy, list_policies, make_policy, waypoint_to_action

__all__ = ["BeaconContext", "Policy", "list_policies", "make_policy", "waypoint_to_action"]
