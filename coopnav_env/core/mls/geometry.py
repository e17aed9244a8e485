"""Geometry of the MLS sensor (Kottege & Zimmer, Acoustics '08; equation numbers are
the paper's): the array layout, relative poses, the true path lengths and delays,
angle wrapping (eq. 4), the theoretical error bounds (eqs. 11-14, corrected) and the
paper's error statistics (eqs. 15-19).

Body frame: x forward, y to port. Projectors P1 (bow) at (+l/2, 0) and P2 (stern) at
(-l/2, 0); hydrophones H1 (port) at (0, +d/2) and H2 (starboard) at (0, -d/2). A
vehicle's reference point is the body origin (the midpoint of each pair).

Errata of the bounds (``mls_error_bounds``):

* eq. (12) is four times too large: r^2 = (sum_ij r_ij^2)/4 - (d^2 + l^2)/4, so
  dr/dr_ij = r_ij / (4 r) and Delta r = v Delta tau sqrt(4r^2 + l^2 + d^2) / (4 f_s r)
  (-> v Delta tau / (2 f_s) for r >> l: four independent TOAs halve the error).
* eq. (13): X carries the same factor (it is 4x the propagated sub-range
  variance), and Y's numerators (l^2 - r_2^2)^2, (l^2 - r_1^2)^2 are not the
  derivative of eq. (10): d alpha / d theta_1 = (l^2 + r_1^2 - r_2^2) / (2 l^2) and
  d alpha / d theta_2 = (l^2 + r_2^2 - r_1^2) / (2 l^2), so Y's numerators are
  ((l^2 + r_1^2 - r_2^2)/2)^2 and ((l^2 + r_2^2 - r_1^2)/2)^2. Checked against a
  finite-difference Jacobian of eq. (10) in tests/test_mls.py. The printed forms
  stay available (``as_printed=True``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

_TWO_PI = 2.0 * math.pi


# --------------------------------------------------------------------------- angles, poses
def wrap_angle_rad(x: ArrayLike) -> Any:
    """Eq. (4), [x]_adj: an angle wrapped to (-pi, pi] (rad). The paper's form only
    handles values within one turn outside (-180, 180] deg; this wraps any angle."""
    x = np.asarray(x, dtype=float)
    return np.pi - np.mod(np.pi - x, _TWO_PI)


def pose_arrays(
    sender_pos_m: ArrayLike, sender_heading_rad: ArrayLike, observer_pos_m: ArrayLike, observer_heading_rad: ArrayLike
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The poses as float arrays (sender pos, sender heading, observer pos, observer
    heading), checked: positions with a last axis of 2, everything finite."""
    sp = np.asarray(sender_pos_m, dtype=float)
    op = np.asarray(observer_pos_m, dtype=float)
    sh = np.asarray(sender_heading_rad, dtype=float)
    oh = np.asarray(observer_heading_rad, dtype=float)
    for name, p in (("sender_pos_m", sp), ("observer_pos_m", op)):
        if p.ndim == 0 or p.shape[-1] != 2:
            raise ValueError(f"{name} must have a last axis of length 2 (east, north in m), got shape {p.shape}")
    for name, a in (
        ("sender_pos_m", sp),
        ("observer_pos_m", op),
        ("sender_heading_rad", sh),
        ("observer_heading_rad", oh),
    ):
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{name} must be finite")
    return sp, sh, op, oh


def relative_pose(
    sender_pos_m: ArrayLike, sender_heading_rad: ArrayLike, observer_pos_m: ArrayLike, observer_heading_rad: ArrayLike
) -> tuple[np.ndarray, np.ndarray]:
    """Sender's reference point (..., 2) in the observer's body frame and the relative heading (...)."""
    sp, sh, op, oh = pose_arrays(sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad)
    dx = sp[..., 0] - op[..., 0]
    dy = sp[..., 1] - op[..., 1]
    c, s = np.cos(oh), np.sin(oh)
    rel = np.stack([c * dx + s * dy, -s * dx + c * dy], axis=-1)
    return rel, wrap_angle_rad(sh - oh)


