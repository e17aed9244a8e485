"""One acoustic cycle of the batched simulator: ``Simulator.step(actions)``.

Data flow in one step (one decision = one acoustic cycle of ``ping_interval_s``):

1. the beacons' actions become ground-velocity commands; their rate-limited
   trajectories over the cycle are computed at once (vectorized over sub-steps);
2. the survey vehicles are integrated in sub-steps of ``substep_s``: line-of-sight
   guidance on their own EKF estimate, the thrust model of eq. (1), the true motion
   (water-relative velocity plus current) and the dead reckoning of eq. (4) from
   the measured attitude (compass bias and noise) and the modelled speed;
3. the EKF covariance is predicted (eq. 6); depth and (at the surface) GPS are fused;
4. every beacon pings; ranges come from the time of flight between moving vehicles
   and are fused sequentially (eqs. 7-13) after a chi-square innovation gate;
5. the survey vehicles reply with their estimate and covariance, which each beacon
   receives or loses; beacons exchange their own positions the same way;
   with ``channel_mode="decide"`` only the beacons whose action's third component is
   > 0 ping, and the pings and replies share one channel in time (``core.channel``:
   propagation, collisions, half-duplex, transmit energy) before the random losses;
6. rewards, observations, terminations and infos are computed from the arrays.

Nothing here knows PettingZoo or Gymnasium; views live in coopnav_env/*.py.
"""

from __future__ import annotations

import numpy as np

from ..scenarios.base import ScenarioConfig
from . import beacon_nav, channel, dr_bias, episode_start, fusion, measurements, observation, rng, substeps
from .contract import BatchSimulator, Snapshot, StepResult
from .dynamics import bearing_to_unit, drag_constant, gauss_markov_step, max_turn_per_substep_rad
from .guidance import build_path
from .information import error_ellipse, logdet_horizontal
from .jit import threaded
from .kernel_records import SurveyParams, beacon_view, knowledge_view, survey_view
from .navigation import gate_threshold, predict
from .reward import TermContext, collect_terms, has_hooks, term_weights, terms_for, weighted_reward
from .state import SimState

INFO_KEYS = (
    "survey_error_m",
    "dr_error_m",
    "cov_logdet",
    "range_ok",
    "ranges_fused",
    "outliers_rejected",
    "nan_rejected",
    "packets_lost",
    "filter_restarts",
    "survey_error_en_m",
    "survey_cov_en_m2",
)
BEACON_INFO_KEYS = ("beacon_error_m",)  # and the channel model's (core.channel registry)
SURVEY_BEACON_INFO_KEYS = ("beacon_away_s",)  # the survey network's: time away on a surfacing
# global_state's values per survey vehicle (true and estimated position, the error ellipse),
# per beacon, and after both (the current, the episode's progress)
SURVEY_STATE_DIM, BEACON_STATE_DIM, GLOBAL_STATE_DIM = 10, 7, 3


def pad_global_state(
    state: np.ndarray, n_survey: int, slots: int, n_beacons: int | None = None, beacon_slots: int | None = None
) -> np.ndarray:
    """``Simulator.global_state()`` (B, state_dim) of a team of ``n_survey`` survey vehicles and
    ``n_beacons`` beacons laid out for ``slots`` survey vehicles and ``beacon_slots`` beacons
    (None: the team's own): the missing vehicles' blocks zero, each part where a team of that
    size has it (survey blocks, beacon blocks, the global values)."""
    B = state.shape[0]
    cut = n_survey * SURVEY_STATE_DIM
    parts = [state[:, :cut], np.zeros((B, (slots - n_survey) * SURVEY_STATE_DIM), dtype=state.dtype)]
    if n_beacons is None or beacon_slots is None or beacon_slots == n_beacons:
        return np.concatenate([*parts, state[:, cut:]], 1)
    end = cut + n_beacons * BEACON_STATE_DIM
    pad = np.zeros((B, (beacon_slots - n_beacons) * BEACON_STATE_DIM), dtype=state.dtype)
    return np.concatenate([*parts, state[:, cut:end], pad, state[:, end:]], 1)


