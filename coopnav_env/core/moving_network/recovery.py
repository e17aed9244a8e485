"""Step 3 of a cycle, its last part: the filter's recovery from gate lockout, from a gated fix
over several cycles with its own covariance.

**The fixes.** Every cycle with d1, d2 and l gives the spherical fix of section V (eq. F1:
x = (d1^2 - d2^2 + l^2) / (2 l), y = sqrt(d1^2 - x^2), on the horizontal ranges) and the
baseline l; its covariance follows from the exchange's (eq. F2: Sigma = J R J^T, J the
Jacobian of (x, y, l) in the slant (d1, d2, l), R = sigma_r^2 ``EXCHANGE_COVARIANCE``), so it
is large near the baseline, where the fix degenerates. The fix is kept as the residual
r = (x, y, l) - (the filter's x, y, l) in a window of the last ``frame_restart_window_cycles``
cycles (``Filter.window_*``); every later correction of the filter is subtracted from the
stored residuals, so r_k = e - U a_k + n_k (eq. F3): e the filter's present error, U the error
of its dead-reckoned velocity per cycle (a wrong c or phi, or a frame that turns faster than
the filter lets phi move: why a filter locks out), a_k the fix's age in cycles, n_k its noise,
Sigma_k plus the filter's process noise q a_k T.

**The trigger, per range.** A counter per range (d1 to B1, d2 to B2, the baseline l) counts
the consecutive cycles in which that range arrived and was gated out. Multipath outliers
(``outlier_probability``) hit single detections, so one range failing now and then is the
channel, not a diverged filter; ``REINIT_AFTER_CYCLES`` failures in a row of the same range
are either a filter that has diverged (the gate refuses the very ranges that would correct
it; a filter whose error runs along the circle around one boat keeps passing that boat's range
while the other's is refused) or a boat whose ranges are bad.

**The decision, from the window.** The largest set of stored fixes on one line of eq. F3
(eq. F4: every pair of fixes of different ages proposes a line, the fixes within the
chi-square gate of it vote, as in RANSAC, Fischler & Bolles 1981; range outliers are caught
by the consistency of redundant measurements as in Olson, Leonard & Teller 2006), at least
``frame_restart_min_fixes``; then the generalized least squares of (e, U) on them, with the
covariance N^-1 the fixes' geometry and ages give (eq. F5; the mean of their l residuals for
l). If e is consistent with the filter (its NIS against P_xy + cov(e) within ``gate2``) the
filter holds and the failing range is distrusted: the counters restart, the gate has kept the
range out. Otherwise the filter restarts (eq. F6): (x, y) += e, (c_x, c_y) += U / T, l +=
the mean residual, with the fit's covariance, cross-covariances with phi zeroed. Too few
consistent fixes: nothing yet, the next cycles add to the window.

With the frame's motion telemetered (``frame_motion_telemetry``) the decision weighs two more
things. The filter's own hypothesis, e = 0 and U = 0, enters the contest of eq. F4: if the
filter explains as many stored fixes as the best line (eq. F4b, ``filter_consensus``) and is at
least as sharp as the fit, it holds: one multipath excess on the path m moves every fix it
spoils the same way (along d(x, y)/dl), and two such fixes made a line that restarted a filter
that was right (issue 21, river seed 11). And a filter the fit agrees with but that knows less
than the fit (det P_xy > det cov(e), eq. F4c) restarts onto the fit: a filter that has refused
ranges for cycles has a grown P that agrees with anything (seed 730044: it held for 15 cycles
and reached 20 m). Before this, the restart
took the triggering cycle's own fix, unchecked, with P = 4 sigma_r^2: with outliers on, that
cycle is the likeliest to hold one, and 19 % of the restarts landed more than 5 m off
(issue 21).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .. import lbl
from ..lbl import ExchangeResult, horizontal_range
from .filter import EXCHANGE_COVARIANCE
from .state import REINIT_AFTER_CYCLES, CycleParams, Filter

_STATES = (0, 1, 5)  # x, y, l in the filter's state E
MAX_FIX_AGE_CYCLES = 30  # a stored fix older than this is dropped [U]
# the prior on a locked-out filter's velocity error U / T (eq. F5; a line of eq. F4 proposing ten
# times it is no hypothesis) is the scenario's frame_restart_velocity_std_mps: for the paper's
# filter 0.3 m/s, the size of the boats' speed fluctuation (0.15 m/s) and a river frame's turn
# (0.35 deg/s at 60 m) [U] (0.5 let more river runs diverge, seeds 800000-800029); with the frame's
# motion telemetered (frame_motion) the velocity is known far better


@njit(cache=True)
def fix_with_covariance(ex: ExchangeResult, dz: float, sigma_r2: float, r: np.ndarray, S: np.ndarray) -> bool:
    """The cycle's fix (x, y, l) into r (3,) (eq. F1) and its covariance into S (3, 3) (eq. F2),
    from ``ex``'s slant d1, d2 and l, dz the depth below the boats, sigma_r2 a two-way range's
    variance. Returns False (r, S untouched) without l or a fix at y > 1 m."""
    if not ex.ok_l:
        return False
    d1, d2, length = horizontal_range(ex.d1, dz), horizontal_range(ex.d2, dz), ex.l
    x, y, ok = lbl.spherical_fix_of(d1, d2, length)
    if not (ok and y > 1.0 and d1 > 0.0 and d2 > 0.0):
        return False
    g1, g2 = ex.d1 / d1, ex.d2 / d2  # d(horizontal)/d(slant)
    J = np.zeros((3, 3))
    J[0, 0], J[0, 1], J[0, 2] = d1 / length * g1, -d2 / length * g2, (length - x) / length
    J[1, 0], J[1, 1] = d1 * (length - x) / (length * y) * g1, x * d2 / (length * y) * g2
    J[1, 2] = -x * (length - x) / (length * y)
    J[2, 2] = 1.0
    S[:, :] = sigma_r2 * (J @ EXCHANGE_COVARIANCE @ J.T)
    r[0], r[1], r[2] = x, y, length
    return True


@njit(cache=True)
def nis3(d: np.ndarray, S: np.ndarray) -> float:
    """d^T S^-1 d for a 3-vector and a symmetric 3 x 3 S (by cofactors); inf if S is singular."""
    c00 = S[1, 1] * S[2, 2] - S[1, 2] * S[2, 1]
    c01 = S[1, 2] * S[2, 0] - S[1, 0] * S[2, 2]
    c02 = S[1, 0] * S[2, 1] - S[1, 1] * S[2, 0]
    det = S[0, 0] * c00 + S[0, 1] * c01 + S[0, 2] * c02
    if not det > 0.0:
        return np.inf
    c11 = S[0, 0] * S[2, 2] - S[0, 2] * S[2, 0]
    c12 = S[0, 1] * S[2, 0] - S[0, 0] * S[2, 1]
    c22 = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
    q = c00 * d[0] * d[0] + c11 * d[1] * d[1] + c22 * d[2] * d[2]
    q += 2.0 * (c01 * d[0] * d[1] + c02 * d[0] * d[2] + c12 * d[1] * d[2])
    return q / det


@njit(cache=True)
def _push(f: Filter, b: int, delta: np.ndarray, r: np.ndarray, S: np.ndarray, has_fix: bool) -> None:
    """Age environment b's window by a cycle, subtract the filter's correction ``delta`` (3,)
    from the stored residuals, and store this cycle's (r, S) when ``has_fix`` (r already the
    residual), dropping the oldest."""
    age, R, C = f.window_age[b], f.window_r[b], f.window_S[b]
    W = age.shape[0]
    for k in range(W):
        if age[k] >= 0:
            age[k] += 1
            R[k, :] -= delta
            if age[k] > MAX_FIX_AGE_CYCLES:
                age[k] = -1
    if not has_fix:
        return
    for k in range(W - 1, 0, -1):
        age[k] = age[k - 1]
        R[k, :] = R[k - 1, :]
        C[k, :, :] = C[k - 1, :, :]
    age[0] = 0
    R[0, :] = r
    C[0, :, :] = S


@njit(cache=True)
def rotate_window(f: Filter, b: int, dphi_rad: float) -> None:
    """The stored (x, y) residuals of environment b turned into a frame rotated by dphi_rad
    (``frame_motion`` eq. M1 without its translation: a residual is a difference of two
    positions, so only the rotation acts on it)."""
    cs, sn = np.cos(dphi_rad), np.sin(dphi_rad)
    for k in range(f.window_age.shape[1]):
        if f.window_age[b, k] >= 0:
            a, c = f.window_r[b, k, 0], f.window_r[b, k, 1]
            f.window_r[b, k, 0], f.window_r[b, k, 1] = a * cs + c * sn, -a * sn + c * cs


@njit(cache=True)
def nis2(d0: float, d1: float, S: np.ndarray) -> float:
    """(d0, d1) S^-1 (d0, d1)^T for a symmetric 2 x 2 S; inf if S is singular."""
    det = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
    if not det > 0.0:
        return np.inf
    return (S[1, 1] * d0 * d0 - 2.0 * S[0, 1] * d0 * d1 + S[0, 0] * d1 * d1) / det


@njit(cache=True)
def _noise2(window_S: np.ndarray, window_age: np.ndarray, k: int, p: CycleParams, out: np.ndarray) -> None:
    """Fix k's (x, y) noise in eq. F3, into out (2, 2): its geometry's covariance plus the
    filter's process noise q a_k T over its age. window_S (W, 3, 3), window_age (W,): one
    environment's rows of ``Filter`` (not the record: numba counts a reference to each of
    its arrays at every call, and this runs W^3 times a restart; docs/performance.md#refcounts)."""
    q = p.frame_q_position_m2ps * window_age[k] * p.ping_interval_s
    out[0, 0], out[0, 1] = window_S[k, 0, 0] + q, window_S[k, 0, 1]
    out[1, 0], out[1, 1] = window_S[k, 1, 0], window_S[k, 1, 1] + q


