"""Information and uncertainty geometry: one home for the Fisher information
matrix, its determinant, the log-determinant of a covariance and the error
ellipse. The reward, the observations, the planners and the plots all call these.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np
from numba import njit, vectorize
from numpy.typing import ArrayLike


def fisher_information(
    target: np.ndarray, beacons: np.ndarray, range_std_m: ArrayLike, horizontal: bool = True
) -> np.ndarray:
    """Fisher information matrix of range-only measurements of ``target``.

    J = sum_i u_i u_i^T / sigma_i^2 with u_i the unit vector from beacon i to the
    target (Sousa, Ferreira & Cruz eq. 4). target: (..., 3); beacons: (..., M, 3);
    range_std_m broadcasts to (..., M). With ``horizontal`` the 2x2 east/north block
    of the 3-D slant geometry is returned (the vehicle's depth is known from its
    depth sensor), else the full 3x3.
    """
    rel = target[..., None, :] - beacons
    u = rel / np.maximum(np.linalg.norm(rel, axis=-1, keepdims=True), 1e-9)
    if horizontal:
        u = u[..., :2]
    w = 1.0 / np.broadcast_to(np.asarray(range_std_m, dtype=float), u.shape[:-1]) ** 2
    return np.einsum("...m,...mi,...mj->...ij", w, u, u)


@vectorize(["float32(float32, float32, float32, float32)", "float64(float64, float64, float64, float64)"], cache=True)
def det2_of(m00: float, m01: float, m10: float, m11: float) -> float:
    """Determinant of a 2x2 matrix from its entries. A ufunc (kernels call it on scalars)."""
    return m00 * m11 - m01 * m10


def det2(M: np.ndarray) -> np.ndarray:
    """Determinant of symmetric 2x2 matrices (..., 2, 2) (``det2_of``)."""
    return det2_of(M[..., 0, 0], M[..., 0, 1], M[..., 1, 0], M[..., 1, 1])


def floored_log(det: ArrayLike) -> np.ndarray:
    """log of determinants, floored at 1e-300 (a collapsed covariance gives a large finite number)."""
    return np.log(np.maximum(det, 1e-300))


def logdet_horizontal(P: np.ndarray) -> np.ndarray:
    """log det of the east/north block of covariances (..., n, n), n >= 2."""
    return floored_log(det2(P[..., :2, :2]))


@njit(cache=True)
def ellipse_of(var_east: float, cov_en: float, var_north: float, n_sigma: float) -> tuple[float, float, float]:
    """Closed-form 2x2 eigendecomposition: (major, minor, bearing) of one covariance.

    n-sigma semi-axes, and the bearing of the major axis (clockwise from north, in [0, pi)).
    """
    mean = 0.5 * (var_east + var_north)
    rad = np.sqrt(0.25 * (var_east - var_north) ** 2 + cov_en * cov_en)
    theta_east = 0.5 * np.arctan2(2.0 * cov_en, var_east - var_north)  # from east, anticlockwise
    bearing = (np.pi / 2 - theta_east) % np.pi
    return n_sigma * np.sqrt(mean + rad), n_sigma * np.sqrt(max(mean - rad, 0.0)), bearing


@njit(cache=True)
def _ellipse_rows(a, b, c, n_sigma, major, minor, bearing):
    for i in range(a.shape[0]):
        major[i], minor[i], bearing[i] = ellipse_of(a[i], b[i], c[i], n_sigma)


# The project's error ellipse: 2-sigma semi-axes, wherever an ellipse is observed, logged or drawn
ELLIPSE_N_SIGMA = 2.0


def error_ellipse(P: ArrayLike, n_sigma: float = ELLIPSE_N_SIGMA) -> tuple[np.ndarray, ...]:
    """Semi-axes and orientation of the horizontal error ellipse of covariances P (..., n, n).

    Returns (major_m, minor_m, bearing_rad) arrays of shape (...): ``ellipse_of``
    applied to the east/north block of each covariance.
    """
    P = np.asarray(P, dtype=float)
    lead = P.shape[:-2]
    a, b, c = (np.ascontiguousarray(P[..., i, j]).reshape(-1) for i, j in ((0, 0), (0, 1), (1, 1)))
    out = [np.empty(a.shape[0]) for _ in range(3)]
    _ellipse_rows(a, b, c, float(n_sigma), *out)
    return tuple(o.reshape(lead) for o in out)


# ------------------------------------------------------------------------------------
# Added for the planners (baselines/) and Sousa's start distance. Everything below is
# additive: the functions above keep their signatures.


def ellipse_to_covariance(
    major_m: ArrayLike, minor_m: ArrayLike, bearing_rad: ArrayLike, n_sigma: float = ELLIPSE_N_SIGMA
) -> np.ndarray:
    """The horizontal covariance (..., 2, 2) (east, north) of an error ellipse.

    The inverse of :func:`error_ellipse`: n-sigma semi-axes and the bearing of the
    major axis (clockwise from north). Observations carry the ellipse; planners
    rebuild the covariance with this.
    """
    major, minor, bearing = np.broadcast_arrays(
        np.asarray(major_m, float), np.asarray(minor_m, float), np.asarray(bearing_rad, float)
    )
    lam1, lam2 = (major / n_sigma) ** 2, (minor / n_sigma) ** 2
    ue, un = np.sin(bearing), np.cos(bearing)  # major axis as an (east, north) unit vector
    P = np.empty(major.shape + (2, 2))
    P[..., 0, 0] = lam1 * ue * ue + lam2 * un * un
    P[..., 1, 1] = lam1 * un * un + lam2 * ue * ue
    P[..., 0, 1] = P[..., 1, 0] = (lam1 - lam2) * ue * un
    return P


def range_information_det(target: np.ndarray, beacons: np.ndarray, range_std_m: ArrayLike = 1.0) -> np.ndarray:
    """det of the horizontal Fisher information of ranges from ``beacons`` to ``target``.

    Sousa, Ferreira & Cruz eq. (4) with 3-D slant geometry: target (..., 3),
    beacons (..., M, 3) -> (...). With ``range_std_m=1`` and two ranges it is
    sin^2 of the angle between the horizontal range directions times the product
    of their horizontal fractions r_h^2 / (r_h^2 + dz^2).
    """
    return det2(fisher_information(target, beacons, range_std_m))


def disc_grid(center: np.ndarray, radius: np.ndarray, n_rings: int = 10, n_angles: int = 64) -> np.ndarray:
    """A polar grid over discs: center (..., 2), radius (...) -> points (..., M, 2).

    The centre, then ``n_rings`` rings of ``n_angles`` points, the outermost on the
    boundary (where constrained optima of the FIM metrics usually lie).
    """
    center = np.asarray(center, dtype=float)
    radius = np.asarray(radius, dtype=float)[..., None]
    rho = np.arange(1, n_rings + 1) / n_rings
    ang = 2 * np.pi * np.arange(n_angles) / n_angles
    unit = np.stack([np.cos(ang), np.sin(ang)], -1)  # (A, 2)
    ring = (rho[:, None, None] * unit[None]).reshape(-1, 2)  # (R*A, 2)
    offs = np.concatenate([np.zeros((1, 2)), ring], 0)  # (M, 2)
    return center[..., None, :] + radius[..., None] * offs


def project_to_disc(points: np.ndarray, center: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Project points (..., M, 2) onto discs center (..., 2), radius (...)."""
    center = np.asarray(center, dtype=float)[..., None, :]
    radius = np.asarray(radius, dtype=float)[..., None, None]
    rel = points - center
    norm = np.linalg.norm(rel, axis=-1, keepdims=True)
    scale = np.minimum(1.0, radius / np.maximum(norm, 1e-12))
    return center + rel * scale


