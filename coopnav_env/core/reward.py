"""The reward: a weighted sum of named terms that the simulators return.

Every simulator puts its terms, unweighted, in ``StepResult.terms`` (name -> (B, N)
array, one value per beacon); ``weighted_reward`` turns them into the environment's
reward with the scenario's weights, and it is the only place that does. The
PettingZoo env, the SB3 VecEnv, the RLlib adapter and the evaluation all read the
reward or its terms from the step result.

===============  ======================================================  ====================
term             value per beacon and cycle                              weight
===============  ======================================================  ====================
``info_gain``    information the survey filters gained from this           +1
                 cycle's measurements: sum over survey vehicles of
                 log det P_before - log det P_after of the horizontal
                 position covariance (nats; shared by the team)
``safety``       1 if the beacon is closer than ``safety_distance_m``      -``safety_penalty``
                 to a survey vehicle
``geofence``     1 if the beacon is outside the geofence                   -``geofence_penalty``
``contact``      1 if none of its ranges was fused this cycle (moving      -``contact_penalty``
                 network: none of the vehicle's)
``baseline``     1 if the boats' baseline is off ``baseline_target_m``     -``baseline_penalty``
                 by more than ``baseline_tolerance_m`` (moving network)
``approach``     1 if the vehicle is nearer the baseline than              -``approach_penalty``
                 ``min_baseline_distance_m`` (moving network)
``rotation``     1 if the frame turned more than                           -``rotation_penalty``
                 ``frame_rotation_tolerance_deg`` from its start (moving
                 network)
``bank``         1 if the boat is farther than ``river_width_m`` / 2      -``bank_penalty``
                 from the river's centerline (moving network with
                 ``mission_frame="world"``: a river survey; there the
                 ``rotation`` term is always 0, the frame must turn
                 with the river)
``ping``         1 if the beacon transmitted a ping this cycle (only with  -``ping_penalty``
                 ``channel_mode="decide"``: the price of the channel and
                 of the transmit energy, ``core.channel``)
===============  ======================================================  ====================
"""

from __future__ import annotations

import numpy as np

# term -> the scenario parameter whose negative weighs it (None: weight +1)
TERM_WEIGHTS = {
    "info_gain": None,
    "safety": "safety_penalty",
    "geofence": "geofence_penalty",
    "contact": "contact_penalty",
    "baseline": "baseline_penalty",
    "approach": "approach_penalty",
    "rotation": "rotation_penalty",
    "ping": "ping_penalty",
    "bank": "bank_penalty",
}
SURVEY_TERMS = ("info_gain", "safety", "geofence", "contact")
CHANNEL_TERMS = SURVEY_TERMS + ("ping",)  # the survey network with channel_mode="decide"
MOVING_NETWORK_TERMS = ("info_gain", "safety", "baseline", "approach", "rotation", "contact")
RIVER_NETWORK_TERMS = MOVING_NETWORK_TERMS + ("bank",)  # the moving network with mission_frame="world"
# all but information and contact
PENALTY_TERMS = ("safety", "geofence", "baseline", "approach", "rotation", "ping", "bank")


def term_weights(config, terms) -> dict:
    """The scenario's weight of each term in ``terms``."""
    return {t: 1.0 if TERM_WEIGHTS[t] is None else -float(getattr(config, TERM_WEIGHTS[t])) for t in terms}


def weighted_reward(terms: dict, weights: dict) -> np.ndarray:
    """sum_k weights[k] * terms[k], in ``weights``' order: (B, N)."""
    total = None
    for name, w in weights.items():
        part = w * terms[name]
        total = part if total is None else total + part
    return total


def penalties(terms: dict, weights: dict) -> np.ndarray:
    """The weighted penalty terms (``PENALTY_TERMS`` present in ``weights``) as a positive
    cost (B, N): what the training signal ``penalties`` subtracts."""
    out = 0.0
    for name in PENALTY_TERMS:
        if name in weights:
            out = out - weights[name] * terms[name]
    return out
