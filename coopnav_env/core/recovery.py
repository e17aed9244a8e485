"""Lock-out recovery from a short window of ranges (issue 21: 'the lock-out recovery
is a single Gaussian at the nearest point of the range circle').

A survey filter whose gate has rejected N ranges in a row has drifted further than
its covariance admits. ``navigation.reinit_on_range`` restarts it from one range,
at the nearest point of the range circle: one range fixes the distance to the
beacon, not the bearing, and the restart keeps the old (wrong) bearing with an
across-range variance of the old one plus the miss squared. This module re-fixes
the horizontal position from the last M (3-6) ranges of the window instead, the
beacon moving between them and the survey's dead-reckoned displacements carrying
each range to the fix time: a weighted (generalized) least-squares fix, with its
covariance from the Jacobian.

Why this and not a Gaussian sum over the range annulus: with ranges from more than
one beacon position the bearing is observable, the fix is a deterministic function
of the window (testable against a reference, no component count or pruning to tune),
and the covariance says how good the geometry was; a Gaussian sum on one range
stays a ring (or a two-lobed crescent) until later ranges cut it, i.e. needs the
same window anyway, and its collapse by moment matching is a broad Gaussian centred
inside the annulus, where the vehicle is not.

Model, for ping k of the window (k = 0 .. M-1), the fix at the time of the last:
    (R1) z_k = sqrt(|x - s_k - (c_k + b)|^2 + dz_k^2) + n_k,
         x the horizontal position at the fix time, s_k the survey's dead-reckoned
         displacement from ping k to the fix time (error e_k, random walk: E[e_i e_j^T]
         = q min(age_i, age_j) I), c_k the beacon's reported horizontal position, b its
         position error (a bias shared by the window, covariance Pbb), dz_k the depth
         difference (pressure sensors), n_k ~ N(0, R).
    (R2) J_k = u_k^T = (x - s_k - c_k)^T / z_hat_k, the horizontal Jacobian of (R1);
         the errors of the residuals r_k = z_k - z_hat_k:
         Sigma_ij = R delta_ij + u_i^T Pbb u_j + q min(age_i, age_j) u_i^T u_j.
   (R2') the dead reckoning's systematic errors (a speed-scale error k and a compass bias
         beta, shared by every shift: e_k = (k I + beta J) s_k, J the 90-degree rotation) add
         sigma_k^2 (u_i^T s_i)(u_j^T s_j) + sigma_beta^2 (u_i^T J s_i)(u_j^T J s_j); the told
         current's error c (``dr_bias.py``, eq. D1'), shared too (e_k = age_k c), adds
         sigma_c^2 age_i age_j u_i^T u_j.
    (R3) prior: the locked-out estimate x0 with P0 inflated by s_lock^2 I, s_lock =
         max(prior_std_m, max_k |r_k(x0)|) (the filter has shown it is off by at least
         its largest miss); it only picks the branch (the mirror image of the fix across
         a straight beacon track fits the ranges as well) and regularizes a poor geometry.
    (R4) Gauss-Newton on r^T Sigma^-1 r + (x - x0)^T Pp^-1 (x - x0):
         (J^T Sigma^-1 J + Pp^-1) dx = J^T Sigma^-1 r - Pp^-1 (x - x0).
    (R5) covariance P = (J^T Sigma^-1 J + Pp^-1)^-1 (the Gauss-Newton / information form
         of the weighted least-squares covariance, e.g. Bar-Shalom, Li & Kirubarajan
         2001); the cross-covariance with the beacon's error (for ``consider.py``):
         Pxb = P J^T Sigma^-1 J Pbb (the estimate's error is x - x_hat = -P J^T Sigma^-1
         (noise), and the noise's part from b is -U b, U = J).
    (R6) the cross-covariance with the survey's own dead-reckoning biases phi = (k, beta,
         c_e, c_n) (``dr_bias.py``; the true shift is s_k + G_k phi, G_k = [s_k, J s_k,
         age_k I], eqs. D1, D1'): the residuals' part from phi is -Uf phi,
         Uf_k = (u_k^T s_k, u_k^T J s_k, age_k u_k^T), so
         Pxd = E[(x - x_hat) phi^T] = P J^T Sigma^-1 Uf Pff (the prior's share, through
         P Pp^-1 <= P / s_lock^2, left out; s_k includes the told current's drift, which the
         biases do not scale, as R2' does: an overstatement where a beacon sends a current).
    (R6') which ranges, by the parameter's default (``window_greedy_fix``; no modem scenario's since 2026-12-05):
         the window holds the rejected ranges that caused the lock-out, multipath among them;
         a fix whose residuals fail their chi-square test (99 %, m - 2 dof) drops its worst
         range (largest |r_k| / sqrt(Sigma_kk)) and is redone, down to 3 ranges.
    (R7) which ranges, with ``lockout_recovery="window_consensus"`` (``window_consensus_fix``):
         a lock-out is set off by a drift or by a streak of multipath ranges, and which
         ranges of the window to drop is a labelling L (each range direct or a longer path).
         Its negative log posterior, by the Laplace approximation of the fix x_K from the
         kept ranges K (R1-R5) and with the channel's own outlier model (``multipath.py``,
         a fraction eps of the ranges too long by Exp(mu)):
             score_L = r_K^T Sigma_K^-1 r_K + log det (2 pi Sigma_K)    (the direct ranges)
                     + (x_K - x0)^T Pp^-1 (x_K - x0) - log det P_K      (the prior R3, the fix's volume)
                     - 2 sum_{k dropped} log g1(r_k(x_K); Sigma_kk)      (eq. M1: longer paths)
                     - 2 |D| log eps - 2 |K| log(1 - eps)                (the labels' prior)
         (constants common to all L left out; a dropped range's residual taken alone, its
         correlation with the kept ones ignored); Pp the prior of R3 at the whole window's
         largest miss.
   (R7') the prior term is the mixture of a lock-out's two causes (``lockout_prior_term``):
         -2 log(pi N(x_K; x0, P0) + (1 - pi) N(x_K; x0, Pp)), pi = ``LOCKOUT_STREAK_PRIOR``:
         either the filter was right and the window holds a streak it did not cause (its
         own covariance P0 holds), or it drifted (R3). With Pp alone a streak of long
         multipath ranges inflates the prior to the streak's miss, and a far fix that keeps
         one more of them costs less than a third longer path (``gao_lawnmower`` seed 950040
         under ``ellipse`` with ``range_model="filter"``: 100 m off, where the filter had
         been 7 m off three cycles before). The fix is the best-scoring L with at least 3 ranges kept whose residuals
         pass their chi-square test at 99.9 % (the test only guards against a model that fits
         nothing); each labelling's fix started at x0 and again at the first pass's best fix
         (from a start far off, Gauss-Newton can settle on the wrong branch of a ring).
         After a multipath streak R6' can drop the direct ranges as too short
         (gao_lawnmower seed 950040: 48 m off), and a rule that drops long ranges only kept a
         spurious ring fit where the oldest ranges were short from the dead reckoning
         (sousa_asv seed 900063: 39 m off); R7 is right on both recorded windows
         (tests/test_window_consensus.py). It is the gao scenarios' default (scenarios/gao.py),
         not the Sousa ones': over held-out blocks it is better on some and worse on one
         (docs/scenarios/consider-fusion.md#consensus).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from .multipath import longer_path_log_likelihood


class RangeWindow(NamedTuple):
    """The last M ranges of one survey filter, oldest first (arrays of length >= M)."""

    z: np.ndarray  # (M,) measured ranges, m
    beacon: np.ndarray  # (M, 2) the beacon's reported horizontal position at each ping, m
    shift: np.ndarray  # (M, 2) dead-reckoned survey displacement from ping k to the fix time, m
    dz: np.ndarray  # (M,) survey depth minus beacon depth, m
    age_s: np.ndarray  # (M,) time from ping k to the fix time, s


class WindowNoise(NamedTuple):
    """What the fix weighs the ranges with."""

    range_var_m2: float  # R: ranging noise (sound speed's share included), m^2
    Pbb: np.ndarray  # (2, 2) the beacon's horizontal position error covariance (a bias over the window), m^2
    dr_rate_m2ps: float  # q: the survey's dead-reckoning variance growth per axis, m^2/s
    prior_std_m: float  # floor of the lock-out prior's inflation s_lock, m
    scale_std: float = 0.0  # the survey's speed-scale error std: a shared error k s_k of the shifts (R2')
    heading_std_rad: float = 0.0  # its compass bias std: a shared error beta J s_k of the shifts (R2')
    current_std_mps: float = 0.0  # the told current's error std per axis: a shared error age_k c (R2')


@njit(cache=True)
def window_terms(
    x: np.ndarray, win: RangeWindow, m: int, noise: WindowNoise, J: np.ndarray, r: np.ndarray, Sigma: np.ndarray
) -> None:
    """(R1)-(R2) at the horizontal position x (2,): J (m, 2), residuals r (m,) and their
    covariance Sigma (m, m), written in place."""
    q = noise.dr_rate_m2ps
    for k in range(m):
        ex = x[0] - win.shift[k, 0] - win.beacon[k, 0]
        ey = x[1] - win.shift[k, 1] - win.beacon[k, 1]
        zh = np.sqrt(ex * ex + ey * ey + win.dz[k] * win.dz[k])
        inv = 1.0 / max(zh, 1e-9)
        J[k, 0], J[k, 1] = ex * inv, ey * inv
        r[k] = win.z[k] - zh
    for i in range(m):
        for j in range(m):
            uu = J[i, 0] * J[j, 0] + J[i, 1] * J[j, 1]
            ubu = J[i, 0] * (noise.Pbb[0, 0] * J[j, 0] + noise.Pbb[0, 1] * J[j, 1]) + J[i, 1] * (
                noise.Pbb[1, 0] * J[j, 0] + noise.Pbb[1, 1] * J[j, 1]
            )
            Sigma[i, j] = ubu + q * min(win.age_s[i], win.age_s[j]) * uu
            if noise.scale_std > 0.0 or noise.heading_std_rad > 0.0:  # (R2')
                us_i = J[i, 0] * win.shift[i, 0] + J[i, 1] * win.shift[i, 1]
                us_j = J[j, 0] * win.shift[j, 0] + J[j, 1] * win.shift[j, 1]
                ujs_i = J[i, 1] * win.shift[i, 0] - J[i, 0] * win.shift[i, 1]
                ujs_j = J[j, 1] * win.shift[j, 0] - J[j, 0] * win.shift[j, 1]
                Sigma[i, j] += noise.scale_std**2 * us_i * us_j + noise.heading_std_rad**2 * ujs_i * ujs_j
            if noise.current_std_mps > 0.0:  # (R2'): the told current's error over each ping's age
                Sigma[i, j] += noise.current_std_mps**2 * win.age_s[i] * win.age_s[j] * uu
        Sigma[i, i] += noise.range_var_m2


@njit(cache=True)
def lockout_prior(win: RangeWindow, m: int, noise: WindowNoise, x0: np.ndarray, P0: np.ndarray) -> np.ndarray:
    """Eq. (R3): the prior's covariance P0 + s_lock^2 I, s_lock = max(prior_std_m, the
    window's largest miss |r_k(x0)|)."""
    J, r, Sig = np.empty((m, 2)), np.empty(m), np.empty((m, m))
    window_terms(x0, win, m, noise, J, r, Sig)
    s_lock = noise.prior_std_m
    for k in range(m):
        s_lock = max(s_lock, abs(r[k]))
    Pp = P0.copy()
    Pp[0, 0] += s_lock * s_lock
    Pp[1, 1] += s_lock * s_lock
    return Pp


