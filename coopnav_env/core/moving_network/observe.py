"""What the boats see and how their actions become motion, in the frame their GPS gives.

The boats know their GPS positions (hence the frame: origin B1, x along B1 -> B2, y
90 degrees clockwise from it, section V), their own velocities, the tracked vehicle
(``tracking``) and, on a river, the river's map. ``observe_boats`` writes each
boat's ``OBS_FIELDS``, ``observe_river`` the ``RIVER_OBS_FIELDS`` of a mission in the
world; ``command_velocity`` turns the actions into ground-velocity commands;
``frame_waypoints`` re-expresses a world mission in the GPS frame, as the vehicle
does with what the boats telemeter.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .. import lbl, river
from ..dynamics import bearing_to_unit
from ..jit import parallel_twin
from ..numerics import complex_abs, complex_div_real
from ..observation import OBS_BOUND  # the survey network's bound
from .state import OBS_DIM, RIVER_OBS_DIM, ObserveParams, Tracker


@njit(cache=True)
def gps_frame_of(b_pos: np.ndarray, gps_err: np.ndarray) -> tuple:
    """The frame as one environment's boat GPS gives it (b_pos (2,3), gps_err (2,2)): B1's
    and B2's GPS positions, the x axis as a complex (east + 1j north) unit and the
    baseline length; the y axis is x turned 90 degrees clockwise, -1j x."""
    g1e, g1n = b_pos[0, 0] + gps_err[0, 0], b_pos[0, 1] + gps_err[0, 1]
    g2e, g2n = b_pos[1, 0] + gps_err[1, 0], b_pos[1, 1] + gps_err[1, 1]
    base = complex(g2e - g1e, g2n - g1n)
    length = complex_abs(base)
    return g1e, g1n, g2e, g2n, complex_div_real(base, max(length, 1e-9)), length


@njit(cache=True)
def command_velocity(
    actions: np.ndarray, b_pos: np.ndarray, gps_err: np.ndarray, max_speed: np.ndarray, mode: int, out: np.ndarray
) -> None:
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
def _clip_obs(v: float) -> float:
    """An observation value clipped to [-OBS_BOUND, OBS_BOUND]."""
    if v < -OBS_BOUND:
        return -OBS_BOUND
    if v > OBS_BOUND:
        return OBS_BOUND
    return v


def _observe_boats(
    b_pos: np.ndarray,
    gps_err: np.ndarray,
    b_vel: np.ndarray,
    k: Tracker,
    cycle: np.ndarray,
    p: ObserveParams,
    out: np.ndarray,
) -> None:
    """Every boat's observation (``MovingNetworkSimulator.observe``), out (B, 2, OBS_DIM)
    float32; k: ``state.Tracker``, cycle (B,), p: ``state.ObserveParams`` (records or
    ``state.packed``)."""
    k, p = Tracker(*k), ObserveParams(*p)
    L = p.L
    for b in prange(b_pos.shape[0]):
        g1e, g1n, g2e, g2n, xa, length = gps_frame_of(b_pos[b], gps_err[b])
        ya = -1j * xa
        te, tn = k.pos[b, 0] + k.vel[b, 0] * k.age_s[b], k.pos[b, 1] + k.vel[b, 1] * k.age_s[b]
        for i in range(2):
            o = out[b, i]
            ge, gn = (g1e, g1n) if i == 0 else (g2e, g2n)
            vals = (
                1.0 - 2.0 * i,
                (b_vel[b, i, 0] * xa.real + b_vel[b, i, 1] * xa.imag) / p.boat_max_speed_mps,
                (b_vel[b, i, 0] * ya.real + b_vel[b, i, 1] * ya.imag) / p.boat_max_speed_mps,
                (length - L) / L,
                ((te - g1e) * xa.real + (tn - g1n) * xa.imag) / L,
                ((te - g1e) * ya.real + (tn - g1n) * ya.imag) / L,
                (k.vel[b, 0] * xa.real + k.vel[b, 1] * xa.imag) / p.survey_speed_mps,
                (k.vel[b, 0] * ya.real + k.vel[b, 1] * ya.imag) / p.survey_speed_mps,
                k.age_s[b] / p.age_scale_s,
                1.0 if k.has_fix[b] else 0.0,
                xa.real,
                xa.imag,
                ((ge - te) * xa.real + (gn - tn) * xa.imag) / L,
                ((ge - te) * ya.real + (gn - tn) * ya.imag) / L,
                cycle[b] / p.max_cycles,
            )
            for j in range(OBS_DIM):
                o[j] = _clip_obs(vals[j])


@njit(cache=True)
def observe_river(
    b_pos: np.ndarray,
    gps_err: np.ndarray,
    k: Tracker,
    pts: np.ndarray,
    cum: np.ndarray,
    direction: float,
    lead_m: float,
    L: float,
    half_width_m: float,
    out: np.ndarray,
) -> None:
    """The river part of every boat's observation (``RIVER_OBS_FIELDS``), out (B, 2,
    RIVER_OBS_DIM) float32, vectors in the boats' GPS frame as in ``observe_boats``: the
    boat's offset from the centerline (GPS position; + right of the mission direction)
    / (river_width_m / 2), so that +-1 are the banks; the river's unit direction of the
    mission at the point ``lead_m`` ahead of the tracked vehicle (``state.Tracker`` k)
    along the centerline (pts, cum: ``river.centerline_of``); that point minus the boat's
    GPS position / L. direction: +1 a downstream mission, -1 upstream
    (``river.mission_direction``). k may come ``state.packed``."""
    k = Tracker(*k)
    for b in range(b_pos.shape[0]):
        g1e, g1n, g2e, g2n, xa, _ = gps_frame_of(b_pos[b], gps_err[b])
        ya = -1j * xa
        te, tn = k.pos[b, 0] + k.vel[b, 0] * k.age_s[b], k.pos[b, 1] + k.vel[b, 1] * k.age_s[b]
        s_v = river.project(te, tn, pts, cum)[0]
        pe, pn, de, dn = river.point_at(s_v + direction * lead_m, pts, cum)
        de, dn = direction * de, direction * dn
        for i in range(2):
            ge, gn = (g1e, g1n) if i == 0 else (g2e, g2n)
            off = river.project(ge, gn, pts, cum)[1]
            vals = (
                direction * off / half_width_m,
                de * xa.real + dn * xa.imag,
                de * ya.real + dn * ya.imag,
                ((pe - ge) * xa.real + (pn - gn) * xa.imag) / L,
                ((pe - ge) * ya.real + (pn - gn) * ya.imag) / L,
            )
            for j in range(RIVER_OBS_DIM):
                out[b, i, j] = _clip_obs(vals[j])


def frame_waypoints(b_pos: np.ndarray, gps_err: np.ndarray, world_waypoints: np.ndarray) -> tuple:
    """A world mission in the frame the boats' GPS gives (what the vehicle computes from
    the telemetered B1 position and bearing to B2): frame x and y (B, W) of the world
    waypoints (W, >=2) through B1's and B2's GPS positions, b_pos (B,2,>=2) plus gps_err
    (B,2,2) (``lbl.world_to_frame``, section II's frame)."""
    g = b_pos[:, :, :2] + gps_err
    x, y, _, _ = lbl.world_to_frame(g[:, 0:1], g[:, 1:2], world_waypoints[None, :, :2])
    return x, y


# compiled twice from one source: plain, and threaded for large batches
observe_boats = njit(cache=True)(_observe_boats)
observe_boats_parallel = parallel_twin(_observe_boats)
