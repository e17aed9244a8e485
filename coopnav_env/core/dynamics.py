"""Vehicle dynamics over the batch: the thrust model, attitude rotation, turning, current.

Conventions, used everywhere in coopnav: the navigation frame is (east, north,
depth) in metres, depth positive down; a bearing is clockwise from north in
radians; a pitch is positive nose-up. In the horizontal plane the sub-step loop
uses complex numbers, east + 1j * north, so that turning is one multiplication.
"""

from __future__ import annotations

import numpy as np
from numba import njit


# --- Gao & Chitre eq. (1): m du/dt = T - 1/2 Cd rho A u^2 ----------------------------
# Erratum: the paper writes the thrust term as g*T, which is a force only if T is
# in kilogram-force. coopnav takes T in newtons (thrust setting % of max_thrust_n).
def drag_constant(drag_coefficient, water_density_kgpm3, cross_section_m2):
    """k in m du/dt = T - k u^2, i.e. k = 1/2 Cd rho A (kg/m)."""
    return 0.5 * drag_coefficient * water_density_kgpm3 * cross_section_m2


def terminal_speed_mps(thrust_n, k):
    """Steady forward speed of eq. (1): sqrt(T / k)."""
    return np.sqrt(np.maximum(thrust_n, 0.0) / k)


def thrust_speed_profile(u0_mps, thrust_n, k, mass_kg, times_s):
    """Exact solution of eq. (1) with constant thrust, at ``times_s`` after u0.

    u0 and thrust broadcast against each other (shape X); times_s has shape (K,);
    the result has shape X + (K,). With u_inf = sqrt(T/k) and rate g = k u_inf / m:
    below u_inf, u = u_inf tanh(atanh(u0/u_inf) + g t); above, the coth branch;
    with zero thrust, u = u0 / (1 + k u0 t / m).
    """
    u0 = np.asarray(u0_mps, dtype=float)[..., None]
    u_inf = terminal_speed_mps(np.asarray(thrust_n, dtype=float), k)[..., None]
    t = np.asarray(times_s, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        g = k * u_inf / mass_kg
        ratio = u0 / u_inf
        below = u_inf * np.tanh(np.arctanh(np.clip(ratio, 0.0, 1.0 - 1e-15)) + g * t)
        above = u_inf / np.tanh(np.arctanh(1.0 / np.maximum(ratio, 1.0 + 1e-15)) + g * t)
        coast = u0 / (1.0 + k * u0 * t / mass_kg)
    return np.where(u_inf <= 0.0, coast, np.where(ratio <= 1.0, below, above))


# --- Gao & Chitre eq. (5): body-frame velocity into the navigation frame ---------------
def body_to_nav_matrix(bearing_rad, pitch_rad, roll_rad):
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


def forward_axis(bearing_rad, pitch_rad):
    """First column of body_to_nav_matrix: the nav-frame direction of body x, (..., 3).

    For v_body = (u, 0, 0) (eq. 3) this is all of eq. (4)'s R v: roll drops out.
    """
    cp = np.cos(pitch_rad)
    return np.stack([cp * np.sin(bearing_rad), cp * np.cos(bearing_rad), -np.sin(pitch_rad)], -1)


def bearing_to_unit(bearing_rad):
    """Bearing (clockwise from north) as a complex unit east + 1j*north."""
    return np.sin(bearing_rad) + 1j * np.cos(bearing_rad)


def unit_to_bearing(h):
    return np.arctan2(h.real, h.imag)


@njit(cache=True)
def turn_toward(heading, desired, max_turn_rad):
    """Rotate a complex unit heading towards ``desired`` by at most ``max_turn_rad``.

    A positive complex angle is anticlockwise, i.e. towards a smaller bearing.
    Where ``desired`` is zero the heading is kept.
    """
    rel = desired * heading.conjugate()
    turn = min(max(np.arctan2(rel.imag, rel.real), -max_turn_rad), max_turn_rad)
    return heading * (np.cos(turn) + 1j * np.sin(turn))


def turn_towards(heading, desired, max_turn_rad):
    """``turn_toward`` over arrays."""
    return np.vectorize(lambda h, d: turn_toward(complex(h), complex(d), float(max_turn_rad)),
                        otypes=[complex])(heading, desired)


def rate_limited_headings(heading0, desired, max_turn_rad_per_step, n_steps):
    """Headings after each of n_steps constant-rate-limited turns, shape X + (n_steps,)."""
    rel = np.angle(desired * heading0.conj())[..., None]
    k = np.arange(1, n_steps + 1)
    turned = np.sign(rel) * np.minimum(np.abs(rel), max_turn_rad_per_step[..., None] * k)
    return heading0[..., None] * np.exp(1j * turned)


# --- ocean current: constant + first-order Gauss-Markov ---------------------------------
def gauss_markov_step(v, dt_s, time_constant_s, std, noise):
    """Exact discretization of dv = -v/tau dt + q dW with stationary std ``std``.

    v <- a v + sqrt(1 - a^2) std n, a = exp(-dt/tau) (cf. UUV Simulator's
    GaussMarkovProcess, which uses the Euler form; shared/reference-values.md 5).
    """
    a = np.exp(-dt_s / time_constant_s)
    return a * v + np.sqrt(1.0 - a * a) * std * noise
