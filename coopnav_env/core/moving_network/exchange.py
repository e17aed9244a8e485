"""Step 3 of a cycle: the three-interval LBL exchange of section V, between moving vehicles.

S1 (vehicle -> B1), B1's reply S2 (heard by the vehicle at t3: range d1, and by B2,
which answers S3, heard at t4: the path m), then the vehicle's S4 to B2 and B2's
reply S5 (heard at t6: range d2); l = m - d1 - d2 (``core.lbl``, Fig. 4). Here the
cycle's draws become the exchange's physics: the true and the assumed sound speed
at the vehicle's depth (Mackenzie), each detection's lateness (a jitter
sigma_t = range_noise_std_m / c, the convention of ``core.acoustics``, plus a rare
multipath excess), each signal's loss by the distance it travels; then
``lbl.exchange_of`` propagates the sound between the moving vehicles.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .. import lbl
from ..acoustics import mackenzie_sound_speed, packet_loss_probability
from .state import Boats, CycleDraws, CycleParams, Vehicle


@njit(cache=True)
def _dist3(a: np.ndarray, b: np.ndarray) -> float:
    """The distance between two points (3,)."""
    dx, dy, dz = a[0] - b[0], a[1] - b[1], a[2] - b[2]
    return np.sqrt(dx * dx + dy * dy + dz * dz)


@njit(cache=True)
def _detections(
    b: int,
    v3: np.ndarray,
    boats: Boats,
    draws: CycleDraws,
    p: CycleParams,
    jitter_scale: float,
    c_true: float,
    err: np.ndarray,
    lost: np.ndarray,
) -> None:
    """Environment b's detection errors err (7,) (jitter plus multipath excess, seconds)
    and losses lost (7,), in ``lbl.DETECTIONS`` order, in place."""
    d_b1 = _dist3(boats.pos[b, 0], v3)
    d_b2 = _dist3(boats.pos[b, 1], v3)
    base = _dist3(boats.pos[b, 1], boats.pos[b, 0])
    u = draws.acoustic_u
    for i in range(err.shape[0]):
        late = -p.outlier_mean_excess_m * draws.log_u[b, i] if u[b, i, 1] < p.outlier_probability else 0.0
        err[i] = jitter_scale * draws.jitter[b, i] + late / c_true
        path = d_b1 if i < 2 else (base if i == 2 else d_b2)  # the distance each signal travels
        lost[i] = u[b, i, 0] < packet_loss_probability(path, p.packet_loss_near, p.packet_loss_far, p.max_range_m)


@njit(cache=True)
def run_exchange(
    b: int,
    vehicle: Vehicle,
    boats: Boats,
    draws: CycleDraws,
    p: CycleParams,
    err: np.ndarray,
    lost: np.ndarray,
    work: np.ndarray,
) -> tuple:
    """Environment b's exchange (``state.Vehicle`` vehicle, ``state.Boats`` boats,
    ``state.CycleDraws`` draws, ``state.CycleParams`` p; scratch err, lost (7,), work
    (2,3)). Returns (``lbl.ExchangeResult``, the assumed sound speed cn, the
    per-detection jitter as range sigma_det)."""
    v3 = vehicle.pos[b, 0]
    depth = v3[2]
    c_true = mackenzie_sound_speed(draws.temperature_c[b], p.salinity_psu, depth)
    cn = mackenzie_sound_speed(p.water_temperature_c, p.salinity_psu, depth)
    # each detection instant is late by a jitter sigma_t = range_noise_std_m / c (the
    # convention of core.acoustics); a two-way range d1, d2 has two of them, halved
    sigma_det = p.range_noise_std_m * draws.noise_scale[b]
    _detections(b, v3, boats, draws, p, sigma_det / cn, c_true, err, lost)
    timeout = 2.0 * p.max_range_m / cn + 2.0 * p.turnaround_s
    movers = lbl.Movers(v3, vehicle.vel_true[b, 0], boats.pos[b, 0], boats.vel[b, 0], boats.pos[b, 1], boats.vel[b, 1])
    ex = lbl.exchange_of(movers, c_true, cn, err, lost, p.turnaround_s, p.turnaround_s, timeout, work)
    return ex, cn, sigma_det
