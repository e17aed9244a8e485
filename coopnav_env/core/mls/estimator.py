"""The MLS sensor's estimator, eqs. (1)-(10) of Kottege & Zimmer (Acoustics '08):
delays -> sub-azimuths, azimuth, sub-ranges, range, heading. Shared by both modes:
the signal level feeds it the delays its correlators measure, the analytic mode the
true delays plus modelled timing errors.

Errata and choices (implemented in ``estimate_from_delays``):

* eq. (2) writes beta = tan^-1(sqrt(d^2 - delta^2) / delta); with a one-argument
  arctangent beta would be negative for delta < 0 and eq. (3) would then give
  sub-azimuths below -90 deg. The physics is beta = arccos(delta/d) in [0, 180] deg,
  i.e. the two-argument arctangent; we use that. Noise can make |delta| > d near
  +-90 deg, where the root is imaginary: delta is clipped to [-d, d].
* eq. (4)'s [x]_adj only wraps values within one turn outside (-180, 180]; we wrap
  any angle (identical on its domain; ``geometry.wrap_angle_rad``).
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
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from .geometry import wrap_angle_rad


class MLSMeasurement(NamedTuple):
    """One (or a batch of) MLS measurements. Angles rad, lengths m, delays in samples."""

    azimuth_rad: np.ndarray  # eq. (5) or the projectors' midpoint bearing, in [-pi/2, pi/2]
    range_m: np.ndarray  # eq. (9)
    heading_rad: np.ndarray  # eq. (10), in (-pi, pi]
    sub_azimuths_rad: np.ndarray  # (..., 2): theta_1 (bow), theta_2 (stern), eqs. (2)-(4)
    sub_ranges_m: np.ndarray  # (..., 2): r_1, r_2, eq. (8)
    tdoa_samples: np.ndarray  # (..., 2): tau_0^i, delay of H1's channel behind H2's, chirp i
    toa_samples: np.ndarray  # (..., 2, 2): tau_0^ij, projector i to hydrophone j, from emission


def estimate_from_delays(
    tdoa_samples: ArrayLike,
    toa_samples: ArrayLike,
    *,
    hydrophone_base_m: float,
    projector_spacing_m: float,
    sound_speed_mps: float,
    sample_rate_hz: float,
    estimator: str = "exact",
) -> MLSMeasurement:
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
        theta = 0.5 * (theta_i[..., 0] + theta_i[..., 1])  # eq. (5)
    else:
        # Near-field sub-azimuths: r_i2^2 - r_i1^2 = 2 r_i d sin(theta_i) exactly, and
        # r_i2^2 - r_i1^2 = -delta_i (r_i1 + r_i2); eq. (2)-(3) are its plane-wave limit
        # sin(theta_i) = -delta_i / d.
        scale = (r_ij[..., 0] + r_ij[..., 1]) / np.maximum(2.0 * r_i, 1e-12)
        theta_i = np.arcsin(np.clip(np.sin(theta_ff) * scale, -1.0, 1.0))
        # In place of eq. (5) (the mean of the sub-azimuths, biased when r ~ l): the
        # bearing of the projectors' midpoint located by (r_i, theta_i).
        theta = np.arctan2(
            r_i[..., 0] * np.sin(theta_i[..., 0]) + r_i[..., 1] * np.sin(theta_i[..., 1]),
            r_i[..., 0] * np.cos(theta_i[..., 0]) + r_i[..., 1] * np.cos(theta_i[..., 1]),
        )

    # eq. (10): heading = direction of the stern-to-bow vector P2 -> P1; tan^-1 is
    # the quadrant-aware arctangent (the heading covers the full circle)
    alpha = wrap_angle_rad(
        np.arctan2(
            r_i[..., 0] * np.sin(theta_i[..., 0]) - r_i[..., 1] * np.sin(theta_i[..., 1]),
            r_i[..., 0] * np.cos(theta_i[..., 0]) - r_i[..., 1] * np.cos(theta_i[..., 1]),
        )
    )
    return MLSMeasurement(theta, r, alpha, theta_i, r_i, tau_i, tau_ij)