@njit(cache=True)
def _inliers(
    R: np.ndarray,
    window_S: np.ndarray,
    age: np.ndarray,
    j: int,
    k: int,
    l_mid: float,
    p: CycleParams,
    inlier: np.ndarray,
) -> int:
    """Eq. F4's hypothesis: the line of eq. F3 through fixes j and k (none if its velocity error
    exceeds 10 ``frame_restart_velocity_std_mps``: a pair of outliers); which stored fixes lie
    on it (chi-square, 2 dof, gate2, against twice their noise) with an l residual within the
    1-dof gate of the window's median l_mid, into inlier (W,) bool. Returns their count (0: no
    hypothesis, or j or k off it). R (W, 3), window_S (W, 3, 3), age (W,): one environment's
    window (``Filter``'s window_r, window_S, window_age rows)."""
    if age[j] == age[k]:
        return 0
    # beyond any boat or river-frame velocity error
    u_max = 10.0 * p.frame_restart_velocity_std_mps * p.ping_interval_s * abs(age[j] - age[k])
    if (R[j, 0] - R[k, 0]) ** 2 + (R[j, 1] - R[k, 1]) ** 2 > u_max * u_max:
        return 0
    S = np.empty((2, 2))
    n = 0
    for i in range(age.shape[0]):
        inlier[i] = False
        if age[i] < 0:
            continue
        w = (age[i] - age[k]) / (age[j] - age[k])  # the line at age i, from j and k
        d0 = R[i, 0] - (R[k, 0] + w * (R[j, 0] - R[k, 0]))
        d1 = R[i, 1] - (R[k, 1] + w * (R[j, 1] - R[k, 1]))
        _noise2(window_S, age, i, p, S)
        dl = R[i, 2] - l_mid
        if nis2(d0, d1, 2.0 * S) <= p.gate2 and dl * dl <= p.gate1 * 2.0 * window_S[i, 2, 2]:
            inlier[i] = True
            n += 1
    return n if inlier[j] and inlier[k] else 0


