"""Signal level of the MLS sensor (Kottege & Zimmer, Acoustics '08, section 2.1).

A sending event is two maximum length sequences (MLS), one from the sender's bow
projector P1 and one from its stern projector P2, each recorded on the observer's
hydrophones H1, H2. ``SignalChain`` synthesises the four channels (fractional delays
by an exact FFT phase shift of the band-limited sequence, spherical spreading 1/r,
optionally one surface or wall reflection by the image method, white Gaussian noise
at a stated SNR, all band-passed by the transducer/receiver response) and processes
them as the paper does: FFT cross-correlation of the two channels and FFT matched
filtering against the replica, peak tracking around the previous peak (bootstrapped
from the absolute maximum), cubic-spline sub-sample refinement. The delays it
returns go through eqs. (1)-(10) (``estimator.estimate_from_delays``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.fft as sfft
from numpy.typing import ArrayLike
from scipy.interpolate import CubicSpline
from scipy.signal import max_len_seq

from .config import MLSConfig
from .geometry import ArrayGeometry, hydrophone_positions, pose_arrays

_TWO_PI = 2.0 * math.pi


@dataclass
class PeakTracker:
    """Peak-tracking state of one observer-sender link: the previous peak lags
    (samples) of the two cross-correlations and the four matched filters; NaN until
    bootstrapped from the absolute maximum. Keep one per link; ``reset()`` after a
    long silence."""

    tdoa: np.ndarray = field(default_factory=lambda: np.full(2, np.nan))
    toa: np.ndarray = field(default_factory=lambda: np.full((2, 2), np.nan))

    def reset(self) -> None:
        self.tdoa[:] = np.nan
        self.toa[:] = np.nan


class SignalChain:
    """The MLS, the receive window, the pass band and the replica of one
    configuration; synthesises an event's four channels and measures their delays.

    config: an ``MLSConfig``; geometry: its ``ArrayGeometry`` (the true sound speed);
    sound_speed_assumed_mps: the receiver's (it sizes the TDOA search)."""

    def __init__(self, config: MLSConfig, geometry: ArrayGeometry, sound_speed_assumed_mps: float) -> None:
        cfg = config
        self.config = cfg
        self.geometry = geometry
        self.fs = geometry.fs
        # MLS chips (+-1), one per sample
        self.n_chips = 2**cfg.mls_order - 1
        chips = max_len_seq(cfg.mls_order)[0].astype(float) * 2.0 - 1.0
        # receive window per chirp: the sequence, the longest direct path from the
        # farthest projector to the farthest hydrophone (+ an image path), a guard
        max_path = cfg.max_range_m + 0.5 * (geometry.l + geometry.d)
        if cfg.reflection is not None and cfg.reflection.kind == "surface":
            max_path = math.hypot(max_path, 2.0 * cfg.depth_m)
        self.toa_max_lag = math.ceil(max_path * self.fs / geometry.sound_speed_true_mps) + 8
        self.tdoa_max_lag = math.ceil(geometry.d * self.fs / sound_speed_assumed_mps) + 2
        guard = 64 + 2 * self.tdoa_max_lag
        self.nfft = sfft.next_fast_len(self.n_chips + self.toa_max_lag + guard, real=True)
        M = self.nfft
        nb = M // 2 + 1
        f_hz = np.arange(nb) * self.fs / M
        self.omega = _TWO_PI * np.arange(nb) / M  # rad per sample
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
        self.H = H
        self.mls_spec = sfft.rfft(chips, n=M)  # emitted chips on the M-grid
        self.R = H * self.mls_spec  # the (recorded) replica's spectrum
        self.R_conj = np.conj(self.R)
        self.replica = sfft.irfft(self.R, n=M)

        # noise: white N(0, sigma_w^2) per sample, band-passed by H; sigma_w from the
        # in-band SNR of the direct path at 1 m (unit amplitude at 1 m)
        p_signal = float(np.sum(self.replica**2)) / self.n_chips
        h_energy = float(np.sum(sfft.irfft(H, n=M) ** 2))  # in-band noise power / sigma_w^2
        snr = 10.0 ** (cfg.snr_db_at_1m / 10.0)
        self.noise_sigma = 0.0 if math.isinf(snr) else math.sqrt(p_signal / (snr * h_energy))

    # ------------------------------------------------------------------ propagation
    def paths(
        self,
        sender_pos_m: ArrayLike,
        sender_heading_rad: ArrayLike,
        observer_pos_m: ArrayLike,
        observer_heading_rad: ArrayLike,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Delays (samples) and amplitudes of every path, shape (2 chirps, 2 hydrophones, n_paths)."""
        sp, sh, op, oh = pose_arrays(sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad)
        if sp.shape != (2,) or op.shape != (2,) or sh.shape != () or oh.shape != ():
            raise ValueError("measure_signal takes one pose pair: positions of shape (2,), scalar headings")
        r_ij, _rel, _alpha, P = self.geometry.path_lengths(sp, sh, op, oh)
        lengths = [r_ij]
        amps = [1.0 / r_ij]  # spherical spreading, 1 at 1 m
        refl = self.config.reflection
        if refl is not None:
            if refl.kind == "surface":
                r_img = np.sqrt(r_ij**2 + (2.0 * self.config.depth_m) ** 2)
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
                diff = Pimg_o[:, None, :] - hydrophone_positions(self.geometry.d)[None, :, :]
                r_img = np.hypot(diff[..., 0], diff[..., 1])
            lengths.append(r_img)
            amps.append(refl.coefficient / r_img)
        lengths_m = np.stack(lengths, axis=-1)
        return lengths_m * self.fs / self.geometry.sound_speed_true_mps, np.stack(amps, axis=-1)

    # ------------------------------------------------------------------ synthesis
    def synthesize(
        self,
        sender_pos_m: ArrayLike,
        sender_heading_rad: ArrayLike,
        observer_pos_m: ArrayLike,
        observer_heading_rad: ArrayLike,
        rng: np.random.Generator,
    ) -> np.ndarray:
        """The four received channels of one sending event (see ``MLSSensor.synthesize``)."""
        delays, amps = self.paths(sender_pos_m, sender_heading_rad, observer_pos_m, observer_heading_rad)
        if self.config.sync_jitter_s > 0.0:
            delays = delays + rng.standard_normal() * self.config.sync_jitter_s * self.fs
        phase = np.exp(-1j * self.omega[None, None, None, :] * delays[..., None])  # (2, 2, P, nb)
        spec = self.mls_spec * np.einsum("ijp,ijpk->ijk", amps, phase)
        if self.noise_sigma > 0.0:
            noise = rng.standard_normal((2, 2, self.nfft)) * self.noise_sigma
            spec = spec + sfft.rfft(noise, axis=-1)
        return sfft.irfft(self.H * spec, n=self.nfft, axis=-1)

    # ------------------------------------------------------------------ processing
    def measure_delays(self, channels: np.ndarray, tracker: PeakTracker | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The delays of one sending event's channels (2, 2, nfft): correlation, peak
        tracking, spline refinement. Returns (tdoa (2,), toa (2, 2)) in samples; the
        tracker (if given) is updated in place."""
        x = np.asarray(channels, dtype=float)
        if x.shape != (2, 2, self.nfft):
            raise ValueError(f"channels must have shape (2, 2, {self.nfft}), got {x.shape}")
        M = self.nfft
        X = sfft.rfft(x, axis=-1, workers=1)
        # matched filtering against the replica (TOAs) and the two channels' cross-correlation
        mf = sfft.irfft(X * self.R_conj, n=M, axis=-1, workers=1)  # (2, 2, M)
        xc = sfft.irfft(X[:, 0, :] * np.conj(X[:, 1, :]), n=M, axis=-1, workers=1)  # (2, M)
        if tracker is None:
            tracker = PeakTracker()
        K = self.config.spline_halfwidth_samples
        offs = np.arange(-K, K + 1)
        peaks = np.empty(6, dtype=np.int64)
        rows = np.empty((2 * K + 1, 6))
        # cross-correlations: lags -tdoa_max_lag .. +tdoa_max_lag (the physically possible ones)
        for i in range(2):
            p = track_peak(
                xc[i], -self.tdoa_max_lag, self.tdoa_max_lag, tracker.tdoa[i], self.config.tdoa_track_halfwidth_samples
            )
            peaks[i] = p
            rows[:, i] = xc[i, (p + offs) % M]
        # matched filters: lags 0 .. toa_max_lag
        for i in range(2):
            for j in range(2):
                p = track_peak(
                    mf[i, j], 0, self.toa_max_lag, tracker.toa[i, j], self.config.toa_track_halfwidth_samples
                )
                n = 2 + 2 * i + j
                peaks[n] = p
                rows[:, n] = mf[i, j, (p + offs) % M]
        est = peaks + spline_peak_offsets(offs, rows)
        tdoa = est[:2]
        toa = est[2:].reshape(2, 2)
        tracker.tdoa[:] = tdoa
        tracker.toa[:] = toa
        return tdoa, toa


# --------------------------------------------------------------------------- peak picking
def track_peak(seq: np.ndarray, lag_lo: int, lag_hi: int, prev: float, halfwidth: int) -> int:
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
        c = round(prev)
        lo = max(c - halfwidth, lag_lo)
        hi = min(c + halfwidth, lag_hi)
        if lo <= hi:
            w = vals[lo - lag_lo : hi - lag_lo + 1]
            k = int(np.argmax(w))
            p = lo + k
            at_edge = (k == 0 and p > lag_lo) or (k == len(w) - 1 and p < lag_hi)
            if not at_edge or seq[(p - 1) % M] <= seq[p % M] >= seq[(p + 1) % M]:
                return p
    return lag_lo + int(np.argmax(vals))


def spline_peak_offsets(offs: np.ndarray, rows: np.ndarray) -> np.ndarray:
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
