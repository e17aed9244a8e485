"""The end of a cycle: depth, GPS and acoustic ranges fused by every survey EKF.

Compiled kernels written once over the batch (loops over environments, beacons
and survey vehicles). The formulas they apply have their homes elsewhere: the
EKF equations in navigation.py, sound speed, time of flight and packet loss in
acoustics.py; the random numbers come in as arrays.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .acoustics import mackenzie_sound_speed, packet_loss_probability, ranging_variance_m2, travel_time
from .navigation import gated_update, joseph_update, range_prediction, reinit_on_range


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


@njit(cache=True)
def modem_range(s_pos, s_vel_true, b_pos, b_vel, c_true, c_assumed, jitter_s, n, two_way, turnaround_s, clock_s,
                delays):
    """The range a modem measures between a beacon and a survey vehicle (m), from the
    time of flight between the moving vehicles at the true sound speed, turned back
    into a range with the assumed one; ``delays`` gets the legs' times for the
    filter's prediction. ``jitter_s`` is sigma_t, one detection's timing jitter; ``n``
    a standard normal.

    One-way: the beacon transmits at t = 0; one detection at the survey, whose clock
    is off by ``clock_s``: r = c_assumed (tau + clock + sigma_t n).
    Two-way: the survey interrogates, the beacon replies after ``turnaround_s``; the
    beacon's and the survey's detections each add a jitter, so the round trip is late
    by sqrt(2) sigma_t n and r = c_assumed (t_rt - TAT) / 2 has variance
    (c sigma_t)^2 / 2 (``acoustics.ranging_variance_m2``).
    """
    if two_way:
        tau1 = travel_time(s_pos, b_pos, b_vel, c_true)
        lag = tau1 + turnaround_s
        tau2 = travel_time(b_pos + b_vel * lag, s_pos + s_vel_true * lag, s_vel_true, c_true)
        t_rt = lag + tau2 + jitter_s * np.sqrt(2.0) * n
        delays[0] = 0.0
        delays[1] = t_rt
        return 0.5 * c_assumed * (t_rt - turnaround_s)
    tau = travel_time(b_pos, s_pos, s_vel_true, c_true)
    r = c_assumed * (tau + clock_s + jitter_s * n)
    delays[0] = r / c_assumed
    return r


@njit(cache=True)
def modem_range_variance(detection_std_m, two_way, beacon_var_m2, predicted_range_m, sound_speed_rel_std):
    """R of a modem range (m^2): the ranging noise (``acoustics.ranging_variance_m2``),
    the beacon's own horizontal position variance (below Gao & Chitre eq. 7), and the
    sound speed's relative uncertainty as a scale error of the predicted range."""
    scale = predicted_range_m * sound_speed_rel_std
    return ranging_variance_m2(detection_std_m, two_way) + beacon_var_m2 + scale * scale