@njit(cache=True)
def _finite(x: np.ndarray, P: np.ndarray) -> bool:
    """A fix and its covariance's diagonal are finite."""
    return bool(np.isfinite(x[0]) and np.isfinite(x[1]) and np.isfinite(P[0, 0]) and np.isfinite(P[1, 1]))


@njit(cache=True)
def _mask_indices(mask: int, m: int) -> np.ndarray:
    """The indices k < m whose bit is set in ``mask``, ascending."""
    n = 0
    for k in range(m):
        n += (mask >> k) & 1
    keep = np.empty(n, np.int64)
    i = 0
    for k in range(m):
        if (mask >> k) & 1:
            keep[i] = k
            i += 1
    return keep


@njit(cache=True)
def window_fix(
    win: RangeWindow,
    m: int,
    noise: WindowNoise,
    x0: np.ndarray,
    P0: np.ndarray,
    out_x: np.ndarray,
    out_P: np.ndarray,
    out_Pxb: np.ndarray,
) -> int:
    """Re-fix the horizontal position from the last m ranges (eqs. R1-R5), starting from
    the locked-out estimate x0 (2,) with covariance P0 (2, 2). Writes the fix out_x (2,),
    its covariance out_P (2, 2) and its cross-covariance with the beacon's error out_Pxb
    (2, 2) (for the consider states; zero it when the beacon's Pbb is folded into R).
    Returns the number of Gauss-Newton iterations (< 0: did not converge in 30)."""
    return window_fix_from(win, m, noise, x0, P0, x0, out_x, out_P, out_Pxb)


