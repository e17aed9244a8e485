"""The survey vehicle's extended Kalman filter (Gao & Chitre eqs. 4-13).

State: position (east, north, depth) in metres; covariance 3 x 3. The equations
live once, in the compiled single-filter functions ``joseph_update`` and
``range_prediction``; the simulator's kernels call them for every filter of the
batch, and ``scalar_update`` / ``range_model`` apply them over any leading batch
axes from Python (for planners, analysis and the tests against filterpy). The
covariance update is the Joseph form, which keeps P symmetric positive definite
under round-off (and is what filterpy's ExtendedKalmanFilter does).

The moving network's six-state filter (Matos & Cruz, below) follows the same
pattern: ``joseph_update_vector``, ``frame_predict``, ``frame_range_prediction`` and
``frame_velocity_of`` are compiled single-filter functions that its kernel calls;
``joseph_update_batch``, ``frame_range_model`` and ``frame_velocity`` apply them over
a batch from Python.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import ArrayLike
from scipy.stats import chi2

from .numerics import lu_solve, matmul, vecmat


def predict(x: np.ndarray, P: np.ndarray, dx: np.ndarray | float, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eq. (4) and (6): x <- x + R v tau (given as ``dx``); P <- P + Q (F = I)."""
    return x + dx, P + Q


@njit(cache=True, inline="always")
def _add_leg(x, velocity, d_s, beacon, beacon_velocity, e_s, weight, H):
    """One leg of a range, eqs. (7)-(8): the distance from the vehicle at x + v d to the
    beacon at b + u e, times ``weight``, its unit vector (times ``weight``) added to H."""
    r0 = x[0] + velocity[0] * d_s - beacon[0] - beacon_velocity[0] * e_s
    r1 = x[1] + velocity[1] * d_s - beacon[1] - beacon_velocity[1] * e_s
    r2 = x[2] + velocity[2] * d_s - beacon[2] - beacon_velocity[2] * e_s
    dist = np.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
    inv = weight / max(dist, 1e-9)
    H[0] += r0 * inv
    H[1] += r1 * inv
    H[2] += r2 * inv
    return dist * weight


@njit(cache=True)
def range_prediction(
    x: np.ndarray, velocity: np.ndarray, delays_s: np.ndarray, beacon: np.ndarray
) -> tuple[float, np.ndarray]:
    """Predicted range and its Jacobian (eqs. 7-8) for one filter, with the motion
    of the vehicle while sound travels, to a beacon that holds still.

    The state is the position at the cycle's reference time; leg l of a measured
    range ends at x + velocity * delays_s[l]: h = mean_l |x + v d_l - b| and
    H = mean_l of the unit vectors. With one leg of zero delay this is exactly
    eq. (7)-(8). x, velocity, beacon: (3,); delays_s: (L,). Returns (h, H (3,)).
    A moving beacon: ``moving_range_prediction``.
    """
    L = delays_s.shape[0]
    h = 0.0
    H = np.zeros(3)
    for leg in range(L):
        h += _add_leg(x, velocity, delays_s[leg], beacon, velocity, 0.0, 1.0 / L, H)
    return h, H


@njit(cache=True)
def moving_range_prediction(
    x: np.ndarray, velocity: np.ndarray, beacon: np.ndarray, beacon_velocity: np.ndarray, legs_s: np.ndarray
) -> tuple[float, np.ndarray]:
    """``range_prediction`` to a beacon that moves too: each leg from its own geometry.

    legs_s (2, L): row 0 the times at which leg l reaches or leaves the vehicle (as
    ``delays_s``), row 1 the times at which it leaves or reaches the beacon, which is at
    b + u e_l then (b, u: the beacon's position at the reference time and its velocity,
    both sent in its message). A two-way range is the mean of the interrogation's leg,
    from x to the beacon where it hears it, and the reply's, from the beacon where it
    replies (``turnaround_s`` later) back to the vehicle: h = mean_l |x + v d_l - b - u e_l|
    (``measurements.modem.modem_range`` fills legs_s). Returns (h, H (3,)).
    """
    L = legs_s.shape[1]
    h = 0.0
    H = np.zeros(3)
    for leg in range(L):
        h += _add_leg(x, velocity, legs_s[0, leg], beacon, beacon_velocity, legs_s[1, leg], 1.0 / L, H)
    return h, H


