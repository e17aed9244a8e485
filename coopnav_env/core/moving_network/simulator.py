"""``MovingNetworkSimulator``: the batched moving LBL network behind the simulator contract.

``step`` runs one positioning cycle (the package's docstring): the boats and the
vehicle move (``_move``: ``vehicle``), the per-cycle kernel runs the exchange, the
filter's updates, its recovery, the boats' tracking and the terms (``_run_cycle``:
``cycle``), and the reward is assembled from the named terms in one marked place.
What numpy computes differently from the C library (arctan2, log) stays in numpy
around the kernels: the frame bearings of the true and the GPS positions, the
multipath excesses' logarithms, the wrapped frame rotation.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .. import lbl, river, rng, substeps
from ..contract import BatchSimulator, Snapshot, StepResult
from ..dynamics import bearing_to_unit, boat_noise_step, disturb_boats, gauss_markov_step, max_turn_per_substep_rad
from ..guidance import build_path
from ..information import error_ellipse, floored_log
from ..jit import threaded
from ..navigation import gate_threshold
from ..observation import (  # the survey network's age scale and bound
    AGE_SCALE_PINGS,
    OBS_BOUND,
)
from ..reward import TermContext, collect_terms, has_hooks, term_weights, terms_for, weighted_reward
from ..sim import BEACON_INFO_KEYS
from .cycle import cycle, cycle_parallel
from .initial import initial_state
from .observe import (
    command_velocity,
    frame_waypoints,
    observe_boats,
    observe_boats_parallel,
    observe_river,
)
from .state import (
    CYCLE_COUNTS,
    CYCLE_OUT,
    FRAME_INFO_KEYS,
    OBS_DIM,
    RIVER_LEAD_BASELINES,
    RIVER_OBS_DIM,
    RIVER_STATE_DIM,
    Boats,
    CycleDraws,
    FrameState,
    ObserveParams,
    VehicleParams,
    cycle_params,
    filter_of,
    obs_dim_of,
    packed,
    tracker_of,
    vehicle_of,
)
from .terms import step_info
from .vehicle import integrate_vehicle

if TYPE_CHECKING:
    from ...scenarios.base import ScenarioConfig


class MovingNetworkSimulator(BatchSimulator):
    """The batched moving LBL network: B independent environments of one scenario."""

    def __init__(self, config: ScenarioConfig, batch_size: int = 1) -> None:
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
        self.reward_terms = terms_for(c, "moving_lbl")  # this network's registered terms (core.reward)
        self._term_hooks = has_hooks(self.reward_terms)  # a plug-in term computed in Python: build its context
        self.reward_weights = term_weights(c, self.reward_terms)
        wp, _ = build_path(c, 0)
        self._waypoints = wp  # frame (x, y, depth), or (east, north, depth) for a world mission
        if self._world:
            self._river_pts, self._river_cum = river.centerline_of(c.river_centerline_m)
            self._mission_dir = river.mission_direction(wp, self._river_pts, self._river_cum)
        self._max_speed = np.array(c.beacon_max_speeds_mps)
        turn = max_turn_per_substep_rad(np.full(2, c.boat_max_turn_rate_dps), c.substep_s)
        self._boat_turn_cos, self._boat_turn_sin = np.cos(turn), np.sin(turn)
        par = threaded(B)  # threaded kernels: off (core/jit.py says why)
        self._k_beacons = substeps.integrate_beacons_parallel if par else substeps.integrate_beacons
        self._k_cycle = cycle_parallel if par else cycle
        self._k_observe = observe_boats_parallel if par else observe_boats
        self._action_mode = ("velocity", "frame_velocity", "heading_speed").index(c.action_mode)
        self._rotation_tolerance_rad = np.radians(c.frame_rotation_tolerance_deg)
        self._build_params()
        n_det = lbl.N_DETECTIONS
        self._draws = rng.DrawLayout(
            [
                ("current", "normal", (2,)),
                ("substep", "normal", (self.K, 2)),
                ("depth", "normal", (1,)),
                ("jitter", "normal", (n_det,)),
                ("acoustic_u", "uniform", (n_det, 3)),
                ("gps", "normal", (2, 2)),
                ("boat", "normal", (2, 2)),  # per boat: surge, course (Gauss-Markov driving noise)
                ("motion", "normal", (2, 2)),  # per boat: GPS velocity error (x, y) of the telemetered frame motion
            ],
            B,
        )
        self.obs_dim = obs_dim_of(c)
        self.state_dim = 24 + (RIVER_STATE_DIM if self._world else 0)
        self.state: FrameState | None = None

    @property
    def _live(self) -> FrameState:
        """The state, after ``reset`` (``state`` is None before the first one)."""
        st = self.state
        assert st is not None, "MovingNetworkSimulator: call reset() before stepping or observing"
        return st

    def _build_params(self) -> None:
        """The kernels' records of the scenario's numbers, once."""
        c = self.config
        vturn = max_turn_per_substep_rad(c.survey_max_turn_rate_dps, c.substep_s)
        Q = np.diag(
            [
                c.frame_q_position_m2ps,
                c.frame_q_position_m2ps,
                c.frame_q_orientation_rad2ps,
                c.frame_q_current_m2ps3,
                c.frame_q_current_m2ps3,
                c.frame_q_baseline_m2ps,
            ]
        )
        self._vehicle_params = VehicleParams(
            float(c.survey_speed_mps),
            float(c.substep_s),
            float(c.los_alpha),
            float(c.waypoint_acceptance_m),
            float(np.cos(vturn)),
            float(np.sin(vturn)),
            Q,
            int(self.K),
        )
        self._cycle_params = cycle_params(
            c,
            gate_threshold(c.range_gate_probability, 1),
            gate_threshold(c.range_gate_probability, 2),
        )
        self._observe_params = ObserveParams(
            float(c.baseline_target_m),
            float(c.boat_max_speed_mps),
            float(c.survey_speed_mps),
            float(AGE_SCALE_PINGS * c.ping_interval_s),
            int(c.max_cycles),
        )

    def _initial_state(self, seeds: np.ndarray) -> FrameState:
        return initial_state(self, seeds)

    # ------------------------------------------------------------------------------
    def command_velocity(self, actions: np.ndarray) -> np.ndarray:
        """Actions (B,2,2) in [-1, 1] -> commanded ground velocity, complex (B,2).
        "frame_velocity": (v_x, v_y) / max speed in the GPS frame; "velocity":
        (v_east, v_north) / max speed (norm clipped to 1 in both); "heading_speed"."""
        a = np.ascontiguousarray(actions, dtype=float)
        out = np.empty(a.shape[:2], dtype=complex)
        st = self._live
        command_velocity(a, st.b_pos, st.b_gps_err, self._max_speed, self._action_mode, out)
        return out

    def _move(self, actions: np.ndarray, draws: dict) -> np.ndarray | None:
        """Steps 1-2: the boats' commands and how far their motion strays from them, the
        vehicle's sub-steps; the water's and the boats' Gauss-Markov states, the clocks and
        the new GPS errors. Returns the bank term (B,2) of a world mission (after the move),
        else None."""
        c, st = self.config, self._live
        K, dt, T = self.K, c.substep_s, c.ping_interval_s
        if self._world:
            # the mission through the frame the boats telemeter (their GPS at the cycle's start),
            # and the river's current where the boats and the vehicle are
            st.s_waypoints[:, 0, :, 0], st.s_waypoints[:, 0, :, 1] = frame_waypoints(
                st.b_pos, st.b_gps_err, self._waypoints
            )
            boat_current, vehicle_current = self._river_currents(self._river_at_boats()[1])
        else:
            vehicle_current = st.current_mean + st.current_gm
        # 1. the boats: their commands, then how far their motion strays from them
        self._k_beacons(
            st.b_pos,
            st.b_heading,
            st.b_vel,
            self.command_velocity(actions),
            self._boat_turn_cos,
            self._boat_turn_sin,
            K,
            dt,
        )
        if not self._world:  # uniform water: the vehicle's current at both boats
            boat_current = np.repeat(vehicle_current[:, None], 2, axis=1)
        disturb_boats(
            st.b_pos, st.b_heading, st.b_vel, st.b_surge, st.b_steer, boat_current, c.boat_current_response, T
        )
        bank = None
        if self._world:
            bank = (np.abs(self._river_at_boats()[0]) > 0.5 * c.river_width_m).astype(float)  # after the move
        n_boat = draws["boat"]
        st.b_surge = boat_noise_step(
            st.b_surge, T, c.boat_noise_time_constant_s, c.boat_surge_noise_mps, n_boat[..., 0]
        )
        st.b_steer = boat_noise_step(
            st.b_steer, T, c.boat_noise_time_constant_s, np.radians(c.boat_steering_noise_deg), n_boat[..., 1]
        )
        # 2. the vehicle: guidance, motion, dead reckoning, filter prediction
        noise = draws["substep"] * st.ep_noise_scale[:, None, None]
        compass_noise = np.radians(c.compass_noise_deg) * noise[:, :, 0]
        integrate_vehicle(
            packed(vehicle_of(st)),
            packed(filter_of(st)),
            compass_noise,
            c.speed_encoder_noise_mps * noise[:, :, 1],
            vehicle_current,
            packed(self._vehicle_params),
        )
        n_cur = draws["current"]
        st.current_gm = gauss_markov_step(
            st.current_gm, T, c.current_gm_time_constant_s, c.current_gm_std_mps, n_cur[:, 0] + 1j * n_cur[:, 1]
        )
        st.t_s = st.t_s + T
        st.cycle = st.cycle + 1
        st.b_gps_err = c.gps_noise_m * draws["gps"]
        return bank

    def _frame_motion(self, start: np.ndarray, end: np.ndarray, draws: dict) -> np.ndarray:
        """The frame's motion over the cycle as the boats telemeter it (B, 4) (``frame_motion``):
        B1's displacement in the frame at the cycle's start, the rotation (bearing, wrapped by
        numpy) and the baseline's change, from the boats' true (east, north) at the start and
        the end (B,2,2), with the error of GPS velocities of std ``boat_velocity_noise_mps``
        per axis held over the cycle (eq. M3); zeros without ``frame_motion_telemetry``."""
        c, B = self.config, self.batch_size
        motion = np.zeros((B, 4))
        if not c.frame_motion_telemetry:
            return motion
        dx, dy, phi0, l0 = lbl.world_to_frame(start[:, 0], start[:, 1], end[:, 0])
        phi1, l1 = lbl.baseline(end[:, 0], end[:, 1])
        T = c.ping_interval_s
        dv = c.boat_velocity_noise_mps * T * draws["motion"]  # (B, boat, axis) in the frame: isotropic
        rel = dv[:, 1] - dv[:, 0]
        motion[:, 0], motion[:, 1] = dx + dv[:, 0, 0], dy + dv[:, 0, 1]
        motion[:, 2] = np.angle(np.exp(1j * (phi1 - phi0))) + rel[:, 1] / np.maximum(l0, 1e-9)
        motion[:, 3] = l1 - l0 + rel[:, 0]
        return motion

    def _run_cycle(self, draws: dict, start: np.ndarray) -> tuple:
        """Steps 3-5 (``cycle``): the exchange, the filter's updates and recovery, the boats'
        tracking, the kernel's terms and infos. The frame bearings of the true and the GPS
        positions, the multipath excesses' logarithms and the wrapped frame rotation are
        numpy's; start (B,2,2) the boats' true (east, north) at the cycle's start. Returns
        (out (B,) ``CYCLE_OUT``, counts (B,) ``CYCLE_COUNTS``, the frame turned beyond its
        tolerance (B,) bool)."""
        st, B = self._live, self.batch_size
        en = np.empty((2, B, 2, 2))
        en[0] = st.b_pos[..., :2]
        np.add(en[0], st.b_gps_err, out=en[1])
        phi, length = lbl.baseline(en[:, :, 0], en[:, :, 1])  # (2, B): true, GPS
        turned = np.abs(np.angle(np.exp(1j * (phi[0] - st.ep_phi0_rad)))) > self._rotation_tolerance_rad
        if self._world:
            turned[:] = False  # the frame must turn with the river: no rotation term (see the package docstring)
        cycle_draws = CycleDraws(
            st.temperature_c,
            st.ep_noise_scale,
            draws["depth"],
            draws["jitter"],
            draws["acoustic_u"],
            np.log(draws["acoustic_u"][..., 2]),
        )
        motion = self._frame_motion(start, en[0], draws)
        boats = Boats(st.b_pos, st.b_vel, phi[0], length[0], en[1], phi[1], length[1], motion)
        out, counts = np.empty(B, CYCLE_OUT), np.empty(B, CYCLE_COUNTS)
        self._k_cycle(
            packed(vehicle_of(st)),
            packed(filter_of(st)),
            packed(boats),
            packed(tracker_of(st)),
            packed(cycle_draws),
            packed(self._cycle_params),
            out,
            counts,
        )
        return out, counts, turned

    def step(self, actions: np.ndarray) -> StepResult:
        """One positioning cycle for every environment (the package's docstring)."""
        c, st, B = self.config, self._live, self.batch_size
        draws = self._draws.draw(st.keys, st.cycle)
        start = st.b_pos[..., :2].copy()  # the boats' true (east, north) at the cycle's start
        bank = self._move(actions, draws)
        out, counts, turned = self._run_cycle(draws, start)
        logdet = floored_log(out["det"])

        # --- the reward's terms (unweighted; the weights are term_weights') -----------------
        info_gain = logdet[:, 0] - logdet[:, 1]
        team = lambda name: np.broadcast_to(out[name][:, None], (B, 2))  # one value for both boats
        arrays = {
            "info_gain": np.broadcast_to(info_gain[:, None], (B, 2)),
            "safety": out["safety"],
            "baseline": team("baseline_off"),
            "approach": team("approach"),
            "rotation": np.broadcast_to(turned.astype(float)[:, None], (B, 2)),
            "contact": team("contact"),
            "bank": bank,
        }
        ctx = (
            TermContext()
            if not self._term_hooks
            else TermContext(
                sim=self, config=c, state=st, arrays={"out": out, "counts": counts, "logdet": logdet, "turned": turned}
            )
        )
        terms = collect_terms(self.reward_terms, arrays, ctx, (B, 2))  # registered terms, in their order
        reward = weighted_reward(terms, self.reward_weights)
        # --------------------------------------------------------------------------------------

        terminated = st.s_done[:, 0].copy()
        if c.mission_duration_s > 0:
            terminated |= st.t_s >= c.mission_duration_s - 1e-9
        truncated = (st.cycle >= c.max_cycles) & ~terminated
        info = step_info(out, counts, logdet, st.f_P)
        return StepResult(self.observe(), reward, terminated, truncated, info, terms, self._beacon_info())

    def _beacon_info(self) -> dict:
        """Per boat (B, 2): the true horizontal error of its GPS position (m)."""
        return {"beacon_error_m": np.hypot(self._live.b_gps_err[..., 0], self._live.b_gps_err[..., 1])}

    def _river_at_boats(self) -> tuple:
        """Each boat's true signed offset from the river's centerline (B, 2), m (+ right of
        downstream), and the downstream unit tangent there (B, 2) complex (``river.offsets``)."""
        return river.offsets(self._live.b_pos[..., :2], self._river_pts, self._river_cum)

    def _river_currents(self, t_boats: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The river's current at each boat (B, 2) and at the vehicle (B,), complex m/s, given
        the tangents at the boats (``_river_at_boats``): the episode's mean speed along the
        local downstream direction of the centerline (the nearest segment's,
        ``river.project``) plus the Gauss-Markov part, which is the same everywhere. [U] a
        plug flow: no slower water near the banks, no secondary flow in the bends."""
        st = self._live
        _, t_vehicle = river.offsets(st.s_pos[:, 0, :2], self._river_pts, self._river_cum)
        speed = st.current_mean.real  # the river's mean speed (see initial.current_mean_of)
        return speed[:, None] * t_boats + st.current_gm[:, None], speed * t_vehicle + st.current_gm

    def _state_info(self) -> dict:
        """The infos that follow from the state, in the true frame (as a step computes
        them in its kernel): errors of the filter and of dead reckoning, the frame's
        orientation and baseline errors, the 2-sigma ellipse, the vehicle's y."""
        st = self._live
        v = st.s_pos[:, 0, :2]
        x, y, phi, length = lbl.world_to_frame(st.b_pos[:, 0, :2], st.b_pos[:, 1, :2], v)
        major, minor, _ = error_ellipse(st.f_P)
        col = lambda a: np.asarray(a, dtype=float)[:, None]  # (B,) -> (B, S=1)
        return {
            "survey_error_m": col(np.hypot(st.f_E[:, 0] - x, st.f_E[:, 1] - y)),
            "dr_error_m": col(np.linalg.norm(st.s_dr[:, 0, :2] - v, axis=-1)),
            "cov_logdet": col(floored_log(st.f_P[:, 0, 0] * st.f_P[:, 1, 1] - st.f_P[:, 0, 1] * st.f_P[:, 1, 0])),
            "error_x_m": col(st.f_E[:, 0] - x),
            "error_y_m": col(st.f_E[:, 1] - y),
            "survey_error_en_m": np.stack([st.f_E[:, 0] - x, st.f_E[:, 1] - y], -1)[:, None],
            "survey_cov_en_m2": st.f_P[:, None, :2, :2].copy(),
            "phi_error_deg": col(np.degrees(np.angle(np.exp(1j * (st.f_E[:, 2] - phi))))),
            "baseline_error_m": col(st.f_E[:, 5] - length),
            "ellipse_major_m": col(major),
            "ellipse_minor_m": col(minor),
            "vehicle_y_m": col(y),
        }

    def snapshot(self) -> Snapshot:
        """Positions in the world: the filter's frame estimate and the mission's
        waypoints placed through the true frame (as the logged boat positions allow
        after the mission, section IV); the covariance rotated from the frame to
        east/north."""
        st = self._live
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
        return Snapshot(
            t_s=st.t_s.copy(),
            survey_true_m=st.s_pos.copy(),
            survey_est_m=est[:, None],
            survey_dr_m=st.s_dr.copy(),
            survey_cov_en_m2=cov[:, None],
            beacon_true_m=st.b_pos.copy(),
            beacon_est_m=gps,
            waypoints_m=np.concatenate([wp_en, wp[..., 2:]], -1)[:, None],
            n_waypoints=st.s_n_waypoints.copy(),
        )

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
        c, st = self.config, self._live
        out = np.empty((self.batch_size, 2, OBS_DIM), dtype=np.float32)
        self._k_observe(
            st.b_pos, st.b_gps_err, st.b_vel, packed(tracker_of(st)), st.cycle, packed(self._observe_params), out
        )
        if self._world:
            extra = np.empty((self.batch_size, 2, RIVER_OBS_DIM), dtype=np.float32)
            L = c.baseline_target_m
            observe_river(
                st.b_pos,
                st.b_gps_err,
                packed(tracker_of(st)),
                self._river_pts,
                self._river_cum,
                self._mission_dir,
                RIVER_LEAD_BASELINES * L,
                L,
                0.5 * c.river_width_m,
                extra,
            )
            out = np.concatenate([out, extra], -1)
        return out

    def global_state(self) -> np.ndarray:
        """True state for a centralized critic (B, state_dim), normalized: 24 values, and for a
        mission in the world the boats' offsets from the river's centerline / (width / 2) and
        the current at the vehicle in place of the uniform one."""
        c, st = self.config, self._live
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
            x / L,
            y / L,
            (st.f_E[:, 0] - x) / 10.0,
            (st.f_E[:, 1] - y) / 10.0,
            np.sin(st.f_E[:, 2] - phi),
            (st.f_E[:, 5] - length) / 10.0,
            (length - L) / L,
            np.cos(phi - st.ep_phi0_rad),
            np.sin(phi - st.ep_phi0_rad),
            major / 50.0,
            minor / 50.0,
            np.cos(2 * bearing),
            np.sin(2 * bearing),
            st.b_vel[:, 0, 0],
            st.b_vel[:, 0, 1],
            st.b_vel[:, 1, 0],
            st.b_vel[:, 1, 1],
            st.s_vel_true[:, 0, 0],
            st.s_vel_true[:, 0, 1],
            cur.real,
            cur.imag,
            (st.k_pos[:, 0] - v[:, 0]) / 10.0,
            (st.k_pos[:, 1] - v[:, 1]) / 10.0,
            st.cycle / c.max_cycles,
        ]
        if self._world:
            off = boat_off / (0.5 * c.river_width_m)
            parts += [off[:, 0], off[:, 1]]
        return np.clip(np.stack(parts, -1), -OBS_BOUND, OBS_BOUND).astype(np.float32)
