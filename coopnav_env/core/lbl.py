"""The moving LBL network of Matos & Cruz, section V: the spherical fix, the
three-interval signal exchange simulated in time, and external tracking.

Frame (section V): origin at beacon B1, x axis from B1 to B2, y axis 90 degrees
clockwise from x seen from above (with bearings clockwise from north, the frame
is (x, y) = (along u(phi), along u(phi + 90 deg)), u(b) = (sin b, cos b) in
(east, north)). The vehicle stays on the side y > 0.

The exchange of one positioning cycle (Fig. 4), with t0 the vehicle's first
transmission and tau the transponders' turn-around delay:

* S1: vehicle -> B1 (all beacons hear it); B1 replies S2 at t1;
* S2 reaches the vehicle at t3 (range d1) and B2, which answers S3 at t2;
* S3 reaches the vehicle at t4 (path d1 + l + d2 = m);
* on hearing S2 the vehicle sends S4 to B2 (after its own reaction delay);
  B2 replies S5 at t5, which reaches the vehicle at t6 (range d2);
* l = m - d1 - d2.

Every instant here comes from propagating sound between vehicles that move
while it travels (``acoustics.travel_time``), every detection is late by a
jitter (and, rarely, by a multipath excess), and every signal can be lost.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, vectorize
from numpy.typing import ArrayLike

from . import acoustics


@njit(cache=True)
def fix_xy(d1: float, d2: float, length: float) -> tuple[float, float]:
    """The fix of section V for one set of ranges: x = (d1^2 - d2^2 + l^2) / (2 l) and
    y^2 = d1^2 - x^2 (negative when the range circles do not meet)."""
    x = (d1 * d1 - d2 * d2 + length * length) / (2.0 * length)
    return x, d1 * d1 - x * x


@njit(cache=True)
def spherical_fix_of(d1: float, d2: float, length: float) -> tuple[float, float, bool]:
    """``spherical_fix`` of one set of ranges without raising: (x, y, ok); where ok is
    False (no solution, a non-finite input or a non-positive baseline) x and y are 0."""
    ok = np.isfinite(d1) and np.isfinite(d2) and np.isfinite(length) and length > 0
    x, y2 = fix_xy(d1, d2, length if ok else 1.0)
    if not (ok and y2 >= 0):
        return 0.0, 0.0, False
    return x, np.sqrt(y2), True


@njit(cache=True)
def _fix_rows(d1, d2, length, x, y2):
    for i in range(d1.shape[0]):
        x[i], y2[i] = fix_xy(d1[i], d2[i], length[i])


@njit(cache=True)
def _fix_batch_rows(d1, d2, length, x, y, ok):
    for i in range(d1.shape[0]):
        x[i], y[i], ok[i] = spherical_fix_of(d1[i], d2[i], length[i])


def _flat_args(*arrays):
    shape = np.broadcast_shapes(*(np.shape(a) for a in arrays))
    return shape, [np.ascontiguousarray(np.broadcast_to(np.asarray(a, dtype=float), shape)).reshape(-1) for a in arrays]


def spherical_fix(d1_m: ArrayLike, d2_m: ArrayLike, baseline_m: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """The LBL fix of section V: x = (d1^2 - d2^2 + l^2) / (2 l), y = sqrt(d1^2 - x^2).

    Horizontal ranges d1 (to B1), d2 (to B2) and the baseline l, scalars or arrays.
    Returns (x, y) in the beacons' frame with y >= 0. Raises ``ValueError`` when
    the geometry has no solution (the circles do not meet: noisy ranges with
    |d1 - d2| > l or d1 + d2 < l), or for a non-positive baseline or negative range,
    rather than returning NaN.
    """
    d1, d2, l = (np.asarray(v, dtype=float) for v in (d1_m, d2_m, baseline_m))
    if not (np.all(np.isfinite(d1)) and np.all(np.isfinite(d2)) and np.all(np.isfinite(l))):
        raise ValueError("spherical_fix: ranges and baseline must be finite")
    if np.any(l <= 0):
        raise ValueError(f"spherical_fix: the baseline length must be > 0, got {l}")
    if np.any(d1 < 0) or np.any(d2 < 0):
        raise ValueError(f"spherical_fix: ranges must be >= 0, got d1={d1}, d2={d2}")
    shape, (a, b, c) = _flat_args(d1, d2, l)
    x, y2 = np.empty(a.shape[0]), np.empty(a.shape[0])
    _fix_rows(a, b, c, x, y2)
    if np.any(y2 < 0):
        raise ValueError(
            f"spherical_fix: no solution for d1={d1}, d2={d2}, l={l}: the range circles do not meet "
            "(|d1 - d2| <= l <= d1 + d2 is needed)"
        )
    x, y = x.reshape(shape), np.sqrt(y2).reshape(shape)
    return (x[()], y[()]) if shape == () else (x, y)


def spherical_fix_batch(
    d1_m: ArrayLike, d2_m: ArrayLike, baseline_m: ArrayLike
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``spherical_fix_of`` over arrays, for the batched simulator: returns (x, y, ok);
    where ok is False (no solution) x and y are 0."""
    shape, (a, b, c) = _flat_args(d1_m, d2_m, baseline_m)
    n = a.shape[0]
    x, y, ok = np.empty(n), np.empty(n), np.empty(n, dtype=bool)
    _fix_batch_rows(a, b, c, x, y, ok)
    x, y, ok = x.reshape(shape), y.reshape(shape), ok.reshape(shape)
    return (x, y[()], ok[()]) if shape == () else (x, y, ok)  # scalars in: x 0-d, y and ok scalars, as numpy gave