def _fuse_ranges(est, P, s_pos, s_vel_true, s_vel_est, b_pos, b_vel, b_est, b_var, temperature_c, t_s,
                clock_offset_s, clock_drift, acoustic_n, acoustic_u, current_sent, sends_current,
                current_est, last_range_t_s, rejected_streak, restarts, fused, rejected, lost, nan_count,
                reinit_after, two_way, turnaround_s, range_noise_std_m, max_range_m, loss_near, loss_far,
                outlier_probability, outlier_mean_excess_m, nan_probability, nominal_temperature_c,
                salinity_psu, temperature_uncertainty_c, gate, mls, mls_state, mls_range, mls_bearing,
                mls_range_var, mls_bearing_var):
    """Every beacon j pings every survey vehicle s; what arrives is gated and fused.

    The true range comes from the time of flight between the moving vehicles at the
    true sound speed; the vehicles convert it back with the speed they assume
    (nominal temperature). One-way: the beacon transmits its position; the
    survey's clock offset and drift enter the measured time. Two-way: the survey
    interrogates, the beacon replies after ``turnaround_s`` with its position.
    range_noise_std_m is per environment (B,) (domain randomization scales it): the
    per-detection jitter as range (``acoustics.ranging_variance_m2``: a two-way
    range has half its variance). R = that range variance + the beacon's own position variance (below Gao eq. 7) + the
    sound-speed uncertainty's share. Outputs (B,N,S) flags fused / rejected (gate)
    / lost and NaN counts (B,S); updates est, P, current_est, last_range_t_s.

    Lock-out recovery: after ``reinit_after`` (> 0) modem ranges in a row rejected by
    the gate with innovations of one sign, the filter restarts from the last one (``navigation.reinit_on_range``);
    ``restarts`` (B,S) counts it.

    With ``mls`` the measurements come in from the MLS sensor's analytic mode
    (core/mls/, run by the Simulator): mls_state (B,N,S) is 0 where beacon j did
    not send this cycle, 1 where it sent but was not heard, 2 where range
    ``mls_range`` and world bearing ``mls_bearing`` (clockwise from north, from the
    survey's compass plus the measured azimuth) are there with their variances; the
    range is fused as above, then the bearing (h = atan2(east, north) of beacon -
    survey; its own gate).
    """
    B, N, S = b_pos.shape[0], b_pos.shape[1], est.shape[1]
    for b in prange(B):
        delays = np.zeros(2 if two_way else 1)
        for s in range(S):
            any_fused = False
            for j in range(N):
                if mls:
                    if mls_state[b, j, s] == 0:
                        continue
                    if mls_state[b, j, s] == 1:
                        lost[b, j, s] = True
                        continue
                    delays[:] = 0.0
                    r = mls_range[b, j, s]
                    h, H = range_prediction(est[b, s], s_vel_est[b, s], delays, b_est[b, j])
                    R = mls_range_var[b, j, s] + b_var[b, j]
                    if gated_update(est[b, s], P[b, s], r, h, H, R, gate):
                        fused[b, j, s] = True
                        any_fused = True
                    else:
                        rejected[b, j, s] = True
                    de = b_est[b, j, 0] - est[b, s, 0]
                    dn = b_est[b, j, 1] - est[b, s, 1]
                    rho2 = max(de * de + dn * dn, 1e-6)
                    hb = np.arctan2(de, dn)
                    H[0] = -dn / rho2  # d bearing / d survey east
                    H[1] = de / rho2
                    H[2] = 0.0
                    R = mls_bearing_var[b, j, s] + b_var[b, j] / rho2
                    y = (mls_bearing[b, j, s] - hb + np.pi) % (2.0 * np.pi) - np.pi  # wrapped innovation
                    if gated_update(est[b, s], P[b, s], hb + y, hb, H, R, gate):
                        fused[b, j, s] = True
                        any_fused = True
                    else:
                        rejected[b, j, s] = True
                    continue
                depth = 0.5 * (s_pos[b, s, 2] + b_pos[b, j, 2])
                c_true = mackenzie_sound_speed(temperature_c[b], salinity_psu, depth)
                c_assumed = mackenzie_sound_speed(nominal_temperature_c, salinity_psu, depth)
                dc_dT = mackenzie_sound_speed(nominal_temperature_c + 1.0, salinity_psu, depth) - c_assumed
                jitter_s = range_noise_std_m[b] / c_assumed
                dx = s_pos[b, s, 0] - b_pos[b, j, 0]
                dy = s_pos[b, s, 1] - b_pos[b, j, 1]
                dz = s_pos[b, s, 2] - b_pos[b, j, 2]
                p_lost = packet_loss_probability(np.sqrt(dx * dx + dy * dy + dz * dz), loss_near, loss_far,
                                                 max_range_m)
                clock = clock_offset_s[b, s, j] + clock_drift[b, s, j] * t_s[b]
                r = modem_range(s_pos[b, s], s_vel_true[b, s], b_pos[b, j], b_vel[b, j], c_true, c_assumed, jitter_s,
                                acoustic_n[b, j, s, 0], two_way, turnaround_s, clock, delays)
                if two_way:
                    p_lost = 1.0 - (1.0 - p_lost) ** 2  # both legs must arrive
                u = acoustic_u[b, j, s]
                if u[0] < p_lost:
                    lost[b, j, s] = True
                    continue
                if u[1] < outlier_probability:  # multipath: a longer path arrives
                    r += -outlier_mean_excess_m * np.log(u[2])
                if u[3] < nan_probability:
                    r = np.nan
                if sends_current[j]:  # the ping carries the beacon's current estimate (Gao II-A)
                    current_est[b, s] = current_sent[b, j]
                if not np.isfinite(r):
                    nan_count[b, s] += 1
                    continue
                h, H = range_prediction(est[b, s], s_vel_est[b, s], delays, b_est[b, j])
                R = modem_range_variance(range_noise_std_m[b], two_way, b_var[b, j], h,
                                         temperature_uncertainty_c * dc_dT / c_assumed)
                if not gated_update(est[b, s], P[b, s], r, h, H, R, gate):
                    rejected[b, j, s] = True
                    # the streak counts rejected ranges in a row whose innovations share a sign (a
                    # filter that has drifted sees them all too long or all too short; multipath
                    # outliers are too long only, between fused ranges): +k or -k
                    sign = 1 if r > h else -1
                    streak = rejected_streak[b, s]
                    rejected_streak[b, s] = streak + sign if streak * sign >= 0 else sign
                    if (0 < reinit_after <= abs(rejected_streak[b, s])
                            and reinit_on_range(est[b, s], P[b, s], r, h, H, R)):
                        rejected_streak[b, s] = 0  # locked out: restarted from this range
                        restarts[b, s] += 1
                    continue
                rejected_streak[b, s] = 0
                fused[b, j, s] = True
                any_fused = True
            if any_fused:
                last_range_t_s[b, s] = t_s[b]


