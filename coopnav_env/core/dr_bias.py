"""The survey vehicle's own dead-reckoning biases as consider states (issue 21: sousa_asv's
99.9 % NEES exceedances).

The survey vehicle dead-reckons with a speed model whose scale is off by this
episode's error k (``survey_speed_scale_error_std``) and a compass whose bias beta
(``compass_bias_std_deg``) is constant over the episode (``core.substeps``): both are
shared by every cycle's displacement. The EKF's process noise Q (Gao & Chitre eq. 6)
is white: it grows P linearly in time, while a constant velocity error grows the
error linearly in time and its variance with the square. With one beacon the ranges
correct only the line-of-sight component, and across it the error outruns P: on
``sousa_asv`` (100 runs, tuning seeds 710000) 242 run-cycles (10x nominal) exceeded the
99.9 % NEES point, 79 of them in the run with k = -0.18, and with k and beta set to 0
3 (0.1x); the exceedance count per run correlates with |k| (r = 0.61).

The filter cannot afford to estimate k and beta from ranges to one moving beacon (a
three-state filter is what the papers and the beacons' messages assume), but it can
know they exist: they are consider parameters (Schmidt 1966; the same treatment as the
beacons' errors in ``consider.py``). phi = (k, beta), zero mean, covariance
Pff = diag(sigma_k^2, sigma_beta^2), never updated. The survey carries Pxd = E[e phi^T]
(3, 4) (the told current's two columns below), e = x - x_hat its error (true minus estimate, as in ``consider.py``).

    (D1) a cycle's true horizontal displacement is the dead-reckoned one D (2,) scaled and
         rotated: d = (1 + k) R(beta) D ~ D + G phi,  G = [D, J D] (2, 2) (3 x 2 with a zero
         depth row), J the 90-degree counter-clockwise rotation (the compass reads the
         bearing plus beta: ``substeps._advance_vehicle``)
    (D2) so the error propagates as e' = e + G phi + w (w: Q's white part), and the predict
         of the pair (e, phi) (phi constant) is
             P'   = P + G Pxd^T + Pxd G^T + G Pff G^T + Q
             Pxd' = Pxd + G Pff
    (D3) any update of x with gain K and row H, the measurement not a function of phi
         (ranges, depth, GPS): Pxd <- (I - K H) Pxd (eq. C6 of ``consider.py``; the Joseph
         update of P is unchanged, the Schmidt gain on phi is 0)
    (D4) a restart that discards the estimate (lock-out): Pxd from the new fix's own
         dependence on phi (``recovery.window_bias_cross``, eq. R6), or 0 after the
         nearest-point restart

The told current's error (issue 21, round 3: gao_lawnmower's 99.9 % exceedances). A
survey vehicle that dead-reckons through the water adds the current a DVL beacon sends
it (Gao & Chitre II-A); the beacon's estimate is off by an episode constant
(``beacon_current_estimate_error_mps`` per axis, ``SimState.b_current_err``), which the
survey's track integrates as a velocity error: the same linear growth, not a random
walk. On gao_lawnmower (100 runs each, tuning seeds 710000 and 730000) the runs with
clustered exceedances were the tail draws of it (seed 730035: 0.21 m/s, the second
largest of 1000, the north error growing 3.5 m a 20-s cycle), and with the error set
to 0 the exceedances fell from 1.6x and 1.8x to 0.5x and 0.0x. So phi gains the told
current's error c = (c_e, c_n), true current minus told, Pff's last two entries
sigma_c^2 each (``considered_biases``), and

    (D1') G = [D, J D, dt e_x, dt e_y] (3, 4): over a cycle of dt seconds the error is
          dt c (the cycle's dead reckoning added the told current for all of it)

D2-D4 and R6 are unchanged in form (R6's Uf_k gains age_k u_k for the current; R2'
adds sigma_c^2 age_i age_j u_i^T u_j to the window's Sigma). The current's slowly
varying Gauss-Markov part is in what the beacon measures and sends, so it is not an
error of the told current; before the first ping that carries a current the survey
adds none, an error this model leaves out (the first 20-s cycle).

The untold current (issue 23's shift ``current_0.5`` on the Sousa scenarios: every planner
lost the survey vehicle, 16-26 m against 1.4 m). A survey vehicle that no beacon AUV tells a
current (an ASV beacon, or ``survey_uses_beacon_current=False``) adds none, and its whole
current is the error c; its filter, whose Q stands for white noise only (0.001 m^2/s on
sousa_asv), then holds a 0.5 m/s drift as 2.5 m of unexplained motion every 5-s cycle and
gates out the ranges that would correct it. So c enters phi the same way, with

    (D1'') sigma_c^2 = (s^2 + s_spread^2 / 3) / 2 per axis: the second moment of the episode's
           mean current per axis (a speed drawn uniformly in s +- s_spread, in a direction
           unknown to the vehicle, split between two axes), 0 without one. The Gauss-Markov
           part is not an episode constant (with tau of seconds it is white from cycle to
           cycle) and stays with Q, as before

(``untold_current_std_mps``). A zero-mean consider state of that second moment is right on
average over directions even when the scenario's direction is fixed (c = (0.5, 0) m/s is
Mahalanobis^2 2 against sigma_c^2 = 0.125 per axis). The scenarios' defaults have no untold
current, so their filters are unchanged.

With every sigma = 0 this is the old filter. D is the change of the dead-reckoning-only
track over the cycle (``SimState.s_dr``), which is what k and beta act on (the current
the survey is told is not scaled by them: an overstatement of their share, small where
the current is small against the vehicle's speed).
"""

