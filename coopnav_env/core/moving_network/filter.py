"""Step 3 of a cycle, the vehicle's side: the moving-frame EKF's range updates (section VII).

The filter's state is E = (x, y, phi, c_x, c_y, l) in the frame of the boats
(``navigation.FRAME_STATE``); its prediction runs in the sub-steps
(``vehicle.integrate_vehicle``). Here it fuses the exchange's ranges: d1 when S2
arrives, then d2 and l when S5 arrives. d2 and l arrive together and share
detection errors: with sigma_t per detection and sigma_r^2 = (c sigma_t)^2 / 2 the
variance of a two-way range, d1 = c(e1 + e2)/2, d2 = c(e5 + e6)/2 and
l = m - d1 - d2 with m = c(e1 + e3 + e4) give var(d1) = var(d2) = sigma_r^2,
var(l) = 6 sigma_r^2, cov(d2, l) = -sigma_r^2 and cov(d1, l) = 0 (e_i: the
detections in ``lbl.DETECTIONS`` order; ``EXCHANGE_COVARIANCE``). So d1 is a scalar
update and (d2, l) one joint update with that R (d2 alone when l is missing);
treating them as independent, as a naive sequential filter would, overweights l.

**The telemetered bearing** (``frame_bearing_fusion``; not in the paper, whose filter infers
phi from the ranges and the compass alone). The boats have GPS and already telemeter B1's
position and the bearing of B2 from it (a world mission needs them to re-express its
waypoints); fused as a measurement of phi it makes phi observable every cycle rather than
through the slow coupling of phi into the dead-reckoned velocity, which a river frame that
turns defeats (issue 21: phi errors of 20-80 deg and velocity errors of 1-3 m/s before the
river runs diverged). With white GPS errors of std sigma_g per axis at B1 and B2, the
bearing's error is the component of (e_2 - e_1) across the baseline over l:

    z_phi = phi + n,   var(n) = 2 sigma_g^2 / l^2                                  (eq. B1)

(sigma_g = 2.1 m, l = 100 m: 1.70 deg), H = (0, 0, 1, 0, 0, 0); the innovation z - phi_hat
is wrapped to (-pi, pi]. Not gated: the GPS fix has no outliers in this model, and a filter
whose phi has drifted is exactly the one that must take it. The compass bias stays out
of the model as in the paper's filter: phi_hat now follows the GPS bearing, not the
compass frame's, and the bias's constant velocity error (v sin b) goes to (c_x, c_y).

Each update is the shared chi-square gate and Joseph update with the model's own
residual (``navigation.joseph_update_vector``, eqs. 9-13 for an m-vector), on the
shared range model with the legs' delays (``navigation.frame_range_prediction``).
The survey filter's scalar ``gated_update_residual`` is written for its 3-state
filter, so the 6-state frame filter uses the general kernel.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from ..acoustics import ranging_variance_m2
from ..lbl import ExchangeResult
from ..navigation import (
    frame_range_prediction,
    frame_velocity_of,
    joseph_update_vector,
    joseph_work,
)
from .state import CycleParams

# the noise covariance of (d1, d2, l) in units of a two-way range's variance sigma_r^2 (see the module
# docstring); tests/test_noise.py checks it against Monte Carlo exchanges
EXCHANGE_COVARIANCE = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, -1.0], [0.0, -1.0, 6.0]])


def exchange_covariance_m2(detection_std_m: float) -> np.ndarray:
    """The covariance of the exchange's (d1, d2, l) for a per-detection jitter as range."""
    return ranging_variance_m2(detection_std_m, True) * EXCHANGE_COVARIANCE


class FilterWork(NamedTuple):
    """Scratch of one filter's updates: leg delays (2,), H (2,6), innovation y (2,), R (2,2),
    and ``navigation.joseph_work(6, 2)``."""

    delays: np.ndarray
    H: np.ndarray
    y: np.ndarray
    R: np.ndarray
    joseph: tuple


@njit(cache=True)
def filter_work() -> FilterWork:
    """A fresh ``FilterWork``."""
    return FilterWork(np.empty(2), np.empty((2, 6)), np.empty(2), np.empty((2, 2)), joseph_work(6, 2))


@njit(cache=True)
def bearing_variance_rad2(gps_noise_m: float, length_m: float) -> float:
    """Eq. B1: the variance of the bearing of B2's GPS position from B1's, 2 sigma_g^2 / l^2."""
    return 2.0 * gps_noise_m * gps_noise_m / max(length_m * length_m, 1e-12)


@njit(cache=True)
def update_phi(E: np.ndarray, P: np.ndarray, phi_meas_rad: float, var_rad2: float, w: FilterWork) -> None:
    """Fuse the telemetered frame bearing into one filter (E (6,), P (6,6)), in place (eq. B1):
    H = (0, 0, 1, 0, 0, 0), innovation z - phi_hat wrapped to (-pi, pi], R = var_rad2; no gate."""
    y = phi_meas_rad - E[2]
    w.y[0] = y - 2.0 * np.pi * np.floor((y + np.pi) / (2.0 * np.pi))
    w.H[0, :] = 0.0
    w.H[0, 2] = 1.0
    w.R[0, 0] = var_rad2
    joseph_update_vector(E, P, w.y[:1], w.H[:1], w.R[:1, :1], np.inf, w.joseph)