@njit(cache=True)
def filter_consensus(f: Filter, b: int, P: np.ndarray, p: CycleParams) -> int:
    """Eq. F4b: the filter's own hypothesis in eq. F4's contest, e = 0 and U = 0 (the fixes'
    residuals are their noise): the count of stored fixes whose (x, y) residual lies within the
    2-dof gate of the fix's noise plus the filter's P_xy and whose l residual within the 1-dof
    gate of the fix's l variance plus P_ll. A line the filter matches in support is no reason to
    restart: correlated outliers (one multipath excess on the path m moves every fix it spoils
    along the same direction, d(x, y)/dl) can otherwise outvote a filter that is right."""
    S = np.empty((2, 2))
    n = 0
    window_S, window_age = f.window_S[b], f.window_age[b]
    for k in range(window_age.shape[0]):
        if window_age[k] < 0:
            continue
        _noise2(window_S, window_age, k, p, S)
        S[0, 0] += P[0, 0]
        S[0, 1] += P[0, 1]
        S[1, 0] += P[1, 0]
        S[1, 1] += P[1, 1]
        dl = f.window_r[b, k, 2]
        if nis2(f.window_r[b, k, 0], f.window_r[b, k, 1], S) <= p.gate2 and dl * dl <= p.gate1 * (
            f.window_S[b, k, 2, 2] + P[5, 5]
        ):
            n += 1
    return n


