"""Step 3 of a cycle, its first part with ``frame_motion_telemetry``: the frame's own motion over
the cycle, telemetered by the boats, carried into the moving-frame EKF.

The paper's filter (section VII) predicts the vehicle in the frame with
dE/dt = (v cos(theta - phi) + c_x, v sin(theta - phi) + c_y, 0, 0, 0, 0): the frame's own
motion (B1's velocity, the frame's rotation, the baseline's stretch) is folded into the
constant "current" c and the random walks of Q. That holds for boats at constant velocity
(the paper's section VIII), not for boats that escort the vehicle down a winding river: they
change speed and turn by up to 1-3 deg/s, the frame-relative velocity then jumps by 1-2 m/s
within a cycle or two, faster than c can follow, and the range gate refuses the very ranges
that would correct it (issue 21: 28 of 100 held-out river runs above 20 m).

The boats know that motion: each has GPS (position and Doppler velocity). With the exchange
they telemeter, besides the bearing (``filter.update_phi``), the frame's motion over the cycle
that just ended, from their GPS velocities integrated over it: B1's displacement d = (d_x, d_y)
in the frame at the cycle's start, the rotation dphi (bearing, clockwise) and the baseline's
change dl. Writing a frame position as the complex z = x - i y (x along B1 -> B2, y 90 deg
clockwise; ``lbl.to_frame``), a point fixed in the world has z' = (z - (d_x - i d_y)) e^{i dphi}
in the frame at the cycle's end, so the filter's state moves by (eq. M1)

    x' = (x - d_x) cos(dphi) + (y - d_y) sin(dphi)
    y' = -(x - d_x) sin(dphi) + (y - d_y) cos(dphi)
    phi' = phi + dphi,   l' = l + dl,
    (c_x', c_y') = the same rotation of (c_x, c_y) (a world vector: the water's current),

so c is now the water current alone, in the frame. (For small dphi over dt: dx/dt = -v_B1,x +
dphi/dt y, dy/dt = -v_B1,y - dphi/dt x, the apparent motion of a point in a turning frame.) The
filter's covariance follows with the Jacobian of eq. M1 in the state, J (rotation blocks for
(x, y) and (c_x, c_y), 1 for phi and l) and in the telemetry's errors (eq. M2):

    P' = J P J^T + G Sigma_t G^T,

G = d(E') / d(d_x, d_y, dphi, dl). The telemetry's errors come from the boats' GPS velocity
errors dv_1, dv_2 (std ``boat_velocity_noise_mps`` per axis, held over the cycle of T s,
white between cycles): d's error is dv_1 T, dphi's (dv_2 - dv_1)_y T / l, dl's (dv_2 - dv_1)_x T
(the rotation rate is the boats' relative velocity across the baseline over its length, its
stretch the one along it), so (eq. M3)

    Sigma_t = sigma_v^2 T^2 [[1, 0, 0, -1], [0, 1, -1/l, 0], [0, -1/l, 2/l^2, 0], [-1, 0, 0, 2]]

in the order (d_x, d_y, dphi, dl). The legs of the ranges then see the vehicle move relative to
B1 at the model's velocity minus B1's, d / T in the new frame (``filter.fuse_ranges``' offset).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def telemetry_covariance(sigma_v_mps: float, T_s: float, length_m: float, out: np.ndarray) -> None:
    """Eq. M3: the covariance of the telemetered (d_x, d_y, dphi, dl) into out (4, 4), from the
    boats' GPS velocity errors of std sigma_v_mps per axis held over a cycle of T_s, the baseline
    length_m."""
    s2 = sigma_v_mps * sigma_v_mps * T_s * T_s
    inv_l = 1.0 / max(length_m, 1e-9)
    out[:, :] = 0.0
    out[0, 0], out[1, 1] = s2, s2
    out[2, 2], out[3, 3] = 2.0 * s2 * inv_l * inv_l, 2.0 * s2
    out[0, 3] = out[3, 0] = -s2
    out[1, 2] = out[2, 1] = -s2 * inv_l


@njit(cache=True)
def move_frame(E: np.ndarray, P: np.ndarray, motion: np.ndarray, Sigma_t: np.ndarray) -> tuple:
    """Eqs. M1-M2 for one filter (E (6,) = (x, y, phi, c_x, c_y, l), P (6,6)), in place:
    the frame moved by motion (4,) = (d_x, d_y, dphi, dl) (d in the frame at the cycle's
    start), the telemetry's covariance Sigma_t (4,4) (``telemetry_covariance``). Returns B1's
    displacement in the new frame (the same rotation applied to d), for the legs' velocity."""
    dx, dy, dphi, dl = motion[0], motion[1], motion[2], motion[3]
    cs, sn = np.cos(dphi), np.sin(dphi)
    a, b = E[0] - dx, E[1] - dy
    x_new, y_new = a * cs + b * sn, -a * sn + b * cs
    cx, cy = E[3], E[4]
    cx_new, cy_new = cx * cs + cy * sn, -cx * sn + cy * cs
    J = np.eye(6)
    J[0, 0], J[0, 1], J[1, 0], J[1, 1] = cs, sn, -sn, cs
    J[3, 3], J[3, 4], J[4, 3], J[4, 4] = cs, sn, -sn, cs
    G = np.zeros((6, 4))
    G[0, 0], G[0, 1], G[1, 0], G[1, 1] = -cs, -sn, sn, -cs  # d(x', y') / d(d_x, d_y)
    G[0, 2], G[1, 2] = y_new, -x_new  # d(x', y') / d(dphi)
    G[3, 2], G[4, 2] = cy_new, -cx_new
    G[2, 2], G[5, 3] = 1.0, 1.0
    E[0], E[1], E[2], E[3], E[4], E[5] = x_new, y_new, E[2] + dphi, cx_new, cy_new, E[5] + dl
    P[:, :] = J @ P @ J.T + G @ Sigma_t @ G.T
    return dx * cs + dy * sn, -dx * sn + dy * cs