@vectorize(["float64(float64, float64)"], cache=True)
def horizontal_range(slant_m: float, depth_difference_m: float) -> float:
    """Horizontal part of a slant range; NaN-free (0 when the slant range is shorter than the depth). A ufunc."""
    v = slant_m * slant_m - depth_difference_m * depth_difference_m
    return np.sqrt(0.0 if v < 0.0 else v)  # not np.maximum(v, 0.0): a NaN stays NaN


@njit(cache=True)
def to_world(b1_e: float, b1_n: float, sin_phi: float, cos_phi: float, x: float, y: float) -> tuple[float, float]:
    """Frame (x, y) -> (east, north) of one point given B1 and the frame bearing's sine and cosine."""
    return b1_e + x * sin_phi + y * cos_phi, b1_n + x * cos_phi + y * -sin_phi


@njit(cache=True)
def to_frame(rel_e: float, rel_n: float, sin_phi: float, cos_phi: float) -> tuple[float, float]:
    """(east, north) relative to B1 -> frame (x, y) of one point, given the frame bearing's sine and cosine."""
    return rel_e * sin_phi + rel_n * cos_phi, rel_e * cos_phi - rel_n * sin_phi


@njit(cache=True)
def _to_world_rows(b1, phi, x, y, out):
    for i in range(x.shape[0]):
        out[i, 0], out[i, 1] = to_world(b1[i, 0], b1[i, 1], np.sin(phi[i]), np.cos(phi[i]), x[i], y[i])


@njit(cache=True)
def _to_frame_rows(rel, phi, x, y):
    for i in range(x.shape[0]):
        x[i], y[i] = to_frame(rel[i, 0], rel[i, 1], np.sin(phi[i]), np.cos(phi[i]))


def frame_to_world(b1_en: ArrayLike, phi_rad: ArrayLike, x: ArrayLike, y: ArrayLike) -> np.ndarray:
    """Frame (x, y) -> (east, north) given B1's position (..., 2) and the frame bearing phi (``to_world``)."""
    b1 = np.asarray(b1_en, dtype=float)
    shape = np.broadcast_shapes(b1.shape[:-1], np.shape(phi_rad), np.shape(x), np.shape(y))
    b1f = np.ascontiguousarray(np.broadcast_to(b1, shape + (2,))).reshape(-1, 2)
    _, (p, xf, yf) = _flat_args(np.broadcast_to(phi_rad, shape), np.broadcast_to(x, shape), np.broadcast_to(y, shape))
    out = np.empty((xf.shape[0], 2))
    _to_world_rows(b1f, p, xf, yf, out)
    return out.reshape(shape + (2,))


