"""What a beacon observes: the layout of its observation vector and the kernel that
builds it from the state, for every beacon of every environment.

Only what the beacon could know enters: its own navigation estimate, and what it
last received from the survey vehicles (their reply: estimate, covariance,
waypoint index) and from the other beacons. Layout (positions divided by
L = ``config.position_scale_m``; everything clipped to [-OBS_BOUND, OBS_BOUND]):

=====================  =====  =====================================================
own position            2      (east, north) estimate - geofence centre, / L
own heading             2      bearing as an (east, north) unit vector
own speed               1      fraction of the beacon's maximum speed
own position std        1      metres / STD_SCALE_M
per survey vehicle s:
  estimate              3      (east, north) - own, / L; depth - own depth, / DEPTH_SCALE_M
  ellipse semi-axes     2      2-sigma major, minor, / ELLIPSE_SCALE_M
  ellipse orientation   2      (cos, sin) of twice the major-axis bearing
  ages                  2      of the reply, and since its last fused range, / (AGE_SCALE_PINGS T)
  next waypoints        2K     (east, north) - its estimate, / L (K = observed_waypoints)
per other beacon        2      last reported (east, north) - own, / L
=====================  =====  =====================================================

``coopnav_env.obs_layout`` decodes it (for planners and tools) with these constants.

One exception to "only what it could know", found by a review and left for the trained
policies' sake: the own heading and speed are the true ones, where a beacon AUV's compass
has a bias (``beacon_dvl_heading_bias_std_deg``) and its DVL a scale error. No planner
reads either; a learned policy sees a heading a fraction of a degree better than its
compass would give.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .information import ELLIPSE_N_SIGMA, ellipse_of
from .jit import parallel_twin

OWN_DIM = 6
PER_SURVEY_FIXED = 9
DEPTH_SCALE_M = 100.0
ELLIPSE_SCALE_M = 50.0
STD_SCALE_M = 10.0
AGE_SCALE_PINGS = 10.0
OBS_BOUND = 10.0


def obs_dim(n_survey: int, n_beacons: int, observed_waypoints: int) -> int:
    """Length of one beacon's observation vector (the layout above)."""
    return OWN_DIM + n_survey * (PER_SURVEY_FIXED + 2 * observed_waypoints) + 2 * (n_beacons - 1)


@njit(cache=True, inline="always")
def _survey_entry(o, i, kv, waypoints, n_waypoints, b, n, s, oe, on, oz, prm):
    """Write survey vehicle s as beacon n of environment b last heard of it into o from
    index i (estimate, ellipse, ages, next of its ``waypoints`` (W, 3), ``n_waypoints``
    used); returns the next index. It takes the survey's path, not the survey record:
    numba counts a reference to every array of a record at each call (docs/performance.md#refcounts)."""
    L = prm.position_scale_m
    age_scale = AGE_SCALE_PINGS * prm.ping_interval_s
    o[i] = (kv.est[b, n, s, 0] - oe) / L
    o[i + 1] = (kv.est[b, n, s, 1] - on) / L
    o[i + 2] = (kv.est[b, n, s, 2] - oz) / DEPTH_SCALE_M
    major, minor, bearing = ellipse_of(kv.P[b, n, s, 0, 0], kv.P[b, n, s, 0, 1], kv.P[b, n, s, 1, 1], ELLIPSE_N_SIGMA)
    o[i + 3] = major / ELLIPSE_SCALE_M
    o[i + 4] = minor / ELLIPSE_SCALE_M
    o[i + 5] = np.cos(2.0 * bearing)
    o[i + 6] = np.sin(2.0 * bearing)
    o[i + 7] = kv.age_s[b, n, s] / age_scale
    o[i + 8] = kv.range_age_s[b, n, s] / age_scale
    i += PER_SURVEY_FIXED
    for w in range(prm.observed_waypoints):
        j = min(kv.wp_index[b, n, s] + w, n_waypoints - 1)
        o[i] = (waypoints[j, 0] - kv.est[b, n, s, 0]) / L
        o[i + 1] = (waypoints[j, 1] - kv.est[b, n, s, 1]) / L
        i += 2
    return i


def _observe(bv, kv, sv, prm, out):
    """Every beacon's observation (the layout above) into out (B, N, obs_dim), from its
    own state (bv, ``kernel_records.BeaconView``), what it last received (kv,
    ``kernel_records.KnowledgeView``) and the survey paths (sv.waypoints, sv.n_waypoints of
    ``kernel_records.SurveyView``); prm: ``kernel_records.SurveyParams``."""
    B, N, S = bv.pos.shape[0], bv.pos.shape[1], kv.est.shape[2]
    L = prm.position_scale_m
    for b in prange(B):
        for n in range(N):
            o = out[b, n]
            oe = bv.pos[b, n, 0] + bv.nav_err[b, n, 0]
            on = bv.pos[b, n, 1] + bv.nav_err[b, n, 1]
            oz = bv.pos[b, n, 2] + bv.nav_err[b, n, 2]
            o[0] = (oe - prm.fence_center[0]) / L
            o[1] = (on - prm.fence_center[1]) / L
            o[2] = bv.heading[b, n].real
            o[3] = bv.heading[b, n].imag
            o[4] = np.sqrt(bv.vel[b, n, 0] ** 2 + bv.vel[b, n, 1] ** 2) / prm.beacon_max_speed[n]
            o[5] = np.sqrt(bv.nav_var[b, n]) / STD_SCALE_M
            i = OWN_DIM
            for s in range(S):
                i = _survey_entry(o, i, kv, sv.waypoints[b, s], sv.n_waypoints[b, s], b, n, s, oe, on, oz, prm)
            for m in range(N):
                if m != n:
                    o[i] = (kv.peer[b, n, m, 0] - oe) / L
                    o[i + 1] = (kv.peer[b, n, m, 1] - on) / L
                    i += 2
            for j in range(i):
                o[j] = min(max(o[j], -OBS_BOUND), OBS_BOUND)


observe = njit(cache=True)(_observe)
observe_parallel = parallel_twin(_observe)
