"""Sound speed and acoustic ranging between moving vehicles.

Sound speed: Mackenzie (1981), J. Acoust. Soc. Am. 70:807, valid for 2-30 degC,
25-40 ppt and 0-8000 m (shared/reference-values.md section 4).

Ranging: the time of flight is solved between the position of the sender at
transmit time and the position of the receiver at receive time (both move while
sound travels), then turned back into a range with the sound speed the vehicles
*assume*. One-way travel time (OWTT) needs synchronized clocks and carries their
offset; two-way travel time (TWTT) measures a round trip through a transponder
with a turn-around delay (shared/reference-values.md section 3).

Noise: one convention for every ranging mode. Each detection of a signal (a
receiver timestamping an arrival) is late by a white timing jitter sigma_t; the
scenario's ``range_noise_std_m`` is that jitter as a range, c sigma_t. A one-way
range has one detection (std c sigma_t); a two-way range r = c (t_rt - TAT) / 2
has two (the transponder's and the interrogator's), so its variance is
2 (c sigma_t)^2 / 4 = (c sigma_t)^2 / 2 (``ranging_variance_m2``); the moving
network's exchange derives its correlated R from the same jitter
(``core.moving_network``). ``tests/test_noise.py`` checks the filters' R against
Monte Carlo variances of the simulated ranges.

The functions are compiled (numba ufuncs and njit) so that the simulator's
kernels call the same formulas that Python code calls on arrays.
"""

from __future__ import annotations

import numpy as np
from numba import njit, vectorize
from numpy.typing import ArrayLike


@vectorize(["float64(float64, float64, float64)"], cache=True)
def mackenzie_sound_speed(temperature_c: float, salinity_psu: float, depth_m: float) -> float:
    """Sound speed in sea water, m/s (Mackenzie 1981). A ufunc: arrays broadcast.

    >>> round(float(mackenzie_sound_speed(10.0, 35.0, 0.0)), 1)
    1489.8
    """
    t = temperature_c
    s = salinity_psu - 35.0
    d = depth_m
    return (
        1448.96
        + 4.591 * t
        - 5.304e-2 * t * t
        + 2.374e-4 * t * t * t
        + 1.340 * s
        + 1.630e-2 * d
        + 1.675e-7 * d * d
        - 1.025e-2 * t * s
        - 7.139e-13 * t * d * d * d
    )


@vectorize(["float64(float64, float64, float64, float64)"], cache=True)
def packet_loss_probability(range_m: float, near: float, far: float, max_range_m: float) -> float:
    """Loss probability growing quadratically from ``near`` at 0 m to ``far`` at max range; 1 beyond."""
    if range_m > max_range_m:
        return 1.0
    frac = max(range_m, 0.0) / max_range_m
    return near + (far - near) * frac * frac


@njit(cache=True)
def ranging_variance_m2(detection_std_m: float, two_way: bool) -> float:
    """Variance of a range (m^2) from the per-detection jitter as range c sigma_t
    (``detection_std_m``): one detection one-way, two halved ones two-way."""
    v = detection_std_m * detection_std_m
    return 0.5 * v if two_way else v


@njit(cache=True)
def sound_speed_rel_std_at(
    c_assumed_mps: float,
    nominal_temperature_c: float,
    salinity_psu: float,
    temperature_uncertainty_c: float,
    depth_m: float,
) -> float:
    """``sound_speed_rel_std`` given the assumed sound speed there (Mackenzie's c at the
    nominal temperature), which the modem's ping has already computed."""
    dc_dT = mackenzie_sound_speed(nominal_temperature_c + 1.0, salinity_psu, depth_m) - c_assumed_mps
    return temperature_uncertainty_c * dc_dT / c_assumed_mps


@vectorize(["float64(float64, float64, float64, float64)"], cache=True)
def sound_speed_rel_std(
    nominal_temperature_c: float, salinity_psu: float, temperature_uncertainty_c: float, depth_m: float
) -> float:
    """The sound speed's relative uncertainty std(c) / c when the water's temperature is
    known to ``temperature_uncertainty_c`` (1 sigma) about the nominal one: the
    temperature derivative of Mackenzie's c over one degree, times the uncertainty, over
    the assumed c. A ufunc: the survey filter's ranges (``measurements.modem``) and the
    planners' model of them (``measurements.range_variance_m2``) call this one formula."""
    c_assumed = mackenzie_sound_speed(nominal_temperature_c, salinity_psu, depth_m)
    return sound_speed_rel_std_at(c_assumed, nominal_temperature_c, salinity_psu, temperature_uncertainty_c, depth_m)


@vectorize(["float64(float64, boolean, float64, float64, float64)"], cache=True)
def modem_range_variance(
    detection_std_m: float, two_way: bool, beacon_var_m2: float, predicted_range_m: float, sound_speed_rel_std: float
) -> float:
    """R of a modem range (m^2): the ranging noise (``ranging_variance_m2``), the beacon's
    own horizontal position variance (below Gao & Chitre eq. 7), and the sound speed's
    relative uncertainty as a scale error of the predicted range, which grows with it:
    R = sigma_r^2 + sigma_b^2 + (d std(c)/c)^2. A ufunc: the survey filter calls it per
    range, the planners over their candidate positions (arrays broadcast)."""
    scale = predicted_range_m * sound_speed_rel_std
    return ranging_variance_m2(detection_std_m, two_way) + beacon_var_m2 + scale * scale


@njit(cache=True)
def travel_time(
    sender: np.ndarray, receiver: np.ndarray, receiver_velocity: np.ndarray, sound_speed_mps: float
) -> float:
    """Time for sound sent from a fixed point to reach a receiver moving at constant velocity.

    Solves tau = |r + v tau - s| / c by fixed-point iteration, a contraction with
    factor |v|/c: the error after n iterations is about (|v|/c)^(n+1) times the
    distance, so five iterations are exact to round-off for vehicle speeds.
    sender, receiver, receiver_velocity: (3,).
    """
    r0 = receiver[0] - sender[0]
    r1 = receiver[1] - sender[1]
    r2 = receiver[2] - sender[2]
    tau = np.sqrt(r0 * r0 + r1 * r1 + r2 * r2) / sound_speed_mps
    for _ in range(5):
        a = r0 + receiver_velocity[0] * tau
        b = r1 + receiver_velocity[1] * tau
        c = r2 + receiver_velocity[2] * tau
        tau = np.sqrt(a * a + b * b + c * c) / sound_speed_mps
    return tau


def travel_time_s(
    sender_pos_m: ArrayLike, receiver_pos_m: ArrayLike, receiver_vel_mps: ArrayLike, sound_speed_mps: ArrayLike
) -> np.ndarray:
    """``travel_time`` over arrays: positions and velocity (..., 3), sound speed (...)."""
    return np.vectorize(travel_time, signature="(3),(3),(3),()->()")(
        np.asarray(sender_pos_m, float),
        np.asarray(receiver_pos_m, float),
        np.asarray(receiver_vel_mps, float),
        np.asarray(sound_speed_mps, float),
    )
