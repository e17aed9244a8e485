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
while it travels (``acoustics.travel_times``), every detection is late by a
jitter (and, rarely, by a multipath excess), and every signal can be lost.
"""

from __future__ import annotations

import numpy as np

from . import acoustics


def spherical_fix(d1_m, d2_m, baseline_m):
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
    x = (d1 ** 2 - d2 ** 2 + l ** 2) / (2 * l)
    y2 = d1 ** 2 - x ** 2
    if np.any(y2 < 0):
        raise ValueError(
            f"spherical_fix: no solution for d1={d1}, d2={d2}, l={l}: the range circles do not meet "
            "(|d1 - d2| <= l <= d1 + d2 is needed)")
    return x, np.sqrt(y2)


def spherical_fix_batch(d1_m, d2_m, baseline_m):
    """``spherical_fix`` without raising, for the batched simulator: returns (x, y, ok);
    where ok is False (no solution) x and y are 0."""
    d1, d2, l = (np.asarray(v, dtype=float) for v in (d1_m, d2_m, baseline_m))
    ok = np.isfinite(d1) & np.isfinite(d2) & np.isfinite(l) & (l > 0)
    l_safe = np.where(ok, l, 1.0)
    x = (d1 ** 2 - d2 ** 2 + l_safe ** 2) / (2 * l_safe)
    y2 = d1 ** 2 - x ** 2
    ok &= y2 >= 0
    return np.where(ok, x, 0.0), np.sqrt(np.where(ok, y2, 0.0)), ok


def horizontal_range(slant_m, depth_difference_m):
    """Horizontal part of a slant range; NaN-free (0 when the slant range is shorter than the depth)."""
    return np.sqrt(np.maximum(np.asarray(slant_m) ** 2 - np.asarray(depth_difference_m) ** 2, 0.0))


def frame_to_world(b1_en, phi_rad, x, y):
    """Frame (x, y) -> (east, north) given B1's position (..., 2) and the frame bearing phi."""
    ux = np.stack([np.sin(phi_rad), np.cos(phi_rad)], -1)  # u(phi)
    uy = np.stack([np.cos(phi_rad), -np.sin(phi_rad)], -1)  # u(phi + 90 deg)
    return b1_en + np.asarray(x)[..., None] * ux + np.asarray(y)[..., None] * uy


def baseline(b1_en, b2_en):
    """The frame of beacons B1, B2 (east, north) (..., 2): bearing phi of its x axis
    (clockwise from north) and the baseline length l."""
    base = b2_en - b1_en
    return np.arctan2(base[..., 0], base[..., 1]), np.linalg.norm(base, axis=-1)


def world_to_frame(b1_en, b2_en, p_en):
    """(east, north) -> frame (x, y) of the beacons B1, B2; also returns phi and l."""
    phi, length = baseline(b1_en, b2_en)
    rel = p_en - b1_en
    x = rel[..., 0] * np.sin(phi) + rel[..., 1] * np.cos(phi)
    y = rel[..., 0] * np.cos(phi) - rel[..., 1] * np.sin(phi)
    return x, y, phi, length


# the detections of one cycle, in order; draws and loss flags use this order
DETECTIONS = ("S1@B1", "S2@vehicle", "S2@B2", "S3@vehicle", "S4@B2", "S5@vehicle", "S1@B2")
N_DETECTIONS = len(DETECTIONS)


