"""The MLS acoustic relative-localisation sensor of Kottege & Zimmer (Acoustics '08).

Source: shared/seeds/zimmer-kottege-2008-mls-azimuth-range-heading.txt (equation
numbers below are the paper's). A *sending event* is two maximum length sequences
(MLS), one from the sender's bow projector P1 and one from its stern projector P2;
the observer records each on two hydrophones H1, H2 and returns the sender's
azimuth, range and heading. Two modes share one estimator (``estimate_from_delays``):

* **signal level** (``MLSSensor.measure_signal``): the four channels of an event
  are synthesised (fractional delays by an exact FFT phase shift of the band-limited
  sequence, spherical spreading 1/r, optionally one surface or wall reflection by
  the image method, white Gaussian noise at a stated SNR, all band-passed by the
  transducer/receiver response) and processed as the paper does: FFT
  cross-correlation of the two channels and FFT matched filtering against the
  replica, peak tracking around the previous peak (bootstrapped from the absolute
  maximum), cubic-spline sub-sample refinement, then eqs. (1)-(10);
* **analytic** (``MLSSensor.measure_analytic``): the same outputs for a whole batch
  in numpy: the true delays plus Gaussian timing errors whose standard deviation is
  the one the signal level's correlator and spline realise at the link's SNR
  (``MLSSensor.timing_std_samples``: the small-error bound of the spline peak, which
  depends on the delay's fractional part), plus the spline's deterministic peak
  locking and its noise-driven choice between two integer peaks near half-sample
  delays, pushed through the same eqs. (1)-(10). To first order the outputs' errors
  are then exactly the bounds (11)-(13) (corrected, ``mls_error_bounds``) at that
  Delta-tau, and they keep what a Gaussian in (theta, r, alpha) would lose: the
  correlation of azimuth and heading errors and the saturation of the sub-azimuths
  at +-90 deg. It models the direct paths only (no reflection) and has no outliers.

Frames and conventions (2-D, both vehicles at the same depth):

* a pose is a position (east, north) in m and a heading in rad, counter-clockwise
  from east (``np.angle`` of the core's complex unit heading);
* body frame: x forward, y to port. Projectors P1 (bow) at (+l/2, 0) and P2 (stern)
  at (-l/2, 0); hydrophones H1 (port) at (0, +d/2) and H2 (starboard) at (0, -d/2).
  A vehicle's reference point is the body origin (the midpoint of each pair);
* azimuth: bearing of the sender's reference point from the observer's, in the
  observer's frame, counter-clockwise (to port) positive, 0 = dead ahead;
* range: distance between the reference points;
* heading: the sender's heading minus the observer's, wrapped to (-pi, pi].

**A two-hydrophone array cannot tell front from back**: every sub-azimuth lies in
[-90, 90] deg, so a sender behind the observer is reported at its mirror image
across the hydrophone baseline (azimuth 180 deg - bearing, heading 180 deg - heading).
``ideal_measurement`` gives what a noise-free sensor reports (the measurement
model a filter should use); ``geometric_truth`` gives the unfolded truth.

For a scenario (e.g. a swarm with a round-robin sender): build one ``MLSSensor``
per configuration (its constructor tabulates the estimator, ~0.2 s); for each
sending event call ``measure_analytic`` on the (observer, sender) pairs in range, as
one batch (positions (..., 2), headings (...)), with the caller's standard normals
(batch + (13,), e.g. from ``core/rng.py``) so draws are reproducible per pair, or
``measure_signal`` per pair with one ``PeakTracker`` per ordered pair. Pairs outside
(``min_range_m``, ``config.max_range_m``] raise ValueError: mask them first.
``ideal_measurement`` is the measurement function h(x) for a filter, and
``error_bounds`` gives one-sigma errors for its noise model
(``measure_analytic_with_bounds``: both from one computation of the geometry).

Errata and choices (each also noted where it is implemented):

* eq. (2) writes beta = tan^-1(sqrt(d^2 - delta^2) / delta); with a one-argument
  arctangent beta would be negative for delta < 0 and eq. (3) would then give
  sub-azimuths below -90 deg. The physics is beta = arccos(delta/d) in [0, 180] deg,
  i.e. the two-argument arctangent; we use that. Noise can make |delta| > d near
  +-90 deg, where the root is imaginary: delta is clipped to [-d, d].
* eq. (4)'s [x]_adj only wraps values within one turn outside (-180, 180]; we wrap
  any angle (identical on its domain).
* eqs. (2)-(3) assume a plane wave. ``estimator="exact"`` (default) uses the exact
  near-field relation sin(theta_i) = -(delta_i/d) (r_i1 + r_i2) / (2 r_i), which
  follows from r_i2^2 - r_i1^2 = 2 r_i d sin(theta_i), with the TOAs the sensor
  measures anyway; eq. (5), the mean of the sub-azimuths, is replaced by the
  bearing of the projectors' midpoint located by (r_i, theta_i). Eq. (5) is biased
  by about (l/2r)^2 sin(2 psi)/2 (psi: the sender's axis against the line of
  sight): a constant over the paper's own tank sweep (r = 1 m, l = 0.5 m,
  psi = 30 deg: 1.54 deg exactly), 0.06 deg at 5 m. ``estimator="paper"`` is eqs. (2)-(5) literally.
  Eqs. (8)-(10) are exact (Apollonius' median theorem; the bow-minus-stern vector)
  and are used as printed in both.
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

Sound speed comes from ``acoustics.mackenzie_sound_speed`` (the project's one home
for it). Mackenzie (1981) is fitted for 25-40 ppt; at 0 ppt (the paper's fresh
water tank) it gives 1481.7 m/s at 20 degC against 1482.4 m/s for fresh water
(Marczak 1997, shared/reference-values.md section 4): 0.05 %, 0.5 mm at 1 m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import scipy.fft as sfft
from scipy.interpolate import CubicSpline
from scipy.signal import max_len_seq

from coopnav_env.core.acoustics import mackenzie_sound_speed

__all__ = [
    "MLSConfig", "Reflection", "MLSSensor", "MLSMeasurement", "PeakTracker",
    "estimate_from_delays", "mls_error_bounds", "geometric_truth", "wrap_angle_rad",
    "error_statistics",
]

_TWO_PI = 2.0 * math.pi


# --------------------------------------------------------------------------- helpers
def wrap_angle_rad(x):
    """Eq. (4), [x]_adj: an angle wrapped to (-pi, pi] (rad). The paper's form only
    handles values within one turn outside (-180, 180] deg; this wraps any angle."""
    x = np.asarray(x, dtype=float)
    return np.pi - np.mod(np.pi - x, _TWO_PI)


def error_statistics(errors):
    """The paper's statistics of estimation errors (eqs. 15-19), over the last axis.

    ``errors``: biased errors phi_i - phi_0i (eq. 15), any unit. Returns
    (mean mu, eq. 16; standard deviation sigma with 1/m, eq. 17; average deviation,
    the mean of the unbiased root squared errors |error - mu|, eqs. 18-19), in the
    unit of ``errors``."""
    e = np.asarray(errors, dtype=float)
    mu = e.mean(axis=-1)                                       # eq. (16)
    dev = e - mu[..., None]
    sigma = np.sqrt(np.mean(dev * dev, axis=-1))               # eq. (17)
    rse = np.sqrt(dev * dev)                                   # eq. (18)
    return mu, sigma, rse.mean(axis=-1)                        # eq. (19)


def _pose_arrays(sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad):
    sp = np.asarray(sender_pos_m, dtype=float)
    op = np.asarray(observer_pos_m, dtype=float)
    sh = np.asarray(sender_heading_rad, dtype=float)
    oh = np.asarray(observer_heading_rad, dtype=float)
    for name, p in (("sender_pos_m", sp), ("observer_pos_m", op)):
        if p.ndim == 0 or p.shape[-1] != 2:
            raise ValueError(f"{name} must have a last axis of length 2 (east, north in m), got shape {p.shape}")
    for name, a in (("sender_pos_m", sp), ("observer_pos_m", op), ("sender_heading_rad", sh),
                    ("observer_heading_rad", oh)):
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{name} must be finite")
    return sp, sh, op, oh


def _check_noise_source(rng, normals):
    if (rng is None) == (normals is None):
        raise ValueError("give exactly one of rng and normals")


def _relative_pose(sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad):
    """Sender's reference point (..., 2) in the observer's body frame and the relative heading (...)."""
    sp, sh, op, oh = _pose_arrays(sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad)
    dx = sp[..., 0] - op[..., 0]
    dy = sp[..., 1] - op[..., 1]
    c, s = np.cos(oh), np.sin(oh)
    rel = np.stack([c * dx + s * dy, -s * dx + c * dy], axis=-1)
    return rel, wrap_angle_rad(sh - oh)


def geometric_truth(sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad):
    """The unfolded truth: (bearing rad of the sender's reference point in the observer's
    frame, distance m between reference points, relative heading rad), all broadcast
    over leading axes. Positions (..., 2) m, headings (...) rad."""
    rel, alpha = _relative_pose(sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad)
    return np.arctan2(rel[..., 1], rel[..., 0]), np.hypot(rel[..., 0], rel[..., 1]), alpha


def _projector_positions(rel, alpha, projector_spacing_m):
    """P1 (bow), P2 (stern) in the observer frame, shape (..., 2 projectors, 2 xy), m."""
    h = 0.5 * projector_spacing_m
    u = np.stack([np.cos(alpha), np.sin(alpha)], axis=-1)
    return np.stack([rel + h * u, rel - h * u], axis=-2)


def _hydrophone_positions(hydrophone_base_m):
    """H1 (port), H2 (starboard) in the observer frame, (2, 2), m."""
    h = 0.5 * hydrophone_base_m
    return np.array([[0.0, h], [0.0, -h]])


# --------------------------------------------------------------------------- estimator
class MLSMeasurement(NamedTuple):
    """One (or a batch of) MLS measurements. Angles rad, lengths m, delays in samples."""
    azimuth_rad: np.ndarray        # eq. (5) or the projectors' midpoint bearing, in [-pi/2, pi/2]
    range_m: np.ndarray            # eq. (9)
    heading_rad: np.ndarray        # eq. (10), in (-pi, pi]
    sub_azimuths_rad: np.ndarray   # (..., 2): theta_1 (bow), theta_2 (stern), eqs. (2)-(4)
    sub_ranges_m: np.ndarray       # (..., 2): r_1, r_2, eq. (8)
    tdoa_samples: np.ndarray       # (..., 2): tau_0^i, delay of H1's channel behind H2's, chirp i
    toa_samples: np.ndarray        # (..., 2, 2): tau_0^ij, projector i to hydrophone j, from emission


def estimate_from_delays(tdoa_samples, toa_samples, *, hydrophone_base_m, projector_spacing_m,
                         sound_speed_mps, sample_rate_hz, estimator="exact"):
    """Eqs. (1)-(10): delays -> sub-azimuths, azimuth, sub-ranges, range, heading.

    tdoa_samples: (..., 2), tau_0^i (samples), the lag of hydrophone H1's channel
        behind H2's for the bow (i=1) and stern (i=2) chirps.
    toa_samples: (..., 2, 2), tau_0^ij (samples) from the emission of chirp i to its
        arrival at hydrophone j.
    hydrophone_base_m d, projector_spacing_m l, sound_speed_mps v (the one the
    receiver assumes), sample_rate_hz f_s. estimator: "exact" (near-field
    sub-azimuths, midpoint azimuth; default) or "paper" (eqs. 2-5 as printed).
    Returns an ``MLSMeasurement``; angles in rad.
    """
    if estimator not in ("exact", "paper"):
        raise ValueError(f"estimator must be 'exact' or 'paper', got {estimator!r}")
    d = float(hydrophone_base_m)
    l = float(projector_spacing_m)
    v = np.asarray(sound_speed_mps, dtype=float)
    fs = float(sample_rate_hz)
    tau_i = np.asarray(tdoa_samples, dtype=float)
    tau_ij = np.asarray(toa_samples, dtype=float)
    vv = v[..., None]

    # eq. (1): path-length differences delta_i = r_i1 - r_i2 (m)
    delta = tau_i * vv / fs
    # eq. (2): beta_i = arccos(delta_i / d). Printed as tan^-1(sqrt(d^2 - delta^2)/delta);
    # the quadrant-aware arctangent is meant (a plain arctangent is negative for
    # delta < 0). Noise can push |delta| past d near +-90 deg: clipped.
    delta_c = np.clip(delta, -d, d)
    beta = np.arctan2(np.sqrt(d * d - delta_c * delta_c), delta_c)
    # eqs. (3)-(4): sub-azimuths theta_i = [beta_i - 90 deg]_adj, in [-90, 90] deg
    theta_ff = wrap_angle_rad(beta - 0.5 * np.pi)

    # eqs. (6)-(7): TOAs -> distances r_ij = tau_0^ij v / f_s (m)
    r_ij = tau_ij * v[..., None, None] / fs
    # eq. (8): sub-ranges r_i = |P_i O_1| (median of triangle P_i H1 H2; exact)
    r_i = np.sqrt(np.maximum(0.5 * (r_ij[..., 0] ** 2 + r_ij[..., 1] ** 2) - 0.25 * d * d, 0.0))
    # eq. (9): range r = |M O_1|, M the projectors' midpoint (exact)
    r = np.sqrt(np.maximum(0.5 * (r_i[..., 0] ** 2 + r_i[..., 1] ** 2) - 0.25 * l * l, 0.0))

    if estimator == "paper":
        theta_i = theta_ff
        theta = 0.5 * (theta_i[..., 0] + theta_i[..., 1])                  # eq. (5)
    else:
        # Near-field sub-azimuths: r_i2^2 - r_i1^2 = 2 r_i d sin(theta_i) exactly, and
        # r_i2^2 - r_i1^2 = -delta_i (r_i1 + r_i2); eq. (2)-(3) are its plane-wave limit
        # sin(theta_i) = -delta_i / d.
        scale = (r_ij[..., 0] + r_ij[..., 1]) / np.maximum(2.0 * r_i, 1e-12)
        theta_i = np.arcsin(np.clip(np.sin(theta_ff) * scale, -1.0, 1.0))
        # In place of eq. (5) (the mean of the sub-azimuths, biased when r ~ l): the
        # bearing of the projectors' midpoint located by (r_i, theta_i).
        theta = np.arctan2(r_i[..., 0] * np.sin(theta_i[..., 0]) + r_i[..., 1] * np.sin(theta_i[..., 1]),
                           r_i[..., 0] * np.cos(theta_i[..., 0]) + r_i[..., 1] * np.cos(theta_i[..., 1]))

    # eq. (10): heading = direction of the stern-to-bow vector P2 -> P1; tan^-1 is
    # the quadrant-aware arctangent (the heading covers the full circle)
    alpha = wrap_angle_rad(np.arctan2(r_i[..., 0] * np.sin(theta_i[..., 0]) - r_i[..., 1] * np.sin(theta_i[..., 1]),
                                      r_i[..., 0] * np.cos(theta_i[..., 0]) - r_i[..., 1] * np.cos(theta_i[..., 1])))
    return MLSMeasurement(theta, r, alpha, theta_i, r_i, tau_i, tau_ij)


def mls_error_bounds(sub_azimuths_rad, sub_ranges_m, range_m, *, hydrophone_base_m, projector_spacing_m,
                     sound_speed_mps, sample_rate_hz, tdoa_std_samples, toa_std_samples=None,
                     as_printed=False):
    """Theoretical error bounds (11)-(13): one-sigma errors of azimuth (rad), range (m)
    and heading (rad) for a timing error Delta-tau (samples), by first-order error
    propagation through eqs. (5), (9) and (10).

    sub_azimuths_rad (..., 2) theta_1, theta_2; sub_ranges_m (..., 2) r_1, r_2;
    range_m (...) r. tdoa_std_samples: Delta-tau of the two cross-correlation delays,
    broadcast to (..., 2); toa_std_samples: Delta-tau of the four TOAs, broadcast to
    (..., 2, 2) (defaults to the paper's single Delta-tau = tdoa_std_samples).

    as_printed=False (default): the propagation done right (see the module docstring:
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
    k = np.asarray(sound_speed_mps, dtype=float) / float(sample_rate_hz)   # m per sample
    c1, c2 = np.cos(th[..., 0]), np.cos(th[..., 1])
    r1, r2 = ri[..., 0], ri[..., 1]
    dtau = np.broadcast_to(np.asarray(tdoa_std_samples, dtype=float), th.shape)
    if as_printed:
        dt = dtau[..., 0]
        d_theta = k * dt / (2.0 * d) * np.sqrt(1.0 / c1 ** 2 + 1.0 / c2 ** 2)                   # (11)
        d_r = k * dt / r * np.sqrt(4.0 * r * r + l * l + d * d)                                # (12)
        X = 4.0 * (r1 ** 2 + r2 ** 2) + d * d / (r1 ** 2 * r2 ** 2) * (r1 ** 4 + r2 ** 4)      # (14)
        Y = (l * l - r2 ** 2) ** 2 / c1 ** 2 + (l * l - r1 ** 2) ** 2 / c2 ** 2               # (14)
        d_alpha = k * dt / (l * l) * np.sqrt(np.sin(th[..., 0] - th[..., 1]) ** 2 / 2.0 * X + Y / (d * d))  # (13)
        return d_theta, d_r, d_alpha
    if toa_std_samples is None:
        toa_std_samples = dtau[..., :, None]
    dtoa = np.broadcast_to(np.asarray(toa_std_samples, dtype=float), th.shape + (2,))
    # sub-azimuth errors: theta_i = -arcsin(delta_i / d) -> d theta_i = d delta_i / (d cos theta_i)
    d_th1 = k * dtau[..., 0] / (d * c1)
    d_th2 = k * dtau[..., 1] / (d * c2)
    # (11): theta = (theta_1 + theta_2) / 2
    d_theta = 0.5 * np.sqrt(d_th1 ** 2 + d_th2 ** 2)
    # TOA distances r_ij from eq. (8) inverted: r_i1^2, r_i2^2 = r_i^2 + d^2/4 -+ r_i d sin theta_i
    s = np.stack([np.sin(th[..., 0]), np.sin(th[..., 1])], axis=-1)
    rij2 = np.stack([ri ** 2 + 0.25 * d * d - ri * d * s, ri ** 2 + 0.25 * d * d + ri * d * s], axis=-1)
    var_rij = (k[..., None, None] if np.ndim(k) else k) ** 2 * dtoa ** 2
    # (12) corrected: dr/dr_ij = r_ij / (4 r)
    d_r = np.sqrt(np.sum(rij2 * var_rij, axis=(-2, -1))) / (4.0 * r)
    # sub-range errors: dr_i/dr_ij = r_ij / (2 r_i)
    var_ri = np.sum(rij2 * var_rij, axis=-1) / (4.0 * ri ** 2)
    # (13) corrected: partial derivatives of eq. (10) at the given values,
    # d alpha/d theta_1 = (r1^2 - r1 r2 cos(theta_1 - theta_2)) / l^2 = (l^2 + r1^2 - r2^2) / (2 l^2),
    # d alpha/d r_1 = -r2 sin(theta_1 - theta_2) / l^2 (and symmetrically), with
    # l^2 = |P1 - P2|^2 from (r_i, theta_i) (= projector_spacing_m^2 when they are exact)
    cd = np.cos(th[..., 0] - th[..., 1])
    l2 = r1 ** 2 + r2 ** 2 - 2.0 * r1 * r2 * cd
    a1 = r1 ** 2 - r1 * r2 * cd
    a2 = r2 ** 2 - r1 * r2 * cd
    sd = np.sin(th[..., 0] - th[..., 1])
    var_alpha = ((a1 * d_th1) ** 2 + (a2 * d_th2) ** 2
                 + sd ** 2 * (r2 ** 2 * var_ri[..., 0] + r1 ** 2 * var_ri[..., 1])) / l2 ** 2
    return d_theta, d_r, np.sqrt(var_alpha)


# --------------------------------------------------------------------------- configuration
@dataclass(frozen=True)
class Reflection:
    """One specular reflection by the image method.

    kind "surface": the sea (tank) surface above both vehicles, which sit at the
    sensor's ``depth_m``; the image path is sqrt(r^2 + (2 depth)^2). kind "wall": a
    vertical wall, the line through ``wall_point_m`` (east, north, m) with normal
    ``wall_normal`` (world frame); the projector is mirrored across it. Amplitude
    ``coefficient`` / path length (a pressure-release surface is about -1, a rigid
    wall about +1)."""
    kind: str = "surface"
    coefficient: float = -0.9
    wall_point_m: tuple = (0.0, 0.0)
    wall_normal: tuple = (1.0, 0.0)

    def __post_init__(self):
        if self.kind not in ("surface", "wall"):
            raise ValueError(f"kind must be 'surface' or 'wall', got {self.kind!r}")
        if not (math.isfinite(self.coefficient) and abs(self.coefficient) <= 1.0):
            raise ValueError(f"coefficient must be finite with |coefficient| <= 1, got {self.coefficient!r}")
        if self.kind == "wall":
            n = np.asarray(self.wall_normal, dtype=float)
            if n.shape != (2,) or not np.all(np.isfinite(n)) or np.hypot(*n) == 0.0:
                raise ValueError(f"wall_normal must be a finite non-zero 2-vector, got {self.wall_normal!r}")
            p = np.asarray(self.wall_point_m, dtype=float)
            if p.shape != (2,) or not np.all(np.isfinite(p)):
                raise ValueError(f"wall_point_m must be a finite 2-vector, got {self.wall_point_m!r}")


@dataclass(frozen=True)
class MLSConfig:
    """Parameters of the MLS sensor. Defaults: the paper's tank array (section 3)
    where it gives them; the rest are assumptions, marked [U].

    hydrophone_base_m d and projector_spacing_m l: the paper's 0.3 and 0.5 m;
    sample_rate_hz f_s: 96 kHz (paper). mls_order: the MLS has 2^order - 1 chips at
    one chip per sample ([U]: 10 -> 1023 chips, 10.7 ms at 96 kHz; the paper gives no
    length). band_hz: pass band (low, high) of the transducer/receiver chain, raised
    cosine edges of band_edge_hz ([U]: low-cost piezo projectors and the 96 kHz
    converter's anti-alias filter; None: flat to Nyquist). snr_db_at_1m: in-band
    signal-to-noise power ratio per sample of the direct path at 1 m, falling by
    20 log10(r) with spherical spreading ([U]; math.inf: no noise).
    water_temperature_c, salinity_psu, depth_m: the water, for Mackenzie's sound
    speed (paper: fresh tap water; 20 degC is [U]); assumed_temperature_c: what the
    receiver assumes (None: the truth). depth_m also places the surface image.
    max_range_m: the receive window covers ranges up to this. reflection: None or a
    ``Reflection``. sync_jitter_s: std of the radio synchronisation error, common to
    the four TOAs of an event (0: perfect). tdoa_track_halfwidth_samples,
    toa_track_halfwidth_samples: the peak-tracking neighbourhoods (+- samples around
    the previous peak). spline_halfwidth_samples: samples each side of the peak fed
    to the cubic spline. estimator: "exact" or "paper" (see ``estimate_from_delays``).
    """
    hydrophone_base_m: float = 0.3
    projector_spacing_m: float = 0.5
    sample_rate_hz: float = 96_000.0
    mls_order: int = 10
    band_hz: tuple | None = (4_000.0, 40_000.0)
    band_edge_hz: float = 2_000.0
    snr_db_at_1m: float = 20.0
    water_temperature_c: float = 20.0
    salinity_psu: float = 0.0
    depth_m: float = 0.5
    assumed_temperature_c: float | None = None
    max_range_m: float = 10.0
    reflection: Reflection | None = None
    sync_jitter_s: float = 0.0
    tdoa_track_halfwidth_samples: int = 4
    toa_track_halfwidth_samples: int = 48
    spline_halfwidth_samples: int = 3
    estimator: str = "exact"

    def __post_init__(self):
        def positive(name):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a positive finite number, got {v!r}")
        for name in ("hydrophone_base_m", "projector_spacing_m", "sample_rate_hz", "max_range_m", "band_edge_hz"):
            positive(name)
        if not (isinstance(self.mls_order, (int, np.integer)) and 4 <= self.mls_order <= 16):
            raise ValueError(f"mls_order must be an integer in [4, 16], got {self.mls_order!r}")
        if self.band_hz is not None:
            try:
                lo, hi = (float(x) for x in self.band_hz)
            except (TypeError, ValueError):
                raise ValueError(f"band_hz must be None or (low, high) in Hz, got {self.band_hz!r}") from None
            if not (0.0 <= lo < hi <= 0.5 * self.sample_rate_hz):
                raise ValueError(f"band_hz must satisfy 0 <= low < high <= sample_rate_hz/2, got {self.band_hz!r}")
        if not (isinstance(self.snr_db_at_1m, (int, float)) and not math.isnan(self.snr_db_at_1m)
                and self.snr_db_at_1m > -math.inf):
            raise ValueError(f"snr_db_at_1m must be a number (math.inf for no noise), got {self.snr_db_at_1m!r}")
        for name in ("water_temperature_c", "salinity_psu", "depth_m"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v)):
                raise ValueError(f"{name} must be a finite number, got {v!r}")
        for name in ("depth_m", "salinity_psu"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)!r}")
        if self.assumed_temperature_c is not None and not math.isfinite(self.assumed_temperature_c):
            raise ValueError(f"assumed_temperature_c must be finite or None, got {self.assumed_temperature_c!r}")
        if not (math.isfinite(self.sync_jitter_s) and self.sync_jitter_s >= 0):
            raise ValueError(f"sync_jitter_s must be >= 0, got {self.sync_jitter_s!r}")
        for name in ("tdoa_track_halfwidth_samples", "toa_track_halfwidth_samples", "spline_halfwidth_samples"):
            v = getattr(self, name)
            if not (isinstance(v, (int, np.integer)) and v >= 2):
                raise ValueError(f"{name} must be an integer >= 2, got {v!r}")
        if self.estimator not in ("exact", "paper"):
            raise ValueError(f"estimator must be 'exact' or 'paper', got {self.estimator!r}")
        if self.reflection is not None and not isinstance(self.reflection, Reflection):
            raise ValueError("reflection must be None or a Reflection")


