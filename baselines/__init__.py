"""Baseline policies with the same interface as learned ones (see ``baselines.base``).

``fim_a`` and ``fim_b``: Sousa, Ferreira & Cruz's FIM guidance (approaches A and B);
``ellipse``: Gao & Chitre's range along the major axis of the error ellipse;
``static``, ``circle``, ``random``: floors.
"""

from .base import BeaconContext, Policy, list_policies, make_policy, waypoint_to_action

__all__ = ["BeaconContext", "Policy", "list_policies", "make_policy", "waypoint_to_action"]