class Simulator(BatchSimulator):
    """The batched coopnav core: B independent environments of one scenario."""

    def __init__(self, config: ScenarioConfig, batch_size: int = 1) -> None:
        if int(batch_size) < 1:
            raise ValueError(f"batch_size must be >= 1, got {batch_size!r}")
        self.config = c = config
        self.batch_size = int(batch_size)
        self.S, self.N, self.K = c.n_survey, c.n_beacons, c.substeps_per_cycle
        self._dr_before: np.ndarray | None = None  # the dead reckoning before this cycle's sub-steps (eq. D1's D)
        is_asv = np.array([k == "asv" for k in c.beacon_kinds])
        self._beacon_is_asv = is_asv
        self._beacon_max_speed = np.array(c.beacon_max_speeds_mps)
        beacon_turn = max_turn_per_substep_rad(
            np.where(is_asv, c.asv_max_turn_rate_dps, c.beacon_auv_max_turn_rate_dps), c.substep_s
        )
        self._beacon_turn_cos, self._beacon_turn_sin = np.cos(beacon_turn), np.sin(beacon_turn)
        self._beacon_depth = np.where(is_asv, 0.0, c.beacon_auv_depth_m)
        self._surfacing_times = beacon_nav.surfacing_times(
            self._beacon_depth, c.beacon_vertical_speed_mps, c.beacon_surface_dwell_s, c.beacon_ranging_min_depth_m
        )
        self._nav_params = beacon_nav.nav_params(c, self.K)  # the beacons' navigation's constants
        self._build_paths()
        self.gate = gate_threshold(c.range_gate_probability)  # the chi-square gate of every acoustic update
        self.sends_current = ~is_asv & c.survey_uses_beacon_current  # DVL beacons send their current estimate
        self._Q_cycle = (
            np.diag([c.process_noise_horizontal_m2ps, c.process_noise_horizontal_m2ps, c.process_noise_vertical_m2ps])
            * c.ping_interval_s
        )
        self.params = self._survey_params()  # the kernels' constants, one record
        # eq. (C7)'s phi per beacon: an ASV's error is its GPS receiver's Gauss-Markov error
        # (white, phi = 0, without a time constant); a DVL beacon's is a bias or random walk
        # between its surfacings (phi = 1; a surfacing resets it, eq. C8)
        tau = c.gps_error_time_constant_s
        phi = np.where(is_asv, np.exp(-c.ping_interval_s / tau) if tau > 0 else 0.0, 1.0)
        self._consider_phi = phi if c.beacon_error_fusion == "schmidt" and (phi != 1.0).any() else None
        self._bias_std = dr_bias.considered_biases(c)  # eqs. D1-D4, or None
        self._holds_hypotheses = c.range_outlier_model == "hold"  # multipath.py, M5-M7: else s_hyp_* stay unused
        self._parallel = threaded(self.batch_size)  # threaded kernels: off (core/jit.py says why)
        par = "_parallel" if self._parallel else ""
        self._k_survey = getattr(substeps, "integrate_survey" + par)
        self._k_beacons = getattr(substeps, "integrate_beacons" + par)
        self._k_depth_gps = getattr(fusion, "fuse_depth_gps" + par)
        self._k_messages = getattr(fusion, "exchange_messages" + par)
        # the fixed clock's channel delivers every reply and position (only the random loss acts)
        self._all_replies = np.ones((self.batch_size, self.N, self.S), dtype=bool)
        self._all_peers = np.ones((self.batch_size, self.N, self.N), dtype=bool)
        self._k_observe = getattr(observation, "observe" + par)
        # every random number of one cycle comes from one hash call, laid out by purpose;
        # a new purpose goes at the end so the others keep their numbers
        S_, N_, K_ = self.S, self.N, self.K
        self._draws = rng.DrawLayout(
            [
                ("current", "normal", (2,)),
                ("sensor_n", "normal", (S_, 3)),
                ("sensor_u", "uniform", (S_, 3)),
                ("substep", "normal", (K_, 2, S_)),
                ("beacon_nav_n", "normal", (N_, 4)),
                ("beacon_nav_u", "uniform", (N_,)),
                ("acoustic_n", "normal", (N_, S_, 2)),
                ("acoustic_u", "uniform", (N_, S_, 4)),
                ("message_u", "uniform", (N_, S_ + N_)),
                *measurements.draw_layout(c.acoustic_sensor, S_, N_, K_),  # the sensor's own draws (its registration)
                ("asv_n", "normal", (N_, 2)),  # the ASVs' surge and course errors
                ("ping_offset_u", "uniform", (N_,)),  # the channel's random ping offsets (core/channel.py)
            ],
            self.batch_size,
        )
        # the survey vehicles' acoustic sensor: one measurement model (core/measurements/)
        self.sensor = measurements.build(c.acoustic_sensor, self)
        self.obs_dim = observation.obs_dim(self.S, self.N, c.observed_waypoints)
        self.state_dim = self.S * SURVEY_STATE_DIM + self.N * BEACON_STATE_DIM + GLOBAL_STATE_DIM
        self.info_keys = INFO_KEYS
        # the channel model (core.channel registry): None for the fixed clock's free channel,
        # else the shared channel (channel_mode="decide"), with its beacon infos
        model = channel.channel_model(c.channel_mode)
        self.channel = model.build(self)
        self.action_dim = model.action_dim
        self.beacon_info_keys = BEACON_INFO_KEYS + SURVEY_BEACON_INFO_KEYS + model.beacon_info_keys
        self.reward_terms = terms_for(c, "survey_beacons")  # this network's registered terms (core.reward)
        self._term_hooks = has_hooks(self.reward_terms)  # a plug-in term computed in Python: build its context
        self.reward_weights = term_weights(c, self.reward_terms)
        self.state: SimState | None = None

    @property
    def _live(self) -> SimState:
        """The state, after ``reset`` (``state`` is None before the first one)."""
        st = self.state
        assert st is not None, "Simulator: call reset() before stepping or observing"
        return st

    def _build_paths(self) -> None:
        """The path library: one (survey_path, depth_m) variant per combination of the
        randomization choices (just the scenario's own path without randomization), padded
        to W waypoints (V, S, W, 3); and the beacons' start distance per variant (V, N)."""
        c = self.config
        self.variants = [
            (kind, depth)
            for kind in (c.randomize_survey_path or (c.survey_path,))
            for depth in (c.randomize_depth_m or (c.depth_m,))
        ]
        built = [
            [build_path(c.replace(survey_path=kind, depth_m=depth), s) for s in range(self.S)]
            for kind, depth in self.variants
        ]
        W = max(len(wp) for paths in built for wp, _ in paths)
        V = len(self.variants)
        self._paths = np.zeros((V, self.S, W, 3))
        self._n_wp = np.zeros((V, self.S), dtype=np.int64)
        self._hover = np.zeros((V, self.S), dtype=bool)
        for v, paths in enumerate(built):
            for s, (wp, hover) in enumerate(paths):
                self._paths[v, s, : len(wp)] = wp
                self._paths[v, s, len(wp) :] = wp[-1]
                self._n_wp[v, s], self._hover[v, s] = len(wp), hover
        if c.beacon_start_distance_m > 0:
            self._beacon_start_distance_m = np.full((V, self.N), c.beacon_start_distance_m)
        else:  # 0: start where the first two ranges inform most (Sousa et al., Fig. 11)
            from .information import optimal_start_distance_m

            self._beacon_start_distance_m = np.array(
                [
                    [
                        optimal_start_distance_m(depth - d, v * c.ping_interval_s)
                        for d, v in zip(self._beacon_depth, self._beacon_max_speed)
                    ]
                    for _, depth in self.variants
                ]
            )

    def _survey_params(self) -> SurveyParams:
        """The scenario's constants the kernels read, gathered once (``kernel_records.SurveyParams``)."""
        c = self.config
        survey_turn = max_turn_per_substep_rad(c.survey_max_turn_rate_dps, c.substep_s)
        fence = c.geofence_m
        return SurveyParams(
            substep_s=float(c.substep_s),
            ping_interval_s=float(c.ping_interval_s),
            drag_k=float(drag_constant(c.survey_drag_coefficient, c.water_density_kgpm3, c.survey_cross_section_m2)),
            mass_kg=float(c.survey_mass_kg),
            los_alpha=float(c.los_alpha),
            acceptance_m=float(c.waypoint_acceptance_m),
            turn_cos=float(np.cos(survey_turn)),
            turn_sin=float(np.sin(survey_turn)),
            max_pitch_rad=float(np.radians(c.survey_max_pitch_deg)),
            depth_gain_per_m=float(c.survey_depth_gain_per_m),
            depth_noise_m=float(c.depth_noise_m),
            gps_noise_m=float(c.gps_noise_m),
            gps_max_depth_m=float(c.gps_max_depth_m),
            nan_probability=float(c.sensor_nan_probability),
            loss_near=float(c.packet_loss_near),
            loss_far=float(c.packet_loss_far),
            max_range_m=float(c.max_range_m),
            position_scale_m=float(c.position_scale_m),
            observed_waypoints=int(c.observed_waypoints),
            beacon_max_speed=np.asarray(self._beacon_max_speed, dtype=float),
            fence_center=np.array([(fence[0] + fence[2]) / 2, (fence[1] + fence[3]) / 2]),
        )

    # ------------------------------------------------------------------------------
    def _initial_state(self, seeds) -> SimState:
        """Every environment's state at the start of an episode seeded with ``seeds`` (B,)."""
        B = len(seeds)
        keys = rng.env_keys(seeds)
        ep = episode_start.episode_draws(self, keys)
        survey = episode_start.survey_start(self, ep)
        beacons = episode_start.beacon_start(self, ep, survey["s_pos"])
        return SimState(
            t_s=np.zeros(B),
            cycle=np.zeros(B, dtype=np.int64),
            keys=keys,
            ep_variant=ep.variant,
            ep_noise_scale=ep.noise_scale,
            **survey,
            **beacons,
            **episode_start.water_and_clocks(self, ep),
            **episode_start.knowledge_start(self, survey, beacons),
            **episode_start.consider_start(self, B),
        )

    def _cycle_draws(self, cycle) -> dict:
        """This cycle's random numbers for every environment, by purpose: name -> (B, *shape)."""
        return self._draws.draw(self._live.keys, cycle)

    # ------------------------------------------------------------------------------
    def command_velocity(self, actions: np.ndarray) -> np.ndarray:
        """Actions (B,N,2) in [-1, 1] (their first two components) -> commanded ground
        velocity, complex (B,N)."""
        vmax = self._beacon_max_speed
        if self.config.action_mode == "velocity":
            v = actions[..., 0] + 1j * actions[..., 1]
            norm = np.abs(v)
            v = np.where(norm > 1.0, v / np.maximum(norm, 1e-12), v)
            return v * vmax
        bearing = np.pi * actions[..., 0]
        speed = 0.5 * (actions[..., 1] + 1.0) * vmax
        return speed * bearing_to_unit(bearing)

    def step(self, actions: np.ndarray) -> StepResult:
        """Advance every environment one acoustic cycle. actions: (B, N, 2) finite; with
        ``channel_mode="decide"`` (B, N, 3), the third component > 0 to transmit this
        slot (a (B, N, 2) action transmits every slot, the fixed clock). The numbered
        steps are the module docstring's."""
        st = self._live
        draws = self._cycle_draws(st.cycle)
        transmit = self.channel.transmit_mask(actions, st.cycle) if self.channel is not None else None
        # 1. beacon motion over the cycle
        moved = self._move_beacons(actions, draws)
        # 2. survey sub-steps; the beacons' own navigation; the current; the clock
        self._integrate_survey(draws)
        self._beacon_navigation(draws, moved)
        if transmit is not None and st.b_away.any():  # away on a surfacing: no ping
            transmit = transmit & ~st.b_away
        self._advance_water_and_clock(draws)
        # 3. EKF prediction (eq. 6), depth and GPS
        out = self._predict_depth_gps(draws)
        logdet_before = logdet_horizontal(st.s_P)
        # 4. acoustic ranging (eqs. 7-13)
        ping = self._acoustic_ranging(draws, out, transmit)
        logdet_after = logdet_horizontal(st.s_P)
        # 5. replies: survey -> beacons, beacon -> beacons
        self._replies(draws, out, transmit, ping)
        # 6. reward terms, ends, infos
        reward, terms = self._reward(out, transmit, (logdet_before - logdet_after).sum(-1))
        terminated, truncated = self._ends()
        return StepResult(
            self.observe(),
            reward,
            terminated,
            truncated,
            self._step_info(out, logdet_after),
            terms,
            self._beacon_info(),
        )

    def _move_beacons(self, actions: np.ndarray, draws: dict) -> np.ndarray:
        """Step 1: the beacons follow their commanded velocity through the sub-steps, the
        ASVs with the boats' errors (``beacon_nav.disturb_asvs``); returns their true
        horizontal displacement over the cycle, complex (B, N)."""
        st = self._live
        b_start = st.b_pos[..., 0] + 1j * st.b_pos[..., 1]
        self._k_beacons(
            st.b_pos,
            st.b_heading,
            st.b_vel,
            self.command_velocity(actions),
            self._beacon_turn_cos,
            self._beacon_turn_sin,
            self.K,
            self.config.substep_s,
        )
        if self._beacon_is_asv.any():
            beacon_nav.disturb_asvs(st, self.config, self._beacon_is_asv, draws["asv_n"])
        return st.b_pos[..., 0] + 1j * st.b_pos[..., 1] - b_start

    def _advance_water_and_clock(self, draws: dict) -> None:
        """Step 2's end: the current's slowly varying part, exact over the cycle; the clock."""
        c, st = self.config, self._live
        T = c.ping_interval_s
        n_cur = draws["current"]
        st.current_gm = gauss_markov_step(
            st.current_gm, T, c.current_gm_time_constant_s, c.current_gm_std_mps, n_cur[:, 0] + 1j * n_cur[:, 1]
        )
        st.t_s = st.t_s + T
        st.cycle = st.cycle + 1

    def _predict_depth_gps(self, draws: dict) -> measurements.FusionOutputs:
        """Step 3: every survey EKF predicted over the cycle (eq. 6, F = I, Q accumulated),
        then depth and (at the surface) GPS fused. Returns the cycle's fusion outputs,
        NaN readings counted so far."""
        st = self._live
        B, N, S = self.batch_size, self.N, self.S
        st.s_est, st.s_P = predict(st.s_est, st.s_P, 0.0, self._Q_cycle)
        if self._bias_std is not None:  # eq. (D2): the survey's own dead-reckoning biases
            var = dr_bias.bias_variances(*self._bias_std, st.ep_noise_scale)
            before = self._dr_before  # set by this cycle's _integrate_survey; None: no sub-steps ran, D = 0
            moved = st.s_dr[..., :2] - before if before is not None else np.zeros_like(st.s_dr[..., :2])
            dt_s = self.config.ping_interval_s if before is not None else 0.0  # (D1'): the told current's time
            held = (st.s_hyp_dP, st.s_hyp_dD) if self._holds_hypotheses else None  # (M5)
            dr_bias.bias_predict(st.s_P, st.s_Pxd, moved, var, dt_s, held=held)
        self._dr_before = None  # one cycle's D is used once
        fused = np.zeros((B, N, S), dtype=bool)
        out = measurements.FusionOutputs(
            fused=fused,
            rejected=np.zeros_like(fused),
            lost=np.zeros_like(fused),
            nan_count=np.zeros((B, S), dtype=np.int64),
            restarts=np.zeros((B, S), dtype=np.int64),
        )
        if self._consider_phi is not None:  # eq. (C7): the beacons' Gauss-Markov errors decorrelate
            st.s_Pxb *= self._consider_phi[None, None, :, None, None]
            if self._holds_hypotheses:
                st.s_hyp_dX *= self._consider_phi[None, None, :, None, None]  # the held hypotheses' too (M5)
        self._k_depth_gps(
            survey_view(st), st.s_Pxb, st.s_Pxd, draws["sensor_n"], draws["sensor_u"], out.nan_count, self.params
        )
        if self._holds_hypotheses:
            st.s_hyp_w[st.s_pos[..., 2] < self.params.gps_max_depth_m] = 1.0  # a GPS fix settles them (M5)
        return out

    def _acoustic_ranging(self, draws: dict, out: measurements.FusionOutputs, transmit):
        """Step 4: the survey vehicles' acoustic sensor fuses what arrived (``out`` filled).
        With the shared channel only the pings it delivers are measured; returns the
        channel's ping resolution (delivered (B, N, S), the whole slot) or None."""
        if self.channel is None:
            masks = beacon_nav.away_masks(self._live, self.S)  # a beacon away on a surfacing sends none
            self.sensor.fuse(draws, out) if masks is None else self.sensor.fuse(draws, out, heard=masks[0])
            return None
        ping_ok, ping_slot = self.channel.pings(transmit, draws)
        self.sensor.fuse(draws, out, heard=ping_ok)
        out.lost[...] |= ping_slot.lost[:, : self.N, self.N :]  # the pings the link's SNR draw lost
        return ping_ok, ping_slot

    def _replies(self, draws: dict, out: measurements.FusionOutputs, transmit, ping) -> None:
        """Step 5: the survey vehicles' replies and the beacons' positions reach the beacons
        (or are lost); on the shared channel a survey vehicle replies once per slot if it
        decoded a ping (core/channel.py), and the beacons' pings, collisions and energy
        are counted."""
        st = self._live
        if self.channel is None:
            self._exchange_messages(draws)
            return
        ping_ok, ping_slot = ping
        replied = (ping_ok & ping_slot.ended[:, : self.N, self.N :] & ~out.lost).any(1)  # decoded by the reply time
        reply_ok, peer_ok, _ = self.channel.replies(transmit, replied, draws, ping_slot)
        self.channel.exchange(draws, reply_ok, peer_ok)
        st.b_pings = transmit.astype(np.int64)
        st.b_collisions = ping_slot[2][:, : self.N, self.N :].sum(-1).astype(np.int64)
        st.b_energy_j = transmit * self.channel.ping_energy_j

    # ---- reward terms: assembled here only; core/reward.py weighs them -------------
    def _reward(self, out: measurements.FusionOutputs, transmit, info_gain: np.ndarray):
        """Step 6: the named reward terms (B, N) and their weighted sum. ``info_gain`` (B,):
        the drop of the survey filters' log det over the acoustic updates."""
        c, st = self.config, self._live
        B, N = self.batch_size, self.N
        dist = np.linalg.norm(st.s_pos[:, None, :, :] - st.b_pos[:, :, None, :], axis=-1)  # (B,N,S)
        fe0, fn0, fe1, fn1 = c.geofence_m
        outside = (
            (st.b_pos[..., 0] < fe0) | (st.b_pos[..., 0] > fe1) | (st.b_pos[..., 1] < fn0) | (st.b_pos[..., 1] > fn1)
        )
        no_contact = ~out.fused.any(-1)  # (B,N): none of this beacon's ranges fused
        heard = self.sensor.heard_mask(st.cycle - 1) if transmit is None else transmit  # who could be heard
        if heard is not None:  # only this cycle's senders can be heard
            no_contact &= heard
        # the reward terms (core.reward registry): the arrays computed here by name, then
        # every registered term's compute(ctx) hook, in self.reward_terms' order
        arrays = {
            "info_gain": np.broadcast_to(info_gain[:, None], (B, N)),
            "safety": (dist < c.safety_distance_m).any(-1).astype(float),
            "geofence": outside.astype(float),
            "contact": no_contact.astype(float),
        }
        if self.channel is not None:
            arrays["ping"] = transmit.astype(float)
        ctx = (
            TermContext()
            if not self._term_hooks
            else TermContext(
                sim=self,
                config=c,
                state=st,
                arrays={
                    "fused": out.fused,
                    "rejected": out.rejected,
                    "lost": out.lost,
                    "transmit": transmit,
                    "dist": dist,
                    "info_gain": info_gain,
                },
            )
        )
        terms = collect_terms(self.reward_terms, arrays, ctx, (B, N))
        return weighted_reward(terms, self.reward_weights), terms

    def _ends(self):
        """Step 6: terminated (every survey path finished, or the mission time is up) and
        truncated (the cycle limit), (B,) each."""
        c, st = self.config, self._live
        terminated = st.s_done.all(-1)
        if c.mission_duration_s > 0:
            terminated |= st.t_s >= c.mission_duration_s - 1e-9
        truncated = (st.cycle >= c.max_cycles) & ~terminated
        return terminated, truncated

    def _step_info(self, out: measurements.FusionOutputs, logdet_after: np.ndarray) -> dict:
        """Step 6: the infos of ``INFO_KEYS``, (B, S, ...) each."""
        info = {
            **self._state_info(logdet_after),
            "range_ok": out.fused.any(1),
            "ranges_fused": out.fused.sum(1),
            "outliers_rejected": out.rejected.sum(1),
            "nan_rejected": out.nan_count,
            "packets_lost": out.lost.sum(1),
            "filter_restarts": out.restarts,
        }
        return {k: info[k] for k in INFO_KEYS}

    def _state_info(self, logdet=None) -> dict:
        """The infos that follow from the state: true horizontal errors of the filter and
        of dead reckoning (m), log det of the horizontal covariance (B, S)."""
        st = self._live
        error_en = st.s_est[..., :2] - st.s_pos[..., :2]
        return {
            "survey_error_m": np.linalg.norm(error_en, axis=-1),
            "dr_error_m": np.linalg.norm(st.s_dr[..., :2] - st.s_pos[..., :2], axis=-1),
            "cov_logdet": logdet_horizontal(st.s_P) if logdet is None else logdet,
            "survey_error_en_m": error_en,
            "survey_cov_en_m2": st.s_P[..., :2, :2].copy(),
        }

    def _beacon_info(self) -> dict:
        """Per beacon (B, N): the true horizontal error of its own navigation (m), the time
        of this cycle it spent away on a surfacing (``beacon_away_s``, s); with
        ``channel_mode="decide"`` also this cycle's ``pings`` (0 or 1), ``collisions``
        (survey vehicles at which its ping collided with another packet) and
        ``energy_J`` (transmit energy, J)."""
        st = self._live
        info = {
            "beacon_error_m": np.hypot(st.b_nav_err[..., 0], st.b_nav_err[..., 1]),
            "beacon_away_s": st.b_away_s.copy(),
        }
        if self.channel is not None:
            info.update(pings=st.b_pings.copy(), collisions=st.b_collisions.copy(), energy_J=st.b_energy_j.copy())
        return info

    def snapshot(self) -> Snapshot:
        """Positions, covariance and planned paths of every environment (copies)."""
        st = self._live
        return Snapshot(
            t_s=st.t_s.copy(),
            survey_true_m=st.s_pos.copy(),
            survey_est_m=st.s_est.copy(),
            survey_dr_m=st.s_dr.copy(),
            survey_cov_en_m2=st.s_P[..., :2, :2].copy(),
            beacon_true_m=st.b_pos.copy(),
            beacon_est_m=st.b_pos + st.b_nav_err,
            waypoints_m=st.s_waypoints.copy(),
            n_waypoints=st.s_n_waypoints.copy(),
        )

    # ------------------------------------------------------------------------------
    def _integrate_survey(self, draws: dict) -> None:
        """Step 2: the survey vehicles through the sub-steps (``substeps.integrate_survey``):
        guidance, eq. (1), the true motion and the dead reckoning of eq. (4)."""
        c, st = self.config, self._live
        noise = draws["substep"] * st.ep_noise_scale[:, None, None, None]  # (B,K,2,S): compass, pitch
        self._dr_before = st.s_dr[..., :2].copy()  # the cycle's dead-reckoned displacement: eq. (D1)'s D
        self._k_survey(
            survey_view(st),
            np.radians(c.compass_noise_deg) * noise[:, :, 0],
            np.radians(c.attitude_noise_deg) * noise[:, :, 1],
            st.current_mean + st.current_gm,
            self.params,
        )

    def _beacon_navigation(self, draws, moved):
        """The beacons' own navigation over the cycle (``beacon_nav.navigate``); ``moved``
        (B,N) complex: their true ground displacement."""
        beacon_nav.navigate(
            self._live, self._nav_params, draws, moved, self._beacon_is_asv, self._surfacing_times, self._beacon_depth
        )

    def _exchange_messages(self, draws: dict) -> None:
        """Step 5 on the fixed clock: replies and positions, lost only at random."""
        st = self._live
        masks = beacon_nav.away_masks(st, self.S) or (self._all_replies, self._all_peers)  # away: none heard
        self._k_messages(
            survey_view(st),
            beacon_view(st),
            knowledge_view(st),
            st.t_s,
            draws["message_u"],
            masks[0],
            masks[1],
            self.params,
        )

    # ------------------------------------------------------------------------------
    def observe(self) -> np.ndarray:
        """What each beacon could know, normalized: (B, N, obs_dim). Layout: core/observation.py."""
        st = self._live
        out = np.empty((self.batch_size, self.N, self.obs_dim))
        self._k_observe(beacon_view(st), knowledge_view(st), survey_view(st), self.params, out)
        return out.astype(np.float32)

    def global_state(self) -> np.ndarray:
        """The true global state for a centralized critic: (B, state_dim), normalized."""
        c, st = self.config, self._live
        B = self.batch_size
        L = c.position_scale_m
        major, minor, bearing = error_ellipse(st.s_P)
        fc = np.append(self.params.fence_center, 0.0)
        survey = np.concatenate(
            [
                (st.s_pos - fc) / L,
                (st.s_est - fc) / L,
                major[..., None] / 50.0,
                minor[..., None] / 50.0,
                np.cos(2 * bearing)[..., None],
                np.sin(2 * bearing)[..., None],
            ],
            -1,
        ).reshape(B, -1)
        beacons = np.concatenate(
            [
                (st.b_pos - fc) / L,
                st.b_nav_err[..., :2] / 10.0,
                st.b_heading.real[..., None],
                st.b_heading.imag[..., None],
            ],
            -1,
        ).reshape(B, -1)
        cur = st.current_mean + st.current_gm
        glob = np.stack([cur.real, cur.imag, st.cycle / c.max_cycles], -1)
        return np.clip(np.concatenate([survey, beacons, glob], -1), -10.0, 10.0).astype(np.float32)