def exchange(vehicle_m, vehicle_vel_mps, b1_m, b1_vel_mps, b2_m, b2_vel_mps, sound_speed_mps, nominal_sound_speed_mps,
             jitter_s, late_s, lost, turnaround_s, reaction_s, timeout_s):
    """Simulate one positioning cycle for a batch; t = 0 is the vehicle's S1 transmission.

    Positions (B, 3) at t = 0 and velocities (B, 3), held over the ~0.3 s of the
    exchange; sound speed (B,) true and as the vehicle assumes it; jitter_s,
    late_s (B, 7): each detection's timing error and multipath excess (seconds,
    order of ``DETECTIONS``); lost (B, 7) bool. The transponders reply
    ``turnaround_s`` after a detection, the vehicle interrogates B2
    ``reaction_s`` after hearing S2, or at ``timeout_s`` if it did not.

    Returns a dict of (B,) arrays: the vehicle's measurements ``d1``, ``m``, ``d2``,
    ``l`` (metres) with flags ``ok_d1``, ``ok_m``, ``ok_d2``, ``ok_l``; the instants
    ``t3`` (S2 heard), ``t3s`` (S4 sent), ``t6`` (S5 heard) for the filter's leg
    delays; and for the boats' tracking, the detection instants ``t_s1_b1``,
    ``t_s1_b2``, ``t_s4_b2`` with flag ``ok_track``; ``lost_count`` counts lost signals.
    """
    c, cn = sound_speed_mps, nominal_sound_speed_mps
    err = jitter_s + late_s

    def at(p, v, t):
        return p + v * t[:, None]

    # S1: vehicle -> B1; B1 detects and replies S2 at t1
    t_s1_b1 = acoustics.travel_times(vehicle_m, b1_m, b1_vel_mps, c) + err[:, 0]
    t1 = t_s1_b1 + turnaround_s
    ok1 = ~lost[:, 0]
    p_b1_t1 = at(b1_m, b1_vel_mps, t1)
    # S2 -> vehicle (t3) and -> B2, which answers S3 at t2
    t3 = t1 + acoustics.travel_times(p_b1_t1, at(vehicle_m, vehicle_vel_mps, t1), vehicle_vel_mps, c) + err[:, 1]
    ok_d1 = ok1 & ~lost[:, 1]
    t2 = t1 + acoustics.travel_times(p_b1_t1, at(b2_m, b2_vel_mps, t1), b2_vel_mps, c) + err[:, 2] + turnaround_s
    ok2b = ok1 & ~lost[:, 2]
    # S3 -> vehicle (t4)
    t4 = t2 + acoustics.travel_times(at(b2_m, b2_vel_mps, t2), at(vehicle_m, vehicle_vel_mps, t2), vehicle_vel_mps,
                                     c) + err[:, 3]
    ok_m = ok2b & ~lost[:, 3]
    # S4: the vehicle interrogates B2 on hearing S2 (or at the timeout); B2 replies S5 at t5
    t3s = np.where(ok_d1, t3 + reaction_s, timeout_s)
    t_s4_b2 = t3s + acoustics.travel_times(at(vehicle_m, vehicle_vel_mps, t3s), at(b2_m, b2_vel_mps, t3s),
                                           b2_vel_mps, c) + err[:, 4]
    t5 = t_s4_b2 + turnaround_s
    t6 = t5 + acoustics.travel_times(at(b2_m, b2_vel_mps, t5), at(vehicle_m, vehicle_vel_mps, t5), vehicle_vel_mps,
                                     c) + err[:, 5]
    ok_d2 = ~lost[:, 4] & ~lost[:, 5]
    # B2 also hears S1 (all beacons detect every interrogation): used for tracking
    t_s1_b2 = acoustics.travel_times(vehicle_m, b2_m, b2_vel_mps, c) + err[:, 6]

    # The vehicle's measured distances. Erratum: the paper writes d1 = (t3 - t0)/(2c),
    # m = (t4 - t0)/c and d2 = (t6 - t3)/(2c), which have units of s^2/m; a distance is
    # c times a time: d1 = c (t3 - t0)/2. The known turn-around delays are subtracted.
    d1 = cn * (t3 - turnaround_s) / 2.0
    m = cn * (t4 - 2.0 * turnaround_s)
    d2 = cn * (t6 - t3s - turnaround_s) / 2.0
    ok_l = ok_d1 & ok_m & ok_d2
    l = m - d1 - d2
    ok_track = ok1 & ok_d1 & ~lost[:, 4] & ~lost[:, 6]
    return {"d1": d1, "m": m, "d2": d2, "l": l, "ok_d1": ok_d1, "ok_m": ok_m, "ok_d2": ok_d2, "ok_l": ok_l,
            "t3": t3, "t3s": t3s, "t6": t6, "t_s1_b1": t_s1_b1, "t_s1_b2": t_s1_b2, "t_s4_b2": t_s4_b2,
            "ok_track": ok_track, "lost_count": lost.sum(-1)}


def track_fix(ex, b1_en, b2_en, depth_below_m, nominal_sound_speed_mps, turnaround_s, reaction_s):
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
    cn = nominal_sound_speed_mps
    total = cn * (ex["t_s4_b2"] - ex["t_s1_b1"] - turnaround_s - reaction_s)
    diff = cn * (ex["t_s1_b2"] - ex["t_s1_b1"])
    r1 = horizontal_range((total - diff) / 2.0, depth_below_m)
    r2 = horizontal_range((total + diff) / 2.0, depth_below_m)
    phi, length = baseline(b1_en, b2_en)  # of the GPS positions
    fx, fy, ok = spherical_fix_batch(r1, r2, length)
    ok &= ex["ok_track"]
    return frame_to_world(b1_en, phi, fx, fy), ok
