"""The moving acoustic network of Matos & Cruz: one AUV navigating in the frame of
two beacon boats, batched (``network = "moving_lbl"``).

One step is one positioning cycle of ``ping_interval_s``:

1. the boats' actions become ground-velocity commands (the same rate-limited
   kernel as every beacon, ``substeps.integrate_beacons``);
2. the vehicle is integrated in sub-steps: line-of-sight guidance (Fig. 5) on its
   filter's frame estimate, heading reference psi + phi_hat steered on the compass,
   true motion = water speed x heading + current; the filter predicts with the
   measured water speed (propeller encoder) and compass heading (section VII);
3. the three-interval exchange of section V runs in time between the moving
   vehicles (``core.lbl.exchange``); the filter fuses d1 as it arrives, then d2 and
   l together (their noises are correlated, see ``_fuse``);
4. the boats, which hear S1, S2 and S4 too, track the vehicle externally
   (``core.lbl.track_fix``): that, their GPS and each other's position over the
   radio is all they observe;
5. reward: the information the vehicle's filter gained this cycle (log det of its
   (x, y) covariance before minus after), shared by the boats, minus penalties: a
   boat within ``safety_distance_m`` of the vehicle; the baseline off its target
   by more than ``baseline_tolerance_m``; the vehicle nearer the baseline than
   ``min_baseline_distance_m``; the frame turned more than
   ``frame_rotation_tolerance_deg`` from its start (the filter models phi as
   constant: a turning frame makes it confidently wrong, which the information
   term alone would reward); no range fused this cycle.

It exposes the same interface as ``core.sim.Simulator`` (reset, step, observe,
global_state, obs_dim, state_dim, info_keys, variants), so every view, the trainer
and evaluate.py run it unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from . import lbl, rng, substeps
from .acoustics import mackenzie_sound_speed, packet_loss_probability
from .dynamics import bearing_to_unit, gauss_markov_step
from .dynamics import turn_toward
from .guidance import build_path, los_point
from .information import ELLIPSE_N_SIGMA, error_ellipse, logdet_horizontal
from .navigation import frame_predict, frame_range_model, frame_velocity, gate_threshold, joseph_update_batch
from .sim import INFO_KEYS, BatchSimulator, StepResult
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
AGE_SCALE_PINGS = 10.0
TRACKER_ALPHA, TRACKER_BETA = 0.5, 0.2  # the boats' alpha-beta tracker on the fixes [U]
REINIT_AFTER_CYCLES = 3  # the vehicle restarts its position from an LBL fix after this many gated-out cycles


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
    # the boats' tracker of the vehicle (shared over their radio link)
    k_pos: np.ndarray  # (B,2) east, north at the last update
    k_vel: np.ndarray  # (B,2)
    k_age_s: np.ndarray  # time since the last fix (B,)
    k_has_fix: np.ndarray  # (B,) bool
    # water
    temperature_c: np.ndarray
    current_mean: np.ndarray  # complex (B,)
    current_gm: np.ndarray

    @property
    def s_est(self):
        """The filter's position mapped to the world through the true frame (B,1,3),
        as the logged boat positions allow after the mission (section IV)."""
        phi, _ = lbl.baseline(self.b_pos[:, 0, :2], self.b_pos[:, 1, :2])
        en = lbl.frame_to_world(self.b_pos[:, 0, :2], phi, self.f_E[:, 0], self.f_E[:, 1])
        return np.concatenate([en, self.s_pos[:, 0, 2:]], -1)[:, None]

    @property
    def waypoints_en(self):
        """The mission's waypoints placed in the world by the current true frame (B,1,W,3)."""
        b1 = self.b_pos[:, 0, :2]
        phi, _ = lbl.baseline(b1, self.b_pos[:, 1, :2])
        wp = self.s_waypoints[:, 0]
        en = lbl.frame_to_world(b1[:, None], phi[:, None], wp[..., 0], wp[..., 1])
        return np.concatenate([en, wp[..., 2:]], -1)[:, None]

    @property
    def s_P(self):
        """The filter's covariance (B,1,6,6); its (x, y) block gives the error ellipse."""
        return self.f_P[:, None]


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
        wp, _ = build_path(c, 0)
        self._waypoints = wp
        self._max_speed = np.full(2, c.boat_max_speed_mps)
        turn = np.radians(np.full(2, c.boat_max_turn_rate_dps)) * c.substep_s
        self._boat_turn_cos, self._boat_turn_sin = np.cos(turn), np.sin(turn)
        vturn = np.radians(c.survey_max_turn_rate_dps) * c.substep_s
        self._turn_cos, self._turn_sin = float(np.cos(vturn)), float(np.sin(vturn))
        self._Q = np.diag([c.frame_q_position_m2ps, c.frame_q_position_m2ps, c.frame_q_orientation_rad2ps,
                           c.frame_q_current_m2ps3, c.frame_q_current_m2ps3, c.frame_q_baseline_m2ps])
        self._gate1 = gate_threshold(c.range_gate_probability, 1)
        self._gate2 = gate_threshold(c.range_gate_probability, 2)
        self._k_beacons = substeps.integrate_beacons_parallel if B >= 256 else substeps.integrate_beacons
        n_det = lbl.N_DETECTIONS
        self._draws = rng.DrawLayout([
            ("current", "normal", (2,)), ("substep", "normal", (self.K, 2)), ("depth", "normal", (1,)),
            ("jitter", "normal", (n_det,)), ("acoustic_u", "uniform", (n_det, 3)), ("gps", "normal", (2, 2)),
        ], B)
        self.obs_dim, self.state_dim = OBS_DIM, 24
        self.state: FrameState | None = None

    def _initial_state(self, seeds) -> FrameState:
        c = self.config
        B = len(seeds)
        keys = rng.env_keys(seeds)
        zero = np.zeros(B, dtype=np.int64)
        # normals: 0-1 position prior, 2 phi prior, 3-4 unused (kept so that the others keep
        # their numbers), 5 l prior, 6-7 dead-reckoning start, 8 speed scale, 9 compass bias,
        # 10-13 GPS, 14 temperature, 15-16 the current's Gauss-Markov part
        n = rng.normal(keys, rng.STREAM_EPISODE, zero, (17,))
        u = rng.uniform(keys, rng.STREAM_EPISODE + 100, zero, (3,))
        phi0 = np.radians(c.frame_orientation_deg + c.frame_orientation_spread_deg * (2 * u[:, 0] - 1))
        L = c.baseline_target_m
        b_pos = np.zeros((B, 2, 3))
        b2 = L * bearing_to_unit(phi0)
        b_pos[:, 1, 0], b_pos[:, 1, 1] = b2.real, b2.imag
        y_axis = bearing_to_unit(phi0 + np.pi / 2)
        transit = c.boat_transit_speed_mps * y_axis
        b_heading = np.repeat((np.where(c.boat_transit_speed_mps < 0, -y_axis, y_axis))[:, None], 2, 1)
        b_vel = np.zeros((B, 2, 3))
        b_vel[..., 0], b_vel[..., 1] = transit.real[:, None], transit.imag[:, None]

        wp = np.broadcast_to(self._waypoints, (B,) + self._waypoints.shape)[:, None].copy()
        x0, y0, z0 = self._waypoints[0]
        start = lbl.frame_to_world(np.zeros((B, 2)), phi0, np.full(B, x0), np.full(B, y0))
        s_pos = np.zeros((B, 1, 3))
        s_pos[:, 0, :2], s_pos[:, 0, 2] = start, z0
        x1, y1, _ = self._waypoints[1]
        first = lbl.frame_to_world(np.zeros((B, 2)), phi0, np.full(B, x1), np.full(B, y1)) - start
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
            b_gps_err=c.gps_noise_m * n[:, 10:14].reshape(B, 2, 2),
            k_pos=start.copy(), k_vel=np.zeros((B, 2)), k_age_s=np.zeros(B), k_has_fix=np.zeros(B, dtype=bool),
            temperature_c=c.water_temperature_c + c.temperature_uncertainty_c * n[:, 14],
            current_mean=cur_speed * bearing_to_unit(cur_dir),
            current_gm=c.current_gm_std_mps * (n[:, 15] + 1j * n[:, 16]),
        )

    # ------------------------------------------------------------------------------
    def _gps_frame(self):
        """The frame as the boats' GPS gives it: B1's position (B,2), x and y axes as
        complex (east + 1j north) units (B,), the baseline length (B,)."""
        gps = self.state.b_pos[..., :2] + self.state.b_gps_err
        base = (gps[:, 1, 0] - gps[:, 0, 0]) + 1j * (gps[:, 1, 1] - gps[:, 0, 1])
        length = np.abs(base)
        x_axis = base / np.maximum(length, 1e-9)
        return gps, x_axis, -1j * x_axis, length  # y = x turned 90 degrees clockwise

    def command_velocity(self, actions):
        """Actions (B,2,2) in [-1, 1] -> commanded ground velocity, complex (B,2).
        "frame_velocity": (v_x, v_y) / max speed in the GPS frame; "velocity":
        (v_east, v_north) / max speed (norm clipped to 1 in both); "heading_speed"."""
        vmax = self._max_speed
        mode = self.config.action_mode
        if mode in ("velocity", "frame_velocity"):
            v = actions[..., 0] + 1j * actions[..., 1]
            norm = np.abs(v)
            v = np.where(norm > 1.0, v / np.maximum(norm, 1e-12), v) * vmax
            if mode == "frame_velocity":
                _, x_axis, y_axis, _ = self._gps_frame()
                v = v.real * x_axis[:, None] + v.imag * y_axis[:, None]
            return v
        return 0.5 * (actions[..., 1] + 1.0) * vmax * bearing_to_unit(np.pi * actions[..., 0])

    def step(self, actions) -> StepResult:
        c, st = self.config, self.state
        B, K, dt, T = self.batch_size, self.K, c.substep_s, c.ping_interval_s
        draws = self._draws.draw(st.keys, st.cycle)

        # 1. the boats
        self._k_beacons(st.b_pos, st.b_heading, st.b_vel, self.command_velocity(np.asarray(actions, dtype=float)),
                        self._boat_turn_cos, self._boat_turn_sin, K, dt)
        # 2. the vehicle: guidance, motion, dead reckoning, filter prediction
        noise = draws["substep"] * st.ep_noise_scale[:, None, None]
        integrate_vehicle(st.s_pos, st.s_heading, st.s_vel_true, st.s_wp_index, st.s_done, st.s_waypoints,
                          st.s_n_waypoints, st.s_speed_scale, c.survey_speed_mps, st.s_compass_bias_rad,
                          np.radians(c.compass_noise_deg) * noise[:, :, 0], c.speed_encoder_noise_mps * noise[:, :, 1],
                          st.current_mean + st.current_gm, st.f_E, st.f_P, self._Q, st.s_dr, st.s_heading_meas_rad,
                          st.s_speed_meas_mps, dt, c.los_alpha, c.waypoint_acceptance_m, self._turn_cos,
                          self._turn_sin, K)
        n_cur = draws["current"]
        st.current_gm = gauss_markov_step(st.current_gm, T, c.current_gm_time_constant_s, c.current_gm_std_mps,
                                          n_cur[:, 0] + 1j * n_cur[:, 1])
        st.t_s = st.t_s + T
        st.cycle = st.cycle + 1
        st.b_gps_err = c.gps_noise_m * draws["gps"]

        # 3. the exchange and the filter's updates
        logdet_before = logdet_horizontal(st.f_P)
        ex = self._exchange(draws)
        fused, rejected = self._fuse(ex, draws)
        logdet_after = logdet_horizontal(st.f_P)

        # 4. the boats' tracking
        self._track(ex)

        # 5. reward, ends, infos
        b1, b2, v = st.b_pos[:, 0, :2], st.b_pos[:, 1, :2], st.s_pos[:, 0, :2]
        x, y, phi, length = lbl.world_to_frame(b1, b2, v)
        dist = np.linalg.norm(st.b_pos - st.s_pos, axis=-1)  # (B,2)
        too_close = dist < c.safety_distance_m
        off_baseline = np.abs(length - c.baseline_target_m) > c.baseline_tolerance_m
        near_baseline = y < c.min_baseline_distance_m
        no_contact = fused.sum(-1) == 0
        turned = np.abs(np.angle(np.exp(1j * (phi - st.ep_phi0_rad)))) > np.radians(c.frame_rotation_tolerance_deg)
        team = (c.baseline_penalty * off_baseline + c.approach_penalty * near_baseline
                + c.rotation_penalty * turned)[:, None]
        penalties = c.safety_penalty * too_close + team
        info_gain = logdet_before - logdet_after
        reward = info_gain[:, None] - penalties - c.contact_penalty * no_contact[:, None]

        terminated = st.s_done[:, 0].copy()
        if c.mission_duration_s > 0:
            terminated |= st.t_s >= c.mission_duration_s - 1e-9
        truncated = (st.cycle >= c.max_cycles) & ~terminated
        ex_, ey_ = st.f_E[:, 0] - x, st.f_E[:, 1] - y
        major, minor, _ = error_ellipse(st.f_P, n_sigma=ELLIPSE_N_SIGMA)
        col = lambda a: np.asarray(a)[:, None]  # noqa: E731  (B,) -> (B, S=1)
        info = {
            "survey_error_m": col(np.hypot(ex_, ey_)),
            "dr_error_m": col(np.linalg.norm(st.s_dr[:, 0, :2] - v, axis=-1)),
            "cov_logdet": col(logdet_after),
            "range_ok": col(fused[:, :2].any(-1)),
            "ranges_fused": col(fused.sum(-1)),
            "outliers_rejected": col(rejected),
            "nan_rejected": col(np.zeros(B, dtype=np.int64)),
            "packets_lost": col(ex["lost_count"]),
            "error_x_m": col(ex_), "error_y_m": col(ey_),
            "phi_error_deg": col(np.degrees(np.angle(np.exp(1j * (st.f_E[:, 2] - phi))))),
            "baseline_error_m": col(st.f_E[:, 5] - length),
            "ellipse_major_m": col(major), "ellipse_minor_m": col(minor), "vehicle_y_m": col(y),
        }
        return StepResult(self.observe(), reward, terminated, truncated, info, penalties)

    def _exchange(self, draws):
        c, st = self.config, self.state
        B = self.batch_size
        depth = st.s_pos[:, 0, 2]
        c_true = mackenzie_sound_speed(st.temperature_c, c.salinity_psu, depth)
        cn = mackenzie_sound_speed(np.full(B, c.water_temperature_c), c.salinity_psu, depth)
        # each detection instant is late by a jitter; a two-way range has two of them,
        # halved: sigma_t = sqrt(2) sigma_r / c gives ranges d1, d2 with std sigma_r
        sigma_r = c.range_noise_std_m * st.ep_noise_scale
        jitter = (np.sqrt(2.0) * sigma_r / cn)[:, None] * draws["jitter"]
        u = draws["acoustic_u"]
        late = np.where(u[..., 1] < c.outlier_probability, -c.outlier_mean_excess_m * np.log(u[..., 2]), 0.0)
        late = late / c_true[:, None]
        v3 = st.s_pos[:, 0]
        d_b1 = np.linalg.norm(st.b_pos[:, 0] - v3, axis=-1)
        d_b2 = np.linalg.norm(st.b_pos[:, 1] - v3, axis=-1)
        base = np.linalg.norm(st.b_pos[:, 1] - st.b_pos[:, 0], axis=-1)
        path = np.stack([d_b1, d_b1, base, d_b2, d_b2, d_b2, d_b2], -1)  # distance each signal travels
        lost = u[..., 0] < packet_loss_probability(path, c.packet_loss_near, c.packet_loss_far, c.max_range_m)
        timeout = 2.0 * c.max_range_m / cn + 2.0 * c.turnaround_s
        ex = lbl.exchange(v3, st.s_vel_true[:, 0], st.b_pos[:, 0], st.b_vel[:, 0], st.b_pos[:, 1], st.b_vel[:, 1],
                          c_true, cn, jitter, late, lost, c.turnaround_s, c.turnaround_s, timeout)
        ex["nominal_sound_speed_mps"] = cn  # the speed everyone converts times with (tracking too)
        return ex

    def _fuse(self, ex, draws):
        """Section VII's updates: d1 when S2 arrives, then d2 and l when S5 arrives.

        d2 and l arrive together and share detection errors: with sigma_t per
        detection, d1 = c(e1 + e2)/2, d2 = c(e5 + e6)/2 and l = m - d1 - d2 with
        m = c(e1 + e3 + e4) give var(d1) = var(d2) = sigma_r^2, var(l) = 6 sigma_r^2,
        cov(d2, l) = -sigma_r^2 and cov(d1, l) = 0 (e_i: the detections in
        ``lbl.DETECTIONS`` order). So d1 is a scalar update and (d2, l) one joint
        update with that R; treating them as independent, as a naive sequential
        filter would, overweights l. Each update passes a chi-square gate.
        """
        c, st = self.config, self.state
        B = self.batch_size
        sigma_r2 = (c.range_noise_std_m * st.ep_noise_scale) ** 2
        dz = st.s_pos[:, 0, 2] + c.depth_noise_m * draws["depth"][:, 0]  # depth cell; boats at the surface
        vel = frame_velocity(st.f_E, st.s_speed_meas_mps, st.s_heading_meas_rad)
        fused = np.zeros((B, 3), dtype=bool)
        # d1: the legs are S1 leaving (t = 0) and S2 arriving (t3)
        h, H = frame_range_model(st.f_E, 1, dz, vel, np.stack([np.zeros(B), ex["t3"]], -1))
        R1 = sigma_r2[:, None, None] * np.ones((B, 1, 1))
        st.f_E, st.f_P, nis = joseph_update_batch(st.f_E, st.f_P, (ex["d1"] - h)[:, None], H[:, None], R1,
                                                  ex["ok_d1"], self._gate1)
        fused[:, 0] = ex["ok_d1"] & (nis <= self._gate1)
        # d2 (legs: S4 leaving at t3s, S5 arriving at t6) with l when it is there, else alone;
        # the two updates touch disjoint rows
        vel = frame_velocity(st.f_E, st.s_speed_meas_mps, st.s_heading_meas_rad)
        h2, H2 = frame_range_model(st.f_E, 2, dz, vel, np.stack([ex["t3s"], ex["t6"]], -1))
        Hl = np.zeros((B, 6))
        Hl[:, 5] = 1.0
        y2 = np.stack([ex["d2"] - h2, ex["l"] - st.f_E[:, 5]], -1)
        R2 = sigma_r2[:, None, None] * np.array([[1.0, -1.0], [-1.0, 6.0]])
        alone = ex["ok_d2"] & ~ex["ok_l"]
        st.f_E, st.f_P, nis2 = joseph_update_batch(st.f_E, st.f_P, y2, np.stack([H2, Hl], 1), R2, ex["ok_l"],
                                                   self._gate2)
        st.f_E, st.f_P, nis1 = joseph_update_batch(st.f_E, st.f_P, y2[:, :1], H2[:, None], R1, alone, self._gate1)
        both = ex["ok_l"] & (nis2 <= self._gate2)
        fused[:, 1] = both | (alone & (nis1 <= self._gate1))
        fused[:, 2] = both
        rejected = np.stack([ex["ok_d1"] & ~fused[:, 0], ex["ok_l"] & ~both, alone & ~fused[:, 1]]).sum(0)
        self._reinitialize(ex, dz, fused, rejected, sigma_r2)
        return fused, rejected

    def _reinitialize(self, ex, dz, fused, rejected, sigma_r2):
        """Recover from gate lockout. A filter whose every measurement is rejected for
        ``REINIT_AFTER_CYCLES`` cycles (it has diverged: the gate now refuses the very
        ranges that would correct it) restarts its position from the spherical fix of
        this cycle's d1, d2 and l, with the fix's uncertainty; the paper does not
        discuss this, every fielded LBL navigator needs it."""
        st = self.state
        st.f_rejected_cycles = np.where(fused.any(-1), 0, st.f_rejected_cycles + (rejected > 0))
        x, y, ok = lbl.spherical_fix_batch(lbl.horizontal_range(ex["d1"], dz), lbl.horizontal_range(ex["d2"], dz),
                                           ex["l"])
        restart = (st.f_rejected_cycles >= REINIT_AFTER_CYCLES) & ex["ok_l"] & ok & (y > 0)
        if not restart.any():
            return
        E, P = st.f_E.copy(), st.f_P.copy()
        E[restart, 0], E[restart, 1], E[restart, 5] = x[restart], y[restart], ex["l"][restart]
        var = 4.0 * sigma_r2[restart]  # a single fix's position variance, GDOP ~ 2 [U]
        P[restart, :2, :] = 0.0
        P[restart, :, :2] = 0.0
        P[restart, 5, :] = 0.0
        P[restart, :, 5] = 0.0
        P[restart, 0, 0] = P[restart, 1, 1] = var
        P[restart, 5, 5] = 6.0 * sigma_r2[restart]
        st.f_E, st.f_P = E, P
        st.f_rejected_cycles = np.where(restart, 0, st.f_rejected_cycles)

    def _track(self, ex):
        """The boats' alpha-beta tracker on the external fixes (section III)."""
        c, st = self.config, self.state
        T = c.ping_interval_s
        gps = st.b_pos[..., :2] + st.b_gps_err
        fix, ok = lbl.track_fix(ex, gps[:, 0], gps[:, 1], c.depth_m, ex["nominal_sound_speed_mps"], c.turnaround_s,
                                c.turnaround_s)
        age = st.k_age_s + T
        pred = st.k_pos + st.k_vel * age[:, None]
        resid = fix - pred
        first = ok & ~st.k_has_fix
        update = ok & st.k_has_fix
        st.k_pos = np.where(first[:, None], fix, np.where(update[:, None], pred + TRACKER_ALPHA * resid, st.k_pos))
        st.k_vel = np.where(update[:, None], st.k_vel + TRACKER_BETA * resid / age[:, None], st.k_vel)
        st.k_age_s = np.where(ok, 0.0, age)
        st.k_has_fix = st.k_has_fix | ok

    # ------------------------------------------------------------------------------
    def observe(self) -> np.ndarray:
        """What each boat knows, normalized: (B, 2, OBS_DIM), fields ``OBS_FIELDS``,
        vectors in the frame of the boats' GPS positions (x along B1 -> B2, y
        clockwise from it), lengths / L (L = baseline_target_m): role (+1 B1, -1 B2);
        own velocity / max speed; (l_gps - L) / L; the vehicle as tracked, predicted
        to now: position / L and velocity / survey speed; age of the last fix /
        (10 T); a fix was ever made; the frame's bearing (sin, cos); own position
        minus the tracked vehicle / L; elapsed fraction of max_cycles."""
        c, st = self.config, self.state
        B, L = self.batch_size, c.baseline_target_m
        gps, x_axis, y_axis, length = self._gps_frame()
        tracked = st.k_pos + st.k_vel * st.k_age_s[:, None]

        def frame(v_en):  # (B, 2) east/north vectors -> frame (x, y)
            return np.stack([v_en[:, 0] * x_axis.real + v_en[:, 1] * x_axis.imag,
                             v_en[:, 0] * y_axis.real + v_en[:, 1] * y_axis.imag], -1)

        rel = frame(tracked - gps[:, 0])
        vel = frame(st.k_vel)
        out = np.empty((B, 2, OBS_DIM))
        for i in range(2):
            out[:, i] = np.column_stack([
                np.full(B, 1.0 - 2.0 * i), frame(st.b_vel[:, i, :2]) / c.boat_max_speed_mps, (length - L) / L,
                rel / L, vel / c.survey_speed_mps, st.k_age_s / (AGE_SCALE_PINGS * c.ping_interval_s),
                st.k_has_fix.astype(float), x_axis.real, x_axis.imag, frame(gps[:, i] - tracked) / L,
                st.cycle / c.max_cycles,
            ])
        return np.clip(out, -10.0, 10.0).astype(np.float32)

    def global_state(self) -> np.ndarray:
        """True state for a centralized critic (B, 24), normalized."""
        c, st = self.config, self.state
        L = c.baseline_target_m
        b1, b2, v = st.b_pos[:, 0, :2], st.b_pos[:, 1, :2], st.s_pos[:, 0, :2]
        x, y, phi, length = lbl.world_to_frame(b1, b2, v)
        major, minor, bearing = error_ellipse(st.f_P, n_sigma=ELLIPSE_N_SIGMA)
        cur = st.current_mean + st.current_gm
        parts = [
            x / L, y / L, (st.f_E[:, 0] - x) / 10.0, (st.f_E[:, 1] - y) / 10.0,
            np.sin(st.f_E[:, 2] - phi), (st.f_E[:, 5] - length) / 10.0, (length - L) / L,
            np.cos(phi - st.ep_phi0_rad), np.sin(phi - st.ep_phi0_rad), major / 50.0, minor / 50.0,
            np.cos(2 * bearing), np.sin(2 * bearing), st.b_vel[:, 0, 0], st.b_vel[:, 0, 1], st.b_vel[:, 1, 0],
            st.b_vel[:, 1, 1], st.s_vel_true[:, 0, 0], st.s_vel_true[:, 0, 1], cur.real, cur.imag,
            (st.k_pos[:, 0] - v[:, 0]) / 10.0, (st.k_pos[:, 1] - v[:, 1]) / 10.0, st.cycle / c.max_cycles,
        ]
        return np.clip(np.stack(parts, -1), -10.0, 10.0).astype(np.float32)
