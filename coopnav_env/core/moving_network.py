"""The moving acoustic network of Matos & Cruz: one AUV navigating in the frame of
two beacon boats, batched (``network = "moving_lbl"``).

One step is one positioning cycle of ``ping_interval_s``:

1. the boats' actions become ground-velocity commands (the same rate-limited
   kernel as every beacon, ``substeps.integrate_beacons``), which the boats follow
   imperfectly (``disturb_boats``): a Gauss-Markov surge and course fluctuation
   each, and the part of the river current their ground-speed control leaves;
2. the vehicle is integrated in sub-steps: line-of-sight guidance (Fig. 5) on its
   filter's frame estimate, heading reference psi + phi_hat steered on the compass,
   true motion = water speed x heading + current; the filter predicts with the
   measured water speed (propeller encoder) and compass heading (section VII);
3. the three-interval exchange of section V runs in time between the moving
   vehicles (``core.lbl.exchange_of``); the filter fuses d1 as it arrives, then d2
   and l together (their noises are correlated, see ``cycle``);
4. the boats, which hear S1, S2 and S4 too, track the vehicle externally
   (``core.lbl.track_fix_of``): that, their GPS and each other's position over the
   radio is all they observe;
5. reward: the information the vehicle's filter gained this cycle (log det of its
   (x, y) covariance before minus after), shared by the boats, minus penalties: a
   boat within ``safety_distance_m`` of the vehicle; the baseline off its target
   by more than ``baseline_tolerance_m``; the vehicle nearer the baseline than
   ``min_baseline_distance_m``; the frame turned more than
   ``frame_rotation_tolerance_deg`` from its start (the filter models phi as
   constant: a turning frame makes it confidently wrong, which the information
   term alone would reward); no range fused this cycle.

**A mission in the world** (``mission_frame="world"``, scenario ``matos_river``): the
paper gives the vehicle its mission in the moving frame (section VI), so where the
boats go hardly matters to it. With ``"world"`` the mission's waypoints are (east,
north, depth) along a river (``core.river``), and at the start of every cycle they
are re-expressed in the frame the boats' GPS gives (B1's GPS position and the bearing
of B2's from it, which the boats telemeter to the vehicle with the exchange; the
vehicle has no other world reference): the vehicle still navigates in the frame with
the moving-frame EKF, but where it must go in the frame now depends on where the
boats are, and boats that stay behind lose it. The river's current is spatially
varying: its mean speed along the local downstream direction of the centerline (at
each boat and at the vehicle, held over the cycle) plus the usual Gauss-Markov part.
Reward: the ``bank`` term (a boat farther than ``river_width_m`` / 2 from the
centerline) is added and the ``rotation`` term is 0, since the frame must turn with
the river. The boats also observe the river (``RIVER_OBS_FIELDS``).

Steps 1-2 and 3-5 are compiled kernels written once over the batch
(``integrate_vehicle``, ``cycle``; the observation ``observe_boats``), so a batch of
one costs tens of microseconds; only what numpy computes differently from the C
library (arctan2, log) is left to numpy around them.

It implements the simulator contract (``core.contract.BatchedSimulator``) as
``core.sim.Simulator`` does, so every view, the trainers and the evaluation run it
unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from . import lbl, river, rng, substeps
from .acoustics import mackenzie_sound_speed, packet_loss_probability, ranging_variance_m2
from .contract import BatchSimulator, Snapshot, StepResult
from .dynamics import bearing_to_unit, gauss_markov_step, turn_toward
from .guidance import build_path, los_point
from .information import (
    ELLIPSE_N_SIGMA,
    det2_of,
    ellipse_of,
    error_ellipse,
    floored_log,
)
from .lbl import horizontal_range
from .navigation import (
    frame_predict,
    frame_range_prediction,
    frame_velocity_of,
    gate_threshold,
    joseph_update_vector,
    joseph_work,
)
from .numerics import complex_abs, complex_div_real
from .observation import AGE_SCALE_PINGS, OBS_BOUND  # the survey network's age scale and bound
from .reward import MOVING_NETWORK_TERMS, RIVER_NETWORK_TERMS, term_weights, weighted_reward
from .sim import BEACON_INFO_KEYS, INFO_KEYS
from .state import BatchArrays

# ellipse_major_m / ellipse_minor_m: ELLIPSE_N_SIGMA (2-sigma) semi-axes of the filter's (x, y)
# covariance, as in the observations, evaluate.py's steps and the plots
FRAME_INFO_KEYS = INFO_KEYS + ("error_x_m", "error_y_m", "phi_error_deg", "baseline_error_m", "ellipse_major_m",
                               "ellipse_minor_m", "vehicle_y_m")
# one boat's observation, in this order (see MovingNetworkSimulator.observe)
OBS_FIELDS = (("role", 1), ("own_velocity_xy", 2), ("baseline_error", 1), ("tracked_xy", 2),
              ("tracked_velocity_xy", 2), ("fix_age", 1), ("has_fix", 1), ("frame_bearing", 2),
              ("own_from_tracked_xy", 2), ("elapsed", 1))
OBS_DIM = sum(n for _, n in OBS_FIELDS)
TRACKER_ALPHA, TRACKER_BETA = 0.5, 0.2  # the boats' alpha-beta tracker on the fixes [U]
REINIT_AFTER_CYCLES = 3  # the vehicle restarts its position from an LBL fix after this many gated-out cycles
# appended for a mission in the world (mission_frame="world"; see MovingNetworkSimulator.observe)
RIVER_OBS_FIELDS = (("bank_offset", 1), ("river_direction_xy", 2), ("river_ahead_from_own_xy", 2))
RIVER_OBS_DIM = sum(n for _, n in RIVER_OBS_FIELDS)
RIVER_LEAD_BASELINES = 0.5  # the river point the boats observe (and start at) lies this many baselines
# ahead of the vehicle along the river: the paper's geometry, the vehicle 50 m from a 100 m baseline
RIVER_STATE_DIM = 2  # global_state's extra values for a world mission: the boats' offsets from the centerline


def obs_fields(config) -> tuple:
    """One boat's observation fields for ``config``: ``OBS_FIELDS``, and ``RIVER_OBS_FIELDS``
    after them for a mission in the world."""
    return OBS_FIELDS + (RIVER_OBS_FIELDS if config.mission_frame == "world" else ())


def obs_dim_of(config) -> int:
    """The length of one boat's observation for ``config``."""
    return sum(n for _, n in obs_fields(config))


