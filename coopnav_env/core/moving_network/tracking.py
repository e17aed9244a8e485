"""Step 4 of a cycle: the boats track the vehicle externally (section III, V).

The boats hear S1 (both) and S4 (B2) too; from those instants, their GPS positions
and the mission depth they place the vehicle (``lbl.track_fix_of``), and an
alpha-beta tracker (``TRACKER_ALPHA``, ``TRACKER_BETA``) smooths the fixes. That,
their GPS and each other's position over the radio is all they observe.

The fixes are gated: a multipath excess on one of the detections the fix uses (S1 at both
boats, S4 at B2) moves it by tens of metres, and an alpha-beta tracker that takes it moves
its position by alpha times that and its velocity by beta / T times that (15 m and 3 m/s for
a 30 m excess), which the boats' escort then chases, turning the frame under the vehicle's
filter. A fix farther than ``TRACKER_GATE_M`` + ``TRACKER_GATE_SPEED_MPS`` x age from the
prediction is set aside; two set-aside fixes in a row that agree with each other (the
second within the same gate of the first, moved by the tracked velocity) mean the vehicle
is where they say, and the tracker restarts at the newer one (the pairwise consistency of
``recovery``, in its simplest form).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .. import lbl
from .state import TRACKER_ALPHA, TRACKER_BETA, TRACKER_GATE_M, TRACKER_GATE_SPEED_MPS, Boats, CycleParams, Tracker


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
    gate = TRACKER_GATE_M + TRACKER_GATE_SPEED_MPS * age
    if ok and k.has_fix[b] and res_e * res_e + res_n * res_n > gate * gate:
        # set aside; restart at it if it agrees with the one set aside the cycle before
        moved_e = k.outlier[b, 0] + k.vel[b, 0] * p.ping_interval_s
        moved_n = k.outlier[b, 1] + k.vel[b, 1] * p.ping_interval_s
        agree = k.outlier[b, 2] > 0.0 and (fix_e - moved_e) ** 2 + (fix_n - moved_n) ** 2 <= TRACKER_GATE_M**2
        k.outlier[b, 0], k.outlier[b, 1], k.outlier[b, 2] = fix_e, fix_n, 1.0
        if not agree:
            k.age_s[b] = age
            return
        k.has_fix[b] = False  # restart at this fix
    elif ok:
        k.outlier[b, 2] = 0.0
    if ok and not k.has_fix[b]:
        k.pos[b, 0], k.pos[b, 1] = fix_e, fix_n
    elif ok:
        k.pos[b, 0], k.pos[b, 1] = pred_e + TRACKER_ALPHA * res_e, pred_n + TRACKER_ALPHA * res_n
        k.vel[b, 0] = k.vel[b, 0] + TRACKER_BETA * res_e / age
        k.vel[b, 1] = k.vel[b, 1] + TRACKER_BETA * res_n / age
    k.age_s[b] = 0.0 if ok else age
    k.has_fix[b] = k.has_fix[b] or ok
