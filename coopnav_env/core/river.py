"""A river for the moving LBL network (``mission_frame="world"``, scenario ``matos_river``):
its centerline as a polyline in world (east, north), listed downstream, and the
geometry the simulator, the boats' observation and the reward need of it.

Matos & Cruz sec. III: the vehicle surveys a river "with winding margins", two boats
"move slowly along the river" and "continuously define a river cross section". Here
the river is the centerline polyline plus a constant width (``river_width_m``); a
point's *arc length* s is the distance along the centerline to its nearest point on
it, its *offset* the signed distance from it, positive to the right of the downstream
direction (90 degrees clockwise from it). The banks are at offsets +-width / 2.

Complex numbers are (east + 1j north) as in ``core.dynamics``; a clockwise turn by 90
degrees is a product with -1j.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import ArrayLike


def centerline_of(points_m: ArrayLike) -> tuple:
    """The centerline's vertices (M, 2) and their cumulative arc lengths (M,) (m) from a
    tuple of (east, north) points; consecutive duplicates are refused."""
    pts = np.ascontiguousarray(np.asarray(points_m, dtype=float).reshape(-1, 2))
    seg = np.hypot(*np.diff(pts, axis=0).T)
    if pts.shape[0] < 2 or np.any(seg <= 0.0):
        raise ValueError("river_centerline_m needs at least two distinct consecutive (east, north) points")
    return pts, np.concatenate([[0.0], np.cumsum(seg)])


@njit(cache=True)
def project(pe: float, pn: float, pts: np.ndarray, cum: np.ndarray) -> tuple[float, float, float, float]:
    """The nearest point of the centerline to (pe, pn): its arc length s (m), the signed
    offset of the point from it (m, + right of downstream) and the downstream unit
    tangent (te, tn) of the segment it lies on (the first nearest segment on a tie)."""
    best = np.inf
    s_best, off_best, te_best, tn_best = 0.0, 0.0, 1.0, 0.0
    for i in range(pts.shape[0] - 1):
        ae, an = pts[i, 0], pts[i, 1]
        de, dn = pts[i + 1, 0] - ae, pts[i + 1, 1] - an
        seg = cum[i + 1] - cum[i]
        te, tn = de / seg, dn / seg
        u = (pe - ae) * te + (pn - an) * tn
        if u < 0.0:
            u = 0.0
        elif u > seg:
            u = seg
        qe, qn = ae + u * te, an + u * tn
        d2 = (pe - qe) * (pe - qe) + (pn - qn) * (pn - qn)
        if d2 < best:
            best = d2
            # right of the tangent t = te + 1j tn is -1j t = tn - 1j te: (east tn, north -te)
            s_best, off_best, te_best, tn_best = cum[i] + u, (pe - ae) * tn - (pn - an) * te, te, tn
    return s_best, off_best, te_best, tn_best


@njit(cache=True)
def point_at(s: float, pts: np.ndarray, cum: np.ndarray) -> tuple[float, float, float, float]:
    """The centerline's point (east, north) at arc length s (clamped to the polyline) and
    its downstream unit tangent (te, tn)."""
    m = pts.shape[0]
    i = 0
    while i < m - 2 and cum[i + 1] < s:
        i += 1
    seg = cum[i + 1] - cum[i]
    te, tn = (pts[i + 1, 0] - pts[i, 0]) / seg, (pts[i + 1, 1] - pts[i, 1]) / seg
    u = min(max(s - cum[i], 0.0), seg)
    return pts[i, 0] + u * te, pts[i, 1] + u * tn, te, tn


@njit(cache=True)
def _offsets_rows(p, pts, cum, off, tan):
    for r in range(p.shape[0]):
        _, o, te, tn = project(p[r, 0], p[r, 1], pts, cum)
        off[r] = o
        tan[r] = complex(te, tn)


def offsets(points_en_m: ArrayLike, pts: np.ndarray, cum: np.ndarray) -> tuple:
    """Signed offsets (..., ) from the centerline (m, + right of downstream) of points
    (..., 2) (east, north), and the downstream unit tangent there, complex (...)."""
    p = np.asarray(points_en_m, dtype=float)
    shape = p.shape[:-1]
    flat = np.ascontiguousarray(p.reshape(-1, 2))
    off, tan = np.empty(flat.shape[0]), np.empty(flat.shape[0], dtype=complex)
    _offsets_rows(flat, pts, cum, off, tan)
    return off.reshape(shape), tan.reshape(shape)


def arc_length_of(points_en_m: ArrayLike, pts: np.ndarray, cum: np.ndarray) -> np.ndarray:
    """Arc lengths (...) of the nearest centerline points of points (..., 2)."""
    p = np.asarray(points_en_m, dtype=float).reshape(-1, 2)
    return np.array([project(e, n, pts, cum)[0] for e, n in p]).reshape(np.shape(points_en_m)[:-1])


def mission_direction(waypoints_en_m: ArrayLike, pts: np.ndarray, cum: np.ndarray) -> float:
    """+1 if the mission's waypoints run downstream (their last one lies further along the
    centerline than their first), else -1 (upstream)."""
    s = arc_length_of(np.asarray(waypoints_en_m, dtype=float)[[0, -1], :2], pts, cum)
    return 1.0 if s[1] >= s[0] else -1.0


def cross_section_at(s_m: float, pts: np.ndarray, cum: np.ndarray, direction: float, baseline_m: float) -> tuple:
    """The boats' cross section at arc length s_m: B1 and B2 (east, north) half a baseline
    either side of the centerline, on the line perpendicular to the river, with B1 on the
    left and B2 on the right of the mission direction, so that the frame's y axis (90
    degrees clockwise from B1 -> B2) points back against the mission direction, towards a
    vehicle that follows the boats; and the frame bearing phi (rad)."""
    pe, pn, te, tn = point_at(float(s_m), pts, cum)
    t = direction * complex(te, tn)
    x_axis = -1j * t  # the mission direction turned 90 degrees clockwise: y = -1j x = -t
    half = 0.5 * baseline_m * x_axis
    b1, b2 = complex(pe, pn) - half, complex(pe, pn) + half
    return np.array([b1.real, b1.imag]), np.array([b2.real, b2.imag]), float(np.arctan2(x_axis.real, x_axis.imag))


def meander(
    length_m: float,
    wavelength_m: float,
    amplitude_m: float,
    bearing_deg: float = 90.0,
    start_m: float = 0.0,
    step_m: float = 25.0,
    origin_en_m: tuple[float, float] = (0.0, 0.0),
) -> tuple:
    """A sine-generated centerline (e, n) points: along the main axis (bearing_deg, clockwise
    from north) from start_m to start_m + length_m every step_m, displaced across it by
    amplitude_m sin(2 pi a / wavelength_m) (a: the main-axis coordinate; positive to the left
    of the main axis); each half wavelength is one bend. Rounded to the millimetre."""
    a = np.arange(start_m, start_m + length_m + 1e-9, step_m)
    axis = complex(np.sin(np.radians(bearing_deg)), np.cos(np.radians(bearing_deg)))
    p = complex(*origin_en_m) + a * axis + 1j * axis * amplitude_m * np.sin(2 * np.pi * a / wavelength_m)
    return tuple((round(float(z.real), 3), round(float(z.imag), 3)) for z in p)