@dataclass
class FrameState(BatchArrays):
    """Arrays of the moving network, leading batch axis B; one vehicle (axis S = 1
    kept where the views expect it), two boats (N = 2)."""

    t_s: np.ndarray
    cycle: np.ndarray
    keys: np.ndarray
    ep_variant: np.ndarray  # always 0: one (path, depth) variant
    ep_noise_scale: np.ndarray
    ep_phi0_rad: np.ndarray  # the frame's initial orientation (the boats' reference)
    # the vehicle (world truth; mission in the frame)
    s_pos: np.ndarray  # (B,1,3) east, north, depth
    s_heading: np.ndarray  # (B,) complex unit
    s_vel_true: np.ndarray  # (B,1,3)
    s_speed_scale: np.ndarray  # true water speed / commanded (B,)
    s_compass_bias_rad: np.ndarray  # (B,)
    s_heading_meas_rad: np.ndarray  # last compass reading (B,)
    s_speed_meas_mps: np.ndarray  # last encoder reading (B,)
    s_waypoints: np.ndarray  # (B,1,W,3) frame x, y, depth
    s_n_waypoints: np.ndarray  # (B,1)
    s_wp_index: np.ndarray  # (B,1)
    s_done: np.ndarray  # (B,1)
    s_dr: np.ndarray  # dead reckoning alone, world (B,1,3)
    f_E: np.ndarray  # the moving-frame EKF (B,6): x, y, phi, c_x, c_y, l
    f_P: np.ndarray  # (B,6,6)
    f_rejected_cycles: np.ndarray  # consecutive cycles whose measurements were all gated out (B,)
    # the boats
    b_pos: np.ndarray  # (B,2,3)
    b_heading: np.ndarray  # (B,2) complex unit
    b_vel: np.ndarray  # (B,2,3)
    b_gps_err: np.ndarray  # this cycle's GPS error (B,2,2)
    b_surge: np.ndarray  # each boat's ground-speed fluctuation along its heading, Gauss-Markov (B,2) m/s
    b_steer: np.ndarray  # each boat's course-over-ground error, Gauss-Markov (B,2) rad
    # the boats' tracker of the vehicle (shared over their radio link)
    k_pos: np.ndarray  # (B,2) east, north at the last update
    k_vel: np.ndarray  # (B,2)
    k_age_s: np.ndarray  # time since the last fix (B,)
    k_has_fix: np.ndarray  # (B,) bool
    # water
    temperature_c: np.ndarray
    current_mean: np.ndarray  # complex (B,)
    current_gm: np.ndarray


@njit(cache=True)
def integrate_vehicle(pos, heading, vel_true, wp_index, done, waypoints, n_wp, speed_scale, speed_mps, bias,
                      compass_noise, speed_noise, current, E, P, Q, dr, heading_meas, speed_meas, dt, alpha,
                      acceptance_m, turn_cos, turn_sin, K):
    """K sub-steps of every vehicle of the batch: guidance on the frame estimate,
    true motion, dead reckoning and the filter's prediction (``frame_predict``)."""
    for b in range(pos.shape[0]):
        for k in range(K):
            speed = 0.0
            if not done[b, 0]:
                i = wp_index[b, 0]
                est = E[b, 0] + 1j * E[b, 1]
                a = waypoints[b, 0, i - 1, 0] + 1j * waypoints[b, 0, i - 1, 1]
                e = waypoints[b, 0, i, 0] + 1j * waypoints[b, 0, i, 1]
                q, along, seg_len = los_point(est, a, e, alpha)
                if along >= seg_len - acceptance_m or abs(est - e) < acceptance_m:
                    i += 1
                    if i >= n_wp[b, 0]:
                        done[b, 0] = True
                    else:
                        wp_index[b, 0] = i
                        a, e = e, waypoints[b, 0, i, 0] + 1j * waypoints[b, 0, i, 1]
                        q, along, seg_len = los_point(est, a, e, alpha)
                if not done[b, 0]:
                    d = q - est
                    # psi: direction of V -> Q in the frame, measured from x towards y
                    # (clockwise); the heading controller's reference is psi + phi_hat
                    # (section VI), which it tracks on the compass, bias included
                    ref = np.arctan2(d.imag, d.real) + E[b, 2] - bias[b]
                    heading[b] = turn_toward(heading[b], np.sin(ref) + 1j * np.cos(ref), turn_cos, turn_sin)
                    speed = speed_mps
            ground = speed * speed_scale[b] * heading[b] + current[b]
            pos[b, 0, 0] += ground.real * dt
            pos[b, 0, 1] += ground.imag * dt
            vel_true[b, 0, 0], vel_true[b, 0, 1], vel_true[b, 0, 2] = ground.real, ground.imag, 0.0
            theta = np.arctan2(heading[b].real, heading[b].imag) + bias[b] + compass_noise[b, k]
            v = speed + speed_noise[b, k] if speed > 0.0 else 0.0
            dr[b, 0, 0] += v * np.sin(theta) * dt
            dr[b, 0, 1] += v * np.cos(theta) * dt
            frame_predict(E[b], P[b], v, theta, dt, Q)
            heading_meas[b], speed_meas[b] = theta, v


@njit(cache=True)
def disturb_boats(pos, heading, vel, surge, steer, current, response, T):
    """The boats' imperfect execution of their commands over one cycle, in place: after
    ``integrate_beacons`` moved each boat at its commanded ground velocity v (vel (B,2,3),
    its last sub-step), the boat actually made good (v + s h) exp(-1j delta) + r c: its
    speed along its heading h off by the surge fluctuation s (surge (B,2), m/s), its course
    off by delta (steer (B,2), rad, clockwise: bearing + delta is the factor exp(-1j delta)),
    and the part r (``boat_current_response``) of the water current c where the boat is
    (current (B,2) complex: the same for both in uniform water, each its own in a river)
    that its ground-speed control does not cancel. s and delta are held over the cycle
    (the Gauss-Markov states are stepped exactly at the cycle's period, see ``step``); the
    difference from the commanded motion is added to pos over the cycle T and to vel."""
    for b in range(pos.shape[0]):
        for n in range(pos.shape[1]):
            drift = response * current[b, n]
            v = complex(vel[b, n, 0], vel[b, n, 1])
            d = steer[b, n]
            made_good = (v + surge[b, n] * heading[b, n]) * complex(np.cos(d), -np.sin(d)) + drift
            w = made_good - v
            pos[b, n, 0] += w.real * T
            pos[b, n, 1] += w.imag * T
            vel[b, n, 0], vel[b, n, 1] = made_good.real, made_good.imag


def boat_noise_step(x, T, time_constant_s, std, noise):
    """One cycle of a boat's Gauss-Markov fluctuation (``gauss_markov_step``; white per cycle
    when the time constant is 0)."""
    if time_constant_s <= 0.0:
        return std * noise
    return gauss_markov_step(x, T, time_constant_s, std, noise)


# the noise covariance of (d1, d2, l) in units of a two-way range's variance sigma_r^2 (see ``cycle``);
# tests/test_noise.py checks it against Monte Carlo exchanges
EXCHANGE_COVARIANCE = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, -1.0], [0.0, -1.0, 6.0]])


def exchange_covariance_m2(detection_std_m):
    """The covariance of the exchange's (d1, d2, l) for a per-detection jitter as range."""
    return ranging_variance_m2(detection_std_m, True) * EXCHANGE_COVARIANCE


# the per-cycle kernel's float outputs (columns of fval), besides its integer outputs
# (ranges fused, outliers rejected, packets lost, the filter restarted) and a range fused (bval)
# reward terms (unweighted, 0/1): _F_SAFETY per boat, then the team's baseline, approach and contact
(_F_DET_BEFORE, _F_DET_AFTER, _F_SURVEY_ERROR, _F_DR_ERROR, _F_ERROR_X, _F_ERROR_Y, _F_BASELINE_ERROR, _F_MAJOR,
 _F_MINOR, _F_VEHICLE_Y, _F_SAFETY, _F_SAFETY_B2, _F_CONTACT, _F_PHI_ERR_SIN, _F_PHI_ERR_COS, _F_BASELINE_OFF,
 _F_APPROACH) = range(17)
N_FVAL, N_IVAL = 17, 4
_INFO_COLUMNS = (("survey_error_m", _F_SURVEY_ERROR), ("dr_error_m", _F_DR_ERROR), ("error_x_m", _F_ERROR_X),
                 ("error_y_m", _F_ERROR_Y), ("baseline_error_m", _F_BASELINE_ERROR), ("ellipse_major_m", _F_MAJOR),
                 ("ellipse_minor_m", _F_MINOR), ("vehicle_y_m", _F_VEHICLE_Y))
