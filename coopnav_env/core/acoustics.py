"""Sound speed and acoustic ranging between moving vehicles, over the batch.

Sound speed: Mackenzie (1981), J. Acoust. Soc. Am. 70:807, valid for 2-30 degC,
25-40 ppt and 0-8000 m (shared/reference-values.md section 4).

Ranging: the time of flight is solved between the position of the sender at
transmit time and the position of the receiver at receive time (both move while
sound travels), then turned back into a range with the sound speed the vehicles
*assume*. One-way travel time (OWTT) needs synchronized clocks and carries their
offset; two-way travel time (TWTT) measures a round trip through a transponder
with a turn-around delay (shared/reference-values.md section 3).
"""

from __future__ import annotations

import numpy as np


def mackenzie_sound_speed(temperature_c, salinity_psu, depth_m):
    """Sound speed in sea water, m/s (Mackenzie 1981). Arrays broadcast.

    >>> round(float(mackenzie_sound_speed(10.0, 35.0, 0.0)), 1)
    1489.8
    """
    t = np.asarray(temperature_c, dtype=float)
    s = np.asarray(salinity_psu, dtype=float) - 35.0
    d = np.asarray(depth_m, dtype=float)
    return (
        1448.96 + 4.591 * t - 5.304e-2 * t**2 + 2.374e-4 * t**3
        + 1.340 * s + 1.630e-2 * d + 1.675e-7 * d**2
        - 1.025e-2 * t * s - 7.139e-13 * t * d**3
    )


def travel_time_s(sender_pos_m, receiver_pos_m, receiver_vel_mps, sound_speed_mps, iterations=3):
    """Time for sound sent from a fixed point to reach a receiver moving at constant velocity.

    Solves tau = |r(t0) + v tau - s| / c by fixed-point iteration (a contraction
    while |v| << c: three iterations reach 1e-9 m for vehicle speeds).
    Shapes broadcast over leading axes; positions (..., 3).
    """
    rel = receiver_pos_m - sender_pos_m
    tau = np.linalg.norm(rel, axis=-1) / sound_speed_mps
    for _ in range(iterations):
        tau = np.linalg.norm(rel + receiver_vel_mps * tau[..., None], axis=-1) / sound_speed_mps
    return tau


def packet_loss_probability(range_m, near, far, max_range_m):
    """Loss probability growing quadratically from ``near`` at 0 m to ``far`` at max range; 1 beyond."""
    frac = np.clip(range_m / max_range_m, 0.0, None)
    p = near + (far - near) * frac**2
    return np.where(range_m > max_range_m, 1.0, p)
