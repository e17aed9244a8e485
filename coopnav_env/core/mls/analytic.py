"""Analytic mode of the MLS sensor: the signal level's errors without synthesising a
signal, for a whole batch in numpy.

The true delays get Gaussian timing errors whose standard deviation is the one the
signal level's correlator and spline realise at the link's SNR (the small-error
bound of the spline peak, which depends on the delay's fractional part), plus the
spline's deterministic peak locking and its noise-driven choice between two integer
peaks near half-sample delays, and go through the same eqs. (1)-(10). To first
order the outputs' errors are then exactly the bounds (11)-(13) (corrected,
``geometry.mls_error_bounds``) at that Delta-tau, and they keep what a Gaussian in
(theta, r, alpha) would lose: the correlation of azimuth and heading errors and the
saturation of the sub-azimuths at +-90 deg. It models the direct paths only (no
reflection) and has no outliers.

``AnalyticModel`` tabulates those statistics once per configuration (~0.2 s) from a
``signal.SignalChain`` (its replica and pass band, and its spline peak estimator).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike

from .estimator import MLSMeasurement
from .geometry import mls_error_bounds
from .signal import SignalChain, spline_peak_offsets

N_NORMALS = 13  # standard normals per pair: 2 TDOA, 4 TOA, 1 sync jitter, 2 + 4 branch choices


def check_noise_source(rng: np.random.Generator | None, normals: ArrayLike | None) -> None:
    if (rng is None) == (normals is None):
        raise ValueError("give exactly one of rng and normals")


class AnalyticModel:
    """The timing-error model of one configuration's signal chain.

    chain: the ``SignalChain``; estimate: (tdoa, toa) -> ``MLSMeasurement``, the
    sensor's eqs. (1)-(10) with the receiver's sound speed; sound_speed_assumed_mps:
    that sound speed (for the bounds)."""

    def __init__(
        self,
        chain: SignalChain,
        estimate: Callable[[np.ndarray, np.ndarray], MLSMeasurement],
        sound_speed_assumed_mps: float,
    ) -> None:
        cfg = chain.config
        self.config = cfg
        self.chain = chain
        self.estimate = estimate
        self.sound_speed_assumed_mps = sound_speed_assumed_mps
        self.fs = chain.fs
        self.noise_sigma = chain.noise_sigma
        M = chain.nfft
        nb = M // 2 + 1
        H = chain.H
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
        w2 = wts * chain.omega**2
        R2 = np.abs(chain.R) ** 2
        curv = float(np.sum(w2 * R2))
        self._K_mf = M * float(np.sum(w2 * R2 * H**2)) / curv**2
        self._K_nn = M * M * float(np.sum(w2 * H**4)) / curv**2
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
        self._u_table = -1.0 + 2.0 * (np.arange(n_u) + 0.5) / n_u  # bin centres
        base = self._autocorr(offs[None, :] - self._u_table[:, None])  # R_rr(o - u)
        eps = 1e-6 * float(self._autocorr(np.zeros(1))[0])
        cols = [base]
        for k in range(2 * K + 1):
            for sgn in (1.0, -1.0):
                c = base.copy()
                c[:, k] += sgn * eps
                cols.append(c)
        allc = np.concatenate(cols, axis=0)  # ((1 + 2(2K+1)) U, 2K+1)
        est = spline_peak_offsets(offs, allc.T).reshape(1 + 2 * (2 * K + 1), n_u)
        self._bias_table = est[0] - self._u_table
        grad = (est[1::2] - est[2::2]).T / (2.0 * eps)  # (U, 2K+1)
        lag = (offs[:, None] - offs[None, :]).ravel()
        cosm = np.cos(chain.omega[:, None] * lag[None, :])
        C_mf = ((R2 * H**2 * wts) @ cosm / M).reshape(2 * K + 1, 2 * K + 1)
        C_nn = ((H**4 * wts) @ cosm).reshape(2 * K + 1, 2 * K + 1)
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
        R2w = self._wts * np.abs(self.chain.R) ** 2 / self.chain.nfft
        return np.cos(t[..., None] * self.chain.omega) @ R2w

    def _frac(self, tau):
        return tau - np.round(tau)

    def _table(self, table, u):
        return np.interp(u, self._u_table, table)

    def interpolation_bias_samples(self, delays_samples: ArrayLike) -> np.ndarray:
        """See ``MLSSensor.interpolation_bias_samples``."""
        return self._table(self._bias_table, self._frac(np.asarray(delays_samples, dtype=float)))

    def _noise_weights(self, toa, tdoa):
        """(alpha, beta, scale) of the sample-noise covariance alpha C_mf + beta C_nn and
        the peak's amplitude, for the TDOAs (..., 2) and the TOAs (..., 2, 2)."""
        r2 = (toa * self.chain.geometry.sound_speed_true_mps / self.fs) ** 2  # 1/A^2 = r^2
        s2 = self.noise_sigma**2
        a_toa = 1.0 / np.sqrt(r2)
        alpha_tdoa = s2 * (1.0 / r2[..., 0] + 1.0 / r2[..., 1])
        return (alpha_tdoa, s2 * s2, a_toa[..., 0] * a_toa[..., 1]), (s2, 0.0, a_toa)

    def timing_std_samples(
        self, toa_samples: ArrayLike, tdoa_samples: ArrayLike | None = None, interpolation: str = "spline"
    ) -> tuple[np.ndarray, np.ndarray]:
        """See ``MLSSensor.timing_std_samples``."""
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

    def measure_from_delays(
        self,
        tdoa: np.ndarray,
        toa: np.ndarray,
        rng: np.random.Generator | None,
        normals: ArrayLike | None,
        interpolation_bias: bool,
    ) -> MLSMeasurement:
        """``MLSSensor.measure_analytic`` from the true delays (``true_delays``); they are not modified."""
        batch = tdoa.shape[:-1]
        if normals is None:
            if not isinstance(rng, np.random.Generator):
                raise ValueError("rng must be a numpy Generator")
            z = rng.standard_normal(batch + (N_NORMALS,))
        else:
            z = np.asarray(normals, dtype=float)
            if z.shape != batch + (N_NORMALS,):
                raise ValueError(f"normals must have shape {batch + (N_NORMALS,)}, got {z.shape}")
        jitter = z[..., 6] * self.config.sync_jitter_s * self.fs
        toa = toa + jitter[..., None, None]  # the arrivals move; their TDOA does not
        z_tdoa, z_toa = z[..., 0:2], z[..., 2:6].reshape(batch + (2, 2))
        if interpolation_bias:
            (a1, b1, s1), (a2, b2, s2) = self._noise_weights(toa, tdoa)
            tdoa_m = self._realised_delay(tdoa, a1, b1, s1, z_tdoa, z[..., 7:9])
            toa_m = self._realised_delay(toa, a2, b2, s2, z_toa, z[..., 9:13].reshape(batch + (2, 2)))
        else:
            s_tdoa, s_toa = self.timing_std_samples(toa, tdoa)
            tdoa_m = tdoa + s_tdoa * z_tdoa
            toa_m = toa + s_toa * z_toa
        return self.estimate(tdoa_m, toa_m)

    def bounds_from_delays(
        self, tdoa: np.ndarray, toa: np.ndarray, as_printed: bool = False
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``MLSSensor.error_bounds`` from the true delays (``true_delays``)."""
        ideal = self.estimate(tdoa, toa)
        s_tdoa, s_toa = self.timing_std_samples(toa)
        if as_printed:
            s_tdoa = np.max(s_tdoa, axis=-1, keepdims=True)
        g = self.chain.geometry
        b = mls_error_bounds(
            ideal.sub_azimuths_rad,
            ideal.sub_ranges_m,
            ideal.range_m,
            hydrophone_base_m=g.d,
            projector_spacing_m=g.l,
            sound_speed_mps=self.sound_speed_assumed_mps,
            sample_rate_hz=self.fs,
            tdoa_std_samples=s_tdoa,
            toa_std_samples=s_toa,
            as_printed=as_printed,
        )
        if self.config.sync_jitter_s > 0.0 and not as_printed:
            d_r = np.sqrt(b[1] ** 2 + (self.sound_speed_assumed_mps * self.config.sync_jitter_s) ** 2)
            b = (b[0], d_r, b[2])
        return b
