"""Step 4 of a cycle: the boats track the vehicle externally (section III, V).

The boats hear S1 (both) and S4 (B2) too; from those instants, their GPS positions
and the mission depth they place the vehicle (``lbl.track_fix_of``), and an
alpha-beta tracker (``TRACKER_ALPHA``, ``TRACKER_BETA``) smooths the fixes. That,
their GPS and each other's position over the radio is all they observe.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .. import lbl
from .state import TRACKER_ALPHA, TRACKER_BETA, Boats, CycleParams, Tracker


@njit(cache=True)
def track(k: Tracker, b: int, ex: lbl.ExchangeResult, boats: Boats, cn: float, p: CycleParams) -> None:
    """Update environment b's tracker (``state.Tracker`` k, in place) with the external fix
    from the exchange ``ex`` (``lbl.ExchangeResult``) in the GPS frame of ``boats``
    (``state.Boats``); cn: the assumed sound speed; p: ``state.CycleParams``."""
    frame = lbl.FrameGeometry(
        boats.gps[b, 0, 0], boats.gps[b, 0, 1], np.sin(boats.phi_gps[b]), np.cos(boats.phi_gps[b]), boats.length_gps[b]
    )
    fix_e, fix_n, ok = lbl.track_fix_of(
        ex.t_s1_b1, ex.t_s1_b2, ex.t_s4_b2, ex.ok_track, frame, p.depth_m, cn, p.turnaround_s, p.turnaround_s
    )
    age = k.age_s[b] + p.ping_interval_s
    pred_e, pred_n = k.pos[b, 0] + k.vel[b, 0] * age, k.pos[b, 1] + k.vel[b, 1] * age
    res_e, res_n = fix_e - pred_e, fix_n - pred_n
    if ok and not k.has_fix[b]:
        k.pos[b, 0], k.pos[b, 1] = fix_e, fix_n
    elif ok:
        k.pos[b, 0], k.pos[b, 1] = pred_e + TRACKER_ALPHA * res_e, pred_n + TRACKER_ALPHA * res_n
        k.vel[b, 0] = k.vel[b, 0] + TRACKER_BETA * res_e / age
        k.vel[b, 1] = k.vel[b, 1] + TRACKER_BETA * res_n / age
    k.age_s[b] = 0.0 if ok else age
    k.has_fix[b] = k.has_fix[b] or ok
