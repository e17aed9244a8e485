"""The initial state of ``core.sim.Simulator``'s episodes, by part: the episode's random
numbers (``EpisodeDraws``), then the survey vehicles', the beacons', the water's and the
beacons' knowledge fields of ``SimState``. ``Simulator._initial_state`` assembles them.

``sim`` is the ``core.sim.Simulator`` being reset, typed ``Any``: this module must not
import ``core.sim`` (it imports this one; ``tests/test_contract.py`` counts type-checking
imports as cycles too). It reads the scenario (``config``), the sizes (``S``, ``N``), the
path library (``variants``, ``_paths``, ``_hover``, ``_n_wp``), the beacons' start layout
(``_beacon_start_distance_m``, ``_beacon_depth``, ``_beacon_is_asv``) and ``params.drag_k``.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from . import dr_bias, rng
from .dynamics import bearing_to_unit, terminal_speed_mps


class EpisodeDraws(NamedTuple):
    """An episode's random numbers at reset, by purpose, (B, ...): the episode stream
    ``rng.STREAM_EPISODE`` and the streams added after it (each its own, so scenarios
    without them keep their numbers)."""

    ns: np.ndarray  # (B,S,4) normals: survey estimate east/north, speed scale, compass bias
    nb: np.ndarray  # (B,N,4) normals: beacon nav error east/north, current error east/north
    n_clock: np.ndarray  # (B,S,N) normals: OWTT clock offsets
    nw: np.ndarray  # (B,3) normals: temperature, Gauss-Markov current east/north
    n_dvl: np.ndarray  # (B,N,2) normals: the beacons' DVL scale error and heading bias
    u_bearing: np.ndarray  # (B,N) uniforms: the beacons' start bearings
    u_current: np.ndarray  # (B,2) uniforms: the current's speed and direction
    u_clock: np.ndarray  # (B,S,N) uniforms: clock drifts
    u_dvl_phase: np.ndarray  # (B,N) uniforms: phase of the DVL heading error's one-cycle part
    n_asv: np.ndarray  # (B,N,2) normals: the ASVs' surge and course errors at the start
    variant: np.ndarray  # (B,) int: index into Simulator.variants (domain randomization)
    noise_scale: np.ndarray  # (B,) factor on the sensor and range noise levels


def episode_draws(sim: Any, keys: np.ndarray) -> EpisodeDraws:
    """The episode's random numbers for environments with ``keys`` (B,)."""
    c, S, N = sim.config, sim.S, sim.N
    B = len(keys)
    zero = np.zeros(B, dtype=np.int64)
    n_ep = rng.normal(keys, rng.STREAM_EPISODE, zero, (S * 4 + N * 4 + S * N + 3,))
    u_ep = rng.uniform(keys, rng.STREAM_EPISODE + 100, zero, (N + 2 + S * N,))
    # the beacons' DVL heading bias and scale error: their own stream (added later)
    n_dvl = rng.normal(keys, rng.STREAM_EPISODE + 300, zero, (2 * N,)).reshape(B, N, 2)
    # domain randomization: its own stream, so scenarios without it keep their numbers
    u_dr = rng.uniform(keys, rng.STREAM_EPISODE + 200, zero, (2,))
    variant = np.minimum((u_dr[:, 0] * len(sim.variants)).astype(np.int64), len(sim.variants) - 1)
    lo, hi = c.randomize_noise_scale or (1.0, 1.0)
    return EpisodeDraws(
        ns=n_ep[:, : S * 4].reshape(B, S, 4),
        nb=n_ep[:, S * 4 : S * 4 + N * 4].reshape(B, N, 4),
        n_clock=n_ep[:, S * 4 + N * 4 : S * 4 + N * 4 + S * N].reshape(B, S, N),
        nw=n_ep[:, -3:],
        n_dvl=n_dvl,
        u_bearing=u_ep[:, :N],
        u_current=u_ep[:, N : N + 2],
        u_clock=u_ep[:, N + 2 :].reshape(B, S, N),
        u_dvl_phase=rng.uniform(keys, rng.STREAM_EPISODE + 301, zero, (N,)),
        n_asv=rng.normal(keys, rng.STREAM_EPISODE + 302, zero, (2 * N,)).reshape(B, N, 2),  # its own stream
        variant=variant,
        noise_scale=lo + (hi - lo) * u_dr[:, 1],
    )