@dataclass
class PeakTracker:
    """Peak-tracking state of one observer-sender link: the previous peak lags
    (samples) of the two cross-correlations and the four matched filters; NaN until
    bootstrapped from the absolute maximum. Keep one per link; ``reset()`` after a
    long silence."""
    tdoa: np.ndarray = field(default_factory=lambda: np.full(2, np.nan))
    toa: np.ndarray = field(default_factory=lambda: np.full((2, 2), np.nan))

    def reset(self):
        self.tdoa[:] = np.nan
        self.toa[:] = np.nan


# --------------------------------------------------------------------------- the sensor
class MLSSensor:
    """The MLS sensor for one configuration; precomputes the replica and its spectrum.

    Signal level, one event::

        sensor = MLSSensor(MLSConfig())
        tracker = PeakTracker()                 # one per observer-sender link
        m = sensor.measure_signal(sender_pos_m, sender_heading_rad,
                                  observer_pos_m, observer_heading_rad, rng, tracker)
        m.azimuth_rad, m.range_m, m.heading_rad

    Analytic, a batch (leading axes broadcast)::

        m = sensor.measure_analytic(sender_pos_m, sender_heading_rad,
                                    observer_pos_m, observer_heading_rad, rng=rng)
        # or normals=z with z.shape == batch + (13,) standard normals (the caller's
        # random numbers: 2 TDOA, 4 TOA, 1 sync jitter, 6 peak-branch choices)

    Poses: positions (..., 2) east/north m, headings (...) rad counter-clockwise
    from east. Ranges outside (min_range_m, max_range_m] raise ValueError.
    """

    N_NORMALS = 13

    def __init__(self, config: MLSConfig | None = None):
        cfg = config if config is not None else MLSConfig()
        if not isinstance(cfg, MLSConfig):
            raise ValueError("config must be an MLSConfig")
        self.config = cfg
        self.d = cfg.hydrophone_base_m
        self.l = cfg.projector_spacing_m
        self.fs = cfg.sample_rate_hz
        # sound speed: the project's one home (Mackenzie 1981)
        self.sound_speed_true_mps = float(mackenzie_sound_speed(cfg.water_temperature_c, cfg.salinity_psu, cfg.depth_m))
        t_assumed = cfg.water_temperature_c if cfg.assumed_temperature_c is None else cfg.assumed_temperature_c
        self.sound_speed_assumed_mps = float(mackenzie_sound_speed(t_assumed, cfg.salinity_psu, cfg.depth_m))
        # geometry limits: a projector must stay outside the hydrophones' circle
        self.min_range_m = 0.5 * (self.l + self.d)

        # MLS chips (+-1), one per sample
        self.n_chips = 2 ** cfg.mls_order - 1
        chips = max_len_seq(cfg.mls_order)[0].astype(float) * 2.0 - 1.0
        # receive window per chirp: the sequence, the longest direct path from the
        # farthest projector to the farthest hydrophone (+ an image path), a guard
        max_path = cfg.max_range_m + 0.5 * (self.l + self.d)
        if cfg.reflection is not None and cfg.reflection.kind == "surface":
            max_path = math.hypot(max_path, 2.0 * cfg.depth_m)
        self.toa_max_lag = int(math.ceil(max_path * self.fs / self.sound_speed_true_mps)) + 8
        self.tdoa_max_lag = int(math.ceil(self.d * self.fs / self.sound_speed_assumed_mps)) + 2
        guard = 64 + 2 * self.tdoa_max_lag
        self.nfft = sfft.next_fast_len(self.n_chips + self.toa_max_lag + guard, real=True)
        M = self.nfft
        nb = M // 2 + 1
        f_hz = np.arange(nb) * self.fs / M
        self._omega = _TWO_PI * np.arange(nb) / M                   # rad per sample
        # transducer/receiver response: raised-cosine band pass; Nyquist bin zeroed
        # (a fractional delay has no real-valued Nyquist component)
        H = np.ones(nb)
        if cfg.band_hz is not None:
            lo, hi = cfg.band_hz
            e = cfg.band_edge_hz
            H = np.where(f_hz < lo - e / 2, 0.0, H)
            rise = (f_hz >= lo - e / 2) & (f_hz < lo + e / 2)
            H = np.where(rise, 0.5 - 0.5 * np.cos(np.pi * (f_hz - (lo - e / 2)) / e), H)
            H = np.where(f_hz > hi + e / 2, 0.0, H)
            fall = (f_hz > hi - e / 2) & (f_hz <= hi + e / 2)
            H = np.where(fall, 0.5 + 0.5 * np.cos(np.pi * (f_hz - (hi - e / 2)) / e), H)
            if lo == 0.0:
                H[f_hz < e / 2] = 1.0
        if M % 2 == 0:
            H[-1] = 0.0
        self._H = H
        self._mls_spec = sfft.rfft(chips, n=M)                      # emitted chips on the M-grid
        self._R = H * self._mls_spec                                # the (recorded) replica's spectrum
        self._R_conj = np.conj(self._R)
        self.replica = sfft.irfft(self._R, n=M)

        # noise: white N(0, sigma_w^2) per sample, band-passed by H; sigma_w from the
        # in-band SNR of the direct path at 1 m (unit amplitude at 1 m)
        p_signal = float(np.sum(self.replica ** 2)) / self.n_chips
        h_energy = float(np.sum(sfft.irfft(H, n=M) ** 2))           # in-band noise power / sigma_w^2
        snr = 10.0 ** (cfg.snr_db_at_1m / 10.0)
        self.noise_sigma = 0.0 if math.isinf(snr) else math.sqrt(p_signal / (snr * h_energy))

        # Small-error timing statistics of the correlation-peak estimators (samples).
        # (a) The ideal continuous-peak estimator, by linearising C'(tau) = 0 about the
        # true lag (full DFT-grid sums, w = 2 pi k / M):
        #   TOA  (matched filter):  var = sigma_w^2 K_mf / A^2
        #   TDOA (channel x-corr.): var = sigma_w^2 K_mf (1/A1^2 + 1/A2^2) + sigma_w^4 K_nn / (A1 A2)^2
        # K_mf = M sum w^2|R|^2|H|^2 / (sum w^2|R|^2)^2, K_nn = M^2 sum w^2|H|^4 / (sum w^2|R|^2)^2;
        # for a flat full band K_mf = 3 / (pi^2 N), the Cramer-Rao bound.
        wts = np.full(nb, 2.0)
        wts[0] = 1.0
        if M % 2 == 0:
            wts[-1] = 1.0
        self._wts = wts
        w2 = wts * self._omega ** 2
        R2 = np.abs(self._R) ** 2
        curv = float(np.sum(w2 * R2))
        self._K_mf = M * float(np.sum(w2 * R2 * H ** 2)) / curv ** 2
        self._K_nn = M * M * float(np.sum(w2 * H ** 4)) / curv ** 2
        # (b) What the paper's estimator realises. The cubic spline through the 2K+1
        # correlation samples around the integer peak c has a bias b(u) and a noise
        # gain that depend on where the true peak c + u lies (peak locking). Without
        # noise those samples are A R_rr(o - u), o = -K..K (A1 A2 R_rr for the
        # cross-correlation); the spline's peak u_hat(samples) is scale invariant, so
        # with g(u) = grad u_hat at A = 1 and the covariance Sigma of the noise in the
        # samples, the timing variance is g' Sigma g / A^2, where
        #   TOA:  Sigma = sigma_w^2 C_mf,
        #   TDOA: Sigma = sigma_w^2 (A1^2 + A2^2) C_mf + sigma_w^4 C_nn  (and A -> A1 A2),
        # C_mf[o, o'] = (1/M) sum |R|^2 |H|^2 cos(w (o - o')), C_nn[o, o'] = sum |H|^4 cos(w (o - o')).
        # Near a half-sample delay the noise decides which of two samples is the
        # integer maximum, and the two windows' splines disagree by ~2 b(1/2): the
        # estimate is a mixture of two branches. The analytic mode draws the branch
        # from the same linearised noise (D = n_s - n_0 against A dR(u), correlated
        # with the timing error). All of it is tabulated over u in [-1, 1].
        K = cfg.spline_halfwidth_samples
        offs = np.arange(-K, K + 1)
        n_u = 512
        self._u_table = -1.0 + 2.0 * (np.arange(n_u) + 0.5) / n_u          # bin centres
        base = self._autocorr(offs[None, :] - self._u_table[:, None])      # R_rr(o - u)
        eps = 1e-6 * float(self._autocorr(np.zeros(1))[0])
        cols = [base]
        for k in range(2 * K + 1):
            for sgn in (1.0, -1.0):
                c = base.copy()
                c[:, k] += sgn * eps
                cols.append(c)
        allc = np.concatenate(cols, axis=0)                                # ((1 + 2(2K+1)) U, 2K+1)
        est = _spline_peak_offsets(offs, allc.T).reshape(1 + 2 * (2 * K + 1), n_u)
        self._bias_table = est[0] - self._u_table
        grad = (est[1::2] - est[2::2]).T / (2.0 * eps)                    # (U, 2K+1)
        lag = (offs[:, None] - offs[None, :]).ravel()
        cosm = np.cos(self._omega[:, None] * lag[None, :])
        C_mf = ((R2 * H ** 2 * wts) @ cosm / M).reshape(2 * K + 1, 2 * K + 1)
        C_nn = ((H ** 4 * wts) @ cosm).reshape(2 * K + 1, 2 * K + 1)
        self._F_mf_table = np.einsum("ua,ab,ub->u", grad, C_mf, grad)
        self._F_nn_table = np.einsum("ua,ab,ub->u", grad, C_nn, grad)
        # branch decision: D = n_s - n_0 (s = the neighbour the true peak leans to)
        sgn_u = np.where(self._u_table >= 0.0, 1, -1)
        e = np.zeros((n_u, 2 * K + 1))
        e[np.arange(n_u), K + sgn_u] = 1.0
        e[:, K] -= 1.0
        self._G_mf_table = np.einsum("ua,ab,ub->u", e, C_mf, grad)
        self._G_nn_table = np.einsum("ua,ab,ub->u", e, C_nn, grad)
        self._D_mf = 2.0 * (C_mf[K, K] - C_mf[K, K + 1])
        self._D_nn = 2.0 * (C_nn[K, K] - C_nn[K, K + 1])
        self._dR_table = self._autocorr(sgn_u - self._u_table) - self._autocorr(-self._u_table)

    def _autocorr(self, t):
        """R_rr(t): the replica's autocorrelation at real lags t (samples), band-limited."""
        t = np.asarray(t, dtype=float)
        R2w = self._wts * np.abs(self._R) ** 2 / self.nfft
        return np.cos(t[..., None] * self._omega) @ R2w

    # ------------------------------------------------------------------ geometry
    def _check_range(self, rel, max_check=True):
        rng_m = np.hypot(rel[..., 0], rel[..., 1])
        if np.any(rng_m <= self.min_range_m):
            bad = float(np.min(rng_m))
            raise ValueError(
                f"sender_pos_m/observer_pos_m: range {bad:.3f} m is shorter than the array geometry allows "
                f"((projector_spacing_m + hydrophone_base_m)/2 = {self.min_range_m:.3f} m)")
        if max_check and np.any(rng_m > self.config.max_range_m):
            bad = float(np.max(rng_m))
            raise ValueError(f"sender_pos_m/observer_pos_m: range {bad:.3f} m exceeds max_range_m = "
                             f"{self.config.max_range_m} m")
        return rng_m

    def _path_lengths(self, sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad):
        """Direct path lengths r_ij (..., 2, 2) m, and the relative pose."""
        rel, alpha = _relative_pose(sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad)
        self._check_range(rel)
        P = _projector_positions(rel, alpha, self.l)                         # (..., 2, 2)
        Hy = _hydrophone_positions(self.d)                                   # (2, 2)
        diff = P[..., :, None, :] - Hy[None, :, :]                           # (..., i, j, xy)
        return np.hypot(diff[..., 0], diff[..., 1]), rel, alpha, P

    def true_delays(self, sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad):
        """Noise-free delays in samples at the true sound speed: (tdoa (..., 2), toa (..., 2, 2))."""
        r_ij = self._path_lengths(sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad)[0]
        toa = r_ij * self.fs / self.sound_speed_true_mps
        return toa[..., 0] - toa[..., 1], toa

    def ideal_measurement(self, sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad):
        """What the noise-free sensor reports: the estimator on the exact delays (with the
        receiver's assumed sound speed). Folded to the front half-plane (see the
        module docstring); the measurement model for a filter."""
        tdoa, toa = self.true_delays(sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad)
        return self._estimate(tdoa, toa)

    def _estimate(self, tdoa, toa):
        return estimate_from_delays(tdoa, toa, hydrophone_base_m=self.d, projector_spacing_m=self.l,
                                    sound_speed_mps=self.sound_speed_assumed_mps, sample_rate_hz=self.fs,
                                    estimator=self.config.estimator)

    def _paths(self, sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad):
        """Delays (samples) and amplitudes of every path, shape (2 chirps, 2 hydrophones, n_paths)."""
        sp, sh, op, oh = _pose_arrays(sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad)
        if sp.shape != (2,) or op.shape != (2,) or sh.shape != () or oh.shape != ():
            raise ValueError("measure_signal takes one pose pair: positions of shape (2,), scalar headings")
        r_ij, rel, alpha, P = self._path_lengths(sp, sh, op, oh)
        lengths = [r_ij]
        amps = [1.0 / r_ij]                                         # spherical spreading, 1 at 1 m
        refl = self.config.reflection
        if refl is not None:
            if refl.kind == "surface":
                r_img = np.sqrt(r_ij ** 2 + (2.0 * self.config.depth_m) ** 2)
            else:
                # mirror the projectors across the wall (world frame), then to the observer frame
                n = np.asarray(refl.wall_normal, float)
                n = n / np.hypot(*n)
                p0 = np.asarray(refl.wall_point_m, float)
                c, s = math.cos(oh), math.sin(oh)
                Pw = op + np.stack([c * P[:, 0] - s * P[:, 1], s * P[:, 0] + c * P[:, 1]], axis=-1)
                Pimg = Pw - 2.0 * ((Pw - p0) @ n)[:, None] * n[None, :]
                dxy = Pimg - op
                Pimg_o = np.stack([c * dxy[:, 0] + s * dxy[:, 1], -s * dxy[:, 0] + c * dxy[:, 1]], axis=-1)
                diff = Pimg_o[:, None, :] - _hydrophone_positions(self.d)[None, :, :]
                r_img = np.hypot(diff[..., 0], diff[..., 1])
            lengths.append(r_img)
            amps.append(refl.coefficient / r_img)
        lengths = np.stack(lengths, axis=-1)
        return lengths * self.fs / self.sound_speed_true_mps, np.stack(amps, axis=-1)

    # ------------------------------------------------------------------ signal level
    def synthesize(self, sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad, rng):
        """The four received channels of one sending event, shape (2 chirps: bow, stern;
        2 hydrophones: H1 port, H2 starboard; nfft samples from each chirp's emission).

        Each channel: sum over paths of amplitude x the band-limited MLS delayed by a
        fractional number of samples (exact phase shift exp(-i w tau) on the FFT grid),
        plus white Gaussian noise, all filtered by the pass band. rng: numpy Generator.
        """
        delays, amps = self._paths(sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad)
        if self.config.sync_jitter_s > 0.0:
            delays = delays + rng.standard_normal() * self.config.sync_jitter_s * self.fs
        phase = np.exp(-1j * self._omega[None, None, None, :] * delays[..., None])      # (2, 2, P, nb)
        spec = self._mls_spec * np.einsum("ijp,ijpk->ijk", amps, phase)
        if self.noise_sigma > 0.0:
            noise = rng.standard_normal((2, 2, self.nfft)) * self.noise_sigma
            spec = spec + sfft.rfft(noise, axis=-1)
        return sfft.irfft(self._H * spec, n=self.nfft, axis=-1)

    def process(self, channels, tracker: PeakTracker | None = None):
        """Process one sending event's channels (2, 2, nfft) as the paper does; returns an
        ``MLSMeasurement`` of scalars. ``tracker`` carries the previous peaks of this
        link (updated in place); None: bootstrap from the absolute maxima each time."""
        x = np.asarray(channels, dtype=float)
        if x.shape != (2, 2, self.nfft):
            raise ValueError(f"channels must have shape (2, 2, {self.nfft}), got {x.shape}")
        M = self.nfft
        X = sfft.rfft(x, axis=-1, workers=1)
        # matched filtering against the replica (TOAs) and the two channels' cross-correlation
        mf = sfft.irfft(X * self._R_conj, n=M, axis=-1, workers=1)                     # (2, 2, M)
        xc = sfft.irfft(X[:, 0, :] * np.conj(X[:, 1, :]), n=M, axis=-1, workers=1)      # (2, M)
        if tracker is None:
            tracker = PeakTracker()
        K = self.config.spline_halfwidth_samples
        offs = np.arange(-K, K + 1)
        peaks = np.empty(6, dtype=np.int64)
        rows = np.empty((2 * K + 1, 6))
        # cross-correlations: lags -tdoa_max_lag .. +tdoa_max_lag (the physically possible ones)
        for i in range(2):
            p = _track_peak(xc[i], -self.tdoa_max_lag, self.tdoa_max_lag, tracker.tdoa[i],
                            self.config.tdoa_track_halfwidth_samples)
            peaks[i] = p
            rows[:, i] = xc[i, (p + offs) % M]
        # matched filters: lags 0 .. toa_max_lag
        for i in range(2):
            for j in range(2):
                p = _track_peak(mf[i, j], 0, self.toa_max_lag, tracker.toa[i, j],
                                self.config.toa_track_halfwidth_samples)
                n = 2 + 2 * i + j
                peaks[n] = p
                rows[:, n] = mf[i, j, (p + offs) % M]
        est = peaks + _spline_peak_offsets(offs, rows)
        tdoa = est[:2]
        toa = est[2:].reshape(2, 2)
        tracker.tdoa[:] = tdoa
        tracker.toa[:] = toa
        return self._estimate(tdoa, toa)

    def measure_signal(self, sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad, rng,
                       tracker: PeakTracker | None = None):
        """One sending event at signal level: synthesise, then process. rng: numpy Generator
        (or an int seed); tracker: this link's ``PeakTracker`` (None: no tracking)."""
        rng = np.random.default_rng(rng) if not isinstance(rng, np.random.Generator) else rng
        ch = self.synthesize(sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad, rng)
        return self.process(ch, tracker)

    # ------------------------------------------------------------------ analytic
    def _frac(self, tau):
        return tau - np.round(tau)

    def _table(self, table, u):
        return np.interp(u, self._u_table, table)

    def interpolation_bias_samples(self, delays_samples):
        """Deterministic error (samples) of the cubic-spline peak for noise-free correlation
        peaks at these true delays (direct path only): the peak locking of the
        sub-sample interpolation, a function of the delay's fractional part."""
        return self._table(self._bias_table, self._frac(np.asarray(delays_samples, dtype=float)))

    def _noise_weights(self, toa, tdoa):
        """(alpha, beta, scale) of the sample-noise covariance alpha C_mf + beta C_nn and
        the peak's amplitude, for the TDOAs (..., 2) and the TOAs (..., 2, 2)."""
        r2 = (toa * self.sound_speed_true_mps / self.fs) ** 2                 # 1/A^2 = r^2
        s2 = self.noise_sigma ** 2
        a_toa = 1.0 / np.sqrt(r2)
        alpha_tdoa = s2 * (1.0 / r2[..., 0] + 1.0 / r2[..., 1])
        return (alpha_tdoa, s2 * s2, a_toa[..., 0] * a_toa[..., 1]), (s2, 0.0, a_toa)

    def timing_std_samples(self, toa_samples, tdoa_samples=None, interpolation="spline"):
        """Small-error std (samples) of the measured delays at the true TOAs (..., 2, 2)
        (samples; TDOAs derived from them unless given, (..., 2)).

        Amplitudes from spherical spreading (1/r, unit at 1 m) and the configured SNR.
        interpolation "spline" (default): what the cubic-spline peak estimator realises
        on its main branch, a function of the delay's fractional part (see __init__);
        "ideal": the continuous-peak small-error bound (for a flat full band, the
        Cramer-Rao bound). Returns (tdoa std (..., 2), toa std (..., 2, 2)); the sync
        jitter is not included."""
        toa = np.asarray(toa_samples, dtype=float)
        tdoa = toa[..., 0] - toa[..., 1] if tdoa_samples is None else np.asarray(tdoa_samples, dtype=float)
        out = []
        for tau, (alpha, beta, scale) in zip((tdoa, toa), self._noise_weights(toa, tdoa)):
            if interpolation == "ideal":
                var = alpha * self._K_mf + beta * self._K_nn
            elif interpolation == "spline":
                u = self._frac(tau)
                var = alpha * self._table(self._F_mf_table, u) + beta * self._table(self._F_nn_table, u)
            else:
                raise ValueError(f"interpolation must be 'spline' or 'ideal', got {interpolation!r}")
            out.append(np.sqrt(var) / scale)
        return out[0], out[1]

    def _realised_delay(self, tau, alpha, beta, scale, z_e, z_b):
        """A measured delay as the spline estimator realises it: branch, bias, noise."""
        u0 = self._frac(tau)
        s = np.where(u0 >= 0.0, 1.0, -1.0)
        u1 = u0 - s
        var0 = alpha * self._table(self._F_mf_table, u0) + beta * self._table(self._F_nn_table, u0)
        var1 = alpha * self._table(self._F_mf_table, u1) + beta * self._table(self._F_nn_table, u1)
        var_d = alpha * self._D_mf + beta * self._D_nn
        cov = alpha * self._table(self._G_mf_table, u0) + beta * self._table(self._G_nn_table, u0)
        with np.errstate(divide="ignore", invalid="ignore"):
            rho = np.clip(np.where(var0 * var_d > 0, cov / np.sqrt(var0 * var_d), 0.0), -1.0, 1.0)
        z_d = rho * z_e + np.sqrt(1.0 - rho * rho) * z_b
        flip = scale * self._table(self._dR_table, u0) + np.sqrt(var_d) * z_d > 0.0
        b0 = self._table(self._bias_table, u0)
        b1 = self._table(self._bias_table, u1)
        return tau + np.where(flip, b1 + np.sqrt(var1) / scale * z_e, b0 + np.sqrt(var0) / scale * z_e)

    def measure_analytic(self, sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad,
                         rng=None, normals=None, interpolation_bias=True):
        """The analytic mode over a batch: the true delays with the errors the signal
        mode's estimator realises at this SNR, through the same eqs. (1)-(10).

        Each delay gets a Gaussian timing error with the SNR-dependent std of
        ``timing_std_samples``; with interpolation_bias=True (default) also the spline's
        deterministic peak locking (``interpolation_bias_samples``) and, near half-sample
        delays, the noise-driven choice between two integer peaks. Exactly one of rng
        (numpy Generator) and normals is given: standard normals of shape batch + (13,):
        2 TDOA, 4 TOA (row-major i, j), 1 sync jitter, then 2 + 4 for the branch choice.
        Returns an ``MLSMeasurement`` of arrays with the batch's shape. A small-error
        model of the direct path: no outliers (lost peaks) and no reflection; see
        ``benchmarks/mls_analytic_vs_signal.py`` for where it stands for the signal mode.
        ``measure_analytic_with_bounds`` returns this and ``error_bounds`` together."""
        _check_noise_source(rng, normals)
        tdoa, toa = self.true_delays(sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad)
        return self._measure_from_delays(tdoa, toa, rng, normals, interpolation_bias)

    def error_bounds(self, sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad,
                     as_printed=False):
        """Bounds (11)-(13) at these poses with the SNR-dependent Delta-tau of
        ``timing_std_samples`` (see ``mls_error_bounds``): (azimuth rad, range m, heading rad).
        as_printed uses the paper's formulas with Delta-tau = the larger TDOA std."""
        tdoa, toa = self.true_delays(sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad)
        return self._bounds_from_delays(tdoa, toa, as_printed)

    def measure_analytic_with_bounds(self, sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad,
                                     rng=None, normals=None, interpolation_bias=True):
        """``measure_analytic`` and ``error_bounds`` of the same poses, the geometry and
        true delays computed once: (``MLSMeasurement``, (azimuth rad, range m, heading
        rad) bounds), each identical to what the two methods return separately. What a
        simulator's sending event needs: the measurement and its noise model."""
        _check_noise_source(rng, normals)
        tdoa, toa = self.true_delays(sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad)
        return (self._measure_from_delays(tdoa, toa, rng, normals, interpolation_bias),
                self._bounds_from_delays(tdoa, toa))

    def _measure_from_delays(self, tdoa, toa, rng, normals, interpolation_bias):
        """``measure_analytic`` from the true delays (``true_delays``); they are not modified."""
        batch = tdoa.shape[:-1]
        if normals is None:
            if not isinstance(rng, np.random.Generator):
                raise ValueError("rng must be a numpy Generator")
            z = rng.standard_normal(batch + (self.N_NORMALS,))
        else:
            z = np.asarray(normals, dtype=float)
            if z.shape != batch + (self.N_NORMALS,):
                raise ValueError(f"normals must have shape {batch + (self.N_NORMALS,)}, got {z.shape}")
        jitter = z[..., 6] * self.config.sync_jitter_s * self.fs
        toa = toa + jitter[..., None, None]                 # the arrivals move; their TDOA does not
        z_tdoa, z_toa = z[..., 0:2], z[..., 2:6].reshape(batch + (2, 2))
        if interpolation_bias:
            (a1, b1, s1), (a2, b2, s2) = self._noise_weights(toa, tdoa)
            tdoa_m = self._realised_delay(tdoa, a1, b1, s1, z_tdoa, z[..., 7:9])
            toa_m = self._realised_delay(toa, a2, b2, s2, z_toa, z[..., 9:13].reshape(batch + (2, 2)))
        else:
            s_tdoa, s_toa = self.timing_std_samples(toa, tdoa)
            tdoa_m = tdoa + s_tdoa * z_tdoa
            toa_m = toa + s_toa * z_toa
        return self._estimate(tdoa_m, toa_m)

    def _bounds_from_delays(self, tdoa, toa, as_printed=False):
        """``error_bounds`` from the true delays (``true_delays``)."""
        ideal = self._estimate(tdoa, toa)
        s_tdoa, s_toa = self.timing_std_samples(toa)
        if as_printed:
            s_tdoa = np.max(s_tdoa, axis=-1, keepdims=True)
        b = mls_error_bounds(ideal.sub_azimuths_rad, ideal.sub_ranges_m, ideal.range_m,
                             hydrophone_base_m=self.d, projector_spacing_m=self.l,
                             sound_speed_mps=self.sound_speed_assumed_mps, sample_rate_hz=self.fs,
                             tdoa_std_samples=s_tdoa, toa_std_samples=s_toa, as_printed=as_printed)
        if self.config.sync_jitter_s > 0.0 and not as_printed:
            d_r = np.sqrt(b[1] ** 2 + (self.sound_speed_assumed_mps * self.config.sync_jitter_s) ** 2)
            b = (b[0], d_r, b[2])
        return b