def baseline(b1_en: np.ndarray, b2_en: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The frame of beacons B1, B2 (east, north) (..., 2): bearing phi of its x axis
    (clockwise from north) and the baseline length l. (numpy's arctan2: the
    simulator's kernels take phi from here.)"""
    base = b2_en - b1_en
    return np.arctan2(base[..., 0], base[..., 1]), np.linalg.norm(base, axis=-1)


def world_to_frame(
    b1_en: np.ndarray, b2_en: np.ndarray, p_en: ArrayLike
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(east, north) -> frame (x, y) of the beacons B1, B2 (``to_frame``); also returns phi and l."""
    phi, length = baseline(b1_en, b2_en)
    rel = np.asarray(p_en, dtype=float) - b1_en
    shape = np.broadcast_shapes(rel.shape[:-1], phi.shape)
    relf = np.ascontiguousarray(np.broadcast_to(rel, shape + (2,))).reshape(-1, 2)
    x, y = np.empty(relf.shape[0]), np.empty(relf.shape[0])
    _to_frame_rows(relf, np.ascontiguousarray(np.broadcast_to(phi, shape)).reshape(-1), x, y)
    return x.reshape(shape), y.reshape(shape), phi, length


# the detections of one cycle, in order; draws and loss flags use this order
DETECTIONS = ("S1@B1", "S2@vehicle", "S2@B2", "S3@vehicle", "S4@B2", "S5@vehicle", "S1@B2")
N_DETECTIONS = len(DETECTIONS)


@njit(cache=True)
def _at(p, v, t, out):
    """out = p + v t: where a vehicle at p moving at v is t seconds later (3,)."""
    for i in range(3):
        out[i] = p[i] + v[i] * t
    return out


class Movers(NamedTuple):
    """The three vehicles of one exchange at its start (t = 0): positions and velocities
    (3,) for one environment, or (B, 3) for a batch (``exchange``)."""

    vehicle_m: np.ndarray
    vehicle_vel_mps: np.ndarray
    b1_m: np.ndarray
    b1_vel_mps: np.ndarray
    b2_m: np.ndarray
    b2_vel_mps: np.ndarray


class ExchangeResult(NamedTuple):
    """What one positioning cycle gives (``exchange_of``): the vehicle's measurements and
    their flags, the instants the filter needs for its leg delays, the boats' detection
    instants for tracking, and the count of lost signals."""

    d1: float
    m: float
    d2: float
    l: float  # the paper's name
    ok_d1: bool
    ok_m: bool
    ok_d2: bool
    ok_l: bool
    t3: float
    t3s: float
    t6: float
    t_s1_b1: float
    t_s1_b2: float
    t_s4_b2: float
    ok_track: bool
    lost_count: int


EXCHANGE_FIELDS = ExchangeResult._fields


class FrameGeometry(NamedTuple):
    """One environment's frame as the boats know it: B1's (east, north), the sine and
    cosine of the bearing of the x axis, and the baseline length."""

    b1_e: float
    b1_n: float
    sin_phi: float
    cos_phi: float
    length: float


@njit(cache=True)
def exchange_of(
    movers: Movers,
    sound_speed_mps: float,
    nominal_sound_speed_mps: float,
    err_s: np.ndarray,
    lost: np.ndarray,
    turnaround_s: float,
    reaction_s: float,
    timeout_s: float,
    work: np.ndarray,
) -> ExchangeResult:
    """One environment's positioning cycle (see ``exchange``): ``movers`` (``Movers``, (3,)
    each), err_s (7,) each detection's timing error (jitter plus multipath excess), lost
    (7,); work (2, 3) scratch. Returns an ``ExchangeResult``."""
    c, cn, tau = sound_speed_mps, nominal_sound_speed_mps, turnaround_s
    tt = acoustics.travel_time
    vehicle_m, vehicle_vel_mps, b1_m, b1_vel_mps, b2_m, b2_vel_mps = movers
    p, q = work[0], work[1]
    # S1: vehicle -> B1; B1 detects and replies S2 at t1
    t_s1_b1 = tt(vehicle_m, b1_m, b1_vel_mps, c) + err_s[0]
    t1 = t_s1_b1 + tau
    ok1 = not lost[0]
    _at(b1_m, b1_vel_mps, t1, p)  # B1 at t1
    # S2 -> vehicle (t3) and -> B2, which answers S3 at t2
    t3 = t1 + tt(p, _at(vehicle_m, vehicle_vel_mps, t1, q), vehicle_vel_mps, c) + err_s[1]
    ok_d1 = ok1 and not lost[1]
    t2 = t1 + tt(p, _at(b2_m, b2_vel_mps, t1, q), b2_vel_mps, c) + err_s[2] + tau
    ok2b = ok1 and not lost[2]
    # S3 -> vehicle (t4)
    t4 = t2 + tt(_at(b2_m, b2_vel_mps, t2, p), _at(vehicle_m, vehicle_vel_mps, t2, q), vehicle_vel_mps, c) + err_s[3]
    ok_m = ok2b and not lost[3]
    # S4: the vehicle interrogates B2 on hearing S2 (or at the timeout); B2 replies S5 at t5
    t3s = t3 + reaction_s if ok_d1 else timeout_s
    t_s4_b2 = t3s + tt(_at(vehicle_m, vehicle_vel_mps, t3s, p), _at(b2_m, b2_vel_mps, t3s, q), b2_vel_mps, c) + err_s[4]
    t5 = t_s4_b2 + tau
    t6 = t5 + tt(_at(b2_m, b2_vel_mps, t5, p), _at(vehicle_m, vehicle_vel_mps, t5, q), vehicle_vel_mps, c) + err_s[5]
    ok_d2 = not lost[4] and not lost[5]
    # B2 also hears S1 (all beacons detect every interrogation): used for tracking
    t_s1_b2 = tt(vehicle_m, b2_m, b2_vel_mps, c) + err_s[6]

    # The vehicle's measured distances. Erratum: the paper writes d1 = (t3 - t0)/(2c),
    # m = (t4 - t0)/c and d2 = (t6 - t3)/(2c), which have units of s^2/m; a distance is
    # c times a time: d1 = c (t3 - t0)/2. The known turn-around delays are subtracted.
    d1 = cn * (t3 - tau) / 2.0
    m = cn * (t4 - 2.0 * tau)
    d2 = cn * (t6 - t3s - tau) / 2.0
    ok_l = ok_d1 and ok_m and ok_d2
    l = m - d1 - d2
    ok_track = ok1 and ok_d1 and not lost[4] and not lost[6]
    n_lost = 0
    for i in range(lost.shape[0]):
        n_lost += lost[i]
    return ExchangeResult(
        d1, m, d2, l, ok_d1, ok_m, ok_d2, ok_l, t3, t3s, t6, t_s1_b1, t_s1_b2, t_s4_b2, ok_track, n_lost
    )


# the float and the flag fields of ``ExchangeResult``, as ``exchange`` returns them
_EXCHANGE_FLOATS = ("d1", "m", "d2", "l", "t3", "t3s", "t6", "t_s1_b1", "t_s1_b2", "t_s4_b2")
_EXCHANGE_FLAGS = ("ok_d1", "ok_m", "ok_d2", "ok_l", "ok_track")


@njit(cache=True)
def _exchange_rows(movers, c, cn, err, lost, turnaround_s, reaction_s, timeout_s, fval, flag, n_lost):
    """``exchange_of`` for every row of a batch: fval (B, 10) in ``_EXCHANGE_FLOATS`` order,
    flag (B, 5) in ``_EXCHANGE_FLAGS`` order, n_lost (B,)."""
    work = np.empty((2, 3))
    vehicle, vehicle_vel, b1, b1_vel, b2, b2_vel = movers
    for b in range(vehicle.shape[0]):
        r = exchange_of(
            Movers(vehicle[b], vehicle_vel[b], b1[b], b1_vel[b], b2[b], b2_vel[b]),
            c[b],
            cn[b],
            err[b],
            lost[b],
            turnaround_s,
            reaction_s,
            timeout_s[b],
            work,
        )
        fval[b, 0], fval[b, 1], fval[b, 2], fval[b, 3] = r.d1, r.m, r.d2, r.l
        fval[b, 4], fval[b, 5], fval[b, 6], fval[b, 7], fval[b, 8], fval[b, 9] = (
            r.t3,
            r.t3s,
            r.t6,
            r.t_s1_b1,
            r.t_s1_b2,
            r.t_s4_b2,
        )
        flag[b, 0], flag[b, 1], flag[b, 2], flag[b, 3], flag[b, 4] = r.ok_d1, r.ok_m, r.ok_d2, r.ok_l, r.ok_track
        n_lost[b] = r.lost_count


def exchange(
    movers: Movers,
    sound_speed_mps: ArrayLike,
    nominal_sound_speed_mps: ArrayLike,
    jitter_s: ArrayLike,
    late_s: ArrayLike,
    lost: ArrayLike,
    turnaround_s: float,
    reaction_s: float,
    timeout_s: ArrayLike,
) -> dict[str, np.ndarray]:
    """Simulate one positioning cycle for a batch; t = 0 is the vehicle's S1 transmission.

    ``movers`` (``Movers``): positions (B, 3) at t = 0 and velocities (B, 3), held over
    the ~0.3 s of the exchange; sound speed (B,) true and as the vehicle assumes it;
    jitter_s, late_s (B, 7): each detection's timing error and multipath excess
    (seconds, order of ``DETECTIONS``); lost (B, 7) bool. The transponders reply
    ``turnaround_s`` after a detection, the vehicle interrogates B2 ``reaction_s``
    after hearing S2, or at ``timeout_s`` if it did not.

    Returns a dict of (B,) arrays: the vehicle's measurements ``d1``, ``m``, ``d2``,
    ``l`` (metres) with flags ``ok_d1``, ``ok_m``, ``ok_d2``, ``ok_l``; the instants
    ``t3`` (S2 heard), ``t3s`` (S4 sent), ``t6`` (S5 heard) for the filter's leg
    delays; and for the boats' tracking, the detection instants ``t_s1_b1``,
    ``t_s1_b2``, ``t_s4_b2`` with flag ``ok_track``; ``lost_count`` counts lost signals.
    """
    vec = Movers(*(np.ascontiguousarray(a, dtype=float) for a in movers))
    B = vec.vehicle_m.shape[0]
    c, cn, timeout = (
        np.ascontiguousarray(np.broadcast_to(a, (B,)), dtype=float)
        for a in (sound_speed_mps, nominal_sound_speed_mps, timeout_s)
    )
    err = np.ascontiguousarray(np.asarray(jitter_s, dtype=float) + late_s)
    fval, flag, n_lost = np.empty((B, 10)), np.empty((B, 5), dtype=bool), np.empty(B, dtype=np.int64)
    _exchange_rows(
        vec,
        c,
        cn,
        err,
        np.ascontiguousarray(lost, dtype=bool),
        float(turnaround_s),
        float(reaction_s),
        timeout,
        fval,
        flag,
        n_lost,
    )
    out = {}
    for name, col in zip(_EXCHANGE_FLOATS, fval.T):
        out[name] = col.copy()
    for name, col in zip(_EXCHANGE_FLAGS, flag.T):
        out[name] = col.copy()
    out["lost_count"] = n_lost
    return {k: out[k] for k in EXCHANGE_FIELDS}


@njit(cache=True)
def track_fix_of(
    t_s1_b1: float,
    t_s1_b2: float,
    t_s4_b2: float,
    ok_track: bool,
    frame: FrameGeometry,
    depth_below_m: float,
    nominal_sound_speed_mps: float,
    turnaround_s: float,
    reaction_s: float,
) -> tuple:
    """``track_fix`` for one environment: the detection instants and their flag, the GPS
    frame (``FrameGeometry``), the depth below the boats. Returns (east, north, ok)."""
    cn = nominal_sound_speed_mps
    total = cn * (t_s4_b2 - t_s1_b1 - turnaround_s - reaction_s)
    diff = cn * (t_s1_b2 - t_s1_b1)
    r1 = horizontal_range((total - diff) / 2.0, depth_below_m)
    r2 = horizontal_range((total + diff) / 2.0, depth_below_m)
    fx, fy, ok = spherical_fix_of(r1, r2, frame.length)
    e, n = to_world(frame.b1_e, frame.b1_n, frame.sin_phi, frame.cos_phi, fx, fy)
    return e, n, ok and ok_track


@njit(cache=True)
def _track_rows(t_a, t_b, t_c, ok_track, gps_frame, depth, cn, turnaround_s, reaction_s, fix, ok):
    """``track_fix_of`` for every row; gps_frame: (b1 (B, 2), phi (B,), length (B,))."""
    b1, phi, length = gps_frame
    for b in range(t_a.shape[0]):
        frame = FrameGeometry(b1[b, 0], b1[b, 1], np.sin(phi[b]), np.cos(phi[b]), length[b])
        fix[b, 0], fix[b, 1], ok[b] = track_fix_of(
            t_a[b], t_b[b], t_c[b], ok_track[b], frame, depth[b], cn[b], turnaround_s, reaction_s
        )


def track_fix(
    ex: dict[str, np.ndarray],
    b1_en: np.ndarray,
    b2_en: np.ndarray,
    depth_below_m: ArrayLike,
    nominal_sound_speed_mps: ArrayLike,
    turnaround_s: float,
    reaction_s: float,
) -> tuple[np.ndarray, np.ndarray]:
    """External tracking from the boats' own detection instants (section III, V).

    The boats never hear the vehicle's measurements; they share over their radio
    link the instants at which they detected signals (and their GPS positions).
    B1 heard S1 at t_a, B2 heard S1 at t_b and S4 at t_c. With the known delays,
    t_c - t_a - tau - tau_v = (d1 + d2)/c and t_b - t_a = (d2 - d1)/c, which give the
    two slant ranges; the mission depth turns them horizontal and the spherical fix
    with the GPS baseline places the vehicle. (The tracking algorithm the paper
    cites, its ref. [8], is not among coopnav's sources; this is our reconstruction
    from the signals the section names.) Returns east/north (B, 2) and ok (B,).
    """
    phi, length = baseline(b1_en, b2_en)  # of the GPS positions
    t_a = np.ascontiguousarray(ex["t_s1_b1"], dtype=float)
    B = t_a.shape[0]
    flat = [
        np.ascontiguousarray(np.broadcast_to(a, (B,)), dtype=float)
        for a in (ex["t_s1_b2"], ex["t_s4_b2"], phi, length, depth_below_m, nominal_sound_speed_mps)
    ]
    fix, ok = np.empty((B, 2)), np.empty(B, dtype=bool)
    gps_frame = (np.ascontiguousarray(np.broadcast_to(b1_en, (B, 2)), dtype=float), flat[2], flat[3])
    _track_rows(
        t_a,
        flat[0],
        flat[1],
        np.ascontiguousarray(ex["ok_track"], dtype=bool),
        gps_frame,
        flat[4],
        flat[5],
        float(turnaround_s),
        float(reaction_s),
        fix,
        ok,
    )
    return fix, ok
