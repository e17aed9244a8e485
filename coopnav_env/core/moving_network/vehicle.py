"""Steps 1-2 of a cycle: the boats' imperfect motion and the vehicle's sub-steps.

The boats' commands are integrated by the rate-limited kernel every beacon uses
(``substeps.integrate_beacons``); ``dynamics.disturb_boats`` then adds what their
motion strays from them: a Gauss-Markov surge and course fluctuation each
(``dynamics.boat_noise_step``), and the part of the river current their ground-speed
control leaves (the survey network's ASVs share the model, ``core.sim``).

The vehicle (``integrate_vehicle``) runs K sub-steps: line-of-sight guidance (Fig. 5)
on its filter's frame estimate, heading reference psi + phi_hat steered on the
compass, true motion = water speed x heading + current; dead reckoning and the
filter's prediction (``navigation.frame_predict``) with the measured water speed
(propeller encoder) and compass heading (section VII).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..dynamics import turn_toward
from ..guidance import los_point
from ..navigation import frame_predict
from .state import Filter, Vehicle, VehicleParams


@njit(cache=True)
def _guide(
    waypoints: np.ndarray,
    n_waypoints: int,
    i: int,
    heading: complex,
    E: np.ndarray,
    compass_bias_rad: float,
    p: VehicleParams,
) -> tuple[float, int, bool, complex]:
    """Line-of-sight guidance of one vehicle for one sub-step on its filter's frame
    estimate E (6,), following ``waypoints`` (W, 3; the first ``n_waypoints``) from leg i:
    advances the waypoint, turns the heading towards the LOS point. Returns (the
    commanded water speed, the leg, whether the mission is done, the heading); speed 0
    once done. It takes the vehicle's row and scalars, not ``state.Vehicle``: numba counts
    a reference to every array of a record at each call (docs/performance.md#refcounts)."""
    est = E[0] + 1j * E[1]
    a = waypoints[i - 1, 0] + 1j * waypoints[i - 1, 1]
    e = waypoints[i, 0] + 1j * waypoints[i, 1]
    q, along, seg_len = los_point(est, a, e, p.los_alpha)
    if along >= seg_len - p.acceptance_m or abs(est - e) < p.acceptance_m:
        if i + 1 >= n_waypoints:
            return 0.0, i, True, heading
        i += 1
        a, e = e, waypoints[i, 0] + 1j * waypoints[i, 1]
        q, along, seg_len = los_point(est, a, e, p.los_alpha)
    d = q - est
    # psi: direction of V -> Q in the frame, measured from x towards y
    # (clockwise); the heading controller's reference is psi + phi_hat
    # (section VI), which it tracks on the compass, bias included
    ref = np.arctan2(d.imag, d.real) + E[2] - compass_bias_rad
    return p.speed_mps, i, False, turn_toward(heading, np.sin(ref) + 1j * np.cos(ref), p.turn_cos, p.turn_sin)


@njit(cache=True)
def integrate_vehicle(
    v: Vehicle, f: Filter, compass_noise: np.ndarray, speed_noise: np.ndarray, current: np.ndarray, p: VehicleParams
) -> None:
    """K sub-steps of every vehicle of the batch, in place: guidance on the frame estimate
    (``_guide``), true motion, dead reckoning and the filter's prediction
    (``frame_predict``). v: ``state.Vehicle``; f: ``state.Filter``; compass_noise,
    speed_noise (B,K) the sensors' errors per sub-step; current (B,) complex, the water's
    at the vehicle; p: ``state.VehicleParams``. The records may come ``state.packed``."""
    v, f, p = Vehicle(*v), Filter(*f), VehicleParams(*p)
    dt = p.dt
    for b in range(v.pos.shape[0]):
        waypoints, n_waypoints, E = v.waypoints[b, 0], v.n_waypoints[b, 0], f.E[b]
        for k in range(p.K):
            speed = 0.0
            if not v.done[b, 0]:
                speed, i, done, v.heading[b] = _guide(
                    waypoints, n_waypoints, v.wp_index[b, 0], v.heading[b], E, v.compass_bias_rad[b], p
                )
                v.wp_index[b, 0], v.done[b, 0] = i, done
            ground = speed * v.speed_scale[b] * v.heading[b] + current[b]
            v.pos[b, 0, 0] += ground.real * dt
            v.pos[b, 0, 1] += ground.imag * dt
            v.vel_true[b, 0, 0], v.vel_true[b, 0, 1], v.vel_true[b, 0, 2] = ground.real, ground.imag, 0.0
            theta = np.arctan2(v.heading[b].real, v.heading[b].imag) + v.compass_bias_rad[b] + compass_noise[b, k]
            s = speed + speed_noise[b, k] if speed > 0.0 else 0.0
            v.dr[b, 0, 0] += s * np.sin(theta) * dt
            v.dr[b, 0, 1] += s * np.cos(theta) * dt
            frame_predict(f.E[b], f.P[b], s, theta, dt, p.Q)
            v.heading_meas_rad[b], v.speed_meas_mps[b] = theta, s
