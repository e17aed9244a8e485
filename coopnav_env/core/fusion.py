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
from .consider import carry_cross_covariance
from .jit import parallel_twin
from .navigation import joseph_update


@njit(cache=True, inline="always")
def _axis_update(x, P, Pxb, Pxd, z, axis, R, H, K):
    """A direct measurement z of state axis ``axis`` (depth: 2, GPS: 0 and 1) with
    variance R fused into one filter (eqs. 9-13), in place, and every beacon's
    cross-covariance Pxb (N, 3, 2) carried through it (eq. C6, with K = P H^T / S before
    the update), and so is the cross-covariance with the survey's own dead-reckoning biases
    Pxd (3, 2) (eq. D3). H, K: scratch (3,)."""
    H[:] = 0.0
    H[axis] = 1.0
    S = P[axis, axis] + R
    for i in range(3):
        K[i] = P[i, axis] / S
    joseph_update(x, P, z, x[axis], H, R)
    for j in range(Pxb.shape[0]):
        carry_cross_covariance(Pxb[j], K, H)
    carry_cross_covariance(Pxd, K, H)


def _fuse_depth_gps(sv, Pxb, Pxd, sensor_n, sensor_u, nan_count, prm):
    """Depth sensor every cycle, GPS (east and north) when at the surface; NaNs rejected
    and counted. Updates sv.est, sv.P (``kernel_records.SurveyView``), the consider
    states' cross-covariances Pxb (B,S,N,3,2) and Pxd (B,S,3,2) (dr_bias.py) and nan_count (B,S) in place; sensor_n,
    sensor_u (B,S,3) this cycle's draws; prm: ``kernel_records.SurveyParams``."""
    est, P, s_pos = sv.est, sv.P, sv.pos
    depth_noise_m, gps_noise_m, nan_probability = prm.depth_noise_m, prm.gps_noise_m, prm.nan_probability
    B, S = est.shape[0], est.shape[1]
    R_depth = max(depth_noise_m, 1e-3) ** 2
    for b in prange(B):
        H, K = np.zeros(3), np.zeros(3)
        for s in range(S):
            z = s_pos[b, s, 2] + depth_noise_m * sensor_n[b, s, 0]
            if sensor_u[b, s, 0] < nan_probability:
                z = np.nan  # fault injection: a NaN must never enter the filter
            if np.isfinite(z):
                _axis_update(est[b, s], P[b, s], Pxb[b, s], Pxd[b, s], z, 2, R_depth, H, K)
            else:
                nan_count[b, s] += 1
            if s_pos[b, s, 2] < prm.gps_max_depth_m:
                for axis in range(2):
                    z = s_pos[b, s, axis] + gps_noise_m * sensor_n[b, s, 1 + axis]
                    if sensor_u[b, s, 1 + axis] < nan_probability:
                        z = np.nan
                    if np.isfinite(z):
                        _axis_update(est[b, s], P[b, s], Pxb[b, s], Pxd[b, s], z, axis, gps_noise_m**2, H, K)
                    else:
                        nan_count[b, s] += 1


# each kernel compiled twice from one source: plain, and threaded for large batches
fuse_depth_gps = njit(cache=True)(_fuse_depth_gps)
fuse_depth_gps_parallel = parallel_twin(_fuse_depth_gps)


@njit(cache=True, inline="always")
def _distance(x, y):
    """Euclidean distance of two 3-vectors, summed east, north, depth (in that order)."""
    return np.sqrt((x[0] - y[0]) ** 2 + (x[1] - y[1]) ** 2 + (x[2] - y[2]) ** 2)


@njit(cache=True, inline="always")
def _arrives(d, u, prm):
    """A packet over distance d arrives if its uniform draw u beats the range-dependent loss."""
    return u >= packet_loss_probability(d, prm.loss_near, prm.loss_far, prm.max_range_m)


def _exchange_messages(sv, bv, kv, t_s, message_u, reply_ok, peer_ok, prm):
    """After the ranges: each survey vehicle's reply (estimate, covariance, waypoint
    index, time since its last fused range) reaches each beacon, or is lost with the
    range-dependent probability; beacons tell each other their positions the same
    way. Updates what each beacon knows (kv, ``kernel_records.KnowledgeView``), in place.
    sv, bv: ``kernel_records.SurveyView``, ``kernel_records.BeaconView``; t_s (B,); message_u
    (B, N, S + N) this cycle's uniforms; ``reply_ok`` (B, N, S) and ``peer_ok`` (B, N, N)
    [receiver, sender] say what the acoustic channel delivered (``core/channel.py``;
    all True on the fixed clock, where only the random loss acts); prm:
    ``kernel_records.SurveyParams``."""
    B, N, S = bv.pos.shape[0], bv.pos.shape[1], sv.pos.shape[1]
    T = prm.ping_interval_s
    for b in prange(B):
        for n in range(N):
            for s in range(S):
                d = _distance(sv.pos[b, s], bv.pos[b, n])
                if reply_ok[b, n, s] and _arrives(d, message_u[b, n, s], prm):
                    kv.est[b, n, s, :] = sv.est[b, s]
                    kv.P[b, n, s, :, :] = sv.P[b, s, :2, :2]
                    kv.wp_index[b, n, s] = sv.wp_index[b, s]
                    kv.age_s[b, n, s] = 0.0
                    kv.range_age_s[b, n, s] = t_s[b] - sv.last_range_t_s[b, s]
                else:
                    kv.age_s[b, n, s] += T
                    kv.range_age_s[b, n, s] += T
            for m in range(N):  # its own position, or a peer's if it arrives
                if m == n or (
                    peer_ok[b, n, m] and _arrives(_distance(bv.pos[b, m], bv.pos[b, n]), message_u[b, n, S + m], prm)
                ):
                    kv.peer[b, n, m, :] = bv.est[b, m]


exchange_messages = njit(cache=True)(_exchange_messages)
exchange_messages_parallel = parallel_twin(_exchange_messages)
