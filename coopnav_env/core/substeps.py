"""The survey vehicles' sub-step loop: the one sequential part of a cycle.

Inside a cycle each survey vehicle steers by line-of-sight guidance on its own
estimate, which moves by dead reckoning, which depends on the heading just
steered: a feedback loop that cannot be vectorized over time. It is compiled
with numba and written once over the batch (loops over environments and
vehicles), so a batch of one costs microseconds instead of hundreds of numpy
calls. Every formula it uses has its home elsewhere: line of sight in
guidance.los_point, turning in dynamics.turn_toward; the random numbers, the
thrust-model speeds (eq. 1) and the current come in as arrays.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .dynamics import turn_toward
from .guidance import los_point


@njit(cache=True)
def integrate_survey(pos, est, dr, heading, wp_index, done, vel_true, vel_est,
                     waypoints, n_waypoints, hover, u_model, u_true, rot_meas, pitch_noise,
                     current, current_est, dt, alpha, acceptance_m, max_turn_rad, max_pitch_rad,
                     depth_gain_per_m):
    """Advance every survey vehicle through K sub-steps, in place.

    In/out: pos, est, dr (B,S,3) true, EKF and dead-reckoning positions;
    heading (B,S) complex unit; wp_index (B,S); done (B,S); vel_true, vel_est
    (B,S,3) written with the last sub-step's velocities.
    In: waypoints (B,S,W,3); n_waypoints, hover (B,S); u_model, u_true (B,S,K)
    modelled and true water speeds; rot_meas (B,K,S) complex compass error
    factor (bias + noise, bearing b -> b + d is exp(-1j d)); pitch_noise (B,K,S);
    current (B,) complex; current_est (B,S) complex (what the survey was told).
    """
    B, S, K = u_model.shape
    for b in range(B):
        for s in range(S):
            p = pos[b, s, 0] + 1j * pos[b, s, 1]
            pz = pos[b, s, 2]
            e = est[b, s, 0] + 1j * est[b, s, 1]
            ez = est[b, s, 2]
            r = dr[b, s, 0] + 1j * dr[b, s, 1]
            rz = dr[b, s, 2]
            h = heading[b, s]
            i = wp_index[b, s]
            steer = not (hover[b, s] or done[b, s])
            d_h = 0.0 + 0.0j
            d_z = 0.0
            ut = 0.0
            pitch = 0.0
            for k in range(K):
                w0 = waypoints[b, s, i - 1]
                w1 = waypoints[b, s, i]
                a = w0[0] + 1j * w0[1]
                q, along, seg_len = los_point(e, a, w1[0] + 1j * w1[1], alpha)
                if steer and along >= seg_len - acceptance_m:  # waypoint reached: next segment
                    i += 1
                    if i >= n_waypoints[b, s]:
                        done[b, s] = True
                        steer = False
                        i = n_waypoints[b, s] - 1
                    w0 = waypoints[b, s, i - 1]
                    w1 = waypoints[b, s, i]
                    a = w0[0] + 1j * w0[1]
                    q, along, seg_len = los_point(e, a, w1[0] + 1j * w1[1], alpha)
                if steer:
                    h = turn_toward(h, q - e, max_turn_rad)
                # depth: the planned depth along the segment, held by pitch
                frac = min(max(along, 0.0), seg_len) / seg_len if seg_len > 0.0 else 0.0
                depth_cmd = w0[2] + frac * (w1[2] - w0[2])
                pitch = min(max(depth_gain_per_m * (pz - depth_cmd), -max_pitch_rad), max_pitch_rad)
                # true motion: water-relative velocity plus current
                ut = u_true[b, s, k]
                p += (ut * np.cos(pitch) * h + current[b]) * dt
                pz -= ut * np.sin(pitch) * dt
                # dead reckoning, eq. (4): R(measured attitude) (u_model, 0, 0) tau
                pm = pitch + pitch_noise[b, k, s]
                um = u_model[b, s, k]
                d_h = (um * np.cos(pm) * dt) * (h * rot_meas[b, k, s])
                d_z = -um * np.sin(pm) * dt
                e += d_h + current_est[b, s] * dt  # told the current by a beacon (Gao II-A)
                ez += d_z
                r += d_h  # the dead-reckoning-only track is not
                rz += d_z
            pos[b, s, 0], pos[b, s, 1], pos[b, s, 2] = p.real, p.imag, pz
            est[b, s, 0], est[b, s, 1], est[b, s, 2] = e.real, e.imag, ez
            dr[b, s, 0], dr[b, s, 1], dr[b, s, 2] = r.real, r.imag, rz
            heading[b, s] = h
            wp_index[b, s] = i
            v = ut * np.cos(pitch) * h + current[b]
            vel_true[b, s, 0], vel_true[b, s, 1], vel_true[b, s, 2] = v.real, v.imag, -ut * np.sin(pitch)
            ve = d_h / dt + current_est[b, s]
            vel_est[b, s, 0], vel_est[b, s, 1], vel_est[b, s, 2] = ve.real, ve.imag, d_z / dt
