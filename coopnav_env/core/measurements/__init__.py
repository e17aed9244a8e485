"""Measurement models of the survey vehicles' acoustic sensors, one module each.

A scenario's ``acoustic_sensor`` names one of ``SENSORS``; the survey simulator
builds it once (``build(sim)``) and calls its ``fuse(draws, out)`` every cycle after
the filters' prediction. Each model is a small compiled kernel over the batch built
from the shared pieces in ``core.navigation`` (the chi-square gate and the Joseph
update with the model's own residual, as filterpy's ``update(..., residual=...)``).

* ``modem``: acoustic-modem ranges, one-way or two-way travel time (Gao & Chitre;
  Sousa et al.), with lock-out recovery;
* ``mls_array``: Kottege & Zimmer's MLS array: range and bearing from one sender per
  cycle (the sensor's analytic mode, ``core.mls``).

A new sensor is one module with ``build(sim) -> object with fuse(draws, out) and
heard_mask(cycle)`` plus one line in ``SENSORS``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..contract import BatchSimulator

SENSORS = {"modem": "coopnav_env.core.measurements.modem", "mls": "coopnav_env.core.measurements.mls_array"}


class FusionOutputs(NamedTuple):
    """What a cycle's acoustic fusion reports, for the infos and the reward: flags per
    (B, N, S) fused / rejected by the gate / lost, and per (B, S) NaN readings and
    filter restarts. A named record, so the fusion kernels take it as one argument and
    write its arrays in place."""

    fused: np.ndarray
    rejected: np.ndarray
    lost: np.ndarray
    nan_count: np.ndarray
    restarts: np.ndarray


def build(name: str, sim: BatchSimulator):
    """The measurement model ``name`` (``SENSORS``) for simulator ``sim``."""
    import importlib

    if name not in SENSORS:
        raise ValueError(f"unknown acoustic_sensor {name!r}; valid: {', '.join(SENSORS)}")
    return importlib.import_module(SENSORS[name]).build(sim)