# the scenario's numbers the kernel uses, in this order (MovingNetworkSimulator._scalars)
CYCLE_SCALARS = ("salinity_psu", "water_temperature_c", "range_noise_std_m", "outlier_probability",
                 "outlier_mean_excess_m", "packet_loss_near", "packet_loss_far", "max_range_m", "turnaround_s",
                 "depth_noise_m", "gate1", "gate2", "depth_m", "ping_interval_s", "safety_distance_m",
                 "baseline_target_m", "baseline_tolerance_m", "min_baseline_distance_m")


@njit(cache=True)
def _one(flag):
    """A flag as numpy multiplies it (bool -> 1.0 or 0.0)."""
    return 1.0 if flag else 0.0


@njit(cache=True)
def _dist3(a, b):
    dx, dy, dz = a[0] - b[0], a[1] - b[1], a[2] - b[2]
    return np.sqrt(dx * dx + dy * dy + dz * dz)


def _cycle(s_pos, s_vel_true, b_pos, b_vel, gps, temperature_c, noise_scale, n_depth, n_jitter, u_acoustic, log_u,
           E, P, rejected_cycles, speed_meas, heading_meas, dr, k_pos, k_vel, k_age_s, k_has_fix, phi, length,
           phi_gps, length_gps, scalars, fval, ival, bval):
    """Steps 3-5 of a cycle for every environment, in place: the exchange (``lbl.exchange_of``),
    the filter's updates and its recovery (below), the boats' tracker, the reward's terms
    and the infos (fval, ival, bval; see ``MovingNetworkSimulator.step``).

    Section VII's updates: d1 when S2 arrives, then d2 and l when S5 arrives. d2 and l
    arrive together and share detection errors: with sigma_t per detection and
    sigma_r^2 = (c sigma_t)^2 / 2 the variance of a two-way range,
    d1 = c(e1 + e2)/2, d2 = c(e5 + e6)/2 and l = m - d1 - d2 with m = c(e1 + e3 + e4)
    give var(d1) = var(d2) = sigma_r^2, var(l) = 6 sigma_r^2, cov(d2, l) = -sigma_r^2
    and cov(d1, l) = 0 (e_i: the detections in ``lbl.DETECTIONS`` order). So d1 is a
    scalar update and (d2, l) one joint update with that R (d2 alone when l is
    missing); treating them as independent, as a naive sequential filter would,
    overweights l. Each update passes a chi-square gate.

    Recovery from gate lockout: a filter that has a measurement rejected in each of
    ``REINIT_AFTER_CYCLES`` consecutive cycles (it has diverged: the gate now refuses
    the very ranges that would correct it) restarts its position from the spherical
    fix of this cycle's d1, d2 and l, with the fix's uncertainty; the paper does not
    discuss this, every fielded LBL navigator needs it. Counting cycles with every
    measurement rejected is not enough: a filter whose error runs along the circle
    around one beacon keeps passing that beacon's range (and l) while the other's is
    refused, and drifts off along the circle (seen with the boats' speed noise).

    The boats' alpha-beta tracker runs on the external fixes (section III, ``lbl.track_fix_of``).
    phi, length (B,): the true frame's bearing and baseline, phi_gps, length_gps the
    GPS positions' (gps (B,2,2)); log_u (B,7) the logarithms of the multipath draws.
    """
    (salinity, nominal_temperature_c, range_noise_std_m, outlier_probability, outlier_mean_excess_m, loss_near,
     loss_far, max_range_m, turnaround_s, depth_noise_m, gate1, gate2, depth_m, T, safety_distance_m,
     baseline_target_m, baseline_tolerance_m, min_baseline_distance_m) = scalars
    n_det = n_jitter.shape[1]
    for b in prange(s_pos.shape[0]):
        work = np.empty((2, 3))
        jwork = joseph_work(6, 2)
        err = np.empty(n_det)
        lost = np.empty(n_det, dtype=np.bool_)
        delays = np.empty(2)
        H = np.empty((2, 6))
        y = np.empty(2)
        R = np.empty((2, 2))
        v3 = s_pos[b, 0]
        fval[b, _F_DET_BEFORE] = det2_of(P[b, 0, 0], P[b, 0, 1], P[b, 1, 0], P[b, 1, 1])
        # the exchange: sound speeds, detection errors, losses
        depth = v3[2]
        c_true = mackenzie_sound_speed(temperature_c[b], salinity, depth)
        cn = mackenzie_sound_speed(nominal_temperature_c, salinity, depth)
        # each detection instant is late by a jitter sigma_t = range_noise_std_m / c (the
        # convention of core.acoustics); a two-way range d1, d2 has two of them, halved
        sigma_det = range_noise_std_m * noise_scale[b]
        jitter_scale = sigma_det / cn
        d_b1 = _dist3(b_pos[b, 0], v3)
        d_b2 = _dist3(b_pos[b, 1], v3)
        base = _dist3(b_pos[b, 1], b_pos[b, 0])
        for i in range(n_det):
            late = -outlier_mean_excess_m * log_u[b, i] if u_acoustic[b, i, 1] < outlier_probability else 0.0
            err[i] = jitter_scale * n_jitter[b, i] + late / c_true
            path = d_b1 if i < 2 else (base if i == 2 else d_b2)  # the distance each signal travels
            lost[i] = u_acoustic[b, i, 0] < packet_loss_probability(path, loss_near, loss_far, max_range_m)
        timeout = 2.0 * max_range_m / cn + 2.0 * turnaround_s
        (d1, _, d2, l, ok_d1, _, ok_d2, ok_l, t3, t3s, t6, t_s1_b1, t_s1_b2, t_s4_b2, ok_track,
         n_lost) = lbl.exchange_of(v3, s_vel_true[b, 0], b_pos[b, 0], b_vel[b, 0], b_pos[b, 1], b_vel[b, 1], c_true,
                                   cn, err, lost, turnaround_s, turnaround_s, timeout, work)

        # the filter's updates
        sigma_r2 = ranging_variance_m2(sigma_det, True)  # var(d1) = var(d2) = (c sigma_t)^2 / 2
        dz = depth + depth_noise_m * n_depth[b, 0]  # depth cell; boats at the surface
        # d1: the legs are S1 leaving (t = 0) and S2 arriving (t3)
        fused0 = False
        if ok_d1:
            vx, vy = frame_velocity_of(E[b], speed_meas[b], heading_meas[b])
            delays[0], delays[1] = 0.0, t3
            h = frame_range_prediction(E[b], 1, dz, vx, vy, delays, H[0])
            y[0] = d1 - h
            R[0, 0] = sigma_r2
            _, status = joseph_update_vector(E[b], P[b], y[:1], H[:1], R[:1, :1], gate1, jwork)
            fused0 = status == 1
        # d2 (legs: S4 leaving at t3s, S5 arriving at t6) with l when it is there, else alone
        both = False
        fused1 = False
        alone = ok_d2 and not ok_l
        if ok_l or alone:
            vx, vy = frame_velocity_of(E[b], speed_meas[b], heading_meas[b])
            delays[0], delays[1] = t3s, t6
            h2 = frame_range_prediction(E[b], 2, dz, vx, vy, delays, H[0])
            y[0] = d2 - h2
            if ok_l:
                y[1] = l - E[b, 5]
                H[1, :] = 0.0
                H[1, 5] = 1.0
                R[0, 0], R[0, 1], R[1, 0], R[1, 1] = (sigma_r2 * EXCHANGE_COVARIANCE[1, 1], sigma_r2 * EXCHANGE_COVARIANCE[1, 2],
                                                      sigma_r2 * EXCHANGE_COVARIANCE[2, 1], sigma_r2 * EXCHANGE_COVARIANCE[2, 2])
                _, status = joseph_update_vector(E[b], P[b], y, H, R, gate2, jwork)
                both = status == 1
                fused1 = both
            else:
                R[0, 0] = sigma_r2
                _, status = joseph_update_vector(E[b], P[b], y[:1], H[:1], R[:1, :1], gate1, jwork)
                fused1 = status == 1
        n_fused = int(fused0) + int(fused1) + int(both)
        rejected = int(ok_d1 and not fused0) + int(ok_l and not both) + int(alone and not fused1)
        # recovery from gate lockout
        if rejected == 0:
            rejected_cycles[b] = 0
        else:
            rejected_cycles[b] += 1
        restarted = 0
        fx, fy, ok_fix = lbl.spherical_fix_of(horizontal_range(d1, dz), horizontal_range(d2, dz), l)
        if rejected_cycles[b] >= REINIT_AFTER_CYCLES and ok_l and ok_fix and fy > 0:
            E[b, 0], E[b, 1], E[b, 5] = fx, fy, l
            for i in range(6):
                for k in (0, 1, 5):
                    P[b, k, i] = 0.0
                    P[b, i, k] = 0.0
            var = 4.0 * sigma_r2  # a single fix's position variance, GDOP ~ 2 [U]
            P[b, 0, 0] = var
            P[b, 1, 1] = var
            P[b, 5, 5] = 6.0 * sigma_r2
            rejected_cycles[b] = 0
            restarted = 1
        fval[b, _F_DET_AFTER] = det2_of(P[b, 0, 0], P[b, 0, 1], P[b, 1, 0], P[b, 1, 1])

        # the boats' tracker
        fix_e, fix_n, ok = lbl.track_fix_of(t_s1_b1, t_s1_b2, t_s4_b2, ok_track, gps[b, 0, 0], gps[b, 0, 1],
                                            np.sin(phi_gps[b]), np.cos(phi_gps[b]), length_gps[b], depth_m, cn,
                                            turnaround_s, turnaround_s)
        age = k_age_s[b] + T
        pred_e, pred_n = k_pos[b, 0] + k_vel[b, 0] * age, k_pos[b, 1] + k_vel[b, 1] * age
        res_e, res_n = fix_e - pred_e, fix_n - pred_n
        if ok and not k_has_fix[b]:
            k_pos[b, 0], k_pos[b, 1] = fix_e, fix_n
        elif ok:
            k_pos[b, 0], k_pos[b, 1] = pred_e + TRACKER_ALPHA * res_e, pred_n + TRACKER_ALPHA * res_n
            k_vel[b, 0] = k_vel[b, 0] + TRACKER_BETA * res_e / age
            k_vel[b, 1] = k_vel[b, 1] + TRACKER_BETA * res_n / age
        k_age_s[b] = 0.0 if ok else age
        k_has_fix[b] = k_has_fix[b] or ok

        # reward terms and infos, in the true frame
        ve, vn = v3[0], v3[1]
        sin_phi, cos_phi = np.sin(phi[b]), np.cos(phi[b])
        x, yv = lbl.to_frame(ve - b_pos[b, 0, 0], vn - b_pos[b, 0, 1], sin_phi, cos_phi)
        fval[b, _F_BASELINE_OFF] = _one(abs(length[b] - baseline_target_m) > baseline_tolerance_m)
        fval[b, _F_APPROACH] = _one(yv < min_baseline_distance_m)
        for i in range(2):
            fval[b, _F_SAFETY + i] = _one(_dist3(b_pos[b, i], v3) < safety_distance_m)
        fval[b, _F_CONTACT] = _one(n_fused == 0)
        ex_, ey_ = E[b, 0] - x, E[b, 1] - yv
        fval[b, _F_SURVEY_ERROR] = np.hypot(ex_, ey_)
        de, dn = dr[b, 0, 0] - ve, dr[b, 0, 1] - vn
        fval[b, _F_DR_ERROR] = np.sqrt(de * de + dn * dn)
        fval[b, _F_ERROR_X], fval[b, _F_ERROR_Y] = ex_, ey_
        rel = E[b, 2] - phi[b]  # wrapped by the caller (numpy's arctan2)
        fval[b, _F_PHI_ERR_SIN], fval[b, _F_PHI_ERR_COS] = np.sin(rel), np.cos(rel)
        fval[b, _F_BASELINE_ERROR] = E[b, 5] - length[b]
        fval[b, _F_MAJOR], fval[b, _F_MINOR], _ = ellipse_of(P[b, 0, 0], P[b, 0, 1], P[b, 1, 1], ELLIPSE_N_SIGMA)
        fval[b, _F_VEHICLE_Y] = yv
        ival[b, 0], ival[b, 1], ival[b, 2], ival[b, 3] = n_fused, rejected, n_lost, restarted
        bval[b, 0] = fused0 or fused1