@njit(cache=True)
def window_fix_from(
    win: RangeWindow,
    m: int,
    noise: WindowNoise,
    x0: np.ndarray,
    P0: np.ndarray,
    x_start: np.ndarray,
    out_x: np.ndarray,
    out_P: np.ndarray,
    out_Pxb: np.ndarray,
) -> int:
    """``window_fix`` with Gauss-Newton started at x_start (2,); the prior (R3) stays the
    locked-out estimate x0 with P0 inflated (a second start finds the other branch of a
    ring that one start misses)."""
    J, r, Sig = np.empty((m, 2)), np.empty(m), np.empty((m, m))
    Ppi = np.linalg.inv(lockout_prior(win, m, noise, x0, P0))
    x = x_start.copy()
    it = -30
    for i in range(30):  # (R4)
        window_terms(x, win, m, noise, J, r, Sig)
        SiJ = np.linalg.solve(Sig, J)
        A = J.T @ SiJ + Ppi
        g = SiJ.T @ r - Ppi @ (x - x0)
        dx = np.linalg.solve(A, g)
        x += dx
        if dx[0] * dx[0] + dx[1] * dx[1] < 1e-12:
            it = i + 1
            break
    window_terms(x, win, m, noise, J, r, Sig)
    SiJ = np.linalg.solve(Sig, J)
    P = np.linalg.inv(J.T @ SiJ + Ppi)  # (R5)
    out_x[:] = x
    out_P[:, :] = 0.5 * (P + P.T)
    out_Pxb[:, :] = P @ (J.T @ SiJ) @ noise.Pbb
    return it


