"""Configuration of the MLS sensor: ``MLSConfig`` (the paper's tank array where it
gives values, assumptions marked [U]) and ``Reflection`` (one specular path by the
image method)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


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
        if not (
            isinstance(self.snr_db_at_1m, (int, float))
            and not math.isnan(self.snr_db_at_1m)
            and self.snr_db_at_1m > -math.inf
        ):
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