@njit(cache=True)
def gps_frame_of(b_pos, gps_err):
    """The frame as one environment's boat GPS gives it (b_pos (2,3), gps_err (2,2)): B1's
    and B2's GPS positions, the x axis as a complex (east + 1j north) unit and the
    baseline length; the y axis is x turned 90 degrees clockwise, -1j x."""
    g1e, g1n = b_pos[0, 0] + gps_err[0, 0], b_pos[0, 1] + gps_err[0, 1]
    g2e, g2n = b_pos[1, 0] + gps_err[1, 0], b_pos[1, 1] + gps_err[1, 1]
    base = complex(g2e - g1e, g2n - g1n)
    length = complex_abs(base)
    return g1e, g1n, g2e, g2n, complex_div_real(base, max(length, 1e-9)), length


@njit(cache=True)
def command_velocity(actions, b_pos, gps_err, max_speed, mode, out):
    """Actions (B,2,2) -> commanded ground velocity, complex (B,2) (``MovingNetworkSimulator.command_velocity``);
    mode 0 "velocity", 1 "frame_velocity", 2 "heading_speed"."""
    for b in range(actions.shape[0]):
        x_axis = 1.0 + 0.0j
        if mode == 1:
            x_axis = gps_frame_of(b_pos[b], gps_err[b])[4]
        y_axis = -1j * x_axis
        for i in range(actions.shape[1]):
            vmax = max_speed[i]
            if mode == 2:
                out[b, i] = 0.5 * (actions[b, i, 1] + 1.0) * vmax * bearing_to_unit(np.pi * actions[b, i, 0])
                continue
            v = complex(actions[b, i, 0], actions[b, i, 1])
            norm = complex_abs(v)
            if norm > 1.0:
                v = complex_div_real(v, max(norm, 1e-12))
            v = v * vmax
            if mode == 1:
                v = v.real * x_axis + v.imag * y_axis
            out[b, i] = v


@njit(cache=True)
def _clip_obs(v):
    """An observation value clipped to [-OBS_BOUND, OBS_BOUND]."""
    if v < -OBS_BOUND:
        return -OBS_BOUND
    if v > OBS_BOUND:
        return OBS_BOUND
    return v