@njit(cache=True, inline="always")
def relative_covariance(P: np.ndarray, Pxb: np.ndarray, Pbb: np.ndarray, i: int, j: int) -> float:
    """Entry (i, j) of Pd = P - Pxb E - E^T Pxb^T + E^T Pbb E (eq. L0): the covariance of the
    survey's position relative to the beacon's true one, d = x - b, with P the filter's 3x3,
    Pxb (3, 2) its cross-covariance with the beacon's horizontal error, Pbb (2, 2) that error's
    covariance and E the
    (2, 3) embedding of the horizontal plane. The one home of Pd (``range_curvature`` and
    ``split_range.split_range_model`` read it): an entry, so a caller allocates nothing."""
    d = P[i, j]
    if j < 2:
        d -= Pxb[i, j]
    if i < 2:
        d -= Pxb[j, i]
        if j < 2:
            d += Pbb[i, j]
    return d


@njit(cache=True)
def range_curvature(P: np.ndarray, Pxb: np.ndarray, Pbb: np.ndarray, H: np.ndarray, h: float) -> tuple[float, float]:
    """The second-order terms of a range (the second-order EKF's measurement terms;
    Bar-Shalom, Li & Kirubarajan 2001, ch. 10): with the relative position d = x - b of
    covariance Pd = P - Pxb - Pxb^T + Pbb (P the filter's 3x3, Pxb (3, 2) its
    cross-covariance with the beacon's horizontal error, Pbb (2, 2) that error's covariance), the
    range |d| has Hessian M = (I - u u^T) / h, u = H / |H| (eq. L1; Pd: eq. L0,
    ``relative_covariance``), so

    E[r] ~ h + tr(M Pd) / 2 (eq. L2), and its variance beyond H Pd H^T is
    tr(M Pd M Pd) / 2 (eq. L3).

    Both are of order sigma_perp^2 / h: negligible at a few metres' error hundreds of
    metres away, dominant when the estimate is tens of metres off and the beacon passes
    within tens of metres, where the first-order update alone moves the estimate along
    a wrong gradient and reports a covariance far too small. Returns (the bias of eq. L2,
    the variance of eq. L3), both 0 for h <= 0."""
    n = np.sqrt(H[0] * H[0] + H[1] * H[1] + H[2] * H[2])
    if not (h > 0.0 and n > 0.0):
        return 0.0, 0.0
    # with M = (I - u u^T) / h: tr(M Pd) = (tr Pd - u^T Pd u) / h and
    # tr(M Pd M Pd) = (tr Pd^2 - 2 |Pd u|^2 + (u^T Pd u)^2) / h^2, element by element
    # (no array is allocated: this runs for every range in the fusion kernel)
    tr = tr2 = uPu = w2 = 0.0
    for i in range(3):
        wi = 0.0
        for j in range(3):
            d = relative_covariance(P, Pxb, Pbb, i, j)  # eq. (L0)
            tr2 += d * d
            wi += d * H[j] / n
            if i == j:
                tr += d
        uPu += H[i] / n * wi
        w2 += wi * wi
    bias = 0.5 * (tr - uPu) / h  # eq. (L2)
    var = 0.5 * (tr2 - 2.0 * w2 + uPu * uPu) / (h * h)  # eq. (L3)
    return bias, var


@njit(cache=True)
def innovation_variance(P: np.ndarray, H: np.ndarray, R: float) -> float:
    """Eq. (11): S = H P H^T + R for one scalar measurement."""
    S = R
    for i in range(3):
        for j in range(3):
            S += H[i] * P[i, j] * H[j]
    return S


@njit(cache=True)
def kalman_gain(P: np.ndarray, H: np.ndarray, S: float, K: np.ndarray) -> None:
    """Eq. (12) for one scalar measurement, into K (3,): K = P H^T / S, S from
    ``innovation_variance``."""
    for i in range(3):
        K[i] = (P[i, 0] * H[0] + P[i, 1] * H[1] + P[i, 2] * H[2]) / S


