"""The beacon's navigation error as consider states (Schmidt-Kalman), and covariance
intersection where the correlation is unknown (issue 21: the survey filter is
over-confident when the beacon navigates).

A beacon AUV that dead-reckons carries an error that is a slowly varying bias: every
range it sends between two of its GPS fixes shares it. The survey EKF (Gao & Chitre
eqs. 7-13) folds the beacon's variance into R, as if it were fresh white noise each
ping, and after a few dozen pings it believes it has averaged away an error it has
not. The remedy used in the field is to carry the beacon's error as extra states
with their cross-covariance to the survey's (Bahr, Walter & Leonard 2009; Webster
et al. 2013). The survey cannot estimate the beacon's error (the beacon's own
navigation owns it), so it is a *consider* state (Schmidt 1966; Simon, Optimal State
Estimation, 2006, its Schmidt-Kalman section; named, not re-read here): its
covariance Pbb comes in each beacon message, the survey carries only Pxb, the
cross-covariance of its own error with the beacon's, and the gain of the consider states is zero.

Conventions. Survey state x = (east, north, depth), covariance P (3, 3). Consider
state b (nb = 2: horizontal, or 3): the beacon's true position minus the position it
reports, so the beacon is at b_est + b and b = -``SimState.b_nav_err``. Its
estimate is always 0 and its covariance Pbb (nb, nb) is what the beacon sends.
Pxb = E[(x - x_hat) b^T] (3, nb), one per (survey vehicle, beacon).

Equations (numbered here; the EKF's own numbers are Gao & Chitre's):

    (C1) range model   h(x, b) = |x - (b_est + b)|;  H = dh/dx (Gao eq. 8),
                       Hb = dh/db = -H[:nb]  (at b = 0)
    (C2) innovation variance
                       S = H P H^T + 2 H Pxb Hb^T + Hb Pbb Hb^T + R
    (C3) Schmidt gain  K = (P H^T + Pxb Hb^T) / S,  Kb = 0
    (C4) state         x <- x + K y,  y = z - h  (b stays 0)
    (C5) covariance    Pa <- A Pa A^T + R Ka Ka^T,  Pa = [[P, Pxb], [Pxb^T, Pbb]],
                       Ka = [K; 0], A = I - Ka [H, Hb]  (Joseph form, valid for any
                       gain, hence for the Schmidt one): P and Pxb change, Pbb not
    (C6) other beacons' cross-covariances on any update of x with gain K that does
                       not involve them (another beacon's range, depth, GPS), the
                       beacons' errors independent of each other:  Pxb_j <- (I - K H) Pxb_j
    (C7) predict       x and P as Gao eqs. (4), (6) (F = I); b_{k+1} = phi b_k + w_k with
                       phi = exp(-dt / tau) (a first-order Gauss-Markov error; tau = inf
                       is a bias or a random walk): Pxb <- phi Pxb. Pbb is not
                       predicted by the survey: each message brings the beacon's own.
    (C8) beacon reset  at a GPS fix the beacon's error restarts from the GPS noise,
                       independent of everything the survey has: Pxb <- 0.

With Pbb = 0 and Pxb = 0, (C2)-(C5) are Gao's eqs. (9)-(13) (``navigation.joseph_update``).

What the beacon must send: its Pbb (2-D: var_e, var_n, cov_en, 3 numbers; 3-D: 6)
and the count of its GPS fixes modulo 16, so that a survey vehicle that missed the
message after a fix still zeroes its Pxb (C8): ``encode_pbb`` / ``decode_pbb``, 24 bits
(+20 over today's ping in 2-D with the 4-bit counter; docs/scenarios/consider-fusion.md).

Covariance intersection (Julier & Uhlmann 1997): fuse two estimates whose
cross-correlation is unknown as C^-1 = w A^-1 + (1 - w) B^-1, c = C (w A^-1 a +
(1 - w) B^-1 b), omega minimizing trace(C) or det(C). ``ci_range_update`` is the
scalar-range case; ``covariance_intersection`` the general two-estimate one.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

GOLDEN = 0.6180339887498949


# beacon_error_fusion as the kernels read it (``measurements.modem``)
WHITE, SCHMIDT, CI = 0, 1, 2
FUSIONS = {"white": WHITE, "schmidt": SCHMIDT, "ci": CI}


@njit(cache=True, inline="always")
def _consider_row(Pxb: np.ndarray, Pbb: np.ndarray, H: np.ndarray, i: int) -> float:
    """Row 3 + i of Pa Ha^T in eq. (C2)-(C5): (Pxb^T H^T + Pbb Hb^T)_i, Hb = -H[:nb]."""
    v = Pxb[0, i] * H[0] + Pxb[1, i] * H[1] + Pxb[2, i] * H[2]
    for k in range(Pbb.shape[0]):
        v -= Pbb[i, k] * H[k]
    return v


@njit(cache=True)
def schmidt_range_update(
    x: np.ndarray,
    P: np.ndarray,
    Pxb: np.ndarray,
    Pbb: np.ndarray,
    y: float,
    H: np.ndarray,
    R: float,
    gate: float,
    K: np.ndarray,
) -> tuple[float, bool]:
    """Schmidt-Kalman update of one survey filter with one range, the beacon's position
    error a consider state, in place (x (3,), P (3, 3), Pxb (3, nb); Pbb (nb, nb) is
    read only). y = z - h (``navigation.range_prediction`` gives h and H, with the
    legs' delays); R: the ranging noise only (sound speed's share included, the
    beacon's variance not: it is Pbb). Writes the gain into K (3,), or zeros when gated.
    Returns (nis, fused): nis = y^2 / S, fused when nis <= gate (never with S <= 0, where nis
    is inf, or a NaN y). Eqs. (C1)-(C5)."""
    nb = Pbb.shape[0]
    # Written out element by element over the augmented state a = (x, b), n = 3 + nb,
    # Pa = [[P, Pxb], [Pxb^T, Pbb]], Ha = [H, -H[:nb]] (C1): nothing is allocated and
    # no BLAS is called, since this runs for every range in the fusion kernel.
    # PH = Pa Ha^T: rows 0-2 (P H^T + Pxb Hb^T), then rows 3.. (Pxb^T H^T + Pbb Hb^T)
    PH0 = PH1 = PH2 = 0.0
    S = R  # (C2): S = Ha Pa Ha^T + R
    for k in range(3 + nb):
        if k < 3:
            hk = H[k]
            c0, c1, c2 = P[0, k], P[1, k], P[2, k]
        else:
            hk = -H[k - 3]
            c0, c1, c2 = Pxb[0, k - 3], Pxb[1, k - 3], Pxb[2, k - 3]
        PH0 += c0 * hk
        PH1 += c1 * hk
        PH2 += c2 * hk
    S += H[0] * PH0 + H[1] * PH1 + H[2] * PH2
    for i in range(nb):  # the consider rows of PH, times Hb
        S -= H[i] * _consider_row(Pxb, Pbb, H, i)
    K[:] = 0.0
    if not S > 0.0:  # only an indefinite joint covariance gives this: no update, never a sign-flipped gain
        return np.inf, False
    nis = y * y / S
    if not nis <= gate:  # a NaN y too
        return nis, False
    K[0], K[1], K[2] = PH0 / S, PH1 / S, PH2 / S  # (C3); Kb = 0
    for i in range(3):
        x[i] += K[i] * y  # (C4)
    # (C5), Joseph form, its rows 0-2 (Pbb does not change): with A = I - Ka Ha,
    # M = A Pa has rows M_i = Pa_i - K_i (Ha Pa) = Pa_i - K_i PH^T, and
    # Pn_ij = (M A^T)_ij + R K_i K_j = M_ij - K_j (M Ha^T)_i + R K_i K_j, where
    # K_j = 0 for the consider columns j >= 3 (so Pxb <- M's columns 3..)
    # symmetrized, (Pn + Pn^T) / 2, in place: entry (i, j) needs only P_ij and P_ji
    PH = (PH0, PH1, PH2)
    MH = (PH0 - K[0] * (S - R), PH1 - K[1] * (S - R), PH2 - K[2] * (S - R))  # (M Ha^T)_i = PH_i - K_i Ha PH
    for i in range(3):
        for j in range(i, 3):
            v = 0.5 * (P[i, j] + P[j, i]) - 0.5 * (K[i] * (PH[j] + MH[j]) + K[j] * (PH[i] + MH[i]))
            P[i, j] = P[j, i] = v + R * K[i] * K[j]
    for j in range(nb):
        pb = _consider_row(Pxb, Pbb, H, j)  # Pxb is not changed yet
        for i in range(3):
            Pxb[i, j] -= K[i] * pb
    return nis, True


@njit(cache=True)
def carry_cross_covariance(Pxb: np.ndarray, K: np.ndarray, H: np.ndarray) -> None:
    """Eq. (C6): Pxb <- (I - K H) Pxb in place, for every cross-covariance the update
    with gain K (3,) and measurement row H (3,) did not involve: the other beacons'
    after a range, all of them after a depth or GPS update (its K = P H^T / S before
    the update). Pxb (3, nb)."""
    nb = Pxb.shape[1]
    for j in range(nb):
        hp = H[0] * Pxb[0, j] + H[1] * Pxb[1, j] + H[2] * Pxb[2, j]
        for i in range(3):
            Pxb[i, j] -= K[i] * hp


@njit(cache=True)
def gauss_markov_factor(dt_s: float, tau_s: float) -> float:
    """Eq. (C7)'s phi = exp(-dt_s / tau_s), the correlation a first-order Gauss-Markov error
    keeps over dt_s; 1 for tau_s <= 0 or inf (a bias or a random walk, whose increments are
    independent of the survey's error). ``consider_predict`` and eq. C8' read it."""
    if tau_s > 0.0 and np.isfinite(tau_s):
        return np.exp(-dt_s / tau_s)
    return 1.0


@njit(cache=True)
def consider_predict(Pxb: np.ndarray, dt_s: float, tau_s: float) -> None:
    """Eq. (C7) for one (survey, beacon) cross-covariance, in place: Pxb <- phi Pxb,
    phi = ``gauss_markov_factor``; tau_s <= 0 or inf: the beacon's error is a bias or a
    random walk (its increments independent of the survey's error), Pxb unchanged.
    The survey's own predict (Gao eqs. 4, 6, F = I) leaves Pxb as it is."""
    if tau_s > 0.0 and np.isfinite(tau_s):
        phi = gauss_markov_factor(dt_s, tau_s)
        for i in range(Pxb.shape[0]):
            for j in range(Pxb.shape[1]):
                Pxb[i, j] *= phi


@njit(cache=True)
def beacon_reset(Pxb: np.ndarray) -> None:
    """Eq. (C8): the beacon took a GPS fix; its new error is independent of the survey's:
    Pxb <- 0 in place."""
    Pxb[:, :] = 0.0


@njit(cache=True, inline="always")
def beacon_covariance(var_m2: float, dev_m2: complex, out: np.ndarray) -> None:
    """The beacon's horizontal Pbb (2, 2) into ``out`` from what its message carries: the
    per-axis variance m (``nav_var_m2``) and the deviator a + 1j c (``nav_dev_m2``,
    ``beacon_nav.covariance_deviator_m2``, eq. N1): Pbb = [[m + a, c], [c, m - a]]. With a
    deviator of 0 it is m I2 to the bit (the ASVs, and a beacon AUV at its fix)."""
    out[0, 0] = var_m2 + dev_m2.real
    out[1, 1] = var_m2 - dev_m2.real
    out[0, 1] = out[1, 0] = dev_m2.imag


@njit(cache=True, inline="always")
def beacon_variance_along(Pbb: np.ndarray, h0: float, h1: float) -> float:
    """h Pbb h^T for a horizontal row h = (h0, h1) (eq. C2's Hb Pbb Hb^T with Hb = -H[:2]),
    as m |h|^2 + (a (h0^2 - h1^2) + 2 c h0 h1) so that an isotropic Pbb = m I2 gives
    m |h|^2 to the bit."""
    m, a, c = 0.5 * (Pbb[0, 0] + Pbb[1, 1]), 0.5 * (Pbb[0, 0] - Pbb[1, 1]), Pbb[0, 1]
    return m * (h0 * h0 + h1 * h1) + (a * (h0 * h0 - h1 * h1) + 2.0 * c * h0 * h1)


@njit(cache=True, inline="always")
def beacon_variance_los(Pbb: np.ndarray, h0: float, h1: float) -> float:
    """The beacon's position variance along the horizontal direction (h0, h1) (of any
    length; m where it is 0): what the papers' white fusion adds to a range's R (along the
    line of sight) or, across it, to a bearing's. m + (a (h0^2 - h1^2) + 2 c h0 h1) / |h|^2:
    m to the bit for an isotropic Pbb."""
    m, a, c = 0.5 * (Pbb[0, 0] + Pbb[1, 1]), 0.5 * (Pbb[0, 0] - Pbb[1, 1]), Pbb[0, 1]
    n2 = h0 * h0 + h1 * h1
    if not n2 > 0.0:
        return m
    return m + (a * (h0 * h0 - h1 * h1) + 2.0 * c * h0 * h1) / n2


class ErrorModel(NamedTuple):
    """The beacon AUV's error model's constants, as eq. (N2) reads them (``beacon_nav``):
    sigma_k^2 + sigma_b0^2, sigma_k^2 - sigma_b0^2, b1^2 and the current estimate's error
    variance per axis (m^2/s^2)."""

    sigma2_sum: float
    sigma2_diff: float
    cycle_rad2: float
    current_var: float


@njit(cache=True, inline="always")
def error_model_covariance(m2: np.ndarray, m1: np.ndarray, model: ErrorModel) -> tuple[float, float, float, float]:
    """Eq. (N2): Cov(b2, b1), the 2x2 covariance of a beacon AUV's dead-reckoning error at two
    of its pings, from the error model's state at each (``SimState`` b_*, as the ping sends it
    with ``beacon_covariance="full"``): m = (D east, D north, s, G re, G im, T, w) with D its
    displacement since its fix, s and G the one-cycle compass error's sums
    (``beacon_nav.heading_cycle_variance_m2``), T its time without bottom lock and w its
    white part's variance per axis; ping 1 the earlier, no fix between. In complex form
    (z = east + i north), A = E[z2 conj(z1)] and C = E[z2 z1]:

        walk (independent increments) and start fix: A += 2 w1;  the told current's error
        c T: A += 2 sigma_c^2 T2 T1;  the constant errors (k - i b0) D:
        A += (sigma_k^2 + sigma_b0^2) D2 conj(D1), C += (sigma_k^2 - sigma_b0^2) D2 D1;
        the one-cycle error -i b1 (e^{i phi} s - e^{-i phi} G) / 2:
        A += b1^2 (s2 s1 + G2 conj(G1)) / 4, C += b1^2 (s2 G1 + G2 s1) / 4;

    then Cov = [[Re(A + C), Im(C - A)], [Im(A + C), Re(A - C)]] / 2 (rows: b2 east, north).
    With m2 = m1 it is the covariance the beacon carries, [[m + a, c], [c, m - a]] (eq. N1).
    Returns (xx, xy, yx, yy)."""
    D1, D2 = m1[0] + 1j * m1[1], m2[0] + 1j * m2[1]
    G1, G2 = m1[3] + 1j * m1[4], m2[3] + 1j * m2[4]
    A = 2.0 * m1[6] + 2.0 * model.current_var * m2[5] * m1[5] + 0j
    A += model.sigma2_sum * D2 * np.conj(D1) + 0.25 * model.cycle_rad2 * (m2[2] * m1[2] + G2 * np.conj(G1))
    C = model.sigma2_diff * D2 * D1 + 0.25 * model.cycle_rad2 * (m2[2] * G1 + G2 * m1[2])
    return 0.5 * (A + C).real, 0.5 * (C - A).imag, 0.5 * (A + C).imag, 0.5 * (A - C).real


@njit(cache=True, inline="always")
def transport_cross_covariance(Pxb: np.ndarray, m2: np.ndarray, m1: np.ndarray, model: ErrorModel) -> None:
    """Eq. (N3) in place: the survey's cross-covariance with a beacon AUV's error carried from
    the ping it last heard (state m1) to this one (m2), Pxb <- Pxb Sigma1^-1 Cov(b2, b1)^T
    (eq. N2; Cov(x, b2) = Cov(x, b1) Sigma1^-1 Cov(b1, b2), b2's part not explained by b1
    independent of x). Eq. (C7) with phi = 1 took the error for a random walk, Pxb kept,
    which is wrong where the covariance turns with the beacon's track (docs/scenarios/
    gao-chitre.md#full-covariance). Nothing changes when Sigma1 is singular (never heard)."""
    s00, s01, _, s11 = error_model_covariance(m1, m1, model)
    det = s00 * s11 - s01 * s01
    if not det > 1e-12 * s00 * s11:  # singular or nearly (never heard): no transport, no rounding blown up
        return
    c00, c01, c10, c11 = error_model_covariance(m2, m1, model)
    # M = Sigma1^-1 C^T, C^T = [[c00, c10], [c01, c11]]
    i00, i01, i11 = s11 / det, -s01 / det, s00 / det
    m00, m01 = i00 * c00 + i01 * c01, i00 * c10 + i01 * c11
    m10, m11 = i01 * c00 + i11 * c01, i01 * c10 + i11 * c11
    for i in range(Pxb.shape[0]):
        p0, p1 = Pxb[i, 0], Pxb[i, 1]
        Pxb[i, 0] = p0 * m00 + p1 * m10
        Pxb[i, 1] = p0 * m01 + p1 * m11


@njit(cache=True, inline="always")
def gps_share(Pxb: np.ndarray, gps_var_m2: float, var_seen_m2: float, dev_seen_m2: complex, phi: float) -> None:
    """Eq. (C8') in place: Pxb <- phi Pxb M with M = var(g) Sigma_seen^-1, the survey's share
    of the beacon's old error e = g + d that was its GPS error g (Cov(x, g) = Cov(x, e)
    Sigma_seen^-1 Cov(e, g), Cov(e, g) = var(g) I2), Sigma_seen = [[m + a, c], [c, m - a]]
    as last heard (``beacon_covariance``). Each of M's eigenvalues var(g) / lambda is capped at
    1 (the share of one error in a sum), which keeps the joint covariance positive
    semi-definite. With a deviator of 0 it is the scalar min(1, var(g) / m), to the bit as
    before the deviator was carried; a variance never heard (0) keeps the share 1."""
    r = abs(dev_seen_m2)
    lam_p, lam_m = var_seen_m2 + r, var_seen_m2 - r
    s_p = min(1.0, gps_var_m2 / lam_p) if lam_p > 0.0 else 1.0
    if r == 0.0:
        Pxb *= phi * s_p
        return
    s_m = min(1.0, gps_var_m2 / lam_m) if lam_m > 0.0 else 1.0
    mu, half = 0.5 * (s_p + s_m), 0.5 * (s_p - s_m)
    ua, uc = dev_seen_m2.real / r, dev_seen_m2.imag / r
    m00, m01, m11 = phi * (mu + half * ua), phi * half * uc, phi * (mu - half * ua)
    for i in range(Pxb.shape[0]):
        p0, p1 = Pxb[i, 0], Pxb[i, 1]
        Pxb[i, 0] = p0 * m00 + p1 * m01
        Pxb[i, 1] = p0 * m01 + p1 * m11


@njit(cache=True)
def ci_trace(P: np.ndarray, H: np.ndarray, R: float, w: float) -> float:
    """trace(C(w)) of the scalar-range CI (see ``ci_range_update``): with s = H P H^T,
    C = (P - K H P) / w, K = P H^T / (s + R w / (1 - w)) (Sherman-Morrison)."""
    if w >= 1.0:
        return np.trace(P)
    PH = P @ H
    s = H @ PH
    return (np.trace(P) - (1.0 - w) * (PH @ PH) / (w * R + (1.0 - w) * s)) / w


@njit(cache=True)
def ci_range_update(x: np.ndarray, P: np.ndarray, y: float, H: np.ndarray, R: float, use_det: bool) -> float:
    """Covariance intersection of the filter (x, P) with one range whose errors are
    correlated with it in an unknown way (Julier & Uhlmann 1997), in place; returns w.

    The range is the information Y2 = H^T H / R about H x (rank 1). CI: C^-1 = w P^-1
    + (1 - w) Y2 (CI1), x <- x + C (1 - w) H^T y / R (CI2). That is the Kalman update
    of P / w with the range at R / (1 - w) (CI3): K = P H^T / (s + R w / (1 - w)),
    P <- (P - K H P) / w, s = H P H^T. omega: det(C) = 1 / det(C^-1) is minimal at
    w = 2a / (3 (a - 1)), a = s / R, when a > 3, else w = 1 (no fusion: a range
    cannot shrink the volume of an uncertainty it might share) (CI4); trace(C) by
    golden-section search on (0, 1] (CI5)."""
    PH = P @ H
    s = H @ PH
    if use_det:
        a = s / R
        w = 2.0 * a / (3.0 * (a - 1.0)) if a > 3.0 else 1.0  # (CI4)
    else:
        lo, hi = 1e-6, 1.0  # (CI5)
        c = hi - GOLDEN * (hi - lo)
        d = lo + GOLDEN * (hi - lo)
        for _ in range(60):
            if ci_trace(P, H, R, c) < ci_trace(P, H, R, d):
                hi = d
            else:
                lo = c
            c = hi - GOLDEN * (hi - lo)
            d = lo + GOLDEN * (hi - lo)
        w = 0.5 * (lo + hi)
        if ci_trace(P, H, R, 1.0) <= ci_trace(P, H, R, w):
            w = 1.0
    if w >= 1.0:
        return 1.0
    K = PH / (s + R * w / (1.0 - w))  # (CI3)
    for i in range(3):
        x[i] += K[i] * y
    Pn = (P - np.outer(K, PH)) / w
    P[:, :] = 0.5 * (Pn + Pn.T)
    return w


@njit(cache=True)
def _ci_criterion(Ai, Bi, w, use_det):
    C = np.linalg.inv(w * Ai + (1.0 - w) * Bi)
    return np.linalg.det(C) if use_det else np.trace(C)


@njit(cache=True)
def covariance_intersection(
    a: np.ndarray,
    A: np.ndarray,
    b: np.ndarray,
    B: np.ndarray,
    use_det: bool,
    out_x: np.ndarray,
    out_P: np.ndarray,
) -> float:
    """Two-estimate CI (Julier & Uhlmann 1997) of (a, A) and (b, B) (n,), (n, n), both
    full rank: C^-1 = w A^-1 + (1 - w) B^-1 (CI1), c = C (w A^-1 a + (1 - w) B^-1 b)
    (CI2); w in [0, 1] minimizing det(C) or trace(C), by golden-section search (both
    are convex in w for the information form's det, unimodal in practice for the
    trace; the end points are checked). Writes out_x, out_P; returns w."""
    Ai, Bi = np.linalg.inv(A), np.linalg.inv(B)
    lo, hi = 0.0, 1.0
    c = hi - GOLDEN * (hi - lo)
    d = lo + GOLDEN * (hi - lo)
    for _ in range(60):
        if _ci_criterion(Ai, Bi, c, use_det) < _ci_criterion(Ai, Bi, d, use_det):
            hi = d
        else:
            lo = c
        c = hi - GOLDEN * (hi - lo)
        d = lo + GOLDEN * (hi - lo)
    w = 0.5 * (lo + hi)
    for end in (0.0, 1.0):
        if _ci_criterion(Ai, Bi, end, use_det) < _ci_criterion(Ai, Bi, w, use_det):
            w = end
    C = np.linalg.inv(w * Ai + (1.0 - w) * Bi)
    out_x[:] = C @ (w * (Ai @ a) + (1.0 - w) * (Bi @ b))
    out_P[:, :] = 0.5 * (C + C.T)
    return w


# --- the beacon's Pbb in its message (2-D: 24 bits) ---------------------------------------
SIGMA_MIN_M = 0.05  # the smallest std the 8-bit log code carries; 0.05 m * 10^(255/51) = 5 km
SIGMA_CODES_PER_DECADE = 51.0
RHO_STEPS = 127.0


@njit(cache=True)
def encode_pbb(Pbb: np.ndarray) -> tuple[int, int, int]:
    """The beacon's horizontal covariance Pbb (2, 2) as three 8-bit codes (M1): sigma_e
    and sigma_n on a log scale, sigma = 0.05 m * 10^(c / 51) (0.05 m to 5 km in 4.6 %
    steps), rounded up; rho = (c - 127) / 127, rounded toward 0. Returns (c_e, c_n, c_rho)."""
    codes = np.zeros(3, dtype=np.int64)
    for i in range(2):
        s = np.sqrt(max(Pbb[i, i], 0.0))
        c = np.ceil(SIGMA_CODES_PER_DECADE * np.log10(max(s, SIGMA_MIN_M) / SIGMA_MIN_M) - 1e-9)
        codes[i] = min(max(int(c), 0), 255)
    den = np.sqrt(max(Pbb[0, 0] * Pbb[1, 1], 1e-300))
    rho = min(max(Pbb[0, 1] / den, -1.0), 1.0)
    codes[2] = 127 + int(np.trunc(rho * RHO_STEPS))  # toward 0
    return codes[0], codes[1], codes[2]


@njit(cache=True)
def decode_pbb(c_e: int, c_n: int, c_rho: int, out: np.ndarray) -> None:
    """Pbb (2, 2) from ``encode_pbb``'s codes into out, made to dominate the sent one (M2):
    with f = 10^(1/51) the std step, sigma rounded up by at most f and rho toward 0 by
    less than 1/127, the off-diagonal is off by at most
    d = sigma_e sigma_n (|rho| (f^2 - 1) + 1/127); adding d to both variances makes the
    difference diagonally dominant, hence positive semi-definite (Gershgorin)."""
    se = SIGMA_MIN_M * 10.0 ** (c_e / SIGMA_CODES_PER_DECADE)
    sn = SIGMA_MIN_M * 10.0 ** (c_n / SIGMA_CODES_PER_DECADE)
    rho = (c_rho - 127) / RHO_STEPS
    f2 = 10.0 ** (2.0 / SIGMA_CODES_PER_DECADE)
    d = se * sn * (abs(rho) * (f2 - 1.0) + 1.0 / RHO_STEPS)
    out[0, 0] = se * se + d
    out[1, 1] = sn * sn + d
    out[0, 1] = out[1, 0] = rho * se * sn
