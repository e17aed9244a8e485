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
from numba import njit
from numpy.typing import ArrayLike

from .consider import ErrorModel
from .dynamics import boat_noise_step, disturb_boats


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


@njit(cache=True)
def _surfacing_depth_m(t_s: float, z0: float, w: float, up_s: float, fix_s: float) -> float:
    """The depth t_s into a surfacing from z0 at vertical speed w: ascending, at the
    surface, descending (module docstring)."""
    if t_s < up_s:
        return z0 - w * t_s
    if t_s <= fix_s:
        return 0.0
    return min(max(w * (t_s - fix_s), 0.0), z0)


@njit(cache=True)
def _lock_pair(a: float, min_m: float, max_m: float, fade_fraction: float, p_loss: float, p_regain: float):
    """(p_loss, p_regain) of bottom lock at altitude a (module docstring)."""
    fade = max(fade_fraction * max_m, 1e-12)
    ramp = min(max((a - (max_m - fade)) / fade, 0.0), 1.0)
    if not (min_m <= a <= max_m):
        return 1.0, 0.0
    return p_loss + (1.0 - p_loss) * ramp, p_regain * (1.0 - ramp)


def dvl_lock_probabilities(
    altitude_m: np.ndarray,
    min_altitude_m: float,
    max_altitude_m: float,
    fade_fraction: float,
    loss_probability: float,
    regain_probability: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Per-cycle probabilities of losing and of regaining bottom lock at ``altitude_m``
    (module docstring): (p_loss, p_regain), each shaped like the altitude (``_lock_pair``
    over the array)."""
    pair = np.vectorize(_lock_pair, otypes=[float, float])
    loss, regain = pair(
        np.asarray(altitude_m, dtype=float),
        min_altitude_m,
        max_altitude_m,
        fade_fraction,
        loss_probability,
        regain_probability,
    )
    return loss, regain


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


class _NavParams(NamedTuple):
    """``navigate``'s scenario constants for one cycle."""

    T: float  # ping_interval_s
    walk_std: float  # the DVL's white velocity noise integrated over the cycle (m)
    lock_fixed: bool  # dvl_lock_model == "fixed"
    p_loss: float  # dvl_lock_loss_probability
    p_regain: float  # dvl_lock_regain_probability
    water_depth_m: float
    min_altitude_m: float  # dvl_min_altitude_m
    max_altitude_m: float  # dvl_max_altitude_m
    fade_fraction: float  # dvl_lock_fade_fraction
    cycle_rad: float  # beacon_dvl_heading_cycle_deg
    sigma2: float  # scale error's plus constant heading error's variance
    sigma2_diff: float  # scale error's minus constant heading error's variance (the deviator's part)
    current_err_mps: float  # beacon_current_estimate_error_mps
    gps_phi: float  # exp(-T / gps_error_time_constant_s), 0 for a white error
    gps_noise_m: float
    every_s: float  # beacon_surface_every_s
    above_std_m: float  # beacon_surface_above_std_m
    timed: bool  # beacon_surfacing == "timed"
    vertical_speed_mps: float
    ranging_min_depth_m: float
    full_covariance: bool  # beacon_covariance == "full": the deviator sent too (eq. N1)


class _NavState(NamedTuple):
    """The beacons' navigation state ``navigate`` replaces each cycle (``SimState``'s b_*, (B, N))."""

    dvl_lock: np.ndarray
    walk_var_m2: np.ndarray
    unlocked_s: np.ndarray
    since_fix_s: np.ndarray
    travelled_m: np.ndarray
    turn_sum_m: np.ndarray
    gps_err: np.ndarray
    fix_count: np.ndarray
    nav_var_m2: np.ndarray
    nav_dev_m2: np.ndarray
    fix_est: np.ndarray
    surfacings: np.ndarray
    surfacing: np.ndarray
    excursion_s: np.ndarray
    away_s: np.ndarray
    away: np.ndarray


_NAV_FIELDS = tuple("b_" + f for f in _NavState._fields)


class _DvlErrors(NamedTuple):
    """This episode's DVL dead-reckoning errors (B, N): the current estimate's (complex),
    the compass's constant part and one-cycle phase, the velocity scale."""

    current_err: np.ndarray
    heading_bias_rad: np.ndarray
    heading_phase_rad: np.ndarray
    scale_error: np.ndarray


def error_model(c: Any) -> ErrorModel:
    """The error model's constants from the scenario config ``c`` (one home: ``nav_params`` and
    the survey's eq. N2 read them): sigma_k^2 +- sigma_b0^2, b1^2 and the current estimate's
    error variance per axis."""
    k2, b2 = float(c.beacon_dvl_scale_error_std) ** 2, float(np.radians(c.beacon_dvl_heading_bias_std_deg)) ** 2
    return ErrorModel(
        k2 + b2,
        k2 - b2,
        float(np.radians(c.beacon_dvl_heading_cycle_deg)) ** 2,
        float(c.beacon_current_estimate_error_mps) ** 2,
    )


def nav_params(c: Any, K: int) -> _NavParams:
    """``navigate``'s constants from the scenario config ``c`` with ``K`` sub-steps a cycle
    (built once per simulator)."""
    tau = c.gps_error_time_constant_s
    em = error_model(c)
    return _NavParams(
        float(c.ping_interval_s),
        float(c.dvl_velocity_noise_mps * c.substep_s * np.sqrt(K)),
        c.dvl_lock_model == "fixed",
        float(c.dvl_lock_loss_probability),
        float(c.dvl_lock_regain_probability),
        float(c.water_depth_m),
        float(c.dvl_min_altitude_m),
        float(c.dvl_max_altitude_m),
        float(c.dvl_lock_fade_fraction),
        float(np.radians(c.beacon_dvl_heading_cycle_deg)),
        em.sigma2_sum,
        em.sigma2_diff,
        float(c.beacon_current_estimate_error_mps),
        float(np.exp(-c.ping_interval_s / tau)) if tau > 0 else 0.0,
        float(c.gps_noise_m),
        float(c.beacon_surface_every_s),
        float(c.beacon_surface_above_std_m),
        c.beacon_surfacing == "timed",
        float(c.beacon_vertical_speed_mps),
        float(c.beacon_ranging_min_depth_m),
        c.beacon_covariance == "full",
    )


@njit(cache=True)
def _surface(on: bool, t0: float, due: bool, times: tuple, z0: float, prm: _NavParams) -> tuple:
    """One cycle of a beacon's surfacings (``beacon_surfacing="timed"``): ``on`` a surfacing
    begun ``t0`` s ago, ``due`` a fix is due (a beacon not yet surfacing begins its ascent at
    the end of this cycle), times (up, fix, end, away from, away until) of a surfacing from its
    depth z0. Returns (the fix taken this cycle, at the end of the cycle in which a dwell ends
    (the dead reckoning over the rest of that cycle is not added: at most one cycle's descent);
    the time above the ranging depth this cycle; on a surfacing now; its time; the depth;
    away)."""
    up_s, fix_s, end_s, away_from_s, away_until_s = times
    t1 = t0 + prm.T
    # the fix in (t0, t1]; at the excursion's start (t0 = 0) also at 0, where a beacon at the
    # surface with no dwell takes it (else it would surface every cycle and never fix)
    fix = on and (t0 < fix_s or t0 == 0.0) and t1 >= fix_s
    away_s = max(min(t1, away_until_s) - max(t0, away_from_s), 0.0) if on else 0.0
    start = due and not on
    going = start or (on and not t1 >= end_s)
    excursion_s = 0.0 if start else (t1 if going else 0.0)
    depth = _surfacing_depth_m(excursion_s, z0, prm.vertical_speed_mps, up_s, fix_s) if going else z0
    return fix, away_s, going, excursion_s, depth, going and depth < min(prm.ranging_min_depth_m, z0) - 1e-9


@njit(cache=True, inline="always")
def _deviator(prm: _NavParams, since_fix_m: complex, travelled_m: float, turn_sum_m: complex) -> complex:
    """Eq. N1's deviator with ``beacon_covariance="full"``; 0 (not computed) with "isotropic",
    which sends m alone."""
    if not prm.full_covariance:
        return 0.0j
    return covariance_deviator_m2(prm.sigma2_diff, since_fix_m, prm.cycle_rad, travelled_m, turn_sum_m)


@njit(cache=True)
def _navigate(old, new, dvl, pos, nav_err, moved, u, draws_n, is_asv, times, cruise_depth_m, prm):
    """``navigate`` over the batch: ``old`` (``_NavState``) read, ``new`` written; pos
    (B, N, 3) depth and nav_err (B, N, 3) horizontal written in place (module docstring,
    ``navigate``'s equations)."""
    for b in range(moved.shape[0]):
        for n in range(moved.shape[1]):
            d = moved[b, n]
            # bottom lock is lost and regained at random (per cycle), from the altitude
            p_loss, p_regain = prm.p_loss, prm.p_regain
            if not prm.lock_fixed:
                alt = prm.water_depth_m - pos[b, n, 2]
                p_loss, p_regain = _lock_pair(
                    alt, prm.min_altitude_m, prm.max_altitude_m, prm.fade_fraction, p_loss, p_regain
                )
            lock = u[b, n] >= p_loss if old.dvl_lock[b, n] else u[b, n] < p_regain
            new.dvl_lock[b, n] = lock
            # DVL: the white velocity noise integrated over the cycle (a random walk); without
            # lock, the thrust model plus the current estimate, whose error drifts
            drift = 0.0j if lock else dvl.current_err[b, n] * prm.T
            heading_err = dvl.heading_bias_rad[b, n] + prm.cycle_rad * np.sin(
                np.arctan2(d.real, d.imag) + dvl.heading_phase_rad[b, n]
            )
            bias = ((1.0 + dvl.scale_error[b, n]) * np.exp(-1j * heading_err) - 1.0) * d
            walk = prm.walk_std * (draws_n[b, n, 0] + 1j * draws_n[b, n, 1])
            err_h = (nav_err[b, n, 0] + 1j * nav_err[b, n, 1]) + drift + bias + walk
            # the variance it carries: the random walk adds up linearly; the current
            # estimate's error is a bias, so its part grows with the square of the time
            # without lock; the constant heading and scale errors' part with the square of the
            # displacement D since the last fix, E|(k - i b0) D|^2 = (sigma_k^2 + sigma_b0^2)
            # |D|^2; half of each per axis; the one-cycle part exact for any path
            # (heading_cycle_variance_m2)
            walk_var = old.walk_var_m2[b, n] + prm.walk_std**2
            unlocked = old.unlocked_s[b, n] + (0.0 if lock else prm.T)
            since_fix = old.since_fix_s[b, n] + prm.T
            est_h = pos[b, n, 0] + 1j * pos[b, n, 1] + err_h
            travelled, turn_sum = add_displacement(old.travelled_m[b, n], old.turn_sum_m[b, n], d)
            since = est_h - old.fix_est[b, n]
            var = (
                walk_var
                + (prm.current_err_mps * unlocked) ** 2
                + 0.5 * prm.sigma2 * abs(since) ** 2
                + heading_cycle_variance_m2(prm.cycle_rad, travelled, turn_sum)
            )
            dev = _deviator(prm, since, travelled, turn_sum)  # eq. N1 ("isotropic": 0)
            # a GPS fix: every cycle for ASVs; at the surface when due for AUVs. The
            # receiver's error is first-order Gauss-Markov, exact over the cycle: e <- phi e
            # + sigma sqrt(1 - phi^2) n (phi = 0: white, a fresh error each fix)
            phi = prm.gps_phi
            gps = phi * old.gps_err[b, n] + prm.gps_noise_m * np.sqrt(1.0 - phi * phi) * (
                draws_n[b, n, 2] + 1j * draws_n[b, n, 3]
            )
            new.gps_err[b, n] = gps
            auv = not is_asv[n]
            due = auv and (
                (prm.every_s > 0 and since_fix >= prm.every_s - 1e-9)
                or (prm.above_std_m > 0 and var > prm.above_std_m**2)
            )
            surface = due
            on, t0, away_s, away = old.surfacing[b, n], old.excursion_s[b, n], old.away_s[b, n], old.away[b, n]
            if prm.timed:  # due: it ascends, dwells, descends (module docstring)
                when = (times.up_s[n], times.fix_s[n], times.end_s[n], times.away_from_s[n], times.away_until_s[n])
                surface, away_s, on, t0, depth, away = _surface(on, t0, due, when, cruise_depth_m[n], prm)
                if cruise_depth_m[n] > 0:  # ASVs (depth 0) stay
                    pos[b, n, 2] = depth
            new.surfacing[b, n], new.excursion_s[b, n], new.away_s[b, n], new.away[b, n] = on, t0, away_s, away
            fix = not auv or surface
            new.fix_count[b, n] = old.fix_count[b, n] + surface  # in the ping: the survey zeroes its Pxb (C8)
            if fix:
                err_h = gps
            gps_var = prm.gps_noise_m**2
            new.nav_var_m2[b, n] = gps_var if fix else var
            new.nav_dev_m2[b, n] = 0.0j if fix else dev
            new.walk_var_m2[b, n] = gps_var if surface else walk_var
            new.unlocked_s[b, n] = 0.0 if surface else unlocked
            new.since_fix_s[b, n] = 0.0 if fix else since_fix
            new.travelled_m[b, n] = 0.0 if fix else travelled
            new.turn_sum_m[b, n] = 0.0j if fix else turn_sum
            new.fix_est[b, n] = pos[b, n, 0] + 1j * pos[b, n, 1] + err_h if fix else old.fix_est[b, n]
            new.surfacings[b, n] = surface
            nav_err[b, n, 0], nav_err[b, n, 1] = err_h.real, err_h.imag


@njit(cache=True)
def add_displacement(travelled_m: float, turn_sum_m: complex, moved: complex) -> tuple[float, complex]:
    """The sums of ``heading_cycle_variance_m2`` after one more cycle's displacement
    ``moved`` (complex, east + 1j north): s + |d| and G + |d| e^{-2i theta} = G - d^2 / |d|."""
    step_m = abs(moved)
    return travelled_m + step_m, turn_sum_m - moved * moved / max(step_m, 1e-300)


@njit(cache=True)
def heading_cycle_variance_m2(cycle_rad: float, travelled_m: float, turn_sum_m: complex) -> float:
    """Per-axis variance of the dead reckoning's error from the one-cycle compass error
    b1 sin(theta + phi) (b1 = ``cycle_rad``, phase phi unknown, uniform), exact for any
    path under the model.

    With the cycles' displacements d_k = i |d_k| e^{-i theta_k} (theta a bearing) the error
    -i b1 sum_k sin(theta_k + phi) d_k is -i b1 (e^{i phi} s - e^{-i phi} G) / 2, with
    s = sum |d_k| (``travelled_m``) and G = sum |d_k| e^{-2i theta_k} (``turn_sum_m``);
    over phi, E|.|^2 = b1^2 (s^2 + |G|^2) / 4, half of it per axis: b1^2 s^2 / 4 per axis on
    a straight run (|G| = s), half that on whole orbits (G = 0)."""
    return 0.125 * cycle_rad**2 * (travelled_m**2 + abs(turn_sum_m) ** 2)


@njit(cache=True)
def covariance_deviator_m2(
    sigma2_diff: float, since_fix_m: complex, cycle_rad: float, travelled_m: float, turn_sum_m: complex
) -> complex:
    """The anisotropic part of the dead reckoning's horizontal error covariance Sigma, as the
    complex deviator (Sigma_xx - Sigma_yy) / 2 + 1j Sigma_xy = E[z^2] / 2 (z = error, east +
    1j north), so that Sigma = [[m + a, c], [c, m - a]] with m the per-axis variance the
    beacon carries (``nav_var_m2``) and a + 1j c this (``consider.beacon_covariance``).
    The white walk and the current estimate's error are isotropic (no part here); the
    constant errors' z = (k - i b0) D over the displacement D since the fix give
    E[z^2] = (sigma_k^2 - sigma_b0^2) D^2; the one-cycle compass error's
    z = -i b1 (e^{i phi} s - e^{-i phi} G) / 2 (``heading_cycle_variance_m2``) gives
    E[z^2] = b1^2 s G / 2 over the uniform phase. So (eq. N1)

        a + 1j c = (sigma_k^2 - sigma_b0^2) D^2 / 2 + b1^2 s G / 4.

    A heading error displaces across the track: on a straight run north (D = i s, G = s) with
    only b1, Sigma_xx = b1^2 s^2 / 2 and Sigma_yy = 0, where an isotropic m would give b1^2
    s^2 / 4 to each."""
    return 0.5 * sigma2_diff * since_fix_m * since_fix_m + 0.25 * cycle_rad**2 * travelled_m * turn_sum_m


def navigate(
    st: Any,
    prm: _NavParams,
    draws: dict,
    moved: np.ndarray,
    is_asv: np.ndarray,
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
    survey filters' R) is the beacon's own error model, not its actual error. On ``st``
    (``SimState``): the errors, variances, lock, fix bookkeeping and counters, each a new
    array (b_pos's depth and b_nav_err in place); prm: ``nav_params``;
    ``surfacing``/``cruise_depth_m`` (N,): the timed surfacing's durations and each
    beacon's depth below it. One compiled kernel over the batch (``_navigate``): as numpy on
    arrays of one it was a quarter of a batch-of-one step."""
    old = _NavState(*(getattr(st, f) for f in _NAV_FIELDS))
    new = _NavState(*(np.empty_like(a) for a in old))
    dvl = _DvlErrors(st.b_current_err, st.b_dvl_heading_bias_rad, st.b_dvl_heading_phase_rad, st.b_dvl_scale_error)
    u, n = draws["beacon_nav_u"], draws["beacon_nav_n"]
    _navigate(old, new, dvl, st.b_pos, st.b_nav_err, moved, u, n, is_asv, surfacing, cruise_depth_m, prm)
    for f, a in zip(_NAV_FIELDS, new):
        setattr(st, f, a)
