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

Errata and choices, each stated in full in the module that implements it:

* ``estimator.py``: eq. (2)'s arctangent is the two-argument one (and delta is
  clipped to [-d, d]); ``estimator="exact"`` replaces the plane-wave eqs. (2)-(3) by
  the exact near-field relation and eq. (5) by the bearing of the projectors'
  midpoint (``"paper"``: eqs. 2-5 as printed).
* ``geometry.py``: eq. (4)'s [x]_adj is applied to any angle (``wrap_angle_rad``);
  eq. (12) and the X term of eq. (13) are four times too large, and eq. (13)'s Y
  numerators are not the derivative of eq. (10) (``mls_error_bounds``; the printed
  forms: ``as_printed=True``).
* ``signal.py`` (peak tracking): a peak that has left the tracking window
  re-bootstraps from the absolute maximum (the paper does not say).

Layout (a part per module; ``MLSSensor`` composes them):

* ``config.py``: ``MLSConfig``, ``Reflection``;
* ``geometry.py``: array layout, relative poses, true path lengths and delays
  (``ArrayGeometry``), ``wrap_angle_rad`` (eq. 4), ``geometric_truth``, the error
  bounds (eqs. 11-14, ``mls_error_bounds``) and statistics (eqs. 15-19,
  ``error_statistics``);
* ``estimator.py``: ``MLSMeasurement``, ``estimate_from_delays`` (eqs. 1-10);
* ``signal.py``: ``SignalChain`` (MLS synthesis, fractional delays, spreading,
  reflection image, noise, band pass, FFT correlation), ``PeakTracker``, peak
  tracking and the spline refinement;
* ``analytic.py``: ``AnalyticModel`` (the tabulated timing statistics of the signal
  chain's estimator, the analytic measurement and its bounds);
* ``sensor.py``: ``MLSSensor``, the facade.

Sound speed comes from ``acoustics.mackenzie_sound_speed`` (the project's one home
for it). Mackenzie (1981) is fitted for 25-40 ppt; at 0 ppt (the paper's fresh
water tank) it gives 1481.7 m/s at 20 degC against 1482.4 m/s for fresh water
(Marczak 1997, shared/reference-values.md section 4): 0.05 %, 0.5 mm at 1 m.
"""

from .config import MLSConfig, Reflection
from .estimator import MLSMeasurement, estimate_from_delays
from .geometry import error_statistics, geometric_truth, mls_error_bounds, wrap_angle_rad
from .sensor import MLSSensor
from .signal import PeakTracker

__all__ = [
    "MLSConfig",
    "Reflection",
    "MLSSensor",
    "MLSMeasurement",
    "PeakTracker",
    "estimate_from_delays",
    "mls_error_bounds",
    "geometric_truth",
    "wrap_angle_rad",
    "error_statistics",
]
