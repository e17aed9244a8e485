"""Information and uncertainty geometry: one home for the Fisher information
matrix, its determinant, the log-determinant of a covariance and the error
ellipse. The reward, the observations, the planners and the plots all call these.
"""

from __future__ import annotations

import numpy as np


def fisher_information(target, beacons, range_std_m, horizontal=True):
    """Fisher information matrix of range-only measurements of ``target``.

    J = sum_i u_i u_i^T / sigma_i^2 with u_i the unit vector from beacon i to the
    target (Sousa, Ferreira & Cruz eq. 4). target: (..., 3); beacons: (..., M, 3);
    range_std_m broadcasts to (..., M). With ``horizontal`` the 2x2 east/north block
    of the 3-D slant geometry is returned (the vehicle's depth is known from its
    depth sensor), else the full 3x3.
    """
    rel = target[..., None, :] - beacons
    u = rel / np.maximum(np.linalg.norm(rel, axis=-1, keepdims=True), 1e-9)
    if horizontal:
        u = u[..., :2]
    w = 1.0 / np.broadcast_to(np.asarray(range_std_m, dtype=float), u.shape[:-1]) ** 2
    return np.einsum("...m,...mi,...mj->...ij", w, u, u)


def det2(M):
    """Determinant of symmetric 2x2 matrices (..., 2, 2)."""
    return M[..., 0, 0] * M[..., 1, 1] - M[..., 0, 1] * M[..., 1, 0]


def logdet_horizontal(P):
    """log det of the east/north block of covariances (..., n, n), n >= 2."""
    return np.log(np.maximum(det2(P[..., :2, :2]), 1e-300))


def error_ellipse(P, n_sigma=2.0):
    """Semi-axes and orientation of the horizontal error ellipse of covariances P.

    Returns (major_m, minor_m, bearing_rad): the n-sigma semi-axes and the bearing
    (clockwise from north, in [0, pi)) of the major axis. Closed-form 2x2 eigen-
    decomposition, so it vectorizes over any leading axes.
    """
    a, b, c = P[..., 0, 0], P[..., 0, 1], P[..., 1, 1]  # var east, cov, var north
    mean = 0.5 * (a + c)
    rad = np.sqrt(0.25 * (a - c) ** 2 + b * b)
    lam1, lam2 = mean + rad, np.maximum(mean - rad, 0.0)
    theta_east = 0.5 * np.arctan2(2 * b, a - c)  # angle of the major axis from east, anticlockwise
    bearing = np.mod(np.pi / 2 - theta_east, np.pi)
    return n_sigma * np.sqrt(lam1), n_sigma * np.sqrt(lam2), bearing
