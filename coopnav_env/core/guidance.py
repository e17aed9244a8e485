"""Planned survey paths and line-of-sight guidance on the vehicle's own estimate.

Paths are waypoint lists (east, north, depth) built from a scenario config.
Guidance is the scheme of Matos & Cruz, Fig. 5: project the vehicle's position
V on the segment W_{i-1} -> W_i to get P, take Q on the segment with
|W_i Q| = alpha |W_i P|, and steer from V towards Q. The vehicle steers on its
*estimate* of V, so estimation error moves the real vehicle off the line.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numba import njit
from numpy.typing import ArrayLike

if TYPE_CHECKING:
    from ..scenarios import ScenarioConfig


def _lawnmower(origin, area, spacing, depth):
    e0, n0 = origin
    w, h = area
    n_tracks = int(np.floor(h / spacing + 1e-9)) + 1
    pts = []
    for i in range(n_tracks):
        north = n0 + i * spacing
        row = [(e0, north), (e0 + w, north)]
        pts.extend(row if i % 2 == 0 else row[::-1])
    return np.array([(e, n, depth) for e, n in pts])


def _circle(center, radius, laps, depth_start, depth_end, n_per_lap=24):
    n = max(int(np.ceil(laps * n_per_lap)), 2) + 1
    ang = np.linspace(0.0, 2 * np.pi * laps, n)
    # start on the south point, go clockwise when seen from above
    east = center[0] - radius * np.sin(ang)
    north = center[1] - radius * np.cos(ang)
    depth = np.linspace(depth_start, depth_end, n)
    return np.stack([east, north, depth], -1)


def build_path(config: ScenarioConfig, vehicle_index: int = 0) -> tuple[np.ndarray, bool]:
    """Waypoints (W, 3) of one survey vehicle and whether it holds station.

    Several survey vehicles fly the same pattern shifted north by
    ``survey_spacing_m`` each.
    """
    c = config
    e0, n0 = c.survey_origin_m
    origin = (e0, n0 + vehicle_index * c.survey_spacing_m)
    center = (origin[0] + c.survey_area_m[0] / 2, origin[1] + c.survey_area_m[1] / 2)
    hover = False
    if c.survey_path == "lawnmower":
        wp = _lawnmower(origin, c.survey_area_m, c.lawnmower_spacing_m, c.depth_m)
    elif c.survey_path == "circle":
        wp = _circle(center, c.circle_radius_m, c.circle_laps, c.depth_m, c.depth_m)
    elif c.survey_path == "spiral":
        end = c.spiral_end_depth_m if c.spiral_end_depth_m > c.depth_m else c.depth_m + 20.0
        wp = _circle(center, c.circle_radius_m, c.circle_laps, c.depth_m, end)
    elif c.survey_path == "line":
        wp = np.array(
            [
                (center[0] - c.line_length_m / 2, center[1], c.depth_m),
                (center[0] + c.line_length_m / 2, center[1], c.depth_m),
            ]
        )
    elif c.survey_path == "stationary":
        wp = np.array([(center[0], center[1], c.depth_m)] * 2)
        hover = True
    elif c.survey_path == "waypoints":
        wp = np.asarray(c.waypoints_m, dtype=float)
        if wp.ndim != 2 or wp.shape[1] != 3 or not np.all(np.isfinite(wp)):
            raise ValueError("waypoints_m must be a list of finite (east, north, depth) triples")
        wp = wp + np.array([0.0, vehicle_index * c.survey_spacing_m, 0.0])
    else:  # validated in the config; kept for safety
        raise ValueError(f"unknown survey_path {c.survey_path!r}")
    if c.path_repeats > 1 and not hover:
        legs = [wp] + [(wp[::-1] if i % 2 else wp)[1:] for i in range(1, c.path_repeats)]
        wp = np.concatenate(legs, 0)
    return wp, hover


def path_length_m(waypoints: np.ndarray) -> float:
    return float(np.sum(np.linalg.norm(np.diff(waypoints[:, :2], axis=0), axis=1)))


@njit(cache=True)
def los_point(est: complex, seg_start: complex, seg_end: complex, alpha: float) -> tuple[complex, float, float]:
    """Line-of-sight point Q for one vehicle (complex east + 1j*north positions).

    Returns (Q, along, seg_len): P = W_{i-1} + along * t is the projection of the
    estimate V on the segment (t its unit direction), and
    Q = W_i + alpha (P - W_i) = W_{i-1} + (alpha * along + (1 - alpha) * len) * t.
    """
    d = seg_end - seg_start
    seg_len = abs(d)
    t = d / seg_len if seg_len > 0.0 else 1.0 + 0.0j
    along = ((est - seg_start) * t.conjugate()).real
    return seg_start + (alpha * along + (1.0 - alpha) * seg_len) * t, along, seg_len


def los_target(
    est_h: ArrayLike, seg_start: ArrayLike, seg_end: ArrayLike, alpha: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``los_point`` over arrays (for analysis and tests; the simulator calls los_point)."""
    return np.vectorize(
        lambda e, a, b: los_point(complex(e), complex(a), complex(b), float(alpha)), otypes=[complex, float, float]
    )(est_h, seg_start, seg_end)
