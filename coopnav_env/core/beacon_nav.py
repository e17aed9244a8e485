"""The beacons' own navigation (``navigate``, step 4 of ``core.sim``): the beacon AUV's
DVL dead reckoning and the error model it carries, its GPS fixes (a Gauss-Markov
receiver error), and what that navigation costs: surfacing for a fix takes time, and
DVL bottom lock depends on the altitude; the ASVs' command-following errors.

Surfacing (``beacon_surfacing="timed"``): once a fix is due the beacon ascends from its
depth z0 at ``beacon_vertical_speed_mps`` w, waits ``beacon_surface_dwell_s`` D at the
surface for the fix, and descends at w. Measured from the start of the ascent:

    at the surface t_up = z0 / w; fix t_fix = t_up + D; back at depth t_end = t_fix + z0 / w;
    above the ranging depth z_r (``beacon_ranging_min_depth_m``) from (z0 - z_r) / w
    until t_fix + z_r / w (z_r capped at z0)

and the depth is z0 - w t, 0, then w (t - t_fix). While above z_r the beacon is away: it
does not ping and hears no reply (``core.sim``). ``"instant"`` is the old model (a fix
the cycle it is due, no time away), the lake trial's surface beacon.

Bottom lock (``dvl_lock_model="altitude"``): the DVL tracks the bottom from
``dvl_min_altitude_m`` to ``dvl_max_altitude_m``; the per-cycle loss probability is
``dvl_lock_loss_probability`` p0 well inside the range and rises linearly to 1 over the
last ``dvl_lock_fade_fraction`` f of it (altitude a, range a_max):

    ramp = clip((a - (1 - f) a_max) / (f a_max), 0, 1),  p_loss = p0 + (1 - p0) ramp,
    p_regain = ``dvl_lock_regain_probability`` (1 - ramp),

and no lock at all outside [a_min, a_max]. ``"fixed"`` keeps p0 whatever the altitude.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from .dynamics import boat_noise_step, disturb_boats, unit_to_bearing


class SurfacingTimes(NamedTuple):
    """A surfacing's times from the start of its ascent (s), per beacon."""

    up_s: np.ndarray  # at the surface
    fix_s: np.ndarray  # the GPS fix, at the end of the dwell
    end_s: np.ndarray  # back at its depth
    away_from_s: np.ndarray  # above the ranging depth from ...
    away_until_s: np.ndarray  # ... until


def surfacing_times(
    depth_m: ArrayLike, vertical_speed_mps: float, dwell_s: float, ranging_min_depth_m: float
) -> SurfacingTimes:
    """The times of a surfacing from ``depth_m`` (module docstring)."""
    z0 = np.asarray(depth_m, dtype=float)
    w = float(vertical_speed_mps)
    zr = np.minimum(float(ranging_min_depth_m), z0)
    up = z0 / w
    fix = up + float(dwell_s)
    return SurfacingTimes(up, fix, fix + z0 / w, (z0 - zr) / w, fix + zr / w)


def surfacing_depth_m(t_s: np.ndarray, depth_m: ArrayLike, vertical_speed_mps: float, times: SurfacingTimes) -> Any:
    """The depth t_s into a surfacing from ``depth_m``: ascending, at the surface, descending."""
    z0 = np.asarray(depth_m, dtype=float)
    w = float(vertical_speed_mps)
    down = np.clip(w * (t_s - times.fix_s), 0.0, z0)
    return np.where(t_s < times.up_s, z0 - w * t_s, np.where(t_s <= times.fix_s, 0.0, down))


def overlap_s(a0: np.ndarray, a1: np.ndarray, b0: ArrayLike, b1: ArrayLike) -> np.ndarray:
    """Length of [a0, a1] intersected with [b0, b1] (s), elementwise."""
    return np.maximum(np.minimum(a1, b1) - np.maximum(a0, b0), 0.0)