# --------------------------------------------------------------------------- peak picking
def _track_peak(seq, lag_lo, lag_hi, prev, halfwidth):
    """Integer lag of the correlation peak within [lag_lo, lag_hi] (negative lags wrap).

    Peak tracking (paper section 2.1): the maximum within +-halfwidth of the previous
    peak; bootstrapped from the absolute maximum when there is no previous peak. If
    the windowed maximum sits on the window's edge and is not a local maximum (the
    peak has left the window), the tracker re-bootstraps from the absolute maximum
    rather than creeping after it over several events (our choice; the paper does
    not say)."""
    M = seq.shape[0]
    lags = np.arange(lag_lo, lag_hi + 1)
    vals = seq[lags % M]
    if np.isfinite(prev):
        c = int(round(prev))
        lo = max(c - halfwidth, lag_lo)
        hi = min(c + halfwidth, lag_hi)
        if lo <= hi:
            w = vals[lo - lag_lo: hi - lag_lo + 1]
            k = int(np.argmax(w))
            p = lo + k
            at_edge = (k == 0 and p > lag_lo) or (k == len(w) - 1 and p < lag_hi)
            if not at_edge or seq[(p - 1) % M] <= seq[p % M] >= seq[(p + 1) % M]:
                return p
    return lag_lo + int(np.argmax(vals))


