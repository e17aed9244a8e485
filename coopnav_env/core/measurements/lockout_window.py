"""The survey filter's lock-out window: each beacon's last ranges, kept as they arrive
(``remember``), and the re-fix from them when a streak of rejected ranges locks the filter
out (``window_refix``, eqs. R1-R7 of ``core.recovery``). Called from the modem's fusion
kernel (``measurements.modem``); the window's arrays are ``ConsiderView``'s ``win_*``."""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numba import njit

from ..consider import SCHMIDT
from ..kernel_records import ConsiderView, SurveyView
from ..recovery import (
    RangeWindow,
    WindowNoise,
    window_bias_cross,
    window_consensus_fix,
    window_greedy_fix,
    window_subset,
)


class Windows(NamedTuple):
    """``ConsiderView``'s lock-out windows (win_*) alone: what ``remember`` writes."""

    z: np.ndarray
    dz: np.ndarray
    t: np.ndarray
    beacon: np.ndarray
    dr: np.ndarray
    n: np.ndarray


@njit(cache=True, inline="always")
def remember(
    win: Windows,
    b: int,
    s: int,
    j: int,
    r: float,
    beacon: np.ndarray,
    depth: float,
    dr: np.ndarray,
    vel_est: np.ndarray,
    delays: np.ndarray,
    t_s: float,
) -> None:
    """Beacon j's finite range r at survey s enters its lock-out window (oldest first,
    the oldest dropped when full), with the beacon's reported position, the survey's
    dead-reckoned position where the sound ended (dr + vel_est d, as ``range_prediction``),
    the depths' difference (the survey's estimated ``depth``) and the time: eqs. R1's
    inputs. win: ``Windows``."""
    M = win.z.shape[3]
    k = win.n[b, s, j]
    if k == M:
        for i in range(M - 1):
            win.z[b, s, j, i] = win.z[b, s, j, i + 1]
            win.dz[b, s, j, i] = win.dz[b, s, j, i + 1]
            win.t[b, s, j, i] = win.t[b, s, j, i + 1]
            for a in range(2):
                win.beacon[b, s, j, i, a] = win.beacon[b, s, j, i + 1, a]
                win.dr[b, s, j, i, a] = win.dr[b, s, j, i + 1, a]
        k = M - 1
    d = 0.0
    for leg in range(delays.shape[1]):  # the survey's times: row 0 (moving_range_prediction)
        d += delays[0, leg] / delays.shape[1]
    win.z[b, s, j, k] = r
    win.dz[b, s, j, k] = depth - beacon[2]
    win.t[b, s, j, k] = t_s
    for a in range(2):
        win.beacon[b, s, j, k, a] = beacon[a]
        win.dr[b, s, j, k, a] = dr[a] + vel_est[a] * d
    win.n[b, s, j] = k + 1


@njit(cache=True)
def window_of(cv: ConsiderView, sv: SurveyView, b: int, s: int, j: int, keep: np.ndarray, t_s: float) -> RangeWindow:
    """Beacon j's window entries ``keep`` (indices, oldest first) as a ``RangeWindow`` at
    time t_s: the filter's own motion since each ping is its dead reckoning plus the
    current it was told."""
    m = keep.shape[0]
    shift, age = np.empty((m, 2)), np.empty(m)
    z, beacon, dz = np.empty(m), np.empty((m, 2)), np.empty(m)
    cur = (sv.current_est[b, s].real, sv.current_est[b, s].imag)
    for k in range(m):
        i = keep[k]
        age[k] = t_s - cv.win_t[b, s, j, i]
        z[k], dz[k] = cv.win_z[b, s, j, i], cv.win_dz[b, s, j, i]
        for a in range(2):
            beacon[k, a] = cv.win_beacon[b, s, j, i, a]
            shift[k, a] = sv.dr[b, s, a] - cv.win_dr[b, s, j, i, a] + cur[a] * age[k]
    return RangeWindow(z, beacon, shift, dz, age)


@njit(cache=True)
def window_refix(
    sv: SurveyView, cv: ConsiderView, prm: Any, b: int, s: int, j: int, R: float, Pbb: np.ndarray, t_s: float
) -> bool:
    """Lock-out recovery from beacon j's last ranges (``recovery.window_greedy_fix``, eqs.
    R1-R5, R6'; with ``lockout_recovery="window_consensus"``, ``window_consensus_fix``, R7):
    the horizontal position and covariance re-fixed in place, the depth kept without cross
    terms, every cross-covariance zeroed but the fix's own with beacon j (with
    ``"schmidt"``). The window holds rejected ranges too, multipath among them: a fix
    whose residuals fail their chi-square test (99 %, m - 2 dof) keeps fewer. Returns
    False (nothing changed) when no fix of at least 3 ranges passes. prm:
    ``measurements.modem.ModemParams``; Pbb (2, 2): the beacon's covariance now, taken as the
    window's shared bias."""
    n = cv.win_n[b, s, j]
    m = min(n, prm.window_m)
    if m < 3:
        return False
    noise = WindowNoise(
        R,
        Pbb.copy(),
        prm.dr_rate_m2ps,
        prm.prior_std_m,
        prm.dr_scale_std,
        prm.dr_heading_std_rad,
        prm.dr_current_std_mps,
    )
    x, P, Pxb, keep = np.empty(2), np.empty((2, 2)), np.empty((2, 2)), np.empty(m, np.int64)
    win = window_of(cv, sv, b, s, j, np.arange(n - m, n), t_s)
    x0, P0 = sv.est[b, s, :2].copy(), sv.P[b, s, :2, :2].copy()
    # the record holds tuples: an array in it would be reference-counted at every call (docs/performance.md#refcounts)
    chi2_by_dof = np.array(prm.window_chi2_consensus if prm.window_consensus else prm.window_chi2)
    if prm.window_consensus:
        eps, mu = prm.outlier_probability, prm.outlier_mean_excess_m
        n_kept = window_consensus_fix(win, m, noise, x0, P0, chi2_by_dof, eps, mu, x, P, Pxb, keep)
    else:
        n_kept = window_greedy_fix(win, m, noise, x0, P0, chi2_by_dof, x, P, Pxb, keep)
    if n_kept < 3:
        return False
    cv.Pxb[b, s] = 0.0  # the old estimate is discarded: so are its correlations
    cv.Pxd[b, s] = 0.0
    if prm.bias_consider:  # (R6, D4)
        window_bias_cross(x, window_subset(win, keep[:n_kept]), n_kept, noise, P, cv.Pxd[b, s, :2])
    for i in range(2):
        sv.est[b, s, i] = x[i]
        sv.P[b, s, i, 2] = sv.P[b, s, 2, i] = 0.0
        for a in range(2):
            sv.P[b, s, i, a] = P[i, a]
            if prm.fusion == SCHMIDT:
                cv.Pxb[b, s, j, i, a] = Pxb[i, a]
    return True
