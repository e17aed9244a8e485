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
(3, 2), e = x - x_hat its error (true minus estimate, as in ``consider.py``).

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

With sigma_k = sigma_beta = 0 this is the old filter. D is the change of the
dead-reckoning-only track over the cycle (``SimState.s_dr``), which is what the
biases act on (the current the survey is told is not scaled by them).
"""

from __future__ import annotations

from typing import Any

import numpy as np


def considered_biases(c: Any) -> tuple[float, float] | None:
    """(sigma_k, sigma_beta in rad) of scenario config ``c`` when its survey filter carries
    them (``survey_bias_consider``), else None. Only with the modem sensor: it carries Pxd
    through its updates (eq. D3); the MLS sensor's bearing reads the compass bias itself (a
    measurement that is a function of phi) and does not."""
    std = (float(c.survey_speed_scale_error_std), float(np.radians(c.compass_bias_std_deg)))
    use = c.survey_bias_consider and c.acoustic_sensor == "modem" and max(std) > 0
    return std if use else None


def bias_variances(scale_std: float, heading_std_rad: float, noise_scale: np.ndarray) -> np.ndarray:
    """Pff's diagonal per environment (B, 2): (sigma_k^2, sigma_beta^2), the episode's
    noise scale (domain randomization, ``SimState.ep_noise_scale``) applied as the
    episode start applies it to the biases."""
    s2 = np.asarray(noise_scale, dtype=float)[:, None] ** 2
    return s2 * np.array([scale_std**2, heading_std_rad**2])


def displacement_jacobian(D: np.ndarray) -> np.ndarray:
    """Eq. (D1): G (..., 3, 2) = [[D, J D]; [0, 0]] for horizontal displacements D (..., 2)."""
    G = np.zeros(D.shape[:-1] + (3, 2))
    G[..., 0, 0], G[..., 1, 0] = D[..., 0], D[..., 1]
    G[..., 0, 1], G[..., 1, 1] = -D[..., 1], D[..., 0]
    return G


def bias_predict(P: np.ndarray, Pxd: np.ndarray, D: np.ndarray, var: np.ndarray) -> None:
    """Eq. (D2) without Q, in place, over the batch: P (B, S, 3, 3), Pxd (B, S, 3, 2),
    D (B, S, 2) the cycle's dead-reckoned horizontal displacements, var (B, 2) Pff's
    diagonal (``bias_variances``)."""
    G = displacement_jacobian(D)
    GPff = G * var[:, None, None, :]  # G Pff, Pff diagonal
    cross = G @ np.swapaxes(Pxd, -1, -2)
    P += cross + np.swapaxes(cross, -1, -2) + GPff @ np.swapaxes(G, -1, -2)
    Pxd += GPff