def _spline_peak_offsets(offs, rows):
    """Sub-sample peak offsets in [-1, 1] from samples ``rows`` (2K+1, n) at offsets ``offs``
    around integer peaks: maximum of a cubic spline (scipy CubicSpline, not-a-knot)
    over the two intervals next to the peak, from the closed-form roots of its
    derivative."""
    cs = CubicSpline(offs, rows, axis=0)
    K = (len(offs) - 1) // 2
    best_val = np.full(rows.shape[1], -np.inf)
    best_off = np.zeros(rows.shape[1])
    for seg, x0 in ((K - 1, -1.0), (K, 0.0)):
        a, b, c, d0 = cs.c[0, seg], cs.c[1, seg], cs.c[2, seg], cs.c[3, seg]
        # stationary points of a t^3 + b t^2 + c t + d on t in [0, 1]
        qa, qb, qc = 3.0 * a, 2.0 * b, c
        disc = qb * qb - 4.0 * qa * qc
        sq = np.sqrt(np.maximum(disc, 0.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            lin = np.abs(qa) < 1e-14 * (np.abs(qb) + np.abs(qc) + 1e-300)
            t1 = np.where(lin, -qc / np.where(qb == 0, np.inf, qb), (-qb + sq) / (2.0 * qa))
            t2 = np.where(lin, np.nan, (-qb - sq) / (2.0 * qa))
        t1 = np.where(disc < 0, np.nan, t1)
        t2 = np.where(disc < 0, np.nan, t2)
        for t in (np.zeros_like(a), np.ones_like(a), t1, t2):
            ok = np.isfinite(t) & (t >= 0.0) & (t <= 1.0)
            tt = np.where(ok, t, 0.0)
            val = np.where(ok, ((a * tt + b) * tt + c) * tt + d0, -np.inf)
            better = val > best_val
            best_val = np.where(better, val, best_val)
            best_off = np.where(better, x0 + tt, best_off)
    return best_off
