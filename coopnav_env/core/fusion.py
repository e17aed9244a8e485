"""The end of a cycle: depth and GPS fused by every survey EKF, and the replies.

The acoustic measurements have their own models in ``core/measurements/``.

Compiled kernels written once over the batch (loops over environments, beacons
and survey vehicles). The formulas they apply have their homes elsewhere: the
EKF equations in navigation.py, sound speed, time of flight and packet loss in
acoustics.py; the random numbers come in as arrays.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .acoustics import packet_loss_probability
from .navigation import joseph_update


def _fuse_depth_gps(est, P, s_pos, sensor_n, sensor_u, nan_count, depth_noise_m, gps_noise_m,
                   gps_max_depth_m, nan_probability):
    """Depth sensor every cycle, GPS (east and north) when at the surface; NaNs rejected and counted."""
    B, S = est.shape[0], est.shape[1]
    R_depth = max(depth_noise_m, 1e-3) ** 2
    for b in prange(B):
        H = np.zeros(3)
        for s in range(S):
            z = s_pos[b, s, 2] + depth_noise_m * sensor_n[b, s, 0]
            if sensor_u[b, s, 0] < nan_probability:
                z = np.nan  # fault injection: a NaN must never enter the filter
            if np.isfinite(z):
                H[:] = 0.0
                H[2] = 1.0
                joseph_update(est[b, s], P[b, s], z, est[b, s, 2], H, R_depth)
            else:
                nan_count[b, s] += 1
            if s_pos[b, s, 2] < gps_max_depth_m:
                for axis in range(2):
                    z = s_pos[b, s, axis] + gps_noise_m * sensor_n[b, s, 1 + axis]
                    if sensor_u[b, s, 1 + axis] < nan_probability:
                        z = np.nan
                    if np.isfinite(z):
                        H[:] = 0.0
                        H[axis] = 1.0
                        joseph_update(est[b, s], P[b, s], z, est[b, s, axis], H, gps_noise_m ** 2)
                    else:
                        nan_count[b, s] += 1


# each kernel compiled twice from one source: plain, and threaded for large batches
fuse_depth_gps = njit(cache=True)(_fuse_depth_gps)
fuse_depth_gps_parallel = njit(cache=True, parallel=True)(_fuse_depth_gps)


def _exchange_messages(s_pos, s_est, s_P, s_wp_index, s_last_range_t_s, b_pos, b_est, t_s, message_u, reply_ok,
                       peer_ok, k_est, k_P, k_wp_index, k_age_s, k_range_age_s, k_peer, ping_interval_s, loss_near,
                       loss_far, max_range_m):
    """After the ranges: each survey vehicle's reply (estimate, covariance, waypoint
    index, time since its last fused range) reaches each beacon, or is lost with the
    range-dependent probability; beacons tell each other their positions the same
    way. Updates what each beacon knows (k_*), in place. ``reply_ok`` (B, N, S) and
    ``peer_ok`` (B, N, N) [receiver, sender] say what the acoustic channel delivered
    (``core/channel.py``; all True on the fixed clock, where only the random loss acts)."""
    B, N, S = b_pos.shape[0], b_pos.shape[1], s_pos.shape[1]
    for b in prange(B):
        for n in range(N):
            for s in range(S):
                d = np.sqrt((s_pos[b, s, 0] - b_pos[b, n, 0]) ** 2 + (s_pos[b, s, 1] - b_pos[b, n, 1]) ** 2
                            + (s_pos[b, s, 2] - b_pos[b, n, 2]) ** 2)
                if reply_ok[b, n, s] and message_u[b, n, s] >= packet_loss_probability(d, loss_near, loss_far,
                                                                                       max_range_m):
                    k_est[b, n, s, :] = s_est[b, s]
                    k_P[b, n, s, :, :] = s_P[b, s, :2, :2]
                    k_wp_index[b, n, s] = s_wp_index[b, s]
                    k_age_s[b, n, s] = 0.0
                    k_range_age_s[b, n, s] = t_s[b] - s_last_range_t_s[b, s]
                else:
                    k_age_s[b, n, s] += ping_interval_s
                    k_range_age_s[b, n, s] += ping_interval_s
            for m in range(N):
                if m == n:
                    k_peer[b, n, m, :] = b_est[b, m]
                    continue
                d = np.sqrt((b_pos[b, m, 0] - b_pos[b, n, 0]) ** 2 + (b_pos[b, m, 1] - b_pos[b, n, 1]) ** 2
                            + (b_pos[b, m, 2] - b_pos[b, n, 2]) ** 2)
                if peer_ok[b, n, m] and message_u[b, n, S + m] >= packet_loss_probability(d, loss_near, loss_far,
                                                                                          max_range_m):
                    k_peer[b, n, m, :] = b_est[b, m]


exchange_messages = njit(cache=True)(_exchange_messages)
exchange_messages_parallel = njit(cache=True, parallel=True)(_exchange_messages)