def dvl_lock_probabilities(
    altitude_m: np.ndarray,
    min_altitude_m: float,
    max_altitude_m: float,
    fade_fraction: float,
    loss_probability: float,
    regain_probability: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Per-cycle probabilities of losing and of regaining bottom lock at ``altitude_m``
    (module docstring): (p_loss, p_regain), each shaped like the altitude."""
    a = np.asarray(altitude_m, dtype=float)
    fade = max(fade_fraction * max_altitude_m, 1e-12)
    ramp = np.clip((a - (max_altitude_m - fade)) / fade, 0.0, 1.0)
    inside = (a >= min_altitude_m) & (a <= max_altitude_m)
    p_loss = np.where(inside, loss_probability + (1.0 - loss_probability) * ramp, 1.0)
    p_regain = np.where(inside, regain_probability * (1.0 - ramp), 0.0)
    return p_loss, p_regain


def lock_probabilities(c: Any, depth_m: np.ndarray) -> tuple[Any, Any]:
    """This cycle's (p_loss, p_regain) of the beacons' bottom lock at ``depth_m`` (B, N)
    under ``c.dvl_lock_model`` (scalars for ``"fixed"``, the old model bit for bit)."""
    if c.dvl_lock_model == "fixed":
        return c.dvl_lock_loss_probability, c.dvl_lock_regain_probability
    return dvl_lock_probabilities(
        c.water_depth_m - depth_m,
        c.dvl_min_altitude_m,
        c.dvl_max_altitude_m,
        c.dvl_lock_fade_fraction,
        c.dvl_lock_loss_probability,
        c.dvl_lock_regain_probability,
    )


def advance_surfacing(st: Any, c: Any, times: SurfacingTimes, cruise_depth_m: np.ndarray, due: np.ndarray) -> Any:
    """One cycle of the beacons' surfacings (``beacon_surfacing="timed"``), in place on the
    state ``st`` (``SimState``: b_surfacing, b_excursion_s, b_away_s, b_away and the depth
    b_pos[..., 2]). ``due`` (B, N): a fix is due; a beacon not yet surfacing begins its
    ascent at the end of this cycle. Returns (B, N) bool: the fixes taken this cycle, at
    the end of the cycle in which a dwell ends (the dead reckoning over the rest of that
    cycle is not added: at most one cycle's descent)."""
    T = c.ping_interval_s
    on = st.b_surfacing
    t0 = st.b_excursion_s
    t1 = t0 + T
    fix = on & (t0 < times.fix_s) & (t1 >= times.fix_s)
    st.b_away_s = np.where(on, overlap_s(t0, t1, times.away_from_s, times.away_until_s), 0.0)
    ended = on & (t1 >= times.end_s)
    start = due & ~on
    st.b_surfacing = start | (on & ~ended)
    st.b_excursion_s = np.where(start, 0.0, np.where(st.b_surfacing, t1, 0.0))
    depth = surfacing_depth_m(st.b_excursion_s, cruise_depth_m, c.beacon_vertical_speed_mps, times)
    depth = np.where(st.b_surfacing, depth, cruise_depth_m)
    st.b_pos[..., 2] = np.where(cruise_depth_m > 0, depth, st.b_pos[..., 2])  # ASVs (depth 0) stay
    st.b_away = st.b_surfacing & (depth < np.minimum(c.beacon_ranging_min_depth_m, cruise_depth_m) - 1e-9)
    return fix


def away_masks(st: Any, S: int) -> tuple[np.ndarray, np.ndarray] | None:
    """The beacons away on a surfacing as delivery masks: (pings and replies (B, N, S), peers'
    positions (B, N, N) [receiver, sender]); None when no beacon is away."""
    away = st.b_away
    if not away.any():
        return None
    here = ~away
    return np.repeat(here[:, :, None], S, axis=2), here[:, :, None] & here[:, None, :]


def disturb_asvs(st: Any, c: Any, is_asv: np.ndarray, noise: np.ndarray) -> None:
    """The ASVs' imperfect execution of their commands over the cycle, in place: the boats'
    model (``dynamics.disturb_boats``, its Gauss-Markov states stepped by
    ``dynamics.boat_noise_step`` with the ``asv_*`` parameters) after
    ``substeps.integrate_beacons``; the other beacons are untouched. noise (B, N, 2)."""
    T = c.ping_interval_s
    current = np.where(is_asv, (st.current_mean + st.current_gm)[:, None], 0.0)
    surge = np.where(is_asv, st.b_surge, 0.0)
    steer = np.where(is_asv, st.b_steer, 0.0)
    disturb_boats(st.b_pos, st.b_heading, st.b_vel, surge, steer, current, c.asv_current_response, T)
    tau = c.asv_noise_time_constant_s
    st.b_surge = np.where(is_asv, boat_noise_step(surge, T, tau, c.asv_surge_noise_mps, noise[..., 0]), 0.0)
    st.b_steer = np.where(
        is_asv, boat_noise_step(steer, T, tau, np.radians(c.asv_steering_noise_deg), noise[..., 1]), 0.0
    )


def add_displacement(travelled_m: np.ndarray, turn_sum_m: np.ndarray, moved: np.ndarray) -> tuple[Any, Any]:
    """The sums of ``heading_cycle_variance_m2`` after one more cycle's displacement
    ``moved`` (complex, east + 1j north): s + |d| and G + |d| e^{-2i theta} = G - d^2 / |d|."""
    step_m = np.abs(moved)
    return travelled_m + step_m, turn_sum_m - moved * moved / np.maximum(step_m, 1e-300)


def heading_cycle_variance_m2(cycle_deg: float, travelled_m: np.ndarray, turn_sum_m: np.ndarray) -> Any:
    """Per-axis variance of the dead reckoning's error from the one-cycle compass error
    b1 sin(theta + phi) (phase phi unknown, uniform), exact for any path under the model.

    With the cycles' displacements d_k = i |d_k| e^{-i theta_k} (theta a bearing) the error
    -i b1 sum_k sin(theta_k + phi) d_k is -i b1 (e^{i phi} s - e^{-i phi} G) / 2, with
    s = sum |d_k| (``travelled_m``) and G = sum |d_k| e^{-2i theta_k} (``turn_sum_m``);
    over phi, E|.|^2 = b1^2 (s^2 + |G|^2) / 4, half of it per axis: b1^2 s^2 / 4 per axis on
    a straight run (|G| = s), half that on whole orbits (G = 0)."""
    return 0.125 * np.radians(cycle_deg) ** 2 * (travelled_m**2 + np.abs(turn_sum_m) ** 2)


def navigate(
    st: Any,
    c: Any,
    draws: dict,
    moved: np.ndarray,
    is_asv: np.ndarray,
    K: int,
    surfacing: SurfacingTimes,
    cruise_depth_m: np.ndarray,
) -> None:
    """The beacons' own navigation over the cycle; ``moved`` (B,N) complex: their true
    ground displacement. AUVs: DVL dead reckoning, whose error grows with the distance
    travelled (this episode's compass error beta = b0 + b1 sin(heading + phase) and
    velocity scale error k turn a displacement d into (1 + k) e^{-i beta} d,
    e^{-i beta} a clockwise rotation) plus
    the integrated white velocity noise, and with the current estimate's error while
    bottom lock is lost; optionally a GPS fix at the surface (every
    ``beacon_surface_every_s``, or when the own std exceeds ``beacon_surface_above_std_m``).
    ASVs: a fresh GPS fix every cycle. The variance each carries (what enters the
    survey filters' R) is the beacon's own error model, not its actual error. In place on
    ``st`` (``SimState``): the errors, variances, lock, fix bookkeeping and counters;
    ``K`` sub-steps of ``c.substep_s``; ``surfacing``/``cruise_depth_m``: the timed
    surfacing's durations and each beacon's depth below it."""
    T, dt = c.ping_interval_s, c.substep_s
    n, u = draws["beacon_nav_n"], draws["beacon_nav_u"]
    auv = ~is_asv
    # bottom lock is lost and regained at random (per cycle), from the altitude (core/py)
    p_loss, p_regain = lock_probabilities(c, st.b_pos[..., 2])
    st.b_dvl_lock = np.where(st.b_dvl_lock, u >= p_loss, u < p_regain)
    # DVL: the white velocity noise integrated over the cycle (a random walk)
    walk_std = c.dvl_velocity_noise_mps * dt * np.sqrt(K)
    drift = np.where(st.b_dvl_lock, 0.0, st.b_current_err * T)  # without lock: thrust model + current estimate
    heading_err = st.b_dvl_heading_bias_rad + np.radians(c.beacon_dvl_heading_cycle_deg) * np.sin(
        unit_to_bearing(moved) + st.b_dvl_heading_phase_rad
    )
    bias = ((1.0 + st.b_dvl_scale_error) * np.exp(-1j * heading_err) - 1.0) * moved
    err_h = (st.b_nav_err[..., 0] + 1j * st.b_nav_err[..., 1]) + drift + bias + walk_std * (n[..., 0] + 1j * n[..., 1])
    # the variance it carries: the random walk adds up linearly; the current-estimate
    # error is a bias, so its part grows with the square of the time spent without lock;
    # the constant heading and scale errors' part grows with the square of the displacement
    # D since the last fix, E|(k - i b0) D|^2 = (sigma_k^2 + sigma_b0^2) |D|^2; half of
    # each per axis; the one-cycle part exact for any path (heading_cycle_variance_m2)
    st.b_walk_var_m2 = st.b_walk_var_m2 + walk_std**2
    st.b_unlocked_s = st.b_unlocked_s + np.where(st.b_dvl_lock, 0.0, T)
    st.b_since_fix_s = st.b_since_fix_s + T
    est_h = st.b_pos[..., 0] + 1j * st.b_pos[..., 1] + err_h
    sigma2 = c.beacon_dvl_scale_error_std**2 + np.radians(c.beacon_dvl_heading_bias_std_deg) ** 2
    st.b_travelled_m, st.b_turn_sum_m = add_displacement(st.b_travelled_m, st.b_turn_sum_m, moved)
    var = (
        st.b_walk_var_m2
        + (c.beacon_current_estimate_error_mps * st.b_unlocked_s) ** 2
        + 0.5 * sigma2 * np.abs(est_h - st.b_fix_est) ** 2
        + heading_cycle_variance_m2(c.beacon_dvl_heading_cycle_deg, st.b_travelled_m, st.b_turn_sum_m)
    )
    # a GPS fix: every cycle for ASVs; at the surface when due for AUVs. The receiver's
    # error is first-order Gauss-Markov, exact over the cycle: e <- phi e + sigma
    # sqrt(1 - phi^2) n, phi = exp(-T / tau) (tau = 0: white, a fresh error each fix)
    tau = c.gps_error_time_constant_s
    phi = np.exp(-T / tau) if tau > 0 else 0.0
    st.b_gps_err = phi * st.b_gps_err + c.gps_noise_m * np.sqrt(1.0 - phi * phi) * (n[..., 2] + 1j * n[..., 3])
    gps_h = st.b_gps_err
    surface = auv & (
        ((c.beacon_surface_every_s > 0) & (st.b_since_fix_s >= c.beacon_surface_every_s - 1e-9))
        | ((c.beacon_surface_above_std_m > 0) & (var > c.beacon_surface_above_std_m**2))
    )
    if c.beacon_surfacing == "timed":  # due: it ascends, dwells, descends (core/py)
        surface = advance_surfacing(st, c, surfacing, cruise_depth_m, surface)
    fix = ~auv | surface
    st.b_fix_count = st.b_fix_count + surface  # sent in the ping: the survey zeroes its Pxb (eq. C8)
    err_h = np.where(fix, gps_h, err_h)
    gps_var = c.gps_noise_m**2
    st.b_nav_var_m2 = np.where(fix, gps_var, var)
    st.b_walk_var_m2 = np.where(surface, gps_var, st.b_walk_var_m2)
    st.b_unlocked_s = np.where(surface, 0.0, st.b_unlocked_s)
    st.b_since_fix_s = np.where(fix, 0.0, st.b_since_fix_s)
    st.b_travelled_m = np.where(fix, 0.0, st.b_travelled_m)
    st.b_turn_sum_m = np.where(fix, 0.0, st.b_turn_sum_m)
    st.b_fix_est = np.where(fix, st.b_pos[..., 0] + 1j * st.b_pos[..., 1] + err_h, st.b_fix_est)
    st.b_surfacings = surface.astype(np.int64)
    st.b_nav_err[..., 0], st.b_nav_err[..., 1] = err_h.real, err_h.imag