def survey_start(sim: Any, ep: EpisodeDraws) -> dict:
    """The survey vehicles' fields of the initial state (``SimState.s_*``): at their
    path's first waypoint, heading along the first leg at the terminal speed of eq. (1),
    the EKF started from an estimate off by ``initial_position_std_m``."""
    c = sim.config
    B, S = len(ep.variant), sim.S
    wp = sim._paths[ep.variant].copy()
    hover = sim._hover[ep.variant]
    start = wp[:, :, 0]
    first_leg = wp[:, :, 1, :2] - wp[:, :, 0, :2]
    heading = np.where(
        np.abs(first_leg[..., 0] + 1j * first_leg[..., 1]) > 0, first_leg[..., 0] + 1j * first_leg[..., 1], 1j
    )
    heading = heading / np.abs(heading)
    thrust = np.where(hover, 0.0, c.survey_thrust_percent / 100.0 * c.max_thrust_n)
    sigma0 = c.initial_position_std_m
    est = start.copy()
    est[..., :2] += sigma0 * ep.ns[..., :2]
    P0 = np.zeros((B, S, 3, 3))
    P0[..., 0, 0] = P0[..., 1, 1] = sigma0**2
    P0[..., 2, 2] = max(c.depth_noise_m, 0.01) ** 2
    scale = ep.noise_scale[:, None]
    return {
        "s_pos": start.copy(),
        "s_heading": heading,
        "s_speed_model_mps": terminal_speed_mps(thrust, sim.params.drag_k),
        "s_speed_scale": 1.0 + c.survey_speed_scale_error_std * scale * ep.ns[..., 2],
        "s_thrust_n": thrust,
        "s_compass_bias_rad": np.radians(c.compass_bias_std_deg) * scale * ep.ns[..., 3],
        "s_vel_true": np.zeros((B, S, 3)),
        "s_vel_est": np.zeros((B, S, 3)),
        "s_waypoints": wp,
        "s_n_waypoints": sim._n_wp[ep.variant],
        "s_wp_index": np.ones((B, S), dtype=np.int64),
        "s_hover": hover,
        "s_done": np.zeros((B, S), dtype=bool),
        "s_est": est,
        "s_P": P0,
        "s_dr": est.copy(),
        "s_last_range_t_s": np.zeros((B, S)),
        "s_rejected_streak": np.zeros((B, S), dtype=np.int64),
        "s_current_est": np.zeros((B, S), dtype=complex),
    }


def beacon_start(sim: Any, ep: EpisodeDraws, start: np.ndarray) -> dict:
    """The beacons' fields of the initial state (``SimState.b_*``): around the survey's
    start point ``start`` (B, S, 3), facing it, with their own navigation error and its
    DVL error model drawn."""
    c = sim.config
    B, N = len(ep.variant), sim.N
    bearing = (
        np.radians(c.beacon_start_bearing_deg)
        + np.radians(c.beacon_start_bearing_spread_deg) * (2 * ep.u_bearing - 1)
        + 2 * np.pi * np.arange(N) / N
    )
    b_pos = np.zeros((B, N, 3))
    b_h = start[:, :1, 0] + 1j * start[:, :1, 1] + sim._beacon_start_distance_m[ep.variant] * bearing_to_unit(bearing)
    b_pos[..., 0], b_pos[..., 1], b_pos[..., 2] = b_h.real, b_h.imag, sim._beacon_depth
    to_survey = (start[:, :1, 0] + 1j * start[:, :1, 1]) - b_h
    b_std0 = np.where(sim._beacon_is_asv, c.gps_noise_m, 1.0)
    b_err = np.zeros((B, N, 3))
    b_err[..., :2] = b_std0[:, None] * ep.nb[..., :2]
    return {
        "b_pos": b_pos,
        "b_heading": to_survey / np.maximum(np.abs(to_survey), 1e-9),
        "b_vel": np.zeros((B, N, 3)),
        "b_nav_err": b_err,
        "b_nav_var_m2": np.broadcast_to(b_std0**2, (B, N)).copy(),
        "b_nav_dev_m2": np.zeros((B, N), dtype=complex),  # the start fix is isotropic
        "b_walk_var_m2": np.broadcast_to(b_std0**2, (B, N)).copy(),
        "b_unlocked_s": np.zeros((B, N)),
        "b_dvl_lock": np.ones((B, N), dtype=bool),
        "b_current_err": c.beacon_current_estimate_error_mps * (ep.nb[..., 2] + 1j * ep.nb[..., 3]),
        "b_dvl_scale_error": c.beacon_dvl_scale_error_std * ep.n_dvl[..., 0],
        "b_dvl_heading_bias_rad": np.radians(c.beacon_dvl_heading_bias_std_deg) * ep.n_dvl[..., 1],
        "b_dvl_heading_phase_rad": 2.0 * np.pi * ep.u_dvl_phase,
        "b_travelled_m": np.zeros((B, N)),
        "b_turn_sum_m": np.zeros((B, N), dtype=complex),
        "b_fix_est": (b_pos[..., 0] + b_err[..., 0]) + 1j * (b_pos[..., 1] + b_err[..., 1]),
        "b_since_fix_s": np.zeros((B, N)),
        "b_surfacings": np.zeros((B, N), dtype=np.int64),
        "b_surfacing": np.zeros((B, N), dtype=bool),
        "b_excursion_s": np.zeros((B, N)),
        "b_away_s": np.zeros((B, N)),
        "b_away": np.zeros((B, N), dtype=bool),
        # the ASVs' command-following errors start stationary (the boats' model, core.dynamics)
        "b_surge": np.where(sim._beacon_is_asv, c.asv_surge_noise_mps * ep.n_asv[..., 0], 0.0),
        "b_steer": np.where(sim._beacon_is_asv, np.radians(c.asv_steering_noise_deg) * ep.n_asv[..., 1], 0.0),
        "b_pings": np.zeros((B, N), dtype=np.int64),
        "b_collisions": np.zeros((B, N), dtype=np.int64),
        "b_energy_j": np.zeros((B, N)),
        # the GPS receiver's Gauss-Markov error starts stationary (an ASV's is its start error)
        "b_gps_err": c.gps_noise_m * (ep.nb[..., 0] + 1j * ep.nb[..., 1]),
        "b_fix_count": np.zeros((B, N), dtype=np.int64),
    }