@njit(cache=True)
def window_bias_cross(
    x: np.ndarray, win: RangeWindow, m: int, noise: WindowNoise, P: np.ndarray, out: np.ndarray
) -> None:
    """Eq. (R6): the cross-covariance (2, 4) of the fix x (2,) with covariance P (2, 2)
    (``window_fix``'s outputs) with the survey's dead-reckoning biases (k, beta, c_e, c_n),
    of variances noise.scale_std^2, noise.heading_std_rad^2 and noise.current_std_mps^2
    (twice), written into out (2, 4)."""
    J, r, Sig = np.empty((m, 2)), np.empty(m), np.empty((m, m))
    window_terms(x, win, m, noise, J, r, Sig)
    Uf = np.empty((m, 4))
    for k in range(m):
        sx, sy = win.shift[k, 0], win.shift[k, 1]
        Uf[k, 0] = (J[k, 0] * sx + J[k, 1] * sy) * noise.scale_std**2
        Uf[k, 1] = (J[k, 1] * sx - J[k, 0] * sy) * noise.heading_std_rad**2  # u^T J s, J s = (-s_y, s_x)
        Uf[k, 2] = win.age_s[k] * J[k, 0] * noise.current_std_mps**2  # age_k u_k^T, eq. (D1')
        Uf[k, 3] = win.age_s[k] * J[k, 1] * noise.current_std_mps**2
    out[:, :] = P @ (J.T @ np.linalg.solve(Sig, Uf))


