"""The survey vehicle's extended Kalman filter (Gao & Chitre eqs. 4-13), over the batch.

State: position (east, north, depth) in metres, shape (..., 3); covariance
(..., 3, 3). Every function takes any number of leading batch axes and a
boolean ``mask`` choosing the rows a measurement is applied to, so one call
updates a whole batch with no Python loop over it. The covariance update is the
Joseph form, which keeps P symmetric positive definite under round-off (and is
what filterpy's ExtendedKalmanFilter does, which the tests compare against).
"""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2

_EYE3 = np.eye(3)


def predict(x, P, dx, Q):
    """Eq. (4) and (6): x <- x + R v tau (given as ``dx``); P <- P + Q (F = I)."""
    return x + dx, P + Q


def range_model(x, velocity, delays_s, beacon):
    """Predicted range and its Jacobian (eq. 7-8), with motion during the sound's flight.

    The filter's state is the position at the cycle's reference time; leg l of the
    measured range ends at x + velocity * delays_s[l] (the vehicle moves while sound
    travels). h = mean over legs of |x + v d_l - b|, H = mean of the unit vectors.
    x, velocity, beacon: (..., 3); delays_s: (..., L). With one leg of zero delay
    this is exactly eq. (7)-(8).
    """
    rel = x[..., None, :] + velocity[..., None, :] * delays_s[..., :, None] - beacon[..., None, :]
    dist = np.linalg.norm(rel, axis=-1)
    unit = rel / np.maximum(dist, 1e-9)[..., None]
    return dist.mean(-1), unit.mean(-2)


def scalar_update(x, P, z, h, H, R, mask):
    """Eqs. (9)-(13) for one scalar measurement, Joseph-form covariance.

    z, h, R: (...); H: (..., 3); mask: (...) bool. Returns x, P, innovation y and
    its variance S (eq. 11). Rows where mask is False are returned unchanged.
    """
    y = z - h  # eq. (10)
    PHt = np.einsum("...ij,...j->...i", P, H)
    S = np.einsum("...i,...i->...", H, PHt) + R  # eq. (11)
    K = PHt / S[..., None]  # eq. (12)
    x_new = x + K * y[..., None]  # eq. (9)
    A = _EYE3 - K[..., :, None] * H[..., None, :]  # I - K H
    P_new = A @ P @ np.swapaxes(A, -1, -2) + (R[..., None, None] * K[..., :, None] * K[..., None, :])  # eq. (13), Joseph
    m = mask[..., None]
    return np.where(m, x_new, x), np.where(m[..., None], P_new, P), y, S


def gate_threshold(probability: float, dof: int = 1) -> float:
    """Chi-square gate on the normalized innovation squared y^2 / S."""
    return float(chi2.ppf(probability, dof))


def axis_measurement(axis: int, shape):
    """H for a direct measurement of one state axis (depth sensor: 2; GPS: 0 and 1)."""
    H = np.zeros(tuple(shape) + (3,))
    H[..., axis] = 1.0
    return H