def _observe_boats(b_pos, gps_err, b_vel, k_pos, k_vel, k_age_s, k_has_fix, cycle, L, boat_max_speed_mps,
                   survey_speed_mps, age_scale_s, max_cycles, out):
    """Every boat's observation (``MovingNetworkSimulator.observe``), out (B, 2, OBS_DIM) float32."""
    for b in prange(b_pos.shape[0]):
        g1e, g1n, g2e, g2n, xa, length = gps_frame_of(b_pos[b], gps_err[b])
        ya = -1j * xa
        te, tn = k_pos[b, 0] + k_vel[b, 0] * k_age_s[b], k_pos[b, 1] + k_vel[b, 1] * k_age_s[b]
        for i in range(2):
            o = out[b, i]
            ge, gn = (g1e, g1n) if i == 0 else (g2e, g2n)
            vals = (1.0 - 2.0 * i,
                    (b_vel[b, i, 0] * xa.real + b_vel[b, i, 1] * xa.imag) / boat_max_speed_mps,
                    (b_vel[b, i, 0] * ya.real + b_vel[b, i, 1] * ya.imag) / boat_max_speed_mps,
                    (length - L) / L,
                    ((te - g1e) * xa.real + (tn - g1n) * xa.imag) / L,
                    ((te - g1e) * ya.real + (tn - g1n) * ya.imag) / L,
                    (k_vel[b, 0] * xa.real + k_vel[b, 1] * xa.imag) / survey_speed_mps,
                    (k_vel[b, 0] * ya.real + k_vel[b, 1] * ya.imag) / survey_speed_mps,
                    k_age_s[b] / age_scale_s,
                    1.0 if k_has_fix[b] else 0.0,
                    xa.real, xa.imag,
                    ((ge - te) * xa.real + (gn - tn) * xa.imag) / L,
                    ((ge - te) * ya.real + (gn - tn) * ya.imag) / L,
                    cycle[b] / max_cycles)
            for k in range(OBS_DIM):
                o[k] = _clip_obs(vals[k])


@njit(cache=True)
def observe_river(b_pos, gps_err, k_pos, k_vel, k_age_s, pts, cum, direction, lead_m, L, half_width_m, out):
    """The river part of every boat's observation (``RIVER_OBS_FIELDS``), out (B, 2,
    RIVER_OBS_DIM) float32, vectors in the boats' GPS frame as in ``observe_boats``: the
    boat's offset from the centerline (GPS position; + right of the mission direction)
    / (river_width_m / 2), so that +-1 are the banks; the river's unit direction of the
    mission at the point ``lead_m`` ahead of the tracked vehicle along the centerline;
    that point minus the boat's GPS position / L. direction: +1 a downstream mission,
    -1 upstream (``river.mission_direction``)."""
    for b in range(b_pos.shape[0]):
        g1e, g1n, g2e, g2n, xa, _ = gps_frame_of(b_pos[b], gps_err[b])
        ya = -1j * xa
        te, tn = k_pos[b, 0] + k_vel[b, 0] * k_age_s[b], k_pos[b, 1] + k_vel[b, 1] * k_age_s[b]
        s_v = river.project(te, tn, pts, cum)[0]
        pe, pn, de, dn = river.point_at(s_v + direction * lead_m, pts, cum)
        de, dn = direction * de, direction * dn
        for i in range(2):
            ge, gn = (g1e, g1n) if i == 0 else (g2e, g2n)
            off = river.project(ge, gn, pts, cum)[1]
            vals = (direction * off / half_width_m,
                    de * xa.real + dn * xa.imag, de * ya.real + dn * ya.imag,
                    ((pe - ge) * xa.real + (pn - gn) * xa.imag) / L,
                    ((pe - ge) * ya.real + (pn - gn) * ya.imag) / L)
            for k in range(RIVER_OBS_DIM):
                out[b, i, k] = _clip_obs(vals[k])


def frame_waypoints(b_pos, gps_err, world_waypoints):
    """A world mission in the frame the boats' GPS gives (what the vehicle computes from
    the telemetered B1 position and bearing to B2): frame x and y (B, W) of the world
    waypoints (W, >=2) through B1's and B2's GPS positions, b_pos (B,2,>=2) plus gps_err
    (B,2,2) (``lbl.world_to_frame``, section II's frame)."""
    g = b_pos[:, :, :2] + gps_err
    x, y, _, _ = lbl.world_to_frame(g[:, 0:1], g[:, 1:2], world_waypoints[None, :, :2])
    return x, y


# each kernel compiled twice from one source: plain, and threaded for large batches
cycle = njit(cache=True)(_cycle)
cycle_parallel = njit(cache=True, parallel=True)(_cycle)
observe_boats = njit(cache=True)(_observe_boats)
observe_boats_parallel = njit(cache=True, parallel=True)(_observe_boats)