def maximize_on_disc(
    score: Callable[[np.ndarray], np.ndarray],
    center: ArrayLike,
    radius: ArrayLike,
    n_rings: int = 10,
    n_angles: int = 64,
    refine_iters: int = 12,
) -> tuple[np.ndarray, np.ndarray]:
    """Maximize ``score`` over discs: a vectorized polar grid, then a local refinement.

    ``score`` maps candidate points (..., M, 2) to values (..., M) (use large
    negative values for infeasible points). The refinement evaluates a 5x5 pattern
    around the incumbent, projected onto the disc, and halves its step each round,
    starting from the grid spacing; after 12 rounds the resolution is about
    radius / n_rings / 4000. Returns (best points (..., 2), best values (...)).
    Works on any leading batch shape of ``center``/``radius``.
    """
    center = np.asarray(center, dtype=float)
    radius = np.broadcast_to(np.asarray(radius, dtype=float), center.shape[:-1])
    pts = disc_grid(center, radius, n_rings, n_angles)
    val = score(pts)
    i = np.argmax(val, axis=-1)
    best = np.take_along_axis(pts, i[..., None, None], axis=-2)[..., 0, :]
    best_val = np.take_along_axis(val, i[..., None], axis=-1)[..., 0]
    g = np.arange(-2, 3)
    pattern = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2) / 2.0  # (25, 2), step 0.5
    step = np.maximum(radius / n_rings, 1e-9)
    for _ in range(refine_iters):
        cand = best[..., None, :] + step[..., None, None] * pattern
        cand = project_to_disc(cand, center, radius)
        v = score(cand)
        j = np.argmax(v, axis=-1)
        v_best = np.take_along_axis(v, j[..., None], axis=-1)[..., 0]
        better = v_best > best_val
        best = np.where(better[..., None], np.take_along_axis(cand, j[..., None, None], axis=-2)[..., 0, :], best)
        best_val = np.where(better, v_best, best_val)
        step = step * 0.5
    return best, best_val