@njit(cache=True)
def _fit(f: Filter, b: int, inlier: np.ndarray, p: CycleParams, theta: np.ndarray, cov: np.ndarray) -> tuple:
    """Eq. F5: generalized least squares of the inlying fixes on r_k = e - U a_k, theta (4,) =
    (e_x, e_y, U_x, U_y) and cov (4, 4) = N^-1, N = sum A_k^T W_k A_k (W_k the inverse of the
    fix's noise) plus the prior's information on U (``frame_restart_velocity_std_mps``), in place.
    Returns (the mean l residual, its variance)."""
    age, R, window_S = f.window_age[b], f.window_r[b], f.window_S[b]
    N, rhs, S, A = np.zeros((4, 4)), np.zeros(4), np.empty((2, 2)), np.zeros((2, 4))
    u_var = (p.frame_restart_velocity_std_mps * p.ping_interval_s) ** 2
    N[2, 2], N[3, 3] = 1.0 / u_var, 1.0 / u_var  # the prior on U
    l_sum, var_l, n = 0.0, 0.0, 0
    for k in range(age.shape[0]):
        if not inlier[k]:
            continue
        _noise2(window_S, age, k, p, S)
        det = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
        Wk = np.array([[S[1, 1], -S[0, 1]], [-S[1, 0], S[0, 0]]]) / det
        A[0, 0], A[1, 1], A[0, 2], A[1, 3] = 1.0, 1.0, -float(age[k]), -float(age[k])
        AtW = A.T @ Wk
        N += AtW @ A
        rhs += AtW @ np.ascontiguousarray(R[k, :2])
        l_sum += R[k, 2]
        var_l += f.window_S[b, k, 2, 2] + p.frame_q_baseline_m2ps * age[k] * p.ping_interval_s
        n += 1
    cov[:, :] = np.linalg.inv(N)
    theta[:] = cov @ rhs
    return l_sum / n, var_l / (n * n)


