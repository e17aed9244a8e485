"""Multipath ranges that pass the gate: the update weighted by the direct path's
posterior probability (issue 21: the Gao scenarios' 99.9 % NEES exceedances).

A modem range is the direct path with probability 1 - p, or a later multipath
arrival, too long by an excess e ~ Exp(mu), with probability p (the simulator's
``outlier_probability`` and ``outlier_mean_excess_m``; ref-values section 3). The
chi-square gate removes the long ones, but an excess of one or two innovation stds
passes it, and the filter then fuses a biased range as if it were good: measured on
``gao_lawnmower`` (50 runs, the papers' filter), 4 of the 7 run-cycles above the
99.9 % NEES point came within 5 cycles after a fused multipath range with a 12-19 m
excess (base rate of such cycles: 5 %), while P was still large (gate ~15 m).

The Bayesian answer for a measurement that is either good or clutter is the
probabilistic data association update (Bar-Shalom & Tse 1975; Bar-Shalom, Li &
Kirubarajan 2001, sec. on PDA), here with two hypotheses for one range:

    (M1) likelihoods of the innovation y (variance S of the direct path):
         direct   g0(y) = N(y; 0, S)
         multipath g1(y) = (N(0, S) * Exp(mu))(y)
                  = (1/mu) exp(S / (2 mu^2) - y / mu) Phi((y - S/mu) / sqrt(S))  (exponentially
                    modified Gaussian)
    (M2) w = (1 - p) g0 / ((1 - p) g0 + p g1), the direct path's posterior probability
    (M3) x <- x0 + w K y;  P <- w P1 + (1 - w) P0 + w (1 - w) (K y)(K y)^T,
         P1 the Kalman-updated covariance, P0 the prior (under multipath the range
         is ignored: its excess is unknown and larger than its noise);
         the cross-covariances of the consider states: Pxb <- w Pxb1 + (1 - w) Pxb0.

With p = 0 (or a range far inside the gate) w = 1 and this is the Kalman update.

Merging at once (M3) loses which hypothesis was right: a range whose w is 0.85 moves
the estimate 85 % of the way, and in the one case in seven that it was the longer path
the error sits several sigma out until a range across it arrives (``gao_lawnmower``, 500
tuning runs: 99.9 % exceedances 2.4x nominal with multipath, 1.0x without). The next
range, from nearly the same direction a cycle later, tells the two apart. So the
filter can keep both hypotheses (``range_outlier_model="hold"``), as a Gaussian sum of two, for one more range (a
two-component Gaussian-sum filter that merges after each range's successor; Sorenson &
Alspach 1971, with Bar-Shalom et al.'s merge), while every other part of the code sees
the merged (M3) moments:

    (M4) a range's likelihood under the multipath model: L(y; S) = (1 - p) g0(y) + p g1(y)
    (M5) held after (M3): w, the step d = x1 - x0 and the differences dP = P0 - P1,
         dX = X0 - X1 (Pxb), dD = D0 - D1 (Pxd). The prediction adds the same Q and
         the same consider terms to both hypotheses, so d and dX (scaled or zeroed as
         Pxb is, eqs. C7-C8) hold and dP moves by eq. D2's G dD' + dD G'.
    (M6) at the next range (innovation y at the merged estimate, row H, variance R):
         x_d = x + (1 - w) d, P_d = P - (1 - w) dP - w (1 - w) d d';  x_m = x - w d, P_m = P_d + dP
         y_d = y - (1 - w) H d, S_d = H P_d H' + R;  y_m = y + w H d, S_m = H P_m H' + R
         (with the beacon's error a consider state, S is eq. C2's, each hypothesis with its
         own cross-covariance: X_d = X - (1 - w) dX, X_m = X + w dX)
    (M7) w' = w L(y_d; S_d) / (w L(y_d; S_d) + (1 - w) L(y_m; S_m)), and the mixture's
         moments with w' in place of w:
         x <- x + (w' - w) d;  P <- P + (w - w') dP + (w' (1 - w') - w (1 - w)) d d';
         X <- X + (w - w') dX;  D <- D + (w - w') dD
         after which the range is gated and fused as any other (M1-M3, M5 again).

A GPS fix or a lock-out restart discards what is held. The depth sensor's updates
between the two ranges are not replayed per hypothesis (they act on the depth, whose
cross terms with the horizontal are small); (M6) refuses a P_d that is not positive.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from .consider import beacon_variance_along

PRUNE_WEIGHT = 0.02  # (M5): a hypothesis of smaller weight is dropped, as a Gaussian-sum filter prunes


@njit(cache=True)
def _log_g1(y: float, S: float, sd: float, mu: float) -> float:
    """Eq. (M1)'s log g1(y) (mu at least 1e-12 sd, sd = sqrt(S))."""
    z = (y - S / mu) / sd
    if z > -30.0:  # (M1) in logs: exp(S / (2 mu^2)) and Phi(z) alone under/overflow once mu << sd
        return S / (2.0 * mu * mu) - y / mu - math.log(mu) + math.log(max(0.5 * math.erfc(-z / math.sqrt(2.0)), 1e-300))
    # Phi(z)'s asymptotic series (Abramowitz & Stegun 26.2.12); S / (2 mu^2) - y / mu - z^2 / 2 = -y^2 / (2 S)
    iz2 = 1.0 / (z * z)
    series = 1.0 - iz2 + 3.0 * iz2 * iz2 - 15.0 * iz2 * iz2 * iz2
    return -0.5 * y * y / S - math.log(mu) - math.log(-z) - 0.5 * math.log(2.0 * math.pi) + math.log(series)