from __future__ import annotations

from typing import Any

import numpy as np

N_BIASES = 4  # phi = (k, beta, c_e, c_n): the columns of SimState.s_Pxd


def told_current(c: Any) -> bool:
    """Whether the survey vehicles of scenario config ``c`` add a current a beacon tells them:
    ``survey_uses_beacon_current`` and a DVL beacon AUV there to send it (Gao II-A)."""
    return bool(c.survey_uses_beacon_current and any(k == "beacon_auv" for k in c.beacon_kinds))


def told_current_std_mps(c: Any) -> float:
    """sigma_c of scenario config ``c``: the per-axis error of the current a DVL beacon
    AUV sends (``beacon_current_estimate_error_mps``) when the survey adds it
    (``told_current``), else 0."""
    return float(c.beacon_current_estimate_error_mps) if told_current(c) else 0.0


def untold_current_std_mps(c: Any) -> float:
    """Eq. (D1''): the per-axis RMS of scenario config ``c``'s mean current, sqrt((s^2 +
    s_spread^2 / 3) / 2), for a survey vehicle that no beacon tells one; 0 without one (the
    Gauss-Markov part stays with Q)."""
    s, spread = float(c.current_speed_mps), float(c.current_speed_spread_mps)
    return float(np.sqrt((s * s + spread * spread / 3.0) / 2.0))


def current_error_std_mps(c: Any) -> float:
    """sigma_c of eqs. (D1', D1''): the error per axis of the current the survey adds, the told
    current's (``told_current_std_mps``) when a beacon AUV sends one it adds, else the whole
    untold current's (``untold_current_std_mps``)."""
    return told_current_std_mps(c) if told_current(c) else untold_current_std_mps(c)


def considered_biases(c: Any) -> tuple[float, float, float] | None:
    """(sigma_k, sigma_beta in rad, sigma_c in m/s; ``current_error_std_mps``) of scenario config ``c`` when its survey
    filter carries them (``survey_bias_consider``), else None. Only with the modem sensor:
    it carries Pxd through its updates (eq. D3); the MLS sensor's bearing reads the compass
    bias itself (a measurement that is a function of phi) and does not."""
    std = (float(c.survey_speed_scale_error_std), float(np.radians(c.compass_bias_std_deg)), current_error_std_mps(c))
    use = c.survey_bias_consider and c.acoustic_sensor == "modem" and max(std) > 0
    return std if use else None


def bias_variances(
    scale_std: float, heading_std_rad: float, current_std_mps: float, noise_scale: np.ndarray
) -> np.ndarray:
    """Pff's diagonal per environment (B, 4): (sigma_k^2, sigma_beta^2, sigma_c^2,
    sigma_c^2), the episode's noise scale (domain randomization,
    ``SimState.ep_noise_scale``) applied to k and beta as the episode start applies it
    (the told current's error is drawn without it)."""
    s2 = np.asarray(noise_scale, dtype=float)[:, None] ** 2
    var = np.empty((s2.shape[0], N_BIASES))
    var[:, :2] = s2 * np.array([scale_std**2, heading_std_rad**2])
    var[:, 2:] = current_std_mps**2
    return var


def displacement_jacobian(D: np.ndarray, dt_s: float | np.ndarray = 0.0) -> np.ndarray:
    """Eqs. (D1, D1'): G (..., 3, 4) = [[D, J D, dt e_x, dt e_y]; [0, 0, 0, 0]] for
    horizontal displacements D (..., 2) over dt_s seconds."""
    G = np.zeros(D.shape[:-1] + (3, N_BIASES))
    G[..., 0, 0], G[..., 1, 0] = D[..., 0], D[..., 1]
    G[..., 0, 1], G[..., 1, 1] = -D[..., 1], D[..., 0]
    G[..., 0, 2] = G[..., 1, 3] = dt_s
    return G


def bias_predict(
    P: np.ndarray,
    Pxd: np.ndarray,
    D: np.ndarray,
    var: np.ndarray,
    dt_s: float = 0.0,
    held: tuple[np.ndarray, np.ndarray] | None = None,
) -> None:
    """Eq. (D2) without Q, in place, over the batch: P (B, S, 3, 3), Pxd (B, S, 3, 4),
    D (B, S, 2) the cycle's dead-reckoned horizontal displacements over dt_s seconds,
    var (B, 4) Pff's diagonal (``bias_variances``). ``held``: the multipath hypotheses'
    differences (dP (B, S, 3, 3), dD (B, S, 3, 4); ``multipath``, eq. M5), which (D2)
    moves by G dD' + dD G' (dD itself does not change)."""
    G = displacement_jacobian(D, dt_s)
    GPff = G * var[:, None, None, :]  # G Pff, Pff diagonal
    cross = G @ np.swapaxes(Pxd, -1, -2)
    P += cross + np.swapaxes(cross, -1, -2) + GPff @ np.swapaxes(G, -1, -2)
    Pxd += GPff
    if held is not None:
        dP, dD = held
        cross = G @ np.swapaxes(dD, -1, -2)
        dP += cross + np.swapaxes(cross, -1, -2)
