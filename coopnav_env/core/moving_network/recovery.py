"""Step 3 of a cycle, its last part: recovery of the vehicle's filter from gate lockout.

A filter that has a measurement rejected in each of ``REINIT_AFTER_CYCLES``
consecutive cycles (it has diverged: the gate now refuses the very ranges that
would correct it) restarts its position from the spherical fix (section V) of this
cycle's d1, d2 and l, with the fix's uncertainty; the paper does not discuss this,
every fielded LBL navigator needs it. Counting cycles with every measurement
rejected is not enough: a filter whose error runs along the circle around one
beacon keeps passing that beacon's range (and l) while the other's is refused, and
drifts off along the circle (seen with the boats' speed noise).

The survey network's restart from one range (``navigation.reinit_on_range``) moves
the estimate along one line of sight; here all three measurements of a cycle are at
hand, so the restart is the full fix instead.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .. import lbl
from ..lbl import ExchangeResult, horizontal_range
from .state import REINIT_AFTER_CYCLES


@njit(cache=True)
def recover(
    E: np.ndarray,
    P: np.ndarray,
    rejected_cycles: np.ndarray,
    b: int,
    rejected: int,
    ex: ExchangeResult,
    dz: float,
    sigma_r2: float,
) -> int:
    """Count filter b's cycles with a rejection (rejected_cycles (B,), in place) and restart
    it (E (6,), P (6,6), in place) from the fix of ``ex`` (``lbl.ExchangeResult``) after
    ``REINIT_AFTER_CYCLES`` of them; dz: the depth below the boats, sigma_r2: a two-way
    range's variance. Returns 1 if it restarted, else 0."""
    if rejected == 0:
        rejected_cycles[b] = 0
    else:
        rejected_cycles[b] += 1
    fx, fy, ok_fix = lbl.spherical_fix_of(horizontal_range(ex.d1, dz), horizontal_range(ex.d2, dz), ex.l)
    if not (rejected_cycles[b] >= REINIT_AFTER_CYCLES and ex.ok_l and ok_fix and fy > 0):
        return 0
    E[0], E[1], E[5] = fx, fy, ex.l
    for i in range(6):
        for k in (0, 1, 5):
            P[k, i] = 0.0
            P[i, k] = 0.0
    var = 4.0 * sigma_r2  # a single fix's position variance, GDOP ~ 2 [U]
    P[0, 0] = var
    P[1, 1] = var
    P[5, 5] = 6.0 * sigma_r2
    rejected_cycles[b] = 0
    return 1
