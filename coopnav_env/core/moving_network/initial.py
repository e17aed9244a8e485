"""An episode's start: the boats, the vehicle, its filter's prior, the water.

Every episode draws its randomness from its environment key (``core.rng``, the
episode stream): normals 0-1 position prior, 2 phi prior, 3-4 unused (kept so that
the others keep their numbers), 5 l prior, 6-7 dead-reckoning start, 8 speed scale,
9 compass bias, 10-13 GPS, 14 temperature, 15-16 the current's Gauss-Markov part,
17-20 the boats' surge and course fluctuations (their stationary distribution;
appended, so 0-16 keep their numbers); uniforms 0 the frame's orientation, 1-2 the
current's speed and direction.

The boats start on the baseline with the frame turned ``frame_orientation_deg``
(+- the spread), or, for a mission in the world, on the river's cross section
``RIVER_LEAD_BASELINES`` baselines ahead of the vehicle, B1 on the left of the
mission direction (``river.cross_section_at``). The vehicle starts at its first
waypoint heading for the second; its filter starts at the waypoint plus its prior's
errors.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from .. import lbl, river, rng
from ..dynamics import bearing_to_unit
from .observe import frame_waypoints
from .state import RIVER_LEAD_BASELINES, FrameState

if TYPE_CHECKING:
    from ...scenarios.base import ScenarioConfig

# sim: the MovingNetworkSimulator; typed Any since importing it here, even for type checking
# only, makes an import cycle (simulator imports this module; tests/test_contract.py)
_Simulator = Any


def boats_start(sim: _Simulator, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The boats' positions (B,2,3) and the frame's bearing phi0 (B,) at the start."""
    c = sim.config
    B, L = u.shape[0], c.baseline_target_m
    b_pos = np.zeros((B, 2, 3))
    if sim._world:
        # the boats' cross section RIVER_LEAD_BASELINES ahead of the vehicle's start along
        # the river, B1 on the left of the mission direction (river.cross_section_at)
        pts, cum, direction = sim._river_pts, sim._river_cum, sim._mission_dir
        s0 = float(river.arc_length_of(sim._waypoints[0, :2], pts, cum))
        b1_en, b2_en, phi_w = river.cross_section_at(s0 + direction * RIVER_LEAD_BASELINES * L, pts, cum, direction, L)
        phi0 = np.full(B, phi_w)
        b_pos[:, 0, :2], b_pos[:, 1, :2] = b1_en, b2_en
    else:
        phi0 = np.radians(c.frame_orientation_deg + c.frame_orientation_spread_deg * (2 * u[:, 0] - 1))
        b2 = L * bearing_to_unit(phi0)
        b_pos[:, 1, 0], b_pos[:, 1, 1] = b2.real, b2.imag
    return b_pos, phi0