@njit(cache=True)
def window_subset(win: RangeWindow, keep: np.ndarray) -> RangeWindow:
    """The entries ``keep`` (indices, oldest first) of the window ``win``."""
    m = keep.shape[0]
    z, beacon, shift, dz, age = np.empty(m), np.empty((m, 2)), np.empty((m, 2)), np.empty(m), np.empty(m)
    for k in range(m):
        i = keep[k]
        z[k], dz[k], age[k] = win.z[i], win.dz[i], win.age_s[i]
        for a in range(2):
            beacon[k, a], shift[k, a] = win.beacon[i, a], win.shift[i, a]
    return RangeWindow(z, beacon, shift, dz, age)


class LabelModel(NamedTuple):
    """What eq. (R7) scores a labelling of the window against."""

    x0: np.ndarray  # (2,) the locked-out estimate
    P0: np.ndarray  # (2, 2) its covariance
    Pp: np.ndarray  # (2, 2) the prior R3 at the whole window's largest miss
    chi2_by_dof: np.ndarray  # the guard's chi-square points by dof |K| - 2
    eps: float  # outlier_probability
    mu: float  # outlier_mean_excess_m


LOCKOUT_STREAK_PRIOR = 0.5  # (R7'): prior probability that a lock-out is a streak the filter did not cause [U]


@njit(cache=True)
def lockout_prior_term(d: np.ndarray, P0: np.ndarray, Pp: np.ndarray, pi: float) -> float:
    """Eq. (R7'): -2 log of the fix's prior density at d = x - x0 (the 2 pi constant left
    out), a mixture of the two causes of a lock-out: with probability ``pi`` the filter was
    right and the window holds a streak of longer paths, so x ~ N(x0, P0), its own
    covariance; else it drifted, x ~ N(x0, Pp), Pp the prior R3 at the window's largest
    miss. By log-sum-exp."""
    a = d @ np.linalg.solve(P0, d) + np.linalg.slogdet(P0)[1]
    b = d @ np.linalg.solve(Pp, d) + np.linalg.slogdet(Pp)[1]
    lo = min(a, b)
    return lo - 2.0 * np.log(pi * np.exp(-0.5 * (a - lo)) + (1.0 - pi) * np.exp(-0.5 * (b - lo)))


@njit(cache=True)
def _labelling_score(win, m, noise, lm, mask, x_start, x, P, Pxb) -> float:
    """Eq. (R7)'s score_L of the labelling ``mask`` (bit k set: range k kept as direct) under
    ``lm`` (``LabelModel``), its fix started at x_start written into x, P, Pxb; inf when
    fewer than 3 are kept, the fix is not finite or its residuals fail the guard."""
    x0, P0, Pp, chi2_by_dof, eps, mu = lm
    keep = _mask_indices(mask, m)
    size = keep.shape[0]
    if size < 3:
        return np.inf
    sub = window_subset(win, keep)
    window_fix_from(sub, size, noise, x0, P0, x_start, x, P, Pxb)
    if not _finite(x, P):
        return np.inf
    J, r, Sig = np.empty((size, 2)), np.empty(size), np.empty((size, size))
    window_terms(x, sub, size, noise, J, r, Sig)
    c2 = r @ np.linalg.solve(Sig, r)
    if c2 > chi2_by_dof[size - 2]:
        return np.inf
    d = x - x0
    score = (
        c2
        + np.linalg.slogdet(Sig)[1]
        + size * np.log(2.0 * np.pi)
        + lockout_prior_term(d, P0, Pp, LOCKOUT_STREAK_PRIOR)
    )
    score += -np.linalg.slogdet(P)[1] - 2.0 * size * np.log(1.0 - eps)
    if size < m:
        Jm, rm, Sm = np.empty((m, 2)), np.empty(m), np.empty((m, m))
        window_terms(x, win, m, noise, Jm, rm, Sm)  # the dropped ranges' residuals at this fix
        for k in range(m):
            if not (mask >> k) & 1:
                score -= 2.0 * (longer_path_log_likelihood(rm[k], Sm[k, k], mu) + np.log(eps))
    return score


