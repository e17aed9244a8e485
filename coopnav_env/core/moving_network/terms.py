"""Step 5 of a cycle: the reward's terms and the infos, in the true frame.

The reward (assembled in ``MovingNetworkSimulator.step``) is the information the
vehicle's filter gained this cycle (log det of its (x, y) covariance before minus
after), shared by the boats, minus penalties: a boat within ``safety_distance_m``
of the vehicle (``safety``, per boat); the baseline off its target by more than
``baseline_tolerance_m`` (``baseline``); the vehicle nearer the baseline than
``min_baseline_distance_m`` (``approach``); the frame turned more than
``frame_rotation_tolerance_deg`` from its start (``rotation``, computed by numpy in
the step: the filter models phi as constant, a turning frame makes it confidently
wrong, which the information term alone would reward); no range fused this cycle
(``contact``). ``cycle_terms`` writes the kernel's part per environment into a
``state.CYCLE_OUT`` record; ``step_info`` turns the records into the step's infos.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .. import lbl
from ..information import ELLIPSE_N_SIGMA, ellipse_of
from .exchange import _dist3
from .state import Boats, CycleParams, Filter, Vehicle


@njit(cache=True)
def _one(flag: bool) -> float:
    """A flag as numpy multiplies it (bool -> 1.0 or 0.0)."""
    return 1.0 if flag else 0.0


@njit(cache=True)
def cycle_terms(o: np.record, b: int, vehicle: Vehicle, boats: Boats, f: Filter, p: CycleParams, n_fused: int) -> None:
    """Environment b's unweighted penalty terms (0/1) and its errors, in the true frame,
    into the ``state.CYCLE_OUT`` record o: ``state.Vehicle`` vehicle, ``state.Boats``
    boats, ``state.Filter`` f (after the updates), ``state.CycleParams`` p, n_fused the
    ranges fused this cycle."""
    v3 = vehicle.pos[b, 0]
    ve, vn = v3[0], v3[1]
    phi, length, E = boats.phi[b], boats.length[b], f.E[b]
    x, yv = lbl.to_frame(ve - boats.pos[b, 0, 0], vn - boats.pos[b, 0, 1], np.sin(phi), np.cos(phi))
    o.baseline_off = _one(abs(length - p.baseline_target_m) > p.baseline_tolerance_m)
    o.approach = _one(yv < p.min_baseline_distance_m)
    for i in range(2):
        o.safety[i] = _one(_dist3(boats.pos[b, i], v3) < p.safety_distance_m)
    o.contact = _one(n_fused == 0)
    ex_, ey_ = E[0] - x, E[1] - yv
    o.survey_error = np.hypot(ex_, ey_)
    de, dn = vehicle.dr[b, 0, 0] - ve, vehicle.dr[b, 0, 1] - vn
    o.dr_error = np.sqrt(de * de + dn * dn)
    o.error_x, o.error_y = ex_, ey_
    rel = E[2] - phi  # wrapped by the caller (numpy's arctan2)
    o.phi_err_sin, o.phi_err_cos = np.sin(rel), np.cos(rel)
    o.baseline_error = E[5] - length
    P = f.P[b]
    o.major, o.minor, _ = ellipse_of(P[0, 0], P[0, 1], P[1, 1], ELLIPSE_N_SIGMA)
    o.vehicle_y = yv


def step_info(out: np.ndarray, counts: np.ndarray, logdet: np.ndarray, P: np.ndarray) -> dict:
    """The step's infos (``FRAME_INFO_KEYS``), (B, S=1) each, from the kernel's records
    ``out`` (``state.CYCLE_OUT``) and ``counts`` (``state.CYCLE_COUNTS``), the log
    determinants before and after (B, 2) and the filter's covariance P (B,6,6)."""
    col = lambda name: out[name][:, None]  # (B,) -> (B, S=1) views
    count = lambda name: counts[name][:, None]
    return {
        "survey_error_m": col("survey_error"),
        "dr_error_m": col("dr_error"),
        "cov_logdet": logdet[:, 1:2],
        "range_ok": count("range_ok"),
        "ranges_fused": count("ranges_fused"),
        "outliers_rejected": count("outliers_rejected"),
        "nan_rejected": np.zeros((out.shape[0], 1), dtype=np.int64),
        "packets_lost": count("packets_lost"),
        "filter_restarts": count("filter_restarts"),
        "survey_error_en_m": np.stack([col("error_x"), col("error_y")], -1),
        "survey_cov_en_m2": P[:, None, :2, :2].copy(),
        "error_x_m": col("error_x"),
        "error_y_m": col("error_y"),
        "phi_error_deg": np.degrees(np.arctan2(out["phi_err_sin"], out["phi_err_cos"]))[:, None],
        "baseline_error_m": col("baseline_error"),
        "ellipse_major_m": col("major"),
        "ellipse_minor_m": col("minor"),
        "vehicle_y_m": col("vehicle_y"),
    }