@njit(cache=True)
def joseph_update_residual(x: np.ndarray, P: np.ndarray, y: float, H: np.ndarray, R: float) -> float:
    """Eqs. (9), (11)-(13) for one scalar measurement of one filter, in place, given its
    innovation ``y`` (filterpy's ``update(..., residual=...)``: each measurement model
    computes its own residual, a bearing's wrapped to (-pi, pi]). Returns S."""
    S = innovation_variance(P, H, R)  # eq. (11)
    # P H^T and H P, element by element (nothing allocated, no BLAS: this runs for
    # every range and depth reading of every environment)
    PH = (
        P[0, 0] * H[0] + P[0, 1] * H[1] + P[0, 2] * H[2],
        P[1, 0] * H[0] + P[1, 1] * H[1] + P[1, 2] * H[2],
        P[2, 0] * H[0] + P[2, 1] * H[1] + P[2, 2] * H[2],
    )
    HP = (
        H[0] * P[0, 0] + H[1] * P[1, 0] + H[2] * P[2, 0],
        H[0] * P[0, 1] + H[1] * P[1, 1] + H[2] * P[2, 1],
        H[0] * P[0, 2] + H[1] * P[1, 2] + H[2] * P[2, 2],
    )
    K = (PH[0] / S, PH[1] / S, PH[2] / S)  # eq. (12)
    for i in range(3):
        x[i] += K[i] * y  # eq. (9)
    # eq. (13), Joseph form: (I - KH) P (I - KH)^T + K R K^T. With A = I - K H,
    # (A P)_ij = P_ij - K_i (H P)_j and (A P H^T)_i = (P H^T)_i - K_i (S - R), so entry
    # (i, j) needs only the old P_ij: P_ij - K_i (HP)_j - K_j ((PH)_i - K_i (S - R)) + R K_i K_j
    for i in range(3):
        aph = PH[i] - K[i] * (S - R)
        for j in range(3):
            P[i, j] = P[i, j] - K[i] * HP[j] - K[j] * aph + R * K[i] * K[j]
    return S


@njit(cache=True)
def joseph_update(x: np.ndarray, P: np.ndarray, z: float, h: float, H: np.ndarray, R: float) -> tuple[float, float]:
    """Eqs. (9)-(13) for one scalar measurement z with prediction h, in place: the
    residual is y = z - h (eq. 10). Returns (y, S)."""
    y = z - h  # eq. (10)
    return y, joseph_update_residual(x, P, y, H, R)


@njit(cache=True)
def gated_update_residual(x: np.ndarray, P: np.ndarray, y: float, H: np.ndarray, R: float, gate: float) -> bool:
    """``joseph_update_residual`` if the innovation passes the chi-square gate on its
    normalized square, y^2 / S <= gate; returns whether it was fused (never with S <= 0 or
    a NaN y: a review found a NaN residual written into the state)."""
    S = innovation_variance(P, H, R)
    if not (S > 0.0 and y * y / S <= gate):
        return False
    joseph_update_residual(x, P, y, H, R)
    return True


@njit(cache=True)
def gated_update(x: np.ndarray, P: np.ndarray, z: float, h: float, H: np.ndarray, R: float, gate: float) -> bool:
    """``gated_update_residual`` with the residual y = z - h."""
    return gated_update_residual(x, P, z - h, H, R, gate)


@njit(cache=True)
def reinit_on_range(x: np.ndarray, P: np.ndarray, z: float, h: float, H: np.ndarray, R: float) -> bool:
    """Recovery from gate lock-out with one range (in place; x (3,), P (3, 3)).

    A filter whose gate has rejected several ranges in a row has drifted further than
    its covariance admits, and the gate now refuses the very ranges that would correct
    it. This restarts its horizontal position from the range: the estimate moves along
    the horizontal line of sight u = H_xy / |H_xy| (eq. 8) by y / |H_xy| (y = z - h),
    onto the measured range; the horizontal covariance becomes (R + y^2) / |H_xy|^2
    along u and, across it, the old variance plus y^2: the filter has shown it was off
    by at least |y|, and a restart that trusted the one range (R along u) would let a
    beacon that follows the survey's reported estimate drag it away, restart after
    restart (a 1.9 km runaway on one of 50 sousa_asv episodes with the circle
    planner). The depth keeps its estimate and variance, without cross terms. Later
    ranges, from other bearings too, then pass the gate and fix the rest. Returns False (nothing changed) when the line
    of sight is steeper than 60 degrees, where a range barely constrains the
    horizontal position."""
    hx, hy = H[0], H[1]
    g2 = hx * hx + hy * hy
    if g2 < 0.25:  # a steep line of sight (|H_xy| < 0.5): the range says little about the horizontal position
        return False
    g = np.sqrt(g2)
    ux, uy = hx / g, hy / g
    tx, ty = -uy, ux
    y = z - h
    x[0] += y * ux / g
    x[1] += y * uy / g
    across = tx * tx * P[0, 0] + 2.0 * tx * ty * P[0, 1] + ty * ty * P[1, 1] + y * y
    along = (R + y * y) / g2
    P[0, 0] = along * ux * ux + across * tx * tx
    P[0, 1] = P[1, 0] = along * ux * uy + across * tx * ty
    P[1, 1] = along * uy * uy + across * ty * ty
    for i in range(2):
        P[i, 2] = 0.0
        P[2, i] = 0.0
    return True