def water_and_clocks(sim: Any, ep: EpisodeDraws) -> dict:
    """The episode's water (temperature, current) and the OWTT clocks of the initial state."""
    c = sim.config
    cur_speed = np.maximum(c.current_speed_mps + c.current_speed_spread_mps * (2 * ep.u_current[:, 0] - 1), 0.0)
    cur_dir = np.radians(c.current_direction_deg + c.current_direction_spread_deg * (2 * ep.u_current[:, 1] - 1))
    return {
        "clock_offset_s": c.clock_offset_std_s * ep.n_clock,
        "clock_drift": c.clock_drift_ppm * 1e-6 * (2 * ep.u_clock - 1),
        "temperature_c": c.water_temperature_c + c.temperature_uncertainty_c * ep.nw[:, 0],
        "current_mean": cur_speed * bearing_to_unit(cur_dir),
        "current_gm": c.current_gm_std_mps * (ep.nw[:, 1] + 1j * ep.nw[:, 2]),
    }


def knowledge_start(sim: Any, survey: dict, beacons: dict) -> dict:
    """What each beacon knows at the start (``SimState.k_*``): every survey vehicle's
    initial estimate and covariance, every peer's initial position estimate."""
    est, P0 = survey["s_est"], survey["s_P"]
    B, N, S = est.shape[0], sim.N, sim.S
    return {
        "k_est": np.broadcast_to(est[:, None], (B, N, S, 3)).copy(),
        "k_P": np.broadcast_to(P0[:, None, :, :2, :2], (B, N, S, 2, 2)).copy(),
        "k_wp_index": np.ones((B, N, S), dtype=np.int64),
        "k_age_s": np.zeros((B, N, S)),
        "k_range_age_s": np.zeros((B, N, S)),
        "k_peer": np.broadcast_to((beacons["b_pos"] + beacons["b_nav_err"])[:, None], (B, N, N, 3)).copy(),
    }


def consider_start(sim: Any, B: int) -> dict:
    """The survey filters' consider states (no correlation with any beacon yet), their
    empty lock-out windows of ``recovery_window`` ranges per beacon (consider-fusion.md)
    and no multipath hypotheses held (``multipath``, eq. M5)."""
    S, N, M = sim.S, sim.N, int(sim.config.recovery_window)
    return {
        "s_Pxb": np.zeros((B, S, N, 3, 2)),
        "s_fix_seen": np.zeros((B, S, N), dtype=np.int64),
        "s_fix_seen_t_s": np.zeros((B, S, N)),
        "s_var_seen_m2": np.zeros((B, S, N)),
        "s_dev_seen_m2": np.zeros((B, S, N), dtype=complex),
        "s_model_seen": np.zeros((B, S, N, 7)),
        "s_win_n": np.zeros((B, S, N), dtype=np.int64),
        "s_win_z": np.zeros((B, S, N, M)),
        "s_win_beacon": np.zeros((B, S, N, M, 2)),
        "s_win_dr": np.zeros((B, S, N, M, 2)),
        "s_win_dz": np.zeros((B, S, N, M)),
        "s_win_t": np.zeros((B, S, N, M)),
        "s_Pxd": np.zeros((B, S, 3, dr_bias.N_BIASES)),
        "s_hyp_w": np.ones((B, S)),
        "s_hyp_d": np.zeros((B, S, 3)),
        "s_hyp_dP": np.zeros((B, S, 3, 3)),
        "s_hyp_dX": np.zeros((B, S, N, 3, 2)),
        "s_hyp_dD": np.zeros((B, S, 3, dr_bias.N_BIASES)),
    }