@njit(cache=True)
def update_d1(
    E: np.ndarray,
    P: np.ndarray,
    ex: ExchangeResult,
    dz: float,
    velocity: tuple,
    sigma_r2: float,
    gate: float,
    w: FilterWork,
) -> bool:
    """Fuse d1 into one filter (E (6,), P (6,6)), in place: the legs are S1 leaving (t = 0)
    and S2 arriving (t3); dz the depth below the boats, velocity the frame-relative
    (v_x, v_y). Returns whether it passed the gate."""
    vx, vy = velocity
    w.delays[0], w.delays[1] = 0.0, ex.t3
    h = frame_range_prediction(E, 1, dz, vx, vy, w.delays, w.H[0])
    w.y[0] = ex.d1 - h
    w.R[0, 0] = sigma_r2
    _, status = joseph_update_vector(E, P, w.y[:1], w.H[:1], w.R[:1, :1], gate, w.joseph)
    return status == 1


@njit(cache=True)
def update_d2_l(
    E: np.ndarray,
    P: np.ndarray,
    ex: ExchangeResult,
    dz: float,
    velocity: tuple,
    sigma_r2: float,
    gate1: float,
    gate2: float,
    w: FilterWork,
    with_l: bool,
) -> tuple:
    """Fuse d2 (legs: S4 leaving at t3s, S5 arriving at t6) with l when ``with_l`` (one
    joint update, R = sigma_r2 ``EXCHANGE_COVARIANCE[1:, 1:]``), else d2 alone, in place.
    Returns (fused, fused jointly with l)."""
    vx, vy = velocity
    w.delays[0], w.delays[1] = ex.t3s, ex.t6
    h2 = frame_range_prediction(E, 2, dz, vx, vy, w.delays, w.H[0])
    w.y[0] = ex.d2 - h2
    if not with_l:
        w.R[0, 0] = sigma_r2
        _, status = joseph_update_vector(E, P, w.y[:1], w.H[:1], w.R[:1, :1], gate1, w.joseph)
        return status == 1, False
    H, R, C = w.H, w.R, EXCHANGE_COVARIANCE
    w.y[1] = ex.l - E[5]
    H[1, :] = 0.0
    H[1, 5] = 1.0
    R[0, 0], R[0, 1], R[1, 0], R[1, 1] = (
        sigma_r2 * C[1, 1],
        sigma_r2 * C[1, 2],
        sigma_r2 * C[2, 1],
        sigma_r2 * C[2, 2],
    )
    _, status = joseph_update_vector(E, P, w.y, H, R, gate2, w.joseph)
    return status == 1, status == 1


@njit(cache=True)
def _relative(E: np.ndarray, speed_meas: float, heading_meas: float, b1_velocity: tuple) -> tuple:
    """The vehicle's velocity relative to B1 in the frame: the model's minus B1's."""
    vx, vy = frame_velocity_of(E, speed_meas, heading_meas)
    return vx - b1_velocity[0], vy - b1_velocity[1]


@njit(cache=True)
def fuse_ranges(
    E: np.ndarray,
    P: np.ndarray,
    ex: ExchangeResult,
    dz: float,
    speed_meas: float,
    heading_meas: float,
    sigma_r2: float,
    p: CycleParams,
    w: FilterWork,
    status: np.ndarray,
    b1_velocity: tuple,
) -> tuple:
    """The cycle's updates of one filter (E (6,), P (6,6)) with the exchange ``ex``
    (``lbl.ExchangeResult``), in place: d1, then (d2, l) jointly or d2 alone, each gated
    (``state.CycleParams`` p: gate1, gate2); sigma_r2 the variance of a two-way range
    (``acoustics.ranging_variance_m2``). The frame-relative velocity for the legs is
    the model's (``frame_velocity_of``) with the last encoder and compass readings, minus
    b1_velocity (v_x, v_y), B1's velocity in the frame: (0, 0) for the paper's filter, whose c
    holds it; the telemetered one with ``frame_motion_telemetry`` (``frame_motion``).

    Each range is checked against the others where they share detections: l = m - d1 - d2
    carries d1's detections (S1@B1, S2@vehicle) with the opposite sign, so a d1 the gate
    refused makes l suspect, and d2 is then fused alone; a joint (d2, l) update the gate
    refuses is retried with d2 alone, since a multipath excess on the path m (S2@B2,
    S3@vehicle) spoils l only. status (3, 2) bool, written: per range (d1, d2, l),
    (arrived, fused) (``recovery.recover``'s per-range counters). Returns (ranges fused,
    measurements rejected by the gate or set aside as suspect)."""
    fused_d1 = False
    if ex.ok_d1:
        fused_d1 = update_d1(E, P, ex, dz, _relative(E, speed_meas, heading_meas, b1_velocity), sigma_r2, p.gate1, w)
    suspect_l = ex.ok_d1 and not fused_d1
    fused_d2, fused_l = False, False
    if ex.ok_l and not suspect_l:
        fused_d2, fused_l = update_d2_l(
            E, P, ex, dz, _relative(E, speed_meas, heading_meas, b1_velocity), sigma_r2, p.gate1, p.gate2, w, True
        )
    if ex.ok_d2 and not fused_d2:
        fused_d2, _ = update_d2_l(
            E, P, ex, dz, _relative(E, speed_meas, heading_meas, b1_velocity), sigma_r2, p.gate1, p.gate2, w, False
        )
    status[0, 0], status[0, 1] = ex.ok_d1, fused_d1
    status[1, 0], status[1, 1] = ex.ok_d2, fused_d2
    status[2, 0], status[2, 1] = ex.ok_l and not suspect_l, fused_l
    n_fused = int(fused_d1) + int(fused_d2) + int(fused_l)
    rejected = int(ex.ok_d1 and not fused_d1) + int(ex.ok_d2 and not fused_d2) + int(ex.ok_l and not fused_l)
    return n_fused, rejected
