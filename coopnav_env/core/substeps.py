"""The sub-step loops of a cycle: survey vehicles and beacons.

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
from numba import njit, prange

from .dynamics import thrust_speed, turn_toward
from .guidance import los_point
from .jit import parallel_twin


@njit(cache=True, inline="always")
def _leg(waypoints, i, e, alpha):
    """Leg i (waypoint i-1 -> i) of one path (W, 3) seen from the estimate e (complex):
    its ends' depths, the line-of-sight point, the distance along it and its length
    (scalars: a row view would cost a reference count per sub-step)."""
    q, along, seg_len = los_point(
        e,
        waypoints[i - 1, 0] + 1j * waypoints[i - 1, 1],
        waypoints[i, 0] + 1j * waypoints[i, 1],
        alpha,
    )
    return waypoints[i - 1, 2], waypoints[i, 2], q, along, seg_len


@njit(cache=True, inline="always")
def _guide(waypoints, n_waypoints, i, steer, e, h, prm):
    """One sub-step of line-of-sight guidance on the estimate e of a vehicle following
    ``waypoints`` (W, 3; the first ``n_waypoints`` used): the next leg once the waypoint
    is reached, the heading h turned toward the line-of-sight point within the turn
    limit, and the depth planned at this point of the leg. Returns (i, steer, h,
    depth_cmd, whether the path ended now). It takes the vehicle's row, not the record:
    numba counts a reference to every array of a record at each call (docs/performance.md#refcounts)."""
    ended = False
    z0, z1, q, along, seg_len = _leg(waypoints, i, e, prm.los_alpha)
    if steer and along >= seg_len - prm.acceptance_m:  # waypoint reached: next segment
        i += 1
        if i >= n_waypoints:
            ended = True
            steer = False
            i = n_waypoints - 1
        z0, z1, q, along, seg_len = _leg(waypoints, i, e, prm.los_alpha)
    if steer:
        h = turn_toward(h, q - e, prm.turn_cos, prm.turn_sin)
    # depth: the planned depth along the segment, held by pitch
    frac = min(max(along, 0.0), seg_len) / seg_len if seg_len > 0.0 else 0.0
    return i, steer, h, z0 + frac * (z1 - z0), ended


def _integrate_survey(sv, compass_noise_rad, pitch_noise_rad, current, prm):
    """Advance every survey vehicle through K sub-steps, in place.

    sv (``kernel_records.SurveyView``): in/out pos, est, dr (B,S,3) true, EKF and
    dead-reckoning positions; heading (B,S) complex unit; wp_index, done (B,S);
    vel_true, vel_est (B,S,3) written with the last sub-step's velocities; speed_model
    (B,S) the water speed of eq. (1) (the vehicle's model; the truth is speed_scale
    times it). In: waypoints, n_waypoints, hover, thrust_n, speed_scale,
    compass_bias_rad, current_est (what the survey was told, complex).
    compass_noise_rad, pitch_noise_rad (B,K,S): the sub-steps' measurement noise;
    current (B,) complex: the true water current; prm: ``kernel_records.SurveyParams``.
    The vehicle's loop is written here, not in a helper taking the record: numba counts
    a reference to every array of a record at each call (docs/performance.md#refcounts).
    """
    B, S = compass_noise_rad.shape[0], compass_noise_rad.shape[2]
    dt = prm.substep_s
    for b in prange(B):
        for s in range(S):
            p = sv.pos[b, s, 0] + 1j * sv.pos[b, s, 1]
            pz = sv.pos[b, s, 2]
            e = sv.est[b, s, 0] + 1j * sv.est[b, s, 1]
            ez = sv.est[b, s, 2]
            r = sv.dr[b, s, 0] + 1j * sv.dr[b, s, 1]
            rz = sv.dr[b, s, 2]
            h = sv.heading[b, s]
            i = sv.wp_index[b, s]
            steer = not (sv.hover[b, s] or sv.done[b, s])
            d_h = 0.0 + 0.0j
            d_z = 0.0
            ut = 0.0
            pitch = 0.0
            u0 = sv.speed_model[b, s]
            um = u0
            waypoints, n_waypoints = sv.waypoints[b, s], sv.n_waypoints[b, s]
            thrust, scale, bias, told = (
                sv.thrust_n[b, s],
                sv.speed_scale[b, s],
                sv.compass_bias_rad[b, s],
                sv.current_est[b, s],
            )
            for k in range(compass_noise_rad.shape[1]):
                i, steer, h, depth_cmd, ended = _guide(waypoints, n_waypoints, i, steer, e, h, prm)
                if ended:
                    sv.done[b, s] = True
                pitch = min(max(prm.depth_gain_per_m * (pz - depth_cmd), -prm.max_pitch_rad), prm.max_pitch_rad)
                # true motion: water-relative velocity plus current
                um = thrust_speed(u0, thrust, prm.drag_k, prm.mass_kg, (k + 1) * dt)  # eq. (1), exact
                ut = um * scale
                cp, sp = np.cos(pitch), np.sin(pitch)
                p += (ut * cp * h + current[b]) * dt
                pz -= ut * sp * dt
                # dead reckoning, eq. (4): R(measured attitude) (u_model, 0, 0) tau
                pm = pitch + pitch_noise_rad[b, k, s]
                # the compass reads bearing + bias + noise: bearing b -> b + d is the factor exp(-1j d)
                err = bias + compass_noise_rad[b, k, s]
                d_h = (um * np.cos(pm) * dt) * (h * (np.cos(err) - 1j * np.sin(err)))
                d_z = -um * np.sin(pm) * dt
                e += d_h + told * dt  # told the current by a beacon (Gao II-A)
                ez += d_z
                r += d_h  # the dead-reckoning-only track is not
                rz += d_z
            sv.pos[b, s, 0], sv.pos[b, s, 1], sv.pos[b, s, 2] = p.real, p.imag, pz
            sv.est[b, s, 0], sv.est[b, s, 1], sv.est[b, s, 2] = e.real, e.imag, ez
            sv.dr[b, s, 0], sv.dr[b, s, 1], sv.dr[b, s, 2] = r.real, r.imag, rz
            sv.heading[b, s] = h
            sv.speed_model[b, s] = um
            sv.wp_index[b, s] = i
            v = ut * np.cos(pitch) * h + current[b]
            sv.vel_true[b, s, 0], sv.vel_true[b, s, 1], sv.vel_true[b, s, 2] = v.real, v.imag, -ut * np.sin(pitch)
            ve = d_h / dt + told
            sv.vel_est[b, s, 0], sv.vel_est[b, s, 1], sv.vel_est[b, s, 2] = ve.real, ve.imag, d_z / dt


def _integrate_beacons(pos, heading, vel, command, cos_max_turn, sin_max_turn, n_substeps, dt):
    """Beacons follow their commanded ground velocity through K sub-steps, in place.

    pos (B,N,3), heading (B,N) complex unit, vel (B,N,3) (written: the last
    sub-step's velocity); command (B,N) complex ground velocity; the turn limit per
    sub-step of each beacon as cos/sin (N,). A beacon commanded to stop keeps its
    heading. Depth is held.
    """
    B, N = pos.shape[0], pos.shape[1]
    for b in prange(B):
        for n in range(N):
            v = command[b, n]
            speed = abs(v)
            h = heading[b, n]
            p = pos[b, n, 0] + 1j * pos[b, n, 1]
            for k in range(n_substeps):
                if speed > 1e-9:
                    h = turn_toward(h, v, cos_max_turn[n], sin_max_turn[n])
                    if h == v / speed:  # on course: the rest of the cycle is a straight line
                        p += speed * h * dt * (n_substeps - k)
                        break
                p += speed * h * dt
            pos[b, n, 0], pos[b, n, 1] = p.real, p.imag
            heading[b, n] = h
            vel[b, n, 0], vel[b, n, 1] = (speed * h).real, (speed * h).imag


# each kernel compiled twice from one source: plain, and threaded for large batches
# (starting threads costs more than a batch of one takes)
integrate_survey = njit(cache=True)(_integrate_survey)
integrate_survey_parallel = parallel_twin(_integrate_survey)
integrate_beacons = njit(cache=True)(_integrate_beacons)
integrate_beacons_parallel = parallel_twin(_integrate_beacons)
