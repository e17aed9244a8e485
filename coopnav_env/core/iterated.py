"""The iterated EKF's range update (``range_linearization="iterated"``, eqs. I1-I3): the
survey filter's range model re-linearized at its own result until it stops moving. The
modem's fusion kernel (``measurements.modem``) calls ``iterated_range_model`` before its
ordinary update; docs/scenarios/consider-fusion.md#iterated says what it does and does
not mend."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from .acoustics import modem_range_variance
from .consider import beacon_variance_los, schmidt_range_update
from .multipath import Moments
from .navigation import innovation_variance, kalman_gain, moving_range_prediction

ITERATIONS_MAX = 10  # eq. (I2)'s Gauss-Newton steps at most; a range converges in 2-4
ITERATION_TOL_M = 1e-4  # ... and stops when a step moves the linearization point less than this


class RangeGeometry(NamedTuple):
    """What the range model needs besides the filter: the survey's velocity estimate, the
    beacon's position and velocity as its message says, the ranging noise (std, m), the
    legs' times (``navigation.moving_range_prediction``), the sound speed's relative std
    and whether the range is two-way."""

    vel_est: np.ndarray
    beacon: np.ndarray
    beacon_vel: np.ndarray
    noise_std: float
    delays: np.ndarray
    rel_std: float
    two_way: bool


@njit(cache=True, inline="always")
def iterated_range_model(
    f: Moments,
    j: int,
    H: np.ndarray,
    meas: tuple,
    scratch: tuple,
    geo: RangeGeometry,
    gate: float,
    schmidt: bool,
) -> tuple[bool, np.ndarray, tuple]:
    """The iterated EKF's range model (Bell & Cathey 1993; Bar-Shalom, Li & Kirubarajan
    2001, sec. 10.3.2), for ``range_linearization="iterated"``. The first-order update
    linearizes |x - b| at the prior x0; where the prior is far off across the line of
    sight of a beacon tens of metres away, that gradient points the wrong way. The
    iterated update re-linearizes at its own result until it stops moving:

    (I1) x_{i+1} = x0 + K_i (r - h(x_i) - H_i (x0 - x_i)), x_0 = x0, K_i the gain
         (white, or Schmidt's with the beacon's consider states) at H_i;
    (I2) stop when |x_{i+1} - x_i| < ITERATION_TOL_M, or after ITERATIONS_MAX steps;
    (I3) the range is gated once, on the first-order innovation r - h(x0) (an outlier is
         judged by the prior, not by a linearization point it has already pulled).

    The Gauss-Newton steps of the maximum a posteriori estimate for one range. Returns
    (passed, H_i, meas_i): whether the range passed the gate (I3) and, if so, the model
    at the last linearization point, whose prediction h(x_i) + H_i (x0 - x_i) makes
    the modem's ordinary update (``_kalman``) land on x_{i+1} with P from H_i; if not, the
    arguments.
    f: the survey filter (``multipath.Moments``); j: the beacon; H, meas: the first-order
    model (``measurements.modem._range_model``); geo: ``RangeGeometry``; gate: the
    chi-square gate for this range's first-order innovation (``modem._gate_of``); schmidt: the beacon's
    error as consider states (else white, in R). Covariance intersection keeps the
    first-order model (the modem does not call this for it). scratch: the modem's
    ``_update``'s (its x0, P0 and Pxb0 serve as working copies; ``_update`` refills them)."""
    K, Pbb, xi, Pw, Xw = scratch[0], scratch[1], scratch[2], scratch[3], scratch[4]
    r, h, R, R_white, Pb = meas[0], meas[1], meas[2], meas[3], meas[4]  # Pb: the beacon's Pbb (2, 2)
    y = r - h
    Pbb[:, :] = Pb
    if schmidt:  # a gate of -1 returns the NIS and touches nothing
        nis, _ = schmidt_range_update(f.x, f.P, f.X[j], Pbb, y, H, R, -1.0, K)
    else:
        nis = y * y / innovation_variance(f.P, H, R_white)
    if not nis <= gate:
        return False, H, meas
    x0 = f.x
    xi[:] = x0
    Hi, lin, Ri, Rwi = H, h, R, R_white
    for _ in range(ITERATIONS_MAX):
        hi, Hi = moving_range_prediction(xi, geo.vel_est, geo.beacon, geo.beacon_vel, geo.delays)
        Ri = modem_range_variance(geo.noise_std, geo.two_way, 0.0, hi, geo.rel_std)
        Rwi = modem_range_variance(geo.noise_std, geo.two_way, beacon_variance_los(Pb, Hi[0], Hi[1]), hi, geo.rel_std)
        lin = hi
        for k in range(3):
            lin += Hi[k] * (x0[k] - xi[k])  # h(x_i) + H_i (x0 - x_i): the model at x_i, read at x0
        if schmidt:  # the gain at H_i: Schmidt's update of copies with a zero innovation leaves x0 as it is
            Pw[:, :] = f.P
            Xw[j, :, :] = f.X[j]
            schmidt_range_update(x0, Pw, Xw[j], Pbb, 0.0, Hi, Ri, np.inf, K)
        else:
            kalman_gain(f.P, Hi, innovation_variance(f.P, Hi, Rwi), K)
        step2 = 0.0
        for k in range(3):  # (I1)
            xn = x0[k] + K[k] * (r - lin)
            step2 += (xn - xi[k]) * (xn - xi[k])
            xi[k] = xn
        if step2 < ITERATION_TOL_M * ITERATION_TOL_M:  # (I2)
            break
    return True, Hi, (r, lin, Ri, Rwi, Pb, 0.0, 0.0)