# each kernel compiled twice from one source: plain, and threaded for large batches
fuse_depth_gps = njit(cache=True)(_fuse_depth_gps)
fuse_depth_gps_parallel = njit(cache=True, parallel=True)(_fuse_depth_gps)
fuse_ranges = njit(cache=True)(_fuse_ranges)
fuse_ranges_parallel = njit(cache=True, parallel=True)(_fuse_ranges)


def _exchange_messages(s_pos, s_est, s_P, s_wp_index, s_last_range_t_s, b_pos, b_est, t_s, message_u,
                       k_est, k_P, k_wp_index, k_age_s, k_range_age_s, k_peer, ping_interval_s,
                       loss_near, loss_far, max_range_m):
    """After the ranges: each survey vehicle's reply (estimate, covariance, waypoint
    index, time since its last fused range) reaches each beacon, or is lost with the
    range-dependent probability; beacons tell each other their positions the same
    way. Updates what each beacon knows (k_*), in place."""
    B, N, S = b_pos.shape[0], b_pos.shape[1], s_pos.shape[1]
    for b in prange(B):
        for n in range(N):
            for s in range(S):
                d = np.sqrt((s_pos[b, s, 0] - b_pos[b, n, 0]) ** 2 + (s_pos[b, s, 1] - b_pos[b, n, 1]) ** 2
                            + (s_pos[b, s, 2] - b_pos[b, n, 2]) ** 2)
                if message_u[b, n, s] >= packet_loss_probability(d, loss_near, loss_far, max_range_m):
                    k_est[b, n, s, :] = s_est[b, s]
                    k_P[b, n, s, :, :] = s_P[b, s, :2, :2]
                    k_wp_index[b, n, s] = s_wp_index[b, s]
                    k_age_s[b, n, s] = 0.0
                    k_range_age_s[b, n, s] = t_s[b] - s_last_range_t_s[b, s]
                else:
                    k_age_s[b, n, s] += ping_interval_s
                    k_range_age_s[b, n, s] += ping_interval_s
            for m in range(N):
                d = np.sqrt((b_pos[b, m, 0] - b_pos[b, n, 0]) ** 2 + (b_pos[b, m, 1] - b_pos[b, n, 1]) ** 2
                            + (b_pos[b, m, 2] - b_pos[b, n, 2]) ** 2)
                if m == n or message_u[b, n, S + m] >= packet_loss_probability(d, loss_near, loss_far, max_range_m):
                    k_peer[b, n, m, :] = b_est[b, m]


exchange_messages = njit(cache=True)(_exchange_messages)
exchange_messages_parallel = njit(cache=True, parallel=True)(_exchange_messages)