@njit(cache=True)
def direct_path_weight(y: float, S: float, p: float, mu: float) -> float:
    """Eqs. (M1)-(M2): the posterior probability that a range with innovation y
    (direct-path innovation variance S) is the direct path, when a fraction p of the
    ranges are too long by Exp(mu). 1 when p or mu is 0."""
    if p <= 0.0 or mu <= 0.0 or S <= 0.0:
        return 1.0
    sd = math.sqrt(S)
    g0 = math.exp(-0.5 * y * y / S) / (sd * math.sqrt(2.0 * math.pi))
    if mu < 1e-12 * sd:  # an excess far below the noise: (M1) tends to g0 (and S / mu would overflow)
        return 1.0 - p
    a = (1.0 - p) * g0
    c = p * math.exp(_log_g1(y, S, sd, mu))
    return a / (a + c) if a + c > 0.0 else 0.0


@njit(cache=True)
def longer_path_log_likelihood(y: float, S: float, mu: float) -> float:
    """Eq. (M1)'s log g1(y): a range too long by Exp(mu) with direct-path innovation y of
    variance S (both > 0; -inf when S or mu is not)."""
    if S <= 0.0 or mu <= 0.0:
        return -math.inf
    sd = math.sqrt(S)
    return _log_g1(y, S, sd, max(mu, 1e-12 * sd))


@njit(cache=True)
def range_log_likelihood(y: float, S: float, p: float, mu: float) -> float:
    """Eq. (M4): log of a range's likelihood under the multipath model, log((1 - p) g0(y)
    + p g1(y)); the Gaussian's when p or mu is 0."""
    if S <= 0.0:
        return -math.inf
    log_g0 = -0.5 * y * y / S - 0.5 * math.log(2.0 * math.pi * S)
    sd = math.sqrt(S)
    if p <= 0.0 or mu <= 0.0 or mu < 1e-12 * sd:
        return log_g0
    p = min(p, 1.0 - 1e-12)
    log_a, log_c = math.log(1.0 - p) + log_g0, math.log(p) + _log_g1(y, S, sd, mu)
    top = max(log_a, log_c)
    return top + math.log(math.exp(log_a - top) + math.exp(log_c - top))


@njit(cache=True)
def blend_update(
    w: float, x0: np.ndarray, P0: np.ndarray, X0: np.ndarray, x: np.ndarray, P: np.ndarray, X: np.ndarray
) -> None:
    """Eq. (M3) in place: (x, P, X) hold the Kalman-updated estimate, covariance and
    consider cross-covariances (N, 3, 2), (x0, P0, X0) the prior ones."""
    for i in range(3):
        d_i = x[i] - x0[i]
        for k in range(3):
            d_k = x[k] - x0[k]
            P[i, k] = w * P[i, k] + (1.0 - w) * P0[i, k] + w * (1.0 - w) * d_i * d_k
    for i in range(3):
        x[i] = x0[i] + w * (x[i] - x0[i])
    for j in range(X.shape[0]):
        for i in range(3):
            for k in range(X.shape[2]):
                X[j, i, k] = w * X[j, i, k] + (1.0 - w) * X0[j, i, k]


class Moments(NamedTuple):
    """A survey filter's moments as (M3)-(M7) read them: estimate x (3,), covariance P
    (3, 3), cross-covariances X with the beacons' errors (N, 3, 2) and D with the dead
    reckoning's biases (3, 4)."""

    x: np.ndarray
    P: np.ndarray
    X: np.ndarray
    D: np.ndarray


