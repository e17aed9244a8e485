"""The split range model (``range_linearization="split"``, eqs. S1-S6): where one range's
first-order update is poor, the range is linearized over its posterior instead of at the
prior's mean (posterior linearization, Garcia-Fernandez, Svensson, Morelande & Sarkka 2015),
with the posterior computed as a sum of Gaussians: the prior split across the line of sight,
where the range bends, each part updated at its own linearization point. The modem's
fusion kernel (``measurements.modem``) calls ``split_range_model`` before its ordinary update,
as it calls the iterated model; docs/scenarios/consider-fusion.md#split says what it does and
does not mend.

Why: with the beacon nearly overhead, or tens of metres away while the estimate is metres
off across the line of sight, the posterior of one range is an arc of the range circle. The
first-order update (one gradient, at the prior's mean) moves the estimate along the wrong
gradient and shrinks its covariance as if the range were linear; the iterated update
(``core/iterated.py``) finds the arc's most probable point but keeps the linearization's
covariance; the second-order terms (``navigation.range_curvature``) only inflate R. A sum of
Gaussians narrow enough that the range is linear over each one follows the arc (Alspach &
Sorenson 1972; the splitting of Huber et al. 2011). The filter carries one Gaussian, and with
the beacons' errors and its dead-reckoning biases as consider states it must keep its joint
covariance with them positive definite while their own covariances stay as they are
(Schmidt). Merging the sum's moments directly breaks that on a bimodal posterior (the
consider errors' conditional means spread wider than their prior); a linear model fitted
over the posterior (its slope A and the variance Omega it leaves) and used in the filter's
ordinary update keeps it by construction, and is the range itself where the range is linear.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .consider import schmidt_range_update
from .iterated import RangeGeometry
from .multipath import Moments
from .navigation import innovation_variance, moving_range_prediction, range_curvature, relative_covariance

SPLIT_COMPONENTS = 15  # eq. (S2)'s Gaussians
SPLIT_WIDTH = 0.5  # each one's std along the split direction, as a fraction of the prior's
# eq. (S1)'s trigger: split when the range's curvature leaves a variance (eq. L3) above this
# fraction squared of the first-order innovation's (below it the update is the first-order one)
SPLIT_TRIGGER = 0.1

# (S2): the offsets (in the prior's std along the direction) and weights of the components,
# Gauss-Hermite nodes of N(0, 1 - w^2): the sum has the prior's mean and variance exactly
_NODES, _WEIGHTS = np.polynomial.hermite_e.hermegauss(SPLIT_COMPONENTS)
SPLIT_OFFSETS = _NODES * np.sqrt(1.0 - SPLIT_WIDTH**2)
SPLIT_WEIGHTS = _WEIGHTS / _WEIGHTS.sum()


@njit(cache=True)
def split_range_model(
    f: Moments,
    j: int,
    H: np.ndarray,
    meas: tuple,
    Pbb: np.ndarray,
    K: np.ndarray,
    geo: RangeGeometry,
    gate: float,
    schmidt: bool,
) -> tuple[bool, np.ndarray, tuple]:
    """Range model of beacon j's range for survey filter f (``multipath.Moments``), linearized
    over its posterior, for ``range_linearization="split"``. H, meas: the first-order model
    (``measurements.modem._range_model``: r, h, R, R_white, the beacon's Pbb (2, 2), ...); Pbb
    (2, 2), K (3,): scratch; geo: ``iterated.RangeGeometry``; gate: the chi-square gate of the
    first-order innovation; schmidt: the beacon's error as consider states (else white, in R).
    Returns (passed, H_eff, meas_eff) as ``iterated.iterated_range_model`` does: whether the
    range passed its gate on the first-order innovation at the prior (as eq. I3) and, if it
    did, the model for the modem's ordinary update (the first-order one where eq. S1 does not
    split).

    (S1) d = x - b, the survey's position relative to the beacon's true one, of covariance
         Pd = P - X - X^T + Pbb (Schmidt; P with white, whose R holds the beacon's variance);
         split when the range bends over it, tr(M Pd M Pd) / 2 > SPLIT_TRIGGER^2 S (eq. L3
         against the first-order innovation's S);
    (S2) Pd split along s = Pd v / sqrt(v^T Pd v), v the horizontal unit vector across the
         line of sight (where the range bends; with the beacon straight above, Pd's widest
         horizontal axis): component k has mean offset a_k s and covariance
         Pd - (1 - w^2) s s^T (a_k, q_k: SPLIT_OFFSETS, SPLIT_WEIGHTS; w = SPLIT_WIDTH), so the
         sum keeps Pd's mean and covariance;
    (S3) each component updated at its own mean (the EKF, noise R; white: R_white), weight
         q_k N(r; h_k, S_k), normalized: the posterior of d as a sum, means m_k, covariances C_k;
    (S4) the range fitted over that posterior (statistical linear regression, each component
         linearized at its posterior mean): hbar = sum w_k h(m_k),
         A = Pdpost^-1 sum w_k (C_k H_k^T + (m_k - mbar)(h(m_k) - hbar)),
         Omega = sum w_k (H_k C_k H_k^T + (h(m_k) - hbar)^2) - A^T Pdpost A;
    (S5) the model the ordinary update takes: H_eff = A (the beacon's error -A, as for d),
         h_eff = hbar + A (0 - mbar), read at the prior; R_eff = R + Omega;
    (S6) so the update is Schmidt's (or white's) own, C1-C6 with D3: the joint covariance with
         the consider states stays positive definite, and with a linear range A = H,
         Omega = 0 and the model is the first-order one."""
    r, h, R, R_white, Pb = meas[0], meas[1], meas[2], meas[3], meas[4]
    y = r - h
    if schmidt:  # a gate of -1 returns the NIS and touches nothing
        nis, _ = schmidt_range_update(f.x, f.P, f.X[j], Pb, 1.0, H, R, -1.0, K)
        if not nis < np.inf:  # S <= 0: an indefinite joint covariance, no update (not a 1/0)
            return False, H, meas
        S = 1.0 / nis
    else:
        S = innovation_variance(f.P, H, R_white)
    if not y * y / S <= gate:
        return False, H, meas
    noise = R if schmidt else R_white
    # (S1) the relative position's covariance (eq. L0): with white, P alone (its R holds the
    # beacon's variance, which the fit over P cannot mend, so the trigger leaves it out too;
    # white keeps no cross-covariance, X = 0)
    Pbb[:, :] = 0.0
    if schmidt:
        Pbb[:, :] = Pb
    _, var = range_curvature(f.P, f.X[j], Pbb, H, h)
    if not var > SPLIT_TRIGGER * SPLIT_TRIGGER * S:
        return True, H, meas
    Pd = np.empty((3, 3))
    for i in range(3):
        for q in range(3):
            Pd[i, q] = relative_covariance(f.P, f.X[j], Pbb, i, q)
    A, hbar, omega = posterior_fit(f.x, Pd, H, r, noise, geo)
    return True, A, (r, hbar, R + omega, R_white + omega, Pb, 0.0, 0.0)


@njit(cache=True)
def _split_direction(Pd: np.ndarray, H: np.ndarray) -> tuple[float, float]:
    """Eq. (S2)'s horizontal unit vector: across the line of sight, where the range bends;
    with the beacon straight above or below (it bends every way), Pd's widest horizontal
    axis."""
    hh = np.sqrt(H[0] * H[0] + H[1] * H[1])
    if hh > 1e-3:  # across the line of sight, where the range bends
        v0, v1 = -H[1] / hh, H[0] / hh
    else:  # the beacon straight above or below: it bends every way; the widest axis
        a, b, c = Pd[0, 0], Pd[0, 1], Pd[1, 1]
        half = 0.5 * (a - c)
        lam = 0.5 * (a + c) + np.sqrt(half * half + b * b)
        if b != 0.0:
            v0, v1 = lam - c, b
        elif a >= c:
            v0, v1 = 1.0, 0.0
        else:
            v0, v1 = 0.0, 1.0
        nv = np.sqrt(v0 * v0 + v1 * v1)
        v0 /= nv
        v1 /= nv
    return v0, v1


@njit(cache=True)
def posterior_fit(
    x: np.ndarray, Pd: np.ndarray, H: np.ndarray, r: float, noise: float, geo: RangeGeometry
) -> tuple[np.ndarray, float, float]:
    """Eqs. (S2)-(S5) for a prior estimate x (3,) whose position relative to the beacon has
    covariance Pd (3, 3), the range's gradient H (3,) at x, a range r of noise variance
    ``noise`` and the range's geometry geo
    (``iterated.RangeGeometry``): the slope A (3,), the prediction at the prior h_eff and the
    variance Omega the fit leaves, of the range fitted over its posterior."""
    v0, v1 = _split_direction(Pd, H)
    sd = np.sqrt(max(Pd[0, 0] * v0 * v0 + 2.0 * Pd[0, 1] * v0 * v1 + Pd[1, 1] * v1 * v1, 1e-12))
    s = np.zeros(3)
    for i in range(3):
        s[i] = (Pd[i, 0] * v0 + Pd[i, 1] * v1) / sd
    shrink = 1.0 - SPLIT_WIDTH * SPLIT_WIDTH
    m = SPLIT_COMPONENTS
    means = np.zeros((m, 3))  # (S3) the components' posterior means (offsets from the prior's) ...
    covs = np.zeros((m, 3, 3))  # ... and covariances
    logw = np.zeros(m)
    xk = np.zeros(3)
    Pk = np.zeros((3, 3))
    Kk = np.zeros(3)
    for k in range(m):
        ak = SPLIT_OFFSETS[k]
        for i in range(3):  # (S2)
            xk[i] = x[i] + ak * s[i]
            for i2 in range(3):
                Pk[i, i2] = Pd[i, i2] - shrink * s[i] * s[i2]
        hk, Hk = moving_range_prediction(xk, geo.vel_est, geo.beacon, geo.beacon_vel, geo.delays)
        Sk = innovation_variance(Pk, Hk, noise)
        for i in range(3):
            Kk[i] = (Pk[i, 0] * Hk[0] + Pk[i, 1] * Hk[1] + Pk[i, 2] * Hk[2]) / Sk
        for i in range(3):
            means[k, i] = ak * s[i] + Kk[i] * (r - hk)
            for i2 in range(3):
                covs[k, i, i2] = Pk[i, i2] - Kk[i] * Sk * Kk[i2]
        logw[k] = np.log(SPLIT_WEIGHTS[k]) - 0.5 * (r - hk) * (r - hk) / Sk - 0.5 * np.log(Sk)
    w = np.exp(logw - logw.max())
    w /= w.sum()
    mbar = np.zeros(3)
    for k in range(m):
        mbar += w[k] * means[k]
    # (S4) the fit over the posterior, each component linearized at its posterior mean
    hs = np.zeros(m)
    Hs = np.zeros((m, 3))
    hbar = 0.0
    for k in range(m):
        for i in range(3):
            xk[i] = x[i] + means[k, i]
        hs[k], Hs[k] = moving_range_prediction(xk, geo.vel_est, geo.beacon, geo.beacon_vel, geo.delays)
        hbar += w[k] * hs[k]
    Ppost = np.zeros((3, 3))
    cross = np.zeros(3)
    vh = 0.0
    for k in range(m):
        dh = hs[k] - hbar
        for i in range(3):
            di = means[k, i] - mbar[i]
            ch = 0.0
            for i2 in range(3):
                Ppost[i, i2] += w[k] * (covs[k, i, i2] + di * (means[k, i2] - mbar[i2]))
                ch += covs[k, i, i2] * Hs[k, i2]
            cross[i] += w[k] * (ch + di * dh)
        vh += w[k] * (innovation_variance(covs[k], Hs[k], 0.0) + dh * dh)
    A = np.linalg.solve(0.5 * (Ppost + Ppost.T), cross)
    omega = max(vh - innovation_variance(Ppost, A, 0.0), 0.0)
    # (S5) the model at the prior
    h_eff = hbar
    for i in range(3):
        h_eff -= A[i] * mbar[i]
    return A, h_eff, omega