@njit(cache=True)
def line_fit(f: Filter, b: int, p: CycleParams, theta: np.ndarray, cov: np.ndarray) -> tuple:
    """Eqs. F4-F5 on environment b's window: the largest set of stored fixes on one line of
    eq. F3, then its least-squares fit (``_fit``): theta (4,) = (present error e_x, e_y;
    velocity error per cycle U_x, U_y), cov (4, 4). Returns (inliers, the mean l residual, its
    variance); 0 inliers when fewer than ``frame_restart_min_fixes``, or fewer than two of them
    younger than ``REINIT_AFTER_CYCLES`` (the present error then rests on extrapolation; the
    rest then not meaningful)."""
    W = f.window_age.shape[1]
    inlier, best_set = np.zeros(W, dtype=np.bool_), np.zeros(W, dtype=np.bool_)
    ls = np.array([f.window_r[b, k, 2] for k in range(W) if f.window_age[b, k] >= 0])
    if ls.shape[0] < p.frame_restart_min_fixes:
        return 0, 0.0, 0.0
    l_mid = np.median(ls)
    best = 0
    R, window_S, age = f.window_r[b], f.window_S[b], f.window_age[b]
    for j in range(W):
        for k in range(j + 1, W):
            if age[j] < 0 or age[k] < 0:
                continue
            n = _inliers(R, window_S, age, j, k, l_mid, p, inlier)
            if n > best:
                best = n
                best_set[:] = inlier
    if best < p.frame_restart_min_fixes:
        return 0, 0.0, 0.0
    _fit(f, b, best_set, p, theta, cov)
    best = _refine(f, b, p, theta, best_set)  # each fix against the fitted line, at its own noise
    recent = 0
    for k in range(W):
        recent += best_set[k] and f.window_age[b, k] < REINIT_AFTER_CYCLES
    if best < p.frame_restart_min_fixes or recent < 2:
        return 0, 0.0, 0.0
    l_mean, var_l = _fit(f, b, best_set, p, theta, cov)
    return best, l_mean, var_l


@njit(cache=True)
def _refine(f: Filter, b: int, p: CycleParams, theta: np.ndarray, inlier: np.ndarray) -> int:
    """The fixes within the 2-dof gate of the fitted line r = e - U a (theta), at their own
    noise (the hypothesis of two fixes was tested at twice it), into inlier (W,); their count."""
    S = np.empty((2, 2))
    n = 0
    window_S, window_age = f.window_S[b], f.window_age[b]
    for i in range(inlier.shape[0]):
        a = window_age[i]
        if not inlier[i]:
            continue
        _noise2(window_S, window_age, i, p, S)
        d0 = f.window_r[b, i, 0] - (theta[0] - theta[2] * a)
        d1 = f.window_r[b, i, 1] - (theta[1] - theta[3] * a)
        inlier[i] = nis2(d0, d1, S) <= p.gate2
        n += inlier[i]
    return n


@njit(cache=True)
def _restart(E: np.ndarray, P: np.ndarray, f: Filter, b: int, theta: np.ndarray, cov: np.ndarray, T: float) -> None:
    """Eq. F6: E (6,) and P (6,6) restarted from the line fit, in place: (x, y) += e,
    (c_x, c_y) += U / T, their covariance the fit's cov (4, 4) (U scaled by 1 / T), their
    cross-covariances with phi and l zeroed (l: ``recover``); the stored residuals follow the
    move (by e - U a)."""
    idx = (0, 1, 3, 4)
    scale = (1.0, 1.0, 1.0 / T, 1.0 / T)
    for i in range(4):
        E[idx[i]] += theta[i] * scale[i]
    for i in range(6):
        for k in idx:
            P[k, i] = 0.0
            P[i, k] = 0.0
    for i in range(4):
        for k in range(4):
            P[idx[i], idx[k]] = cov[i, k] * scale[i] * scale[k]
    for k in range(f.window_age.shape[1]):
        a = f.window_age[b, k]
        if a >= 0:
            f.window_r[b, k, 0] -= theta[0] - theta[2] * a
            f.window_r[b, k, 1] -= theta[1] - theta[3] * a