class Held(NamedTuple):
    """What (M5) holds between two ranges: the direct path's step d (3,) and the
    differences dP (3, 3), dX (N, 3, 2), dD (3, 4) of the multipath hypothesis' moments
    minus the direct path's."""

    d: np.ndarray
    dP: np.ndarray
    dX: np.ndarray
    dD: np.ndarray


@njit(cache=True)
def hold_hypotheses(w: float, prior: Moments, direct: Moments, held: Held) -> float:
    """Eq. (M5): what (M3) merged, kept until the next range: d = x1 - x0, dP = P0 - P1,
    dX = X0 - X1, dD = D0 - D1 of the direct path's hypothesis (the Kalman-updated
    moments ``direct``) and the multipath one (the ``prior``), written into ``held``.
    Returns the weight to hold (1.0, nothing held, when either hypothesis weighs less
    than PRUNE_WEIGHT)."""
    if not PRUNE_WEIGHT <= w <= 1.0 - PRUNE_WEIGHT:
        return 1.0
    held.d[:] = direct.x - prior.x
    held.dP[:, :] = prior.P - direct.P
    held.dX[:, :, :] = prior.X - direct.X
    held.dD[:, :] = prior.D - direct.D
    return w


@njit(cache=True)
def reweigh_hypotheses(
    w: float,
    held: Held,
    f: Moments,
    H: np.ndarray,
    y: float,
    R: float,
    p: float,
    mu: float,
    j: int = -1,
    Pbb: np.ndarray | None = None,
) -> float:
    """Eqs. (M6)-(M7) in place: the next range (innovation y at the merged estimate f.x,
    row H, variance R) re-weighs the hypotheses (M5) held since the last one, and the
    merged moments ``f`` move to the re-weighed mixture's. With the beacon's error a
    consider state (``"schmidt"``: j the ranging beacon, Pbb (2, 2) its covariance,
    R without it) each hypothesis' innovation variance is eq. (C2)'s, with its own
    cross-covariance X_j; else (j < 0) R holds the beacon's variance. Returns the new
    weight w' (w when the held hypotheses do not fit the covariance any more: nothing
    changes)."""
    d, dP, dX, dD = held
    x, P, X, D = f
    # (M6) the two hypotheses, recovered from the merge: x_d = x + (1 - w) d, x_m = x - w d,
    # P_d = P - (1 - w) dP - w (1 - w) d d', P_m = P_d + dP (the prediction since added the
    # same to both, so the differences hold)
    Pd = P - (1.0 - w) * dP - w * (1.0 - w) * np.outer(d, d)
    if Pd[0, 0] <= 0.0 or Pd[1, 1] <= 0.0 or Pd[0, 0] * Pd[1, 1] <= Pd[0, 1] * Pd[1, 0]:
        return w
    Hd = H @ d
    S_d = H @ Pd @ H + R
    S_m = S_d + H @ dP @ H
    if j >= 0:  # (C2): + Hb Pbb Hb' + 2 H X_j Hb', Hb = -H[:2], X_d = X - (1 - w) dX, X_m = X + w dX
        S_b = beacon_variance_along(Pbb, H[0], H[1]) if Pbb is not None else 0.0  # None: an exact beacon
        c_d, c_m = 0.0, 0.0
        for i in range(3):
            for a in range(2):
                c_d += H[i] * (X[j, i, a] - (1.0 - w) * dX[j, i, a]) * H[a]
                c_m += H[i] * (X[j, i, a] + w * dX[j, i, a]) * H[a]
        S_d += S_b - 2.0 * c_d
        S_m += S_b - 2.0 * c_m
    if S_d <= 0.0 or S_m <= 0.0:
        return w
    l_d = range_log_likelihood(y - (1.0 - w) * Hd, S_d, p, mu)
    l_m = range_log_likelihood(y + w * Hd, S_m, p, mu)
    # (M7) w' = w L_d / (w L_d + (1 - w) L_m), and the mixture's moments with w' for w
    e = min(max(l_m - l_d + math.log(1.0 - w) - math.log(w), -700.0), 700.0)
    w2 = 1.0 / (1.0 + math.exp(e))
    spread = w2 * (1.0 - w2) - w * (1.0 - w)
    for i in range(3):
        x[i] += (w2 - w) * d[i]
        for k in range(3):
            P[i, k] += (w - w2) * dP[i, k] + spread * d[i] * d[k]
        for k in range(D.shape[1]):
            D[i, k] += (w - w2) * dD[i, k]
    X += (w - w2) * dX
    return w2