def geometric_truth(
    sender_pos_m: ArrayLike, sender_heading_rad: ArrayLike, observer_pos_m: ArrayLike, observer_heading_rad: ArrayLike
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The unfolded truth: (bearing rad of the sender's reference point in the observer's
    frame, distance m between reference points, relative heading rad), all broadcast
    over leading axes. Positions (..., 2) m, headings (...) rad."""
    rel, alpha = relative_pose(sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad)
    return np.arctan2(rel[..., 1], rel[..., 0]), np.hypot(rel[..., 0], rel[..., 1]), alpha


# --------------------------------------------------------------------------- array layout
def projector_positions(rel: np.ndarray, alpha: ArrayLike, projector_spacing_m: float) -> np.ndarray:
    """P1 (bow), P2 (stern) in the observer frame, shape (..., 2 projectors, 2 xy), m."""
    h = 0.5 * projector_spacing_m
    u = np.stack([np.cos(alpha), np.sin(alpha)], axis=-1)
    return np.stack([rel + h * u, rel - h * u], axis=-2)


def hydrophone_positions(hydrophone_base_m: float) -> np.ndarray:
    """H1 (port), H2 (starboard) in the observer frame, (2, 2), m."""
    h = 0.5 * hydrophone_base_m
    return np.array([[0.0, h], [0.0, -h]])


class ArrayGeometry:
    """The two arrays of one configuration and the water's true sound speed: direct
    path lengths and true delays for (sender, observer) poses, with the range checks.

    hydrophone_base_m d, projector_spacing_m l, sample_rate_hz f_s,
    sound_speed_true_mps v; ranges must lie in (min_range_m, max_range_m], where
    min_range_m = (l + d)/2 keeps a projector outside the hydrophones' circle."""

    def __init__(
        self,
        hydrophone_base_m: float,
        projector_spacing_m: float,
        sample_rate_hz: float,
        sound_speed_true_mps: float,
        max_range_m: float,
    ) -> None:
        self.d = hydrophone_base_m
        self.l = projector_spacing_m
        self.fs = sample_rate_hz
        self.sound_speed_true_mps = sound_speed_true_mps
        self.max_range_m = max_range_m
        # geometry limits: a projector must stay outside the hydrophones' circle
        self.min_range_m = 0.5 * (self.l + self.d)

    def check_range(self, rel: np.ndarray, max_check: bool = True) -> np.ndarray:
        rng_m = np.hypot(rel[..., 0], rel[..., 1])
        if np.any(rng_m <= self.min_range_m):
            bad = float(np.min(rng_m))
            raise ValueError(
                f"sender_pos_m/observer_pos_m: range {bad:.3f} m is shorter than the array geometry allows "
                f"((projector_spacing_m + hydrophone_base_m)/2 = {self.min_range_m:.3f} m)"
            )
        if max_check and np.any(rng_m > self.max_range_m):
            bad = float(np.max(rng_m))
            raise ValueError(
                f"sender_pos_m/observer_pos_m: range {bad:.3f} m exceeds max_range_m = {self.max_range_m} m"
            )
        return rng_m

    def path_lengths(
        self,
        sender_pos_m: ArrayLike,
        sender_heading_rad: ArrayLike,
        observer_pos_m: ArrayLike,
        observer_heading_rad: ArrayLike,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Direct path lengths r_ij (..., 2, 2) m, and the relative pose."""
        rel, alpha = relative_pose(sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad)
        self.check_range(rel)
        P = projector_positions(rel, alpha, self.l)  # (..., 2, 2)
        Hy = hydrophone_positions(self.d)  # (2, 2)
        diff = P[..., :, None, :] - Hy[None, :, :]  # (..., i, j, xy)
        return np.hypot(diff[..., 0], diff[..., 1]), rel, alpha, P

    def true_delays(
        self,
        sender_pos_m: ArrayLike,
        sender_heading_rad: ArrayLike,
        observer_pos_m: ArrayLike,
        observer_heading_rad: ArrayLike,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Noise-free delays in samples at the true sound speed: (tdoa (..., 2), toa (..., 2, 2))."""
        r_ij = self.path_lengths(sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad)[0]
        toa = r_ij * self.fs / self.sound_speed_true_mps
        return toa[..., 0] - toa[..., 1], toa


# --------------------------------------------------------------------------- error bounds, statistics
def mls_error_bounds(
    sub_azimuths_rad: ArrayLike,
    sub_ranges_m: ArrayLike,
    range_m: ArrayLike,
    *,
    hydrophone_base_m: float,
    projector_spacing_m: float,
    sound_speed_mps: float,
    sample_rate_hz: float,
    tdoa_std_samples: ArrayLike,
    toa_std_samples: ArrayLike | None = None,
    as_printed: bool = False,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Theoretical error bounds (11)-(13): one-sigma errors of azimuth (rad), range (m)
    and heading (rad) for a timing error Delta-tau (samples), by first-order error
    propagation through eqs. (5), (9) and (10).

    sub_azimuths_rad (..., 2) theta_1, theta_2; sub_ranges_m (..., 2) r_1, r_2;
    range_m (...) r. tdoa_std_samples: Delta-tau of the two cross-correlation delays,
    broadcast to (..., 2); toa_std_samples: Delta-tau of the four TOAs, broadcast to
    (..., 2, 2) (defaults to the paper's single Delta-tau = tdoa_std_samples).

    as_printed=False (default): the propagation done right (see this module's docstring:
    eq. 12 and the X term of eq. 13 are 4x too large in the paper, eq. 13's Y
    numerators are not the derivative of eq. 10); it also allows a different Delta-tau
    per delay. as_printed=True: eqs. (11)-(14) exactly as printed, with
    Delta-tau = tdoa_std_samples (must be one value per row).
    """
    th = np.asarray(sub_azimuths_rad, dtype=float)
    ri = np.asarray(sub_ranges_m, dtype=float)
    r = np.asarray(range_m, dtype=float)
    d = float(hydrophone_base_m)
    l = float(projector_spacing_m)
    k = np.asarray(sound_speed_mps, dtype=float) / float(sample_rate_hz)  # m per sample
    c1, c2 = np.cos(th[..., 0]), np.cos(th[..., 1])
    r1, r2 = ri[..., 0], ri[..., 1]
    dtau = np.broadcast_to(np.asarray(tdoa_std_samples, dtype=float), th.shape)
    if as_printed:
        dt = dtau[..., 0]
        d_theta = k * dt / (2.0 * d) * np.sqrt(1.0 / c1**2 + 1.0 / c2**2)  # (11)
        d_r = k * dt / r * np.sqrt(4.0 * r * r + l * l + d * d)  # (12)
        X = 4.0 * (r1**2 + r2**2) + d * d / (r1**2 * r2**2) * (r1**4 + r2**4)  # (14)
        Y = (l * l - r2**2) ** 2 / c1**2 + (l * l - r1**2) ** 2 / c2**2  # (14)
        d_alpha = k * dt / (l * l) * np.sqrt(np.sin(th[..., 0] - th[..., 1]) ** 2 / 2.0 * X + Y / (d * d))  # (13)
        return d_theta, d_r, d_alpha
    if toa_std_samples is None:
        toa_std_samples = dtau[..., :, None]
    dtoa = np.broadcast_to(np.asarray(toa_std_samples, dtype=float), th.shape + (2,))
    # sub-azimuth errors: theta_i = -arcsin(delta_i / d) -> d theta_i = d delta_i / (d cos theta_i)
    d_th1 = k * dtau[..., 0] / (d * c1)
    d_th2 = k * dtau[..., 1] / (d * c2)
    # (11): theta = (theta_1 + theta_2) / 2
    d_theta = 0.5 * np.sqrt(d_th1**2 + d_th2**2)
    # TOA distances r_ij from eq. (8) inverted: r_i1^2, r_i2^2 = r_i^2 + d^2/4 -+ r_i d sin theta_i
    s = np.stack([np.sin(th[..., 0]), np.sin(th[..., 1])], axis=-1)
    rij2 = np.stack([ri**2 + 0.25 * d * d - ri * d * s, ri**2 + 0.25 * d * d + ri * d * s], axis=-1)
    var_rij = (k[..., None, None] if np.ndim(k) else k) ** 2 * dtoa**2
    # (12) corrected: dr/dr_ij = r_ij / (4 r)
    d_r = np.sqrt(np.sum(rij2 * var_rij, axis=(-2, -1))) / (4.0 * r)
    # sub-range errors: dr_i/dr_ij = r_ij / (2 r_i)
    var_ri = np.sum(rij2 * var_rij, axis=-1) / (4.0 * ri**2)
    # (13) corrected: partial derivatives of eq. (10) at the given values,
    # d alpha/d theta_1 = (r1^2 - r1 r2 cos(theta_1 - theta_2)) / l^2 = (l^2 + r1^2 - r2^2) / (2 l^2),
    # d alpha/d r_1 = -r2 sin(theta_1 - theta_2) / l^2 (and symmetrically), with
    # l^2 = |P1 - P2|^2 from (r_i, theta_i) (= projector_spacing_m^2 when they are exact)
    cd = np.cos(th[..., 0] - th[..., 1])
    l2 = r1**2 + r2**2 - 2.0 * r1 * r2 * cd
    a1 = r1**2 - r1 * r2 * cd
    a2 = r2**2 - r1 * r2 * cd
    sd = np.sin(th[..., 0] - th[..., 1])
    var_alpha = (
        (a1 * d_th1) ** 2 + (a2 * d_th2) ** 2 + sd**2 * (r2**2 * var_ri[..., 0] + r1**2 * var_ri[..., 1])
    ) / l2**2
    return d_theta, d_r, np.sqrt(var_alpha)


def error_statistics(errors: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The paper's statistics of estimation errors (eqs. 15-19), over the last axis.

    ``errors``: biased errors phi_i - phi_0i (eq. 15), any unit. Returns
    (mean mu, eq. 16; standard deviation sigma with 1/m, eq. 17; average deviation,
    the mean of the unbiased root squared errors |error - mu|, eqs. 18-19), in the
    unit of ``errors``."""
    e = np.asarray(errors, dtype=float)
    mu = e.mean(axis=-1)  # eq. (16)
    dev = e - mu[..., None]
    sigma = np.sqrt(np.mean(dev * dev, axis=-1))  # eq. (17)
    rse = np.sqrt(dev * dev)  # eq. (18)
    return mu, sigma, rse.mean(axis=-1)  # eq. (19)
