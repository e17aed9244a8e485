"""Vehicle dynamics over the batch: the thrust model, attitude rotation, turning, current.

Conventions, used everywhere in coopnav: the navigation frame is (east, north,
depth) in metres, depth positive down; a bearing is clockwise from north in
radians; a pitch is positive nose-up. In the horizontal plane the sub-step loop
uses complex numbers, east + 1j * north, so that turning is one multiplication.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit, vectorize
from numpy.typing import ArrayLike


# --- Gao & Chitre eq. (1): m du/dt = T - 1/2 Cd rho A u^2 ----------------------------
# Erratum: the paper writes the thrust term as g*T, which is a force only if T is
# in kilogram-force. coopnav takes T in newtons (thrust setting % of max_thrust_n).
def drag_constant(drag_coefficient: float, water_density_kgpm3: float, cross_section_m2: float) -> float:
    """k in m du/dt = T - k u^2, i.e. k = 1/2 Cd rho A (kg/m)."""
    return 0.5 * drag_coefficient * water_density_kgpm3 * cross_section_m2


def terminal_speed_mps(thrust_n: ArrayLike, k: float) -> np.ndarray:
    """Steady forward speed of eq. (1): sqrt(T / k)."""
    return np.sqrt(np.maximum(thrust_n, 0.0) / k)


@vectorize(["float64(float64, float64, float64, float64, float64)"], cache=True)
def thrust_speed(u0_mps: float, thrust_n: float, k: float, mass_kg: float, t_s: float) -> float:
    """Exact solution of eq. (1) with constant thrust: the speed t_s after u0. A ufunc.

    With u_inf = sqrt(T/k) and rate g = k u_inf / m: below u_inf,
    u = u_inf tanh(atanh(u0/u_inf) + g t); above, u = u_inf coth(acoth(u0/u_inf) + g t);
    with zero thrust, u = u0 / (1 + k u0 t / m).
    """
    if thrust_n <= 0.0:
        return u0_mps / (1.0 + k * u0_mps * t_s / mass_kg)
    u_inf = np.sqrt(thrust_n / k)
    g = k * u_inf / mass_kg
    ratio = u0_mps / u_inf
    if ratio == 1.0:  # cruising: the steady state of eq. (1)
        return u_inf
    if ratio <= 1.0:
        return u_inf * np.tanh(np.arctanh(min(max(ratio, 0.0), 1.0 - 1e-15)) + g * t_s)
    return u_inf / np.tanh(np.arctanh(1.0 / max(ratio, 1.0 + 1e-15)) + g * t_s)


def thrust_speed_profile(
    u0_mps: ArrayLike, thrust_n: ArrayLike, k: float, mass_kg: float, times_s: ArrayLike
) -> np.ndarray:
    """``thrust_speed`` at several times: u0 and thrust (shape X), times (K,) -> X + (K,)."""
    u0 = np.asarray(u0_mps, dtype=float)[..., None]
    thrust = np.asarray(thrust_n, dtype=float)[..., None]
    return thrust_speed(u0, thrust, float(k), float(mass_kg), np.asarray(times_s, dtype=float))


# --- Gao & Chitre eq. (5): body-frame velocity into the navigation frame ---------------
def body_to_nav_matrix(bearing_rad: ArrayLike, pitch_rad: ArrayLike, roll_rad: ArrayLike) -> np.ndarray:
    """Rotation from body axes (forward, starboard, down) to (east, north, depth).

    Z-Y-X Euler angles (yaw = compass bearing, pitch nose-up, roll starboard-down),
    shape (..., 3, 3). Note on the paper's eq. (5): with beta = -b its first column
    is (cos b cos p, sin b cos p, sin p), i.e. its first axis is north (not east as
    the text says) and its third axis points up for nose-up pitch; we keep the
    physics (east, north, depth-down) and order the rows accordingly.
    """
    cb, sb = np.cos(bearing_rad), np.sin(bearing_rad)
    cp, sp = np.cos(pitch_rad), np.sin(pitch_rad)
    cr, sr = np.cos(roll_rad), np.sin(roll_rad)
    # the standard NED rotation R_z(b) R_y(p) R_x(r) (pitch nose-up positive there too),
    # rows reordered to (east, north, down): a left-handed triad, so det = -1.
    north = np.stack([cb * cp, cb * sp * sr - sb * cr, cb * sp * cr + sb * sr], -1)
    east = np.stack([sb * cp, sb * sp * sr + cb * cr, sb * sp * cr - cb * sr], -1)
    down = np.stack([-sp, cp * sr, cp * cr], -1)
    return np.stack([east, north, down], -2)


def forward_axis(bearing_rad: ArrayLike, pitch_rad: ArrayLike) -> np.ndarray:
    """First column of body_to_nav_matrix: the nav-frame direction of body x, (..., 3).

    For v_body = (u, 0, 0) (eq. 3) this is all of eq. (4)'s R v: roll drops out.
    """
    cp = np.cos(pitch_rad)
    return np.stack([cp * np.sin(bearing_rad), cp * np.cos(bearing_rad), -np.sin(pitch_rad)], -1)


@vectorize(["complex128(float64)"], cache=True)
def bearing_to_unit(bearing_rad: float) -> complex:
    """Bearing (clockwise from north) as a complex unit east + 1j*north. A ufunc."""
    return complex(np.sin(bearing_rad), np.cos(bearing_rad))


def unit_to_bearing(h: np.ndarray | complex) -> Any:
    return np.arctan2(h.real, h.imag)


@njit(cache=True)
def turn_toward(heading: complex, desired: complex, cos_max_turn: float, sin_max_turn: float) -> complex:
    """Rotate a complex unit heading towards ``desired`` by at most the angle whose
    cosine and sine are given (precomputed: this runs every sub-step, and needs no
    trigonometry). A positive complex angle is anticlockwise, i.e. towards a smaller
    bearing. Where ``desired`` is zero the heading is kept.
    """
    rel = desired * heading.conjugate()
    mag = abs(rel)
    if mag == 0.0:
        return heading
    if rel.real >= mag * cos_max_turn:  # within reach: point straight at it
        return desired / abs(desired)
    if rel.imag >= 0.0:
        return heading * (cos_max_turn + 1j * sin_max_turn)
    return heading * (cos_max_turn - 1j * sin_max_turn)


def max_turn_per_substep_rad(rate_dps: ArrayLike, substep_s: float) -> np.ndarray:
    """The largest heading change in one sub-step, rate x sub-step, at most pi: a limit
    of pi or more is no limit (``turn_toward`` points straight at the target), where its
    cosine and sine alone would wrap (360 deg would never turn; a review found it)."""
    return np.minimum(np.radians(np.asarray(rate_dps, float)) * float(substep_s), np.pi)


def turn_towards(heading: ArrayLike, desired: ArrayLike, max_turn_rad: float) -> np.ndarray:
    """``turn_toward`` over arrays, with the limit as an angle (half a turn or more is no limit:
    capped at pi, as ``max_turn_per_substep_rad`` caps it, where cos and sin would wrap)."""
    limit = min(float(max_turn_rad), np.pi)
    cm, sm = float(np.cos(limit)), float(np.sin(limit))
    return np.vectorize(lambda h, d: turn_toward(complex(h), complex(d), cm, sm), otypes=[complex])(heading, desired)


# --- ocean current: constant + first-order Gauss-Markov ---------------------------------
def gauss_markov_step(
    v: np.ndarray | float,
    dt_s: float,
    time_constant_s: np.ndarray | float,
    std: np.ndarray | float,
    noise: np.ndarray | float,
) -> np.ndarray:
    """Exact discretization of dv = -v/tau dt + q dW with stationary std ``std``.

    v <- a v + sqrt(1 - a^2) std n, a = exp(-dt/tau) (cf. UUV Simulator's
    GaussMarkovProcess, which uses the Euler form; shared/reference-values.md 5).
    """
    a = np.exp(-dt_s / time_constant_s)
    return a * v + np.sqrt(1.0 - a * a) * std * noise


# --- surface craft following commands: the boats of the moving network, the ASVs -------
@njit(cache=True)
def disturb_boats(
    pos: np.ndarray,
    heading: np.ndarray,
    vel: np.ndarray,
    surge: np.ndarray,
    steer: np.ndarray,
    current: np.ndarray,
    response: float,
    T: float,
) -> None:
    """The boats' (and the ASVs') imperfect execution of their commands over one cycle, in
    place: after
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


def boat_noise_step(x: np.ndarray, T: float, time_constant_s: float, std: float, noise: np.ndarray) -> np.ndarray:
    """One cycle of a boat's Gauss-Markov fluctuation (``gauss_markov_step``; white per cycle
    when the time constant is 0)."""
    if time_constant_s <= 0.0:
        return std * noise
    return gauss_markov_step(x, T, time_constant_s, std, noise)