# --- the same equations over any leading batch axes, from Python ----------------------
@njit(cache=True)
def _update_rows(x, P, z, h, H, R, mask, y, S):
    for m in range(x.shape[0]):
        y[m] = z[m] - h[m]
        S[m] = innovation_variance(P[m], H[m], R[m])
        if mask[m]:
            joseph_update(x[m], P[m], z[m], h[m], H[m], R[m])


def scalar_update(
    x: ArrayLike, P: ArrayLike, z: ArrayLike, h: ArrayLike, H: ArrayLike, R: ArrayLike, mask: ArrayLike
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Eqs. (9)-(13) for one scalar measurement per filter, over leading batch axes.

    x (..., 3), P (..., 3, 3), H (..., 3); z, h, R, mask broadcast to (...).
    Returns new (x, P) and the innovation y and its variance S; rows where mask
    is False are returned unchanged.
    """
    lead = np.broadcast_shapes(
        np.shape(x)[:-1], np.shape(P)[:-2], np.shape(H)[:-1], np.shape(z), np.shape(h), np.shape(R), np.shape(mask)
    )
    x2 = np.array(np.broadcast_to(x, lead + (3,)), dtype=float).reshape(-1, 3)
    P2 = np.array(np.broadcast_to(P, lead + (3, 3)), dtype=float).reshape(-1, 3, 3)
    flat = [np.ascontiguousarray(np.broadcast_to(a, lead), dtype=float).reshape(-1) for a in (z, h, R)]
    H2 = np.ascontiguousarray(np.broadcast_to(H, lead + (3,)), dtype=float).reshape(-1, 3)
    m2 = np.ascontiguousarray(np.broadcast_to(mask, lead), dtype=bool).reshape(-1)
    y, S = np.empty(len(m2)), np.empty(len(m2))
    _update_rows(x2, P2, flat[0], flat[1], H2, flat[2], m2, y, S)
    return x2.reshape(lead + (3,)), P2.reshape(lead + (3, 3)), y.reshape(lead), S.reshape(lead)


@njit(cache=True)
def _predict_rows(x, v, d, b, h, H):
    for m in range(x.shape[0]):
        hm, Hm = range_prediction(x[m], v[m], d[m], b[m])
        h[m] = hm
        H[m] = Hm


def range_model(
    x: ArrayLike, velocity: ArrayLike, delays_s: ArrayLike, beacon: ArrayLike
) -> tuple[np.ndarray, np.ndarray]:
    """``range_prediction`` over leading batch axes: x, velocity, beacon (..., 3);
    delays_s (..., L). Returns h (...) and H (..., 3)."""
    lead = np.broadcast_shapes(
        np.shape(x)[:-1], np.shape(velocity)[:-1], np.shape(delays_s)[:-1], np.shape(beacon)[:-1]
    )
    L = np.shape(delays_s)[-1]
    args = [
        np.ascontiguousarray(np.broadcast_to(a, lead + (n,)), dtype=float).reshape(-1, n)
        for a, n in ((x, 3), (velocity, 3), (delays_s, L), (beacon, 3))
    ]
    M = args[0].shape[0]
    h, H = np.empty(M), np.empty((M, 3))
    _predict_rows(args[0], args[1], args[2], args[3], h, H)
    return h.reshape(lead), H.reshape(lead + (3,))


def gate_threshold(probability: float, dof: int = 1) -> float:
    """Chi-square gate on the normalized innovation squared y^2 / S."""
    return float(chi2.ppf(probability, dof))


def axis_measurement(axis: int, shape: tuple[int, ...]) -> np.ndarray:
    """H for a direct measurement of one state axis (depth sensor: 2; GPS: 0 and 1)."""
    H = np.zeros(tuple(shape) + (3,))
    H[..., axis] = 1.0
    return H


# --- the general update, over a batch (any state and measurement size) -------------------
@njit(cache=True)
def joseph_update_vector(
    x: np.ndarray, P: np.ndarray, y: np.ndarray, H: np.ndarray, R: np.ndarray, gate: float, work: tuple[np.ndarray, ...]
) -> tuple[float, int]:
    """Eqs. (9)-(13) for an m-vector measurement of one filter, Joseph form, in place.

    x (n,), P (n, n), innovation y = z - h (m,), H (m, n), R (m, m); gate: the
    chi-square bound on the normalized innovation squared. ``work`` is scratch from
    ``joseph_work(n, m)``. The update is applied when nis <= gate. Returns
    (nis, status): 1 updated, 0 not (gated out), -1 S singular (nis NaN). The
    arithmetic is numpy's (core.numerics), so the moving network's outputs stayed
    what they were when this was numpy code.
    """
    m, n = H.shape
    HP, S, lu, Sy, X, A, RK, AP, T1, T2, piv = work
    HP, S, lu, Sy, X = HP[:m], S[:m, :m], lu[:m, :m], Sy[:m], X[:m]
    RK = RK[:m]
    piv = piv[:m]
    if m == 1:
        vecmat(H[0], P, HP[0])
    else:
        matmul(H, P, HP)
    matmul(HP, H.T, S)
    for i in range(m):
        for j in range(m):
            S[i, j] += R[i, j]  # eq. (11)
    for i in range(m):
        Sy[i, 0] = y[i]
    if not lu_solve(S, Sy, Sy, lu, piv):
        return np.nan, -1
    nis = 0.0
    for i in range(m):
        nis += y[i] * Sy[i, 0]
    if not nis <= gate:
        return nis, 0
    lu_solve(S, HP, X, lu, piv)  # X = S^-1 H P = K^T, eq. (12)
    for i in range(n):  # eq. (9)
        s = 0.0
        for j in range(m):
            s += X[j, i] * y[j]
        x[i] += s
    matmul(X.T, H, A)  # K H
    for i in range(n):
        for j in range(n):
            A[i, j] = (1.0 if i == j else 0.0) - A[i, j]
    matmul(R, X, RK)
    matmul(A, P, AP)
    matmul(AP, A.T, T1)
    matmul(X.T, RK, T2)
    for i in range(n):  # eq. (13), Joseph form: (I - KH) P (I - KH)^T + K R K^T
        for j in range(n):
            P[i, j] = T1[i, j] + T2[i, j]
    return nis, 1


@njit(cache=True)
def joseph_work(n: int, m: int) -> tuple[np.ndarray, ...]:
    """Scratch arrays for ``joseph_update_vector`` with state size n and up to m measurements."""
    return (
        np.empty((m, n)),
        np.empty((m, m)),
        np.empty((m, m)),
        np.empty((m, 1)),
        np.empty((m, n)),
        np.empty((n, n)),
        np.empty((m, n)),
        np.empty((n, n)),
        np.empty((n, n)),
        np.empty((n, n)),
        np.empty(m, dtype=np.int64),
    )


@njit(cache=True)
def _joseph_rows(x, P, y, H, R, mask, gate, nis, singular):
    work = joseph_work(x.shape[1], y.shape[1])
    for b in range(x.shape[0]):
        # a row not to update still reports its nis: gate -inf updates nothing
        nis[b], status = joseph_update_vector(x[b], P[b], y[b], H[b], R[b], gate if mask[b] else -np.inf, work)
        singular[b] = status < 0


def joseph_update_batch(
    x: ArrayLike, P: ArrayLike, y: ArrayLike, H: ArrayLike, R: ArrayLike, mask: ArrayLike, gate: float = np.inf
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eqs. (9)-(13) for an m-vector measurement per filter, Joseph form, over a batch.

    x (B, n), P (B, n, n), innovation y = z - h (B, m), H (B, m, n), R (m, m) or
    (B, m, m), mask (B,): rows to update; gate: the chi-square bound on the
    normalized innovation squared, rows above it are not updated. Returns new
    (x, P) and the normalized innovation squared y^T S^-1 y (B,) (a row was
    updated where mask and nis <= gate). Other rows are returned unchanged.
    ``joseph_update_vector`` applied to every row.
    """
    x2 = np.array(x, dtype=float)
    P2 = np.array(P, dtype=float)
    B = x2.shape[0]
    y2 = np.ascontiguousarray(y, dtype=float)
    H2 = np.ascontiguousarray(H, dtype=float)
    R2 = np.ascontiguousarray(np.broadcast_to(R, (B,) + np.shape(R)[-2:]), dtype=float)
    m2 = np.ascontiguousarray(np.broadcast_to(mask, (B,)), dtype=bool)
    nis, singular = np.empty(B), np.zeros(B, dtype=bool)
    _joseph_rows(x2, P2, y2, H2, R2, m2, float(gate), nis, singular)
    if singular.any():
        raise np.linalg.LinAlgError("Singular matrix")
    return x2, P2, nis


# --- the moving-frame EKF of Matos & Cruz, section VII -----------------------------------
# State E = (x, y, phi, c_x, c_y, l): the vehicle's position in the frame of the two
# beacons (origin B1, x towards B2, y 90 degrees clockwise from x, seen from above),
# the bearing phi of the frame's x axis (clockwise from north), the water current
# relative to the frame, expressed in it (it absorbs the frame's own translation),
# and the baseline length. The paper updates P with P - K H P; coopnav uses the
# Joseph form (same value in exact arithmetic, stays positive definite in floats).
FRAME_STATE = ("x_m", "y_m", "phi_rad", "current_x_mps", "current_y_mps", "baseline_m")


@njit(cache=True)
def frame_predict(
    E: np.ndarray, P: np.ndarray, speed_mps: float, heading_rad: float, dt_s: float, Q: np.ndarray
) -> None:
    """Integrate the filter over dt_s with the measured water speed and compass heading
    held constant, in place (one filter; E (6,), P (6, 6), Q (6, 6) per second).

    State (section VII): dE/dt = F(E, v, theta) = (v cos(theta - phi) + c_x,
    v sin(theta - phi) + c_y, 0, 0, 0, 0): with its inputs constant F is constant
    over the step, so E advances exactly by F dt. Covariance: dP/dt = A P + P A^T + Q,
    A = dF/dE, whose only non-zero entries are A[0,2] = v sin(theta - phi), A[1,2] =
    -v cos(theta - phi), A[0,3] = A[1,4] = 1. A A = 0 (rows 2-5 are zero and
    columns 0-1 are zero), so Phi = I + A dt exactly and the covariance equation has
    the closed form P(dt) = Phi P Phi^T + Q dt + (A Q + Q A^T) dt^2/2 + A Q A^T dt^3/3.
    """
    rel = heading_rad - E[2]
    c, s = np.cos(rel), np.sin(rel)
    a = (speed_mps * s, -speed_mps * c)  # A[0, 2], A[1, 2]; A[0, 3] = A[1, 4] = 1
    E[0] += (speed_mps * c + E[3]) * dt_s
    E[1] += (speed_mps * s + E[4]) * dt_s
    # In place, element by element (this runs every sub-step of every environment; no
    # allocation, no BLAS): Phi = I + A dt changes rows 0-1 of Phi P, then columns 0-1
    # of (Phi P) Phi^T; each reads only rows or columns 2-4, which it does not change.
    for r in range(2):
        for k in range(6):
            P[r, k] += dt_s * (a[r] * P[2, k] + P[3 + r, k])
    for col in range(2):
        for i in range(6):
            P[i, col] += dt_s * (a[col] * P[i, 2] + P[i, 3 + col])
    # + Q dt + (A Q + Q A^T) dt^2/2 + A Q A^T dt^3/3, with (A Q)[r, k] = a_r Q[2, k] + Q[3 + r, k]
    # for r = 0, 1 (the other rows are zero) and (A Q A^T)[i, j] = a_j (A Q)[i, 2] + (A Q)[i, 3 + j]
    h2, h3 = dt_s * dt_s / 2.0, dt_s**3 / 3.0
    for i in range(6):
        for j in range(6):
            P[i, j] += Q[i, j] * dt_s
    for r in range(2):
        for k in range(6):
            aq = a[r] * Q[2, k] + Q[3 + r, k]
            P[r, k] += aq * h2
            P[k, r] += aq * h2
        for j in range(2):
            P[r, j] += (a[j] * (a[r] * Q[2, 2] + Q[3 + r, 2]) + a[r] * Q[2, 3 + j] + Q[3 + r, 3 + j]) * h3


@njit(cache=True)
def frame_velocity_of(E: np.ndarray, speed_mps: float, heading_rad: float) -> tuple[float, float]:
    """The frame-relative velocity F[0:2] of section VII's model for one filter E (6,): (v_x, v_y)."""
    rel = heading_rad - E[2]
    return speed_mps * np.cos(rel) + E[3], speed_mps * np.sin(rel) + E[4]


@njit(cache=True)
def _frame_velocity_rows(E, speed, heading, out):
    for b in range(E.shape[0]):
        out[b, 0], out[b, 1] = frame_velocity_of(E[b], speed[b], heading[b])


def frame_velocity(E: np.ndarray, speed_mps: ArrayLike, heading_rad: ArrayLike) -> np.ndarray:
    """``frame_velocity_of`` over leading batch axes: E (..., 6), speed and heading (...) -> (..., 2)."""
    lead = np.broadcast_shapes(np.shape(E)[:-1], np.shape(speed_mps), np.shape(heading_rad))
    E2 = np.ascontiguousarray(np.broadcast_to(E, lead + (6,)), dtype=float).reshape(-1, 6)
    sp, hd = (np.ascontiguousarray(np.broadcast_to(a, lead), dtype=float).reshape(-1) for a in (speed_mps, heading_rad))
    out = np.empty((E2.shape[0], 2))
    _frame_velocity_rows(E2, sp, hd, out)
    return out.reshape(lead + (2,))


@njit(cache=True)
def frame_range_prediction(
    E: np.ndarray, beacon: int, depth_below_m: float, vx: float, vy: float, delays_s: np.ndarray, H: np.ndarray
) -> float:
    """Predicted range z* to beacon B1 (beacon=1) or B2 (beacon=2) of one filter E (6,)
    and its Jacobian over the 6 states, written into H (6,); returns z*.

    Section VII: z* = sqrt(x^2 + y^2) for B1 and sqrt((x - l)^2 + y^2) for B2; coopnav
    measures slant ranges, so the depth below the beacons enters as a third
    coordinate, and the vehicle's motion while the sound travels enters through leg
    delays as in the survey EKF (``range_prediction``): the range is the mean of the
    legs' distances from x + v d to the beacon. (vx, vy) frame-relative velocity;
    delays_s (L,) relative to the filter's time.
    """
    pos = np.empty(3)
    pos[0], pos[1], pos[2] = E[0], E[1], depth_below_m
    vel = np.empty(3)
    vel[0], vel[1], vel[2] = vx, vy, 0.0
    bpos = np.zeros(3)
    if beacon == 2:
        bpos[0] = E[5]
    h, H3 = range_prediction(pos, vel, delays_s, bpos)
    H[:] = 0.0
    H[0], H[1] = H3[0], H3[1]
    if beacon == 2:
        H[5] = -H3[0]  # d z* / d l = -(x - l) / z*
    return h


@njit(cache=True)
def _frame_range_rows(E, beacon, depth, vel, delays, h, H):
    for b in range(E.shape[0]):
        h[b] = frame_range_prediction(E[b], beacon, depth[b], vel[b, 0], vel[b, 1], delays[b], H[b])


def frame_range_model(
    E: np.ndarray, beacon: int, depth_below_m: ArrayLike, velocity_mps: np.ndarray, delays_s: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``frame_range_prediction`` for filters E (B, 6): depth_below_m (B,) or scalar,
    velocity_mps (B, 2) frame-relative, delays_s (B, L). Returns h (B,), H (B, 6)."""
    E = np.ascontiguousarray(E, dtype=float)
    B = E.shape[0]
    depth = np.ascontiguousarray(np.broadcast_to(depth_below_m, (B,)), dtype=float)
    vel = np.ascontiguousarray(velocity_mps, dtype=float)
    delays = np.ascontiguousarray(delays_s, dtype=float)
    h, H = np.empty(B), np.empty((B, 6))
    _frame_range_rows(E, int(beacon), depth, vel, delays, h, H)
    return h, H