@njit(cache=True)
def _restart_l(E: np.ndarray, P: np.ndarray, f: Filter, b: int, l_mean: float, var_l: float) -> None:
    """Eq. F6 for l: E[5] += the mean l residual, P's l row and column to its variance alone."""
    E[5] += l_mean
    for i in range(6):
        P[5, i] = 0.0
        P[i, 5] = 0.0
    P[5, 5] = var_l
    for k in range(f.window_age.shape[1]):
        if f.window_age[b, k] >= 0:
            f.window_r[b, k, 2] -= l_mean


@njit(cache=True)
def recover(
    E: np.ndarray,
    P: np.ndarray,
    f: Filter,
    b: int,
    status: np.ndarray,
    prior: np.ndarray,
    ex: ExchangeResult,
    dz: float,
    sigma_r2: float,
    p: CycleParams,
) -> int:
    """Filter b's window and counters after its updates (E (6,), P (6,6), ``state.Filter`` f,
    all in place), and its restart when one range has been gated out ``REINIT_AFTER_CYCLES``
    cycles in a row and the window's line fit disagrees with it (the module docstring).
    status (3, 2) bool: per range (d1, d2, l), (arrived, fused); prior (3,): the filter's
    (x, y, l) before the updates; dz the depth below the boats, sigma_r2 a two-way range's
    variance. Returns 1 if it restarted, else 0."""
    counts = f.rejected_cycles[b]
    for i in range(3):
        if status[i, 1]:
            counts[i] = 0
        elif status[i, 0]:
            counts[i] += 1
    r, S, delta = np.empty(3), np.empty((3, 3)), np.empty(3)
    for i in range(3):
        delta[i] = E[_STATES[i]] - prior[i]
    has_fix = fix_with_covariance(ex, dz, sigma_r2, r, S)
    if has_fix:
        for i in range(3):
            r[i] -= E[_STATES[i]]
    _push(f, b, delta, r, S, has_fix)
    if counts.max() < REINIT_AFTER_CYCLES:
        return 0
    theta, cov = np.empty(4), np.empty((4, 4))
    n, l_mean, var_l = line_fit(f, b, p, theta, cov)
    if n == 0:
        return 0  # too few consistent fixes yet: the next cycles add to the window
    counts[:] = 0
    # eq. F4c: does the fit know (x, y) better than the filter (a filter that has refused ranges
    # for cycles has a grown P that agrees with anything)? Eqs. F4b-F4c only with the frame's
    # motion telemetered, whose fit has a tight velocity prior; the paper's filter keeps the
    # decision of before (on the river its frame turns under it, and the sharper fit of a
    # turning frame restarted one of 50 runs off, seed 40)
    telemetry = p.frame_motion_telemetry > 0.0
    sharper = telemetry and (cov[0, 0] * cov[1, 1] - cov[0, 1] * cov[1, 0] < P[0, 0] * P[1, 1] - P[0, 1] * P[1, 0])
    if telemetry and not sharper and filter_consensus(f, b, P, p) >= n:
        return 0  # a sharp filter explains as many fixes as the best line: it holds (eq. F4b)
    Pc = np.empty((2, 2))
    for i in range(2):
        for k in range(2):
            Pc[i, k] = P[i, k] + cov[i, k]
    holds_l = l_mean * l_mean <= p.gate1 * (P[5, 5] + var_l)
    if nis2(theta[0], theta[1], Pc) <= p.gate2 and holds_l and not sharper:
        return 0  # the filter agrees with the fixes and knows (x, y) as well: the range was the channel's
    _restart(E, P, f, b, theta, cov, p.ping_interval_s)
    if not holds_l:
        _restart_l(E, P, f, b, l_mean, var_l)
    return 1