def best_second_range_det(
    horizontal_distance_m: ArrayLike, depth_difference_m: float, reach_m: float, **grid: int
) -> np.ndarray:
    """The largest det of the two-range information matrix within the reaching set.

    The survey vehicle is at the origin, ``depth_difference_m`` below the beacon;
    the first range is taken with the beacon at ``horizontal_distance_m`` (any
    shape), the second anywhere in the disc of radius ``reach_m`` around it
    (Sousa et al. Fig. 12 for one distance). range_std = 1, so the value is the
    geometric factor in [0, 1].
    """
    d = np.atleast_1d(np.asarray(horizontal_distance_m, dtype=float))
    h = float(depth_difference_m)
    target = np.array([0.0, 0.0, h])
    first = np.stack([d, np.zeros_like(d), np.zeros_like(d)], -1)  # (K, 3)

    def score(pts):  # pts (K, M, 2)
        second = np.concatenate([pts, np.zeros(pts.shape[:-1] + (1,))], -1)
        beacons = np.stack([np.broadcast_to(first[:, None, :], second.shape), second], -2)  # (K,M,2,3)
        return range_information_det(target, beacons)

    center = np.stack([d, np.zeros_like(d)], -1)
    _, val = maximize_on_disc(score, center, np.full(d.shape, float(reach_m)), **grid)
    return val.reshape(np.shape(horizontal_distance_m))


def optimal_start_distance_m(depth_difference_m: float, reach_m: float) -> float:
    """Horizontal start distance of a beacon that maximizes the best det of the
    two-range information matrix within its reaching set (Sousa et al. Fig. 11).

    For a survey vehicle ``depth_difference_m`` below (or above) the beacon and a
    reaching set of radius ``reach_m`` (max speed x ping interval), the first range
    is taken at horizontal distance d and the second anywhere in the disc of radius
    ``reach_m`` around the first position; the answer is the d whose best second
    range gives the largest det (computed: a coarse scan over d, then a bounded
    scalar optimization; the inner maximum is a grid + refinement over the disc).

    Geometry: det = [d^2/(d^2+h^2)] * [y^2/(x^2+y^2+h^2)] with (x, y) the second
    position in a frame with the first range along x. Too close and the ranges are
    nearly vertical; too far and the reaching set subtends a small angle, so the
    optimum is interior for h > 0. At h = 0 every d <= reach_m is optimal (det = 1);
    the limit h -> 0+ of the optimum is reach_m / sqrt(2), which is returned there.
    """
    h = abs(float(depth_difference_m))
    R = float(reach_m)
    if not (np.isfinite(h) and np.isfinite(R)) or R <= 0:
        raise ValueError(f"need a finite depth difference and reach_m > 0, got {depth_difference_m!r}, {reach_m!r}")
    return _optimal_start_distance_cached(round(h, 9), round(R, 9))


@functools.lru_cache(maxsize=256)
def _optimal_start_distance_cached(h, R):
    if h <= 1e-6 * R:
        return R / np.sqrt(2.0)
    from scipy.optimize import minimize_scalar

    def f(d):
        return float(best_second_range_det(np.array([d]), h, R)[0])

    hi = 2.0 * (R + h)
    for _ in range(20):  # widen the scan until the optimum is inside it
        ds = np.linspace(hi / 200, hi, 200)
        vals = best_second_range_det(ds, h, R)
        k = int(np.argmax(vals))
        if k < len(ds) - 1:
            break
        hi *= 2.0
    lo_b = ds[max(k - 1, 0)] if k > 0 else 0.0
    hi_b = ds[min(k + 1, len(ds) - 1)]
    res = minimize_scalar(lambda d: -f(d), bounds=(lo_b, hi_b), method="bounded", options={"xatol": 1e-4 * (R + h)})
    return float(res.x) if -res.fun >= vals[k] else float(ds[k])