class MovingNetworkSimulator(BatchSimulator):
    """The batched moving LBL network: B independent environments of one scenario."""

    def __init__(self, config, batch_size: int = 1):
        if int(batch_size) < 1:
            raise ValueError(f"batch_size must be >= 1, got {batch_size!r}")
        c = self.config = config
        if c.network != "moving_lbl":
            raise ValueError(f"MovingNetworkSimulator needs network='moving_lbl', got {c.network!r}")
        self.batch_size = B = int(batch_size)
        self.S, self.N, self.K = 1, 2, c.substeps_per_cycle
        self.variants = [(c.survey_path, c.depth_m)]
        self.info_keys = FRAME_INFO_KEYS
        self.beacon_info_keys = BEACON_INFO_KEYS
        self._world = c.mission_frame == "world"
        self.reward_terms = RIVER_NETWORK_TERMS if self._world else MOVING_NETWORK_TERMS
        self.reward_weights = term_weights(c, self.reward_terms)
        wp, _ = build_path(c, 0)
        self._waypoints = wp  # frame (x, y, depth), or (east, north, depth) for a world mission
        if self._world:
            self._river_pts, self._river_cum = river.centerline_of(c.river_centerline_m)
            self._mission_dir = river.mission_direction(wp, self._river_pts, self._river_cum)
        self._max_speed = np.array(c.beacon_max_speeds_mps)
        turn = np.radians(np.full(2, c.boat_max_turn_rate_dps)) * c.substep_s
        self._boat_turn_cos, self._boat_turn_sin = np.cos(turn), np.sin(turn)
        vturn = np.radians(c.survey_max_turn_rate_dps) * c.substep_s
        self._turn_cos, self._turn_sin = float(np.cos(vturn)), float(np.sin(vturn))
        self._Q = np.diag([c.frame_q_position_m2ps, c.frame_q_position_m2ps, c.frame_q_orientation_rad2ps,
                           c.frame_q_current_m2ps3, c.frame_q_current_m2ps3, c.frame_q_baseline_m2ps])
        self._gate1 = gate_threshold(c.range_gate_probability, 1)
        self._gate2 = gate_threshold(c.range_gate_probability, 2)
        par = B >= 256  # threaded kernels pay off only for large batches
        self._k_beacons = substeps.integrate_beacons_parallel if par else substeps.integrate_beacons
        self._k_cycle = cycle_parallel if par else cycle
        self._k_observe = observe_boats_parallel if par else observe_boats
        self._action_mode = ("velocity", "frame_velocity", "heading_speed").index(c.action_mode)
        self._rotation_tolerance_rad = np.radians(c.frame_rotation_tolerance_deg)
        named = {"gate1": self._gate1, "gate2": self._gate2}
        self._scalars = tuple(float(named[k] if k in named else getattr(c, k)) for k in CYCLE_SCALARS)
        n_det = lbl.N_DETECTIONS
        self._draws = rng.DrawLayout([
            ("current", "normal", (2,)), ("substep", "normal", (self.K, 2)), ("depth", "normal", (1,)),
            ("jitter", "normal", (n_det,)), ("acoustic_u", "uniform", (n_det, 3)), ("gps", "normal", (2, 2)),
            ("boat", "normal", (2, 2)),  # per boat: surge, course (Gauss-Markov driving noise)
        ], B)
        self.obs_dim = obs_dim_of(c)
        self.state_dim = 24 + (RIVER_STATE_DIM if self._world else 0)
        self.state: FrameState | None = None

    def _initial_state(self, seeds) -> FrameState:
        c = self.config
        B = len(seeds)
        keys = rng.env_keys(seeds)
        zero = np.zeros(B, dtype=np.int64)
        # normals: 0-1 position prior, 2 phi prior, 3-4 unused (kept so that the others keep
        # their numbers), 5 l prior, 6-7 dead-reckoning start, 8 speed scale, 9 compass bias,
        # 10-13 GPS, 14 temperature, 15-16 the current's Gauss-Markov part, 17-20 the boats'
        # surge and course fluctuations (their stationary distribution; appended, so 0-16 keep their numbers)
        n = rng.normal(keys, rng.STREAM_EPISODE, zero, (21,))
        u = rng.uniform(keys, rng.STREAM_EPISODE + 100, zero, (3,))
        L = c.baseline_target_m
        b_pos = np.zeros((B, 2, 3))
        if self._world:
            # the boats' cross section RIVER_LEAD_BASELINES ahead of the vehicle's start along
            # the river, B1 on the left of the mission direction (river.cross_section_at)
            pts, cum, direction = self._river_pts, self._river_cum, self._mission_dir
            s0 = float(river.arc_length_of(self._waypoints[0, :2], pts, cum))
            b1_en, b2_en, phi_w = river.cross_section_at(s0 + direction * RIVER_LEAD_BASELINES * L, pts, cum,
                                                         direction, L)
            phi0 = np.full(B, phi_w)
            b_pos[:, 0, :2], b_pos[:, 1, :2] = b1_en, b2_en
        else:
            phi0 = np.radians(c.frame_orientation_deg + c.frame_orientation_spread_deg * (2 * u[:, 0] - 1))
            b2 = L * bearing_to_unit(phi0)
            b_pos[:, 1, 0], b_pos[:, 1, 1] = b2.real, b2.imag
        y_axis = bearing_to_unit(phi0 + np.pi / 2)
        transit = c.boat_transit_speed_mps * y_axis
        b_heading = np.repeat((np.where(c.boat_transit_speed_mps < 0, -y_axis, y_axis))[:, None], 2, 1)
        b_vel = np.zeros((B, 2, 3))
        b_vel[..., 0], b_vel[..., 1] = transit.real[:, None], transit.imag[:, None]

        wp = np.broadcast_to(self._waypoints, (B,) + self._waypoints.shape)[:, None].copy()
        gps_err = c.gps_noise_m * n[:, 10:14].reshape(B, 2, 2)
        if self._world:  # the vehicle starts at its first world waypoint; its mission goes to the frame
            start = np.broadcast_to(self._waypoints[0, :2], (B, 2)).copy()
            z0 = self._waypoints[0, 2]
            x0, y0, _, _ = lbl.world_to_frame(b_pos[:, 0, :2], b_pos[:, 1, :2], start)
            first = np.broadcast_to(self._waypoints[1, :2] - self._waypoints[0, :2], (B, 2))
            wp[:, 0, :, 0], wp[:, 0, :, 1] = frame_waypoints(b_pos, gps_err, self._waypoints)
        else:
            x0, y0, z0 = self._waypoints[0]
            start = lbl.frame_to_world(np.zeros((B, 2)), phi0, np.full(B, x0), np.full(B, y0))
            x1, y1, _ = self._waypoints[1]
            first = lbl.frame_to_world(np.zeros((B, 2)), phi0, np.full(B, x1), np.full(B, y1)) - start
        s_pos = np.zeros((B, 1, 3))
        s_pos[:, 0, :2], s_pos[:, 0, 2] = start, z0
        heading = (first[:, 0] + 1j * first[:, 1]) / np.maximum(np.hypot(first[:, 0], first[:, 1]), 1e-9)
        sigma0 = c.initial_position_std_m
        sphi = np.radians(c.initial_frame_orientation_std_deg)
        E = np.stack([x0 + sigma0 * n[:, 0], y0 + sigma0 * n[:, 1],
                      phi0 + np.radians(c.initial_frame_orientation_error_deg) + sphi * n[:, 2],
                      np.zeros(B), np.zeros(B),  # the vehicle knows neither the current nor the boats' speed
                      L + c.initial_baseline_std_m * n[:, 5]], -1)
        P = np.broadcast_to(np.diag([sigma0 ** 2, sigma0 ** 2, sphi ** 2, c.initial_current_std_mps ** 2,
                                     c.initial_current_std_mps ** 2, c.initial_baseline_std_m ** 2]), (B, 6, 6)).copy()
        dr = s_pos.copy()
        dr[:, 0, :2] += sigma0 * n[:, 6:8]
        cur_speed = np.maximum(c.current_speed_mps + c.current_speed_spread_mps * (2 * u[:, 1] - 1), 0.0)
        cur_dir = np.radians(c.current_direction_deg + c.current_direction_spread_deg * (2 * u[:, 2] - 1))
        # a river's current flows along the river (``_river_currents``): current_mean holds its speed
        current_mean = cur_speed + 0j if self._world else cur_speed * bearing_to_unit(cur_dir)
        return FrameState(
            t_s=np.zeros(B), cycle=np.zeros(B, dtype=np.int64), keys=keys, ep_variant=np.zeros(B, dtype=np.int64),
            ep_noise_scale=np.ones(B), ep_phi0_rad=phi0,
            s_pos=s_pos, s_heading=heading, s_vel_true=np.zeros((B, 1, 3)),
            s_speed_scale=1.0 + c.survey_speed_scale_error_std * n[:, 8],
            s_compass_bias_rad=np.radians(c.compass_bias_std_deg) * n[:, 9],
            s_heading_meas_rad=np.arctan2(heading.real, heading.imag), s_speed_meas_mps=np.zeros(B),
            s_waypoints=wp, s_n_waypoints=np.full((B, 1), len(self._waypoints), dtype=np.int64),
            s_wp_index=np.ones((B, 1), dtype=np.int64), s_done=np.zeros((B, 1), dtype=bool), s_dr=dr,
            f_E=E, f_P=P, f_rejected_cycles=np.zeros(B, dtype=np.int64), b_pos=b_pos, b_heading=b_heading, b_vel=b_vel,
            b_gps_err=gps_err,
            k_pos=start.copy(), k_vel=np.zeros((B, 2)), k_age_s=np.zeros(B), k_has_fix=np.zeros(B, dtype=bool),
            temperature_c=c.water_temperature_c + c.temperature_uncertainty_c * n[:, 14],
            current_mean=current_mean,
            current_gm=c.current_gm_std_mps * (n[:, 15] + 1j * n[:, 16]),
            b_surge=c.boat_surge_noise_mps * n[:, 17:19].copy(),
            b_steer=np.radians(c.boat_steering_noise_deg) * n[:, 19:21].copy(),
        )

    # ------------------------------------------------------------------------------
    def command_velocity(self, actions):
        """Actions (B,2,2) in [-1, 1] -> commanded ground velocity, complex (B,2).
        "frame_velocity": (v_x, v_y) / max speed in the GPS frame; "velocity":
        (v_east, v_north) / max speed (norm clipped to 1 in both); "heading_speed"."""
        a = np.ascontiguousarray(actions, dtype=float)
        out = np.empty(a.shape[:2], dtype=complex)
        st = self.state
        command_velocity(a, st.b_pos, st.b_gps_err, self._max_speed, self._action_mode, out)
        return out

    def step(self, actions) -> StepResult:
        c, st = self.config, self.state
        B, K, dt, T = self.batch_size, self.K, c.substep_s, c.ping_interval_s
        draws = self._draws.draw(st.keys, st.cycle)

        if self._world:
            # the mission through the frame the boats telemeter (their GPS at the cycle's start),
            # and the river's current where the boats and the vehicle are
            st.s_waypoints[:, 0, :, 0], st.s_waypoints[:, 0, :, 1] = frame_waypoints(st.b_pos, st.b_gps_err,
                                                                                     self._waypoints)
            boat_current, vehicle_current = self._river_currents(self._river_at_boats()[1])
        else:
            vehicle_current = st.current_mean + st.current_gm
        # 1. the boats: their commands, then how far their motion strays from them
        self._k_beacons(st.b_pos, st.b_heading, st.b_vel, self.command_velocity(actions),
                        self._boat_turn_cos, self._boat_turn_sin, K, dt)
        if not self._world:  # uniform water: the vehicle's current at both boats
            boat_current = np.repeat(vehicle_current[:, None], 2, axis=1)
        disturb_boats(st.b_pos, st.b_heading, st.b_vel, st.b_surge, st.b_steer, boat_current,
                      c.boat_current_response, T)
        if self._world:
            bank = (np.abs(self._river_at_boats()[0]) > 0.5 * c.river_width_m).astype(float)  # after the move
        n_boat = draws["boat"]
        st.b_surge = boat_noise_step(st.b_surge, T, c.boat_noise_time_constant_s, c.boat_surge_noise_mps,
                                     n_boat[..., 0])
        st.b_steer = boat_noise_step(st.b_steer, T, c.boat_noise_time_constant_s,
                                     np.radians(c.boat_steering_noise_deg), n_boat[..., 1])
        # 2. the vehicle: guidance, motion, dead reckoning, filter prediction
        noise = draws["substep"] * st.ep_noise_scale[:, None, None]
        integrate_vehicle(st.s_pos, st.s_heading, st.s_vel_true, st.s_wp_index, st.s_done, st.s_waypoints,
                          st.s_n_waypoints, st.s_speed_scale, c.survey_speed_mps, st.s_compass_bias_rad,
                          np.radians(c.compass_noise_deg) * noise[:, :, 0], c.speed_encoder_noise_mps * noise[:, :, 1],
                          vehicle_current, st.f_E, st.f_P, self._Q, st.s_dr, st.s_heading_meas_rad,
                          st.s_speed_meas_mps, dt, c.los_alpha, c.waypoint_acceptance_m, self._turn_cos,
                          self._turn_sin, K)
        n_cur = draws["current"]
        st.current_gm = gauss_markov_step(st.current_gm, T, c.current_gm_time_constant_s, c.current_gm_std_mps,
                                          n_cur[:, 0] + 1j * n_cur[:, 1])
        st.t_s = st.t_s + T
        st.cycle = st.cycle + 1
        st.b_gps_err = c.gps_noise_m * draws["gps"]

        # 3.-5. the exchange, the filter's updates, the boats' tracking, reward terms and
        # infos, in one kernel (``cycle``). What numpy computes differently from the C
        # library (arctan2, log) stays here: the frame bearings of the true and the GPS
        # positions, the multipath excesses' logarithms, the wrapped frame rotation.
        en = np.empty((2, B, 2, 2))
        en[0] = st.b_pos[..., :2]
        np.add(en[0], st.b_gps_err, out=en[1])
        phi, length = lbl.baseline(en[:, :, 0], en[:, :, 1])  # (2, B): true, GPS
        turned = np.abs(np.angle(np.exp(1j * (phi[0] - st.ep_phi0_rad)))) > self._rotation_tolerance_rad
        if self._world:
            turned[:] = False  # the frame must turn with the river: no rotation term (see the module docstring)
        log_u = np.log(draws["acoustic_u"][..., 2])
        fval = np.empty((B, N_FVAL))
        ival = np.empty((B, N_IVAL), dtype=np.int64)
        bval = np.empty((B, 1), dtype=bool)
        self._k_cycle(st.s_pos, st.s_vel_true, st.b_pos, st.b_vel, en[1], st.temperature_c, st.ep_noise_scale,
                      draws["depth"], draws["jitter"], draws["acoustic_u"], log_u, st.f_E, st.f_P,
                      st.f_rejected_cycles, st.s_speed_meas_mps, st.s_heading_meas_rad, st.s_dr, st.k_pos, st.k_vel,
                      st.k_age_s, st.k_has_fix, phi[0], length[0], phi[1], length[1], self._scalars,
                      fval, ival, bval)
        logdet = floored_log(fval[:, _F_DET_BEFORE:_F_DET_AFTER + 1])
        info_gain = logdet[:, 0] - logdet[:, 1]
        team = lambda k: np.broadcast_to(fval[:, k:k + 1], (B, 2))  # noqa: E731 - one value for both boats
        terms = {"info_gain": np.broadcast_to(info_gain[:, None], (B, 2)),
                 "safety": fval[:, _F_SAFETY:_F_SAFETY_B2 + 1], "baseline": team(_F_BASELINE_OFF),
                 "approach": team(_F_APPROACH), "rotation": np.broadcast_to(turned.astype(float)[:, None], (B, 2)),
                 "contact": team(_F_CONTACT)}
        if self._world:
            terms["bank"] = bank

        terminated = st.s_done[:, 0].copy()
        if c.mission_duration_s > 0:
            terminated |= st.t_s >= c.mission_duration_s - 1e-9
        truncated = (st.cycle >= c.max_cycles) & ~terminated
        col = {name: fval[:, k:k + 1] for name, k in _INFO_COLUMNS}  # (B, S=1) views
        info = {
            "survey_error_m": col["survey_error_m"],
            "dr_error_m": col["dr_error_m"],
            "cov_logdet": logdet[:, 1:2],
            "range_ok": bval[:, 0:1],
            "ranges_fused": ival[:, 0:1],
            "outliers_rejected": ival[:, 1:2],
            "nan_rejected": np.zeros((B, 1), dtype=np.int64),
            "packets_lost": ival[:, 2:3],
            "filter_restarts": ival[:, 3:4],
            "survey_error_en_m": np.stack([col["error_x_m"], col["error_y_m"]], -1),
            "survey_cov_en_m2": st.f_P[:, None, :2, :2].copy(),
            "error_x_m": col["error_x_m"], "error_y_m": col["error_y_m"],
            "phi_error_deg": np.degrees(np.arctan2(fval[:, _F_PHI_ERR_SIN], fval[:, _F_PHI_ERR_COS]))[:, None],
            "baseline_error_m": col["baseline_error_m"],
            "ellipse_major_m": col["ellipse_major_m"], "ellipse_minor_m": col["ellipse_minor_m"],
            "vehicle_y_m": col["vehicle_y_m"],
        }
        return StepResult(self.observe(), weighted_reward(terms, self.reward_weights), terminated, truncated, info, terms,
                          self._beacon_info())

    def _beacon_info(self) -> dict:
        """Per boat (B, 2): the true horizontal error of its GPS position (m)."""
        return {"beacon_error_m": np.hypot(self.state.b_gps_err[..., 0], self.state.b_gps_err[..., 1])}

    def _river_at_boats(self) -> tuple:
        """Each boat's true signed offset from the river's centerline (B, 2), m (+ right of
        downstream), and the downstream unit tangent there (B, 2) complex (``river.offsets``)."""
        return river.offsets(self.state.b_pos[..., :2], self._river_pts, self._river_cum)

    def _river_currents(self, t_boats) -> tuple:
        """The river's current at each boat (B, 2) and at the vehicle (B,), complex m/s, given
        the tangents at the boats (``_river_at_boats``): the episode's mean speed along the
        local downstream direction of the centerline (the nearest segment's,
        ``river.project``) plus the Gauss-Markov part, which is the same everywhere. [U] a
        plug flow: no slower water near the banks, no secondary flow in the bends."""
        st = self.state
        _, t_vehicle = river.offsets(st.s_pos[:, 0, :2], self._river_pts, self._river_cum)
        speed = st.current_mean.real  # the river's mean speed (see _initial_state)
        return speed[:, None] * t_boats + st.current_gm[:, None], speed * t_vehicle + st.current_gm

    def _state_info(self) -> dict:
        """The infos that follow from the state, in the true frame (as a step computes
        them in its kernel): errors of the filter and of dead reckoning, the frame's
        orientation and baseline errors, the 2-sigma ellipse, the vehicle's y."""
        st = self.state
        v = st.s_pos[:, 0, :2]
        x, y, phi, length = lbl.world_to_frame(st.b_pos[:, 0, :2], st.b_pos[:, 1, :2], v)
        major, minor, _ = error_ellipse(st.f_P)
        col = lambda a: np.asarray(a, dtype=float)[:, None]  # noqa: E731 - (B,) -> (B, S=1)
        return {
            "survey_error_m": col(np.hypot(st.f_E[:, 0] - x, st.f_E[:, 1] - y)),
            "dr_error_m": col(np.linalg.norm(st.s_dr[:, 0, :2] - v, axis=-1)),
            "cov_logdet": col(floored_log(st.f_P[:, 0, 0] * st.f_P[:, 1, 1] - st.f_P[:, 0, 1] * st.f_P[:, 1, 0])),
            "error_x_m": col(st.f_E[:, 0] - x), "error_y_m": col(st.f_E[:, 1] - y),
            "survey_error_en_m": np.stack([st.f_E[:, 0] - x, st.f_E[:, 1] - y], -1)[:, None],
            "survey_cov_en_m2": st.f_P[:, None, :2, :2].copy(),
            "phi_error_deg": col(np.degrees(np.angle(np.exp(1j * (st.f_E[:, 2] - phi))))),
            "baseline_error_m": col(st.f_E[:, 5] - length),
            "ellipse_major_m": col(major), "ellipse_minor_m": col(minor), "vehicle_y_m": col(y),
        }

    def snapshot(self) -> Snapshot:
        """Positions in the world: the filter's frame estimate and the mission's
        waypoints placed through the true frame (as the logged boat positions allow
        after the mission, section IV); the covariance rotated from the frame to
        east/north."""
        st = self.state
        b1 = st.b_pos[:, 0, :2]
        phi, _ = lbl.baseline(b1, st.b_pos[:, 1, :2])
        est = np.concatenate([lbl.frame_to_world(b1, phi, st.f_E[:, 0], st.f_E[:, 1]), st.s_pos[:, 0, 2:]], -1)
        wp = st.s_waypoints[:, 0]
        if self._world:  # the mission itself
            wp = np.broadcast_to(self._waypoints, wp.shape)
            wp_en = wp[..., :2]
        else:
            wp_en = lbl.frame_to_world(b1[:, None], phi[:, None], wp[..., 0], wp[..., 1])
        # frame (x, y) -> (east, north): the columns are the unit vectors of x and y (y is x turned
        # 90 degrees clockwise), so P_en = R P_xy R^T
        x_axis = bearing_to_unit(phi)
        R = np.stack([np.stack([x_axis.real, x_axis.imag], -1), np.stack([x_axis.imag, -x_axis.real], -1)], -1)
        cov = R @ st.f_P[:, :2, :2] @ np.swapaxes(R, -1, -2)
        gps = np.concatenate([st.b_pos[..., :2] + st.b_gps_err, st.b_pos[..., 2:]], -1)
        return Snapshot(t_s=st.t_s.copy(), survey_true_m=st.s_pos.copy(), survey_est_m=est[:, None],
                        survey_dr_m=st.s_dr.copy(), survey_cov_en_m2=cov[:, None], beacon_true_m=st.b_pos.copy(),
                        beacon_est_m=gps, waypoints_m=np.concatenate([wp_en, wp[..., 2:]], -1)[:, None],
                        n_waypoints=st.s_n_waypoints.copy())

    # ------------------------------------------------------------------------------
    def observe(self) -> np.ndarray:
        """What each boat knows, normalized: (B, 2, obs_dim), fields ``obs_fields(config)``,
        vectors in the frame of the boats' GPS positions (x along B1 -> B2, y
        clockwise from it), lengths / L (L = baseline_target_m): role (+1 B1, -1 B2);
        own velocity / max speed; (l_gps - L) / L; the vehicle as tracked, predicted
        to now: position / L and velocity / survey speed; age of the last fix /
        (10 T); a fix was ever made; the frame's bearing (sin, cos); own position
        minus the tracked vehicle / L; elapsed fraction of max_cycles (``observe_boats``).
        A mission in the world appends ``RIVER_OBS_FIELDS`` (``observe_river``): the boat's
        offset from the centerline / (river_width_m / 2), the river's direction and the
        centerline point ``RIVER_LEAD_BASELINES`` L ahead of the tracked vehicle, minus
        the boat's position, / L: where to go (the boats know the river's map)."""
        c, st = self.config, self.state
        out = np.empty((self.batch_size, 2, OBS_DIM), dtype=np.float32)
        self._k_observe(st.b_pos, st.b_gps_err, st.b_vel, st.k_pos, st.k_vel, st.k_age_s, st.k_has_fix, st.cycle,
                        c.baseline_target_m, c.boat_max_speed_mps, c.survey_speed_mps,
                        AGE_SCALE_PINGS * c.ping_interval_s, c.max_cycles, out)
        if self._world:
            extra = np.empty((self.batch_size, 2, RIVER_OBS_DIM), dtype=np.float32)
            L = c.baseline_target_m
            observe_river(st.b_pos, st.b_gps_err, st.k_pos, st.k_vel, st.k_age_s, self._river_pts, self._river_cum,
                          self._mission_dir, RIVER_LEAD_BASELINES * L, L, 0.5 * c.river_width_m, extra)
            out = np.concatenate([out, extra], -1)
        return out

    def global_state(self) -> np.ndarray:
        """True state for a centralized critic (B, state_dim), normalized: 24 values, and for a
        mission in the world the boats' offsets from the river's centerline / (width / 2) and
        the current at the vehicle in place of the uniform one."""
        c, st = self.config, self.state
        L = c.baseline_target_m
        b1, b2, v = st.b_pos[:, 0, :2], st.b_pos[:, 1, :2], st.s_pos[:, 0, :2]
        x, y, phi, length = lbl.world_to_frame(b1, b2, v)
        major, minor, bearing = error_ellipse(st.f_P)
        if self._world:  # the boats projected once, for the current and their offsets
            boat_off, boat_tangent = self._river_at_boats()
            cur = self._river_currents(boat_tangent)[1]
        else:
            cur = st.current_mean + st.current_gm
        parts = [
            x / L, y / L, (st.f_E[:, 0] - x) / 10.0, (st.f_E[:, 1] - y) / 10.0,
            np.sin(st.f_E[:, 2] - phi), (st.f_E[:, 5] - length) / 10.0, (length - L) / L,
            np.cos(phi - st.ep_phi0_rad), np.sin(phi - st.ep_phi0_rad), major / 50.0, minor / 50.0,
            np.cos(2 * bearing), np.sin(2 * bearing), st.b_vel[:, 0, 0], st.b_vel[:, 0, 1], st.b_vel[:, 1, 0],
            st.b_vel[:, 1, 1], st.s_vel_true[:, 0, 0], st.s_vel_true[:, 0, 1], cur.real, cur.imag,
            (st.k_pos[:, 0] - v[:, 0]) / 10.0, (st.k_pos[:, 1] - v[:, 1]) / 10.0, st.cycle / c.max_cycles,
        ]
        if self._world:
            off = boat_off / (0.5 * c.river_width_m)
            parts += [off[:, 0], off[:, 1]]
        return np.clip(np.stack(parts, -1), -OBS_BOUND, OBS_BOUND).astype(np.float32)
