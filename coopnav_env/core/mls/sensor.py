"""``MLSSensor``: the MLS sensor of one configuration, a facade over the array
geometry (``geometry.ArrayGeometry``), the signal chain (``signal.SignalChain``), the
estimator of eqs. (1)-(10) (``estimator.estimate_from_delays``) and the analytic
mode's timing model (``analytic.AnalyticModel``)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from coopnav_env.core.acoustics import mackenzie_sound_speed

from .analytic import N_NORMALS, AnalyticModel, check_noise_source
from .config import MLSConfig
from .estimator import MLSMeasurement, estimate_from_delays
from .geometry import ArrayGeometry
from .signal import PeakTracker, SignalChain


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

    Parts: ``geometry`` (``ArrayGeometry``), ``signal`` (``SignalChain``),
    ``analytic`` (``AnalyticModel``).
    """

    N_NORMALS = N_NORMALS

    def __init__(self, config: MLSConfig | None = None) -> None:
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
        self.geometry = ArrayGeometry(self.d, self.l, self.fs, self.sound_speed_true_mps, cfg.max_range_m)
        self.signal = SignalChain(cfg, self.geometry, self.sound_speed_assumed_mps)
        self.analytic = AnalyticModel(self.signal, self._estimate, self.sound_speed_assumed_mps)

    # the parts' numbers a caller reads
    min_range_m = property(
        lambda self: self.geometry.min_range_m,
        doc="shortest range (m) the arrays allow: (projector_spacing_m + hydrophone_base_m)/2",
    )
    n_chips = property(lambda self: self.signal.n_chips, doc="MLS length (chips = samples)")
    nfft = property(lambda self: self.signal.nfft, doc="samples per channel (the receive window)")
    toa_max_lag = property(lambda self: self.signal.toa_max_lag, doc="largest TOA searched (samples)")
    tdoa_max_lag = property(lambda self: self.signal.tdoa_max_lag, doc="largest |TDOA| searched (samples)")
    replica = property(lambda self: self.signal.replica, doc="the band-passed MLS the receiver correlates with")
    noise_sigma = property(lambda self: self.signal.noise_sigma, doc="std of the white noise per sample")

    # ------------------------------------------------------------------ geometry
    def true_delays(
        self,
        sender_pos_m: ArrayLike,
        sender_heading_rad: ArrayLike,
        observer_pos_m: ArrayLike,
        observer_heading_rad: ArrayLike,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Noise-free delays in samples at the true sound speed: (tdoa (..., 2), toa (..., 2, 2))."""
        return self.geometry.true_delays(sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad)

    def ideal_measurement(
        self,
        sender_pos_m: ArrayLike,
        sender_heading_rad: ArrayLike,
        observer_pos_m: ArrayLike,
        observer_heading_rad: ArrayLike,
    ) -> MLSMeasurement:
        """What the noise-free sensor reports: the estimator on the exact delays (with the
        receiver's assumed sound speed). Folded to the front half-plane (see the
        package docstring); the measurement model for a filter."""
        tdoa, toa = self.true_delays(sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad)
        return self._estimate(tdoa, toa)

    def _estimate(self, tdoa, toa):
        return estimate_from_delays(
            tdoa,
            toa,
            hydrophone_base_m=self.d,
            projector_spacing_m=self.l,
            sound_speed_mps=self.sound_speed_assumed_mps,
            sample_rate_hz=self.fs,
            estimator=self.config.estimator,
        )

    def _paths(self, sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad):
        """Delays (samples) and amplitudes of every path, shape (2 chirps, 2 hydrophones, n_paths)."""
        return self.signal.paths(sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad)

    # ------------------------------------------------------------------ signal level
    def synthesize(
        self,
        sender_pos_m: ArrayLike,
        sender_heading_rad: ArrayLike,
        observer_pos_m: ArrayLike,
        observer_heading_rad: ArrayLike,
        rng: np.random.Generator,
    ) -> np.ndarray:
        """The four received channels of one sending event, shape (2 chirps: bow, stern;
        2 hydrophones: H1 port, H2 starboard; nfft samples from each chirp's emission).

        Each channel: sum over paths of amplitude x the band-limited MLS delayed by a
        fractional number of samples (exact phase shift exp(-i w tau) on the FFT grid),
        plus white Gaussian noise, all filtered by the pass band. rng: numpy Generator.
        """
        return self.signal.synthesize(sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad, rng)

    def process(self, channels: np.ndarray, tracker: PeakTracker | None = None) -> MLSMeasurement:
        """Process one sending event's channels (2, 2, nfft) as the paper does; returns an
        ``MLSMeasurement`` of scalars. ``tracker`` carries the previous peaks of this
        link (updated in place); None: bootstrap from the absolute maxima each time."""
        tdoa, toa = self.signal.measure_delays(channels, tracker)
        return self._estimate(tdoa, toa)

    def measure_signal(
        self,
        sender_pos_m: ArrayLike,
        sender_heading_rad: ArrayLike,
        observer_pos_m: ArrayLike,
        observer_heading_rad: ArrayLike,
        rng: np.random.Generator | int | None,
        tracker: PeakTracker | None = None,
    ) -> MLSMeasurement:
        """One sending event at signal level: synthesise, then process. rng: numpy Generator
        (or an int seed); tracker: this link's ``PeakTracker`` (None: no tracking)."""
        rng = np.random.default_rng(rng) if not isinstance(rng, np.random.Generator) else rng
        ch = self.synthesize(sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad, rng)
        return self.process(ch, tracker)

    # ------------------------------------------------------------------ analytic
    def interpolation_bias_samples(self, delays_samples: ArrayLike) -> np.ndarray:
        """Deterministic error (samples) of the cubic-spline peak for noise-free correlation
        peaks at these true delays (direct path only): the peak locking of the
        sub-sample interpolation, a function of the delay's fractional part."""
        return self.analytic.interpolation_bias_samples(delays_samples)

    def timing_std_samples(
        self, toa_samples: ArrayLike, tdoa_samples: ArrayLike | None = None, interpolation: str = "spline"
    ) -> tuple[np.ndarray, np.ndarray]:
        """Small-error std (samples) of the measured delays at the true TOAs (..., 2, 2)
        (samples; TDOAs derived from them unless given, (..., 2)).

        Amplitudes from spherical spreading (1/r, unit at 1 m) and the configured SNR.
        interpolation "spline" (default): what the cubic-spline peak estimator realises
        on its main branch, a function of the delay's fractional part (see
        ``analytic.AnalyticModel``); "ideal": the continuous-peak small-error bound (for
        a flat full band, the Cramer-Rao bound). Returns (tdoa std (..., 2), toa std
        (..., 2, 2)); the sync jitter is not included."""
        return self.analytic.timing_std_samples(toa_samples, tdoa_samples, interpolation)

    def measure_analytic(
        self,
        sender_pos_m: ArrayLike,
        sender_heading_rad: ArrayLike,
        observer_pos_m: ArrayLike,
        observer_heading_rad: ArrayLike,
        rng: np.random.Generator | None = None,
        normals: ArrayLike | None = None,
        interpolation_bias: bool = True,
    ) -> MLSMeasurement:
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
        check_noise_source(rng, normals)
        tdoa, toa = self.true_delays(sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad)
        return self.analytic.measure_from_delays(tdoa, toa, rng, normals, interpolation_bias)

    def error_bounds(
        self,
        sender_pos_m: ArrayLike,
        sender_heading_rad: ArrayLike,
        observer_pos_m: ArrayLike,
        observer_heading_rad: ArrayLike,
        as_printed: bool = False,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Bounds (11)-(13) at these poses with the SNR-dependent Delta-tau of
        ``timing_std_samples`` (see ``mls_error_bounds``): (azimuth rad, range m, heading rad).
        as_printed uses the paper's formulas with Delta-tau = the larger TDOA std."""
        tdoa, toa = self.true_delays(sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad)
        return self.analytic.bounds_from_delays(tdoa, toa, as_printed)

    def measure_analytic_with_bounds(
        self,
        sender_pos_m: ArrayLike,
        sender_heading_rad: ArrayLike,
        observer_pos_m: ArrayLike,
        observer_heading_rad: ArrayLike,
        rng: np.random.Generator | None = None,
        normals: ArrayLike | None = None,
        interpolation_bias: bool = True,
    ) -> tuple[MLSMeasurement, tuple[np.ndarray, ...]]:
        """``measure_analytic`` and ``error_bounds`` of the same poses, the geometry and
        true delays computed once: (``MLSMeasurement``, (azimuth rad, range m, heading
        rad) bounds), each identical to what the two methods return separately. What a
        simulator's sending event needs: the measurement and its noise model."""
        check_noise_source(rng, normals)
        tdoa, toa = self.true_delays(sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad)
        return (
            self.analytic.measure_from_delays(tdoa, toa, rng, normals, interpolation_bias),
            self.analytic.bounds_from_delays(tdoa, toa),
        )