def boats_motion(config: ScenarioConfig, phi0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The boats' headings (B,2) complex and velocities (B,2,3): the transit speed along y."""
    B = phi0.shape[0]
    y_axis = bearing_to_unit(phi0 + np.pi / 2)
    transit = config.boat_transit_speed_mps * y_axis
    b_heading = np.repeat((np.where(config.boat_transit_speed_mps < 0, -y_axis, y_axis))[:, None], 2, 1)
    b_vel = np.zeros((B, 2, 3))
    b_vel[..., 0], b_vel[..., 1] = transit.real[:, None], transit.imag[:, None]
    return b_heading, b_vel


def vehicle_start(sim: _Simulator, b_pos: np.ndarray, phi0: np.ndarray, gps_err: np.ndarray) -> tuple:
    """The vehicle's start: (east, north) (B,2), depth, frame (x0, y0), its mission in the
    frame (B,1,W,3) and its first heading (B,) complex."""
    B, wps = phi0.shape[0], sim._waypoints
    wp = np.broadcast_to(wps, (B,) + wps.shape)[:, None].copy()
    if sim._world:  # the vehicle starts at its first world waypoint; its mission goes to the frame
        start = np.broadcast_to(wps[0, :2], (B, 2)).copy()
        z0 = wps[0, 2]
        x0, y0, _, _ = lbl.world_to_frame(b_pos[:, 0, :2], b_pos[:, 1, :2], start)
        first = np.broadcast_to(wps[1, :2] - wps[0, :2], (B, 2))
        wp[:, 0, :, 0], wp[:, 0, :, 1] = frame_waypoints(b_pos, gps_err, wps)
    else:
        x0, y0, z0 = wps[0]
        start = lbl.frame_to_world(np.zeros((B, 2)), phi0, np.full(B, x0), np.full(B, y0))
        x1, y1, _ = wps[1]
        first = lbl.frame_to_world(np.zeros((B, 2)), phi0, np.full(B, x1), np.full(B, y1)) - start
    heading = (first[:, 0] + 1j * first[:, 1]) / np.maximum(np.hypot(first[:, 0], first[:, 1]), 1e-9)
    return start, z0, x0, y0, wp, heading


def filter_prior(
    config: ScenarioConfig, x0: float | np.ndarray, y0: float | np.ndarray, phi0: np.ndarray, n: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The filter's start E (B,6) and P (B,6,6) around the vehicle's start (x0, y0)."""
    c, B = config, phi0.shape[0]
    sigma0 = c.initial_position_std_m
    sphi = np.radians(c.initial_frame_orientation_std_deg)
    E = np.stack(
        [
            x0 + sigma0 * n[:, 0],
            y0 + sigma0 * n[:, 1],
            phi0 + np.radians(c.initial_frame_orientation_error_deg) + sphi * n[:, 2],
            np.zeros(B),
            np.zeros(B),  # the vehicle knows neither the current nor the boats' speed
            c.baseline_target_m + c.initial_baseline_std_m * n[:, 5],
        ],
        -1,
    )
    P = np.broadcast_to(
        np.diag(
            [
                sigma0**2,
                sigma0**2,
                sphi**2,
                c.initial_current_std_mps**2,
                c.initial_current_std_mps**2,
                c.initial_baseline_std_m**2,
            ]
        ),
        (B, 6, 6),
    ).copy()
    return E, P


def current_mean_of(sim: _Simulator, u: np.ndarray) -> np.ndarray:
    """The episode's mean current (B,) complex; a river's flows along the river
    (``MovingNetworkSimulator._river_currents``): current_mean holds its speed."""
    c = sim.config
    cur_speed = np.maximum(c.current_speed_mps + c.current_speed_spread_mps * (2 * u[:, 1] - 1), 0.0)
    cur_dir = np.radians(c.current_direction_deg + c.current_direction_spread_deg * (2 * u[:, 2] - 1))
    return cur_speed + 0j if sim._world else cur_speed * bearing_to_unit(cur_dir)


def initial_state(sim: _Simulator, seeds: np.ndarray) -> FrameState:
    """The state of new episodes for ``seeds`` (``MovingNetworkSimulator._initial_state``)."""
    c = sim.config
    B = len(seeds)
    keys = rng.env_keys(seeds)
    zero = np.zeros(B, dtype=np.int64)
    n = rng.normal(keys, rng.STREAM_EPISODE, zero, (21,))  # see the module docstring
    u = rng.uniform(keys, rng.STREAM_EPISODE + 100, zero, (3,))
    b_pos, phi0 = boats_start(sim, u)
    b_heading, b_vel = boats_motion(c, phi0)
    gps_err = c.gps_noise_m * n[:, 10:14].reshape(B, 2, 2)
    start, z0, x0, y0, wp, heading = vehicle_start(sim, b_pos, phi0, gps_err)
    s_pos = np.zeros((B, 1, 3))
    s_pos[:, 0, :2], s_pos[:, 0, 2] = start, z0
    E, P = filter_prior(c, x0, y0, phi0, n)
    dr = s_pos.copy()
    dr[:, 0, :2] += c.initial_position_std_m * n[:, 6:8]
    return FrameState(
        t_s=np.zeros(B),
        cycle=np.zeros(B, dtype=np.int64),
        keys=keys,
        ep_variant=np.zeros(B, dtype=np.int64),
        ep_noise_scale=np.ones(B),
        ep_phi0_rad=phi0,
        s_pos=s_pos,
        s_heading=heading,
        s_vel_true=np.zeros((B, 1, 3)),
        s_speed_scale=1.0 + c.survey_speed_scale_error_std * n[:, 8],
        s_compass_bias_rad=np.radians(c.compass_bias_std_deg) * n[:, 9],
        s_heading_meas_rad=np.arctan2(heading.real, heading.imag),
        s_speed_meas_mps=np.zeros(B),
        s_waypoints=wp,
        s_n_waypoints=np.full((B, 1), len(sim._waypoints), dtype=np.int64),
        s_wp_index=np.ones((B, 1), dtype=np.int64),
        s_done=np.zeros((B, 1), dtype=bool),
        s_dr=dr,
        f_E=E,
        f_P=P,
        f_rejected_cycles=np.zeros((B, 3), dtype=np.int64),
        f_window_r=np.zeros((B, c.frame_restart_window_cycles, 3)),
        f_window_S=np.zeros((B, c.frame_restart_window_cycles, 3, 3)),
        f_window_age=np.full((B, c.frame_restart_window_cycles), -1, dtype=np.int64),
        b_pos=b_pos,
        b_heading=b_heading,
        b_vel=b_vel,
        b_gps_err=gps_err,
        k_pos=start.copy(),
        k_vel=c.survey_speed_mps * np.stack([heading.real, heading.imag], axis=-1),  # the mission's, until fixes say
        k_age_s=np.zeros(B),
        k_has_fix=np.zeros(B, dtype=bool),
        k_outlier=np.zeros((B, 3)),
        temperature_c=c.water_temperature_c + c.temperature_uncertainty_c * n[:, 14],
        current_mean=current_mean_of(sim, u),
        current_gm=c.current_gm_std_mps * (n[:, 15] + 1j * n[:, 16]),
        b_surge=c.boat_surge_noise_mps * n[:, 17:19].copy(),
        b_steer=np.radians(c.boat_steering_noise_deg) * n[:, 19:21].copy(),
    )
