"""Steps 3-5 of a cycle in one compiled kernel over the batch, from the named steps:

1. ``exchange.run_exchange``: the sound speeds, the detections' errors and losses,
   the exchange between the moving vehicles (``lbl.exchange_of``); with
   ``frame_motion_telemetry``, ``frame_motion.move_frame``: the frame's motion over the cycle;
2. ``filter.update_phi`` (with ``frame_bearing_fusion``): the telemetered frame bearing;
   ``filter.fuse_ranges``: d1, then (d2, l) jointly, each gated (section VII);
3. ``recovery.recover``: the window of fixes and, after gate lockout, the restart from their
   consensus;
4. ``tracking.track``: the boats' external fix and alpha-beta tracker;
5. ``terms.cycle_terms``: the reward's terms and the errors, in the true frame.

Written once, compiled twice: ``cycle`` and, for large batches, the threaded
``cycle_parallel``.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..acoustics import ranging_variance_m2
from ..information import det2_of
from ..jit import parallel_twin
from .exchange import run_exchange
from .filter import bearing_variance_rad2, filter_work, fuse_ranges, update_phi
from .frame_motion import move_frame, telemetry_covariance
from .recovery import recover, rotate_window
from .state import Boats, CycleDraws, CycleParams, Filter, Tracker, Vehicle
from .terms import cycle_terms
from .tracking import track


def _cycle(
    vehicle: Vehicle,
    f: Filter,
    boats: Boats,
    tracker: Tracker,
    draws: CycleDraws,
    p: CycleParams,
    out: np.ndarray,
    counts: np.ndarray,
) -> None:
    """Steps 3-5 for every environment, in place: ``state.Vehicle`` vehicle, ``state.Filter``
    f, ``state.Boats`` boats, ``state.Tracker`` tracker, ``state.CycleDraws`` draws,
    ``state.CycleParams`` p, each as a plain tuple (``state.packed``) or the record; out (B,)
    ``state.CYCLE_OUT``, counts (B,) ``state.CYCLE_COUNTS``."""
    vehicle, f, boats, tracker = Vehicle(*vehicle), Filter(*f), Boats(*boats), Tracker(*tracker)
    draws, p = CycleDraws(*draws), CycleParams(*p)
    n_det = draws.jitter.shape[1]
    for b in prange(vehicle.pos.shape[0]):
        work = np.empty((2, 3))
        err = np.empty(n_det)
        lost = np.empty(n_det, dtype=np.bool_)
        w = filter_work()
        status = np.empty((3, 2), dtype=np.bool_)
        prior = np.empty(3)
        sigma_t = np.empty((4, 4))
        E, P, o = f.E[b], f.P[b], out[b]
        o.det[0] = det2_of(P[0, 0], P[0, 1], P[1, 0], P[1, 1])
        ex, cn, sigma_det = run_exchange(b, vehicle, boats, draws, p, err, lost, work)
        dz = vehicle.pos[b, 0, 2] + p.depth_noise_m * draws.depth[b, 0]  # depth cell; boats at the surface
        sigma_r2 = ranging_variance_m2(sigma_det, True)  # var(d1) = var(d2) = (c sigma_t)^2 / 2
        b1_velocity = (0.0, 0.0)
        if p.frame_motion_telemetry > 0.0:  # the frame's motion over the cycle (frame_motion eqs. M1-M3)
            telemetry_covariance(p.boat_velocity_noise_mps, p.ping_interval_s, boats.length_gps[b], sigma_t)
            moved = move_frame(E, P, boats.motion[b], sigma_t)
            b1_velocity = (moved[0] / p.ping_interval_s, moved[1] / p.ping_interval_s)
            rotate_window(f, b, boats.motion[b, 2])
        prior[0], prior[1], prior[2] = E[0], E[1], E[5]
        if p.frame_bearing_fusion > 0.0:  # the bearing the boats telemeter with the exchange (filter eq. B1)
            update_phi(E, P, boats.phi_gps[b], bearing_variance_rad2(p.gps_noise_m, boats.length_gps[b]), w)
        n_fused, rejected = fuse_ranges(
            E, P, ex, dz, vehicle.speed_meas_mps[b], vehicle.heading_meas_rad[b], sigma_r2, p, w, status, b1_velocity
        )
        restarted = recover(E, P, f, b, status, prior, ex, dz, sigma_r2, p)
        o.det[1] = det2_of(P[0, 0], P[0, 1], P[1, 0], P[1, 1])
        track(tracker, b, ex, boats, cn, p)
        cycle_terms(o, b, vehicle, boats, f, p, n_fused)
        c = counts[b]
        c.ranges_fused, c.outliers_rejected, c.packets_lost, c.filter_restarts = (
            n_fused,
            rejected,
            ex.lost_count,
            restarted,
        )
        c.range_ok = n_fused > 0


cycle = njit(cache=True)(_cycle)
cycle_parallel = parallel_twin(_cycle)