@njit(cache=True)
def window_consensus_fix(
    win: RangeWindow,
    m: int,
    noise: WindowNoise,
    x0: np.ndarray,
    P0: np.ndarray,
    chi2_by_dof: np.ndarray,
    outlier_probability: float,
    outlier_mean_excess_m: float,
    out_x: np.ndarray,
    out_P: np.ndarray,
    out_Pxb: np.ndarray,
    out_keep: np.ndarray,
) -> int:
    """Eq. (R7): of the labellings of the window's m ranges with at least 3 kept whose
    residuals pass chi2_by_dof[|K| - 2], the one of smallest score_L; ``window_fix`` (R1-R5)
    on its kept ranges, started at x0 and again at the best fix of that first pass (each
    labelling keeps its better start). With no multipath model (outlier_probability or the
    mean excess 0) nothing may be dropped. Writes the fix as ``window_fix`` and the kept
    indices (oldest first) into out_keep[:n]; returns n (0: no labelling passes; the outputs
    are then unspecified)."""
    Pp = lockout_prior(win, m, noise, x0, P0)  # (R3) at the whole window's largest miss: one for every labelling
    eps, mu = outlier_probability, outlier_mean_excess_m
    lm = LabelModel(x0, P0, Pp, chi2_by_dof, eps, mu)
    first = (1 << m) - 1 if not (0.0 < eps < 1.0 and mu > 0.0) else 1  # no model: the whole window only
    x, P, Pxb = np.empty(2), np.empty((2, 2)), np.empty((2, 2))
    best, best_mask = np.inf, 0
    starts = np.empty((2, 2))
    starts[0] = x0
    for pass_ in range(2):
        if pass_ == 1:
            if best == np.inf:
                break
            starts[1] = out_x
        for mask in range(first, 1 << m):
            score = _labelling_score(win, m, noise, lm, mask, starts[pass_], x, P, Pxb)
            if score < best:
                best, best_mask = score, mask
                out_x[:] = x
                out_P[:, :] = P
                out_Pxb[:, :] = Pxb
    keep = _mask_indices(best_mask, m)
    out_keep[: keep.shape[0]] = keep
    return keep.shape[0]


@njit(cache=True)
def window_greedy_fix(
    win: RangeWindow,
    m: int,
    noise: WindowNoise,
    x0: np.ndarray,
    P0: np.ndarray,
    chi2_by_dof: np.ndarray,
    out_x: np.ndarray,
    out_P: np.ndarray,
    out_Pxb: np.ndarray,
    out_keep: np.ndarray,
) -> int:
    """Eq. (R6'): ``window_fix`` (R1-R5) on the window's m ranges; while its residuals fail
    chi2_by_dof[|K| - 2], the worst range (largest |r_k| / sqrt(Sigma_kk)) is dropped and the
    fix redone. Outputs as ``window_consensus_fix``; returns the number kept (0: fewer than 3
    left, or a fix that is not finite)."""
    keep = np.arange(m)
    while keep.shape[0] >= 3:
        mk = keep.shape[0]
        sub = window_subset(win, keep)
        window_fix(sub, mk, noise, x0, P0, out_x, out_P, out_Pxb)
        if not _finite(out_x, out_P):
            return 0
        J, r, Sig = np.empty((mk, 2)), np.empty(mk), np.empty((mk, mk))
        window_terms(out_x, sub, mk, noise, J, r, Sig)
        if r @ np.linalg.solve(Sig, r) <= chi2_by_dof[mk - 2]:
            out_keep[:mk] = keep
            return mk
        worst, k_worst = -1.0, 0
        for k in range(mk):
            if abs(r[k]) / np.sqrt(Sig[k, k]) > worst:
                worst, k_worst = abs(r[k]) / np.sqrt(Sig[k, k]), k
        keep = np.concatenate((keep[:k_worst], keep[k_worst + 1 :]))
    return 0
