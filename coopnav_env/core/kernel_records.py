"""Named records the survey simulator's compiled kernels take, instead of long
positional argument lists (not to be confused with ``coopnav_env.records``: files).

numba passes a ``typing.NamedTuple`` of arrays and scalars to a kernel as one
argument and reads its fields by name at no cost inside the kernel (the fields are
unboxed once per call, as positional arguments are). Three kinds:

* ``SurveyParams``: the scenario's constants the kernels read, built once in
  ``Simulator.__init__``;
* views of the state (``SurveyView``, ``BeaconView``, ``KnowledgeView``): the arrays of
  ``state.SimState`` grouped by who they describe, built when a kernel is called (a
  tuple of references, about a microsecond; the state's fields are replaced by some
  steps, so a view built at reset could go stale). Writes through a view's arrays
  land in the state;
* a sensor's own parameters and inputs live beside it (``measurements/``).

A record's field order is part of its numba type only: kernels read fields by name.

A compiled helper that takes a record is ``inline="always"``: a real call copies the
record and increfs/decrefs every array in it, per sub-step or per ping; that doubled
a batch-of-one step (~0.5 -> ~0.9 ms CPU) before the helpers were inlined.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .state import SimState


class SurveyParams(NamedTuple):
    """The scenario's constants for the survey simulator's kernels (built once)."""

    substep_s: float  # sub-step of the survey integration, s
    ping_interval_s: float  # one acoustic cycle T, s
    drag_k: float  # quadratic drag constant of eq. (1), N s^2 / m^2
    mass_kg: float  # survey vehicle mass of eq. (1)
    los_alpha: float  # line-of-sight lookahead (guidance.los_point)
    acceptance_m: float  # waypoint acceptance radius
    turn_cos: float  # survey turn limit per sub-step, as cos ...
    turn_sin: float  # ... and sin
    max_pitch_rad: float
    depth_gain_per_m: float  # pitch per metre of depth error
    depth_noise_m: float  # depth sensor std
    gps_noise_m: float  # GPS std per axis
    gps_max_depth_m: float  # GPS fixes above this depth
    nan_probability: float  # fault injection: a sensor reads NaN
    loss_near: float  # packet loss probability near ...
    loss_far: float  # ... and at max_range_m (acoustics.packet_loss_probability)
    max_range_m: float
    position_scale_m: float  # L of the observation (observation.py)
    observed_waypoints: int  # next waypoints per survey vehicle in an observation
    beacon_max_speed: np.ndarray  # (N,) m/s
    fence_center: np.ndarray  # (2,) east, north of the geofence's centre


class SurveyView(NamedTuple):
    """The survey vehicles' state (``SimState.s_*``), (B, S, ...)."""

    pos: np.ndarray  # true position (B,S,3)
    est: np.ndarray  # EKF estimate (B,S,3)
    P: np.ndarray  # EKF covariance (B,S,3,3)
    dr: np.ndarray  # dead-reckoning-only track (B,S,3)
    heading: np.ndarray  # complex unit (B,S)
    wp_index: np.ndarray  # (B,S) int
    done: np.ndarray  # (B,S) bool
    vel_true: np.ndarray  # (B,S,3)
    vel_est: np.ndarray  # (B,S,3)
    speed_model: np.ndarray  # eq. (1) water speed (B,S)
    waypoints: np.ndarray  # (B,S,W,3)
    n_waypoints: np.ndarray  # (B,S) int
    hover: np.ndarray  # (B,S) bool
    thrust_n: np.ndarray  # (B,S)
    speed_scale: np.ndarray  # true / modelled water speed (B,S)
    compass_bias_rad: np.ndarray  # (B,S)
    current_est: np.ndarray  # current told by a beacon, complex (B,S)
    last_range_t_s: np.ndarray  # (B,S)
    rejected_streak: np.ndarray  # (B,S) int


class BeaconView(NamedTuple):
    """The beacons' state (``SimState.b_*``), (B, N, ...); ``est`` = pos + nav_err, the
    position each beacon believes and sends."""

    pos: np.ndarray  # true (B,N,3)
    vel: np.ndarray  # true ground velocity (B,N,3)
    heading: np.ndarray  # complex unit (B,N)
    nav_err: np.ndarray  # own estimate - truth (B,N,3)
    nav_var: np.ndarray  # own per-axis position variance, carried (B,N)
    est: np.ndarray  # own estimate (B,N,3)
    nav_dev: np.ndarray  # its covariance's deviator (Sxx - Syy) / 2 + 1j Sxy, complex (B,N) (beacon_nav, eq. N1)
    # its error model's state, what beacon_covariance="full" sends besides (eq. N2, consider.error_model_covariance)
    walk_var: np.ndarray  # (B,N) the white part's variance per axis
    unlocked_s: np.ndarray  # (B,N) time without bottom lock since the fix
    travelled_m: np.ndarray  # (B,N) s
    turn_sum_m: np.ndarray  # (B,N) G, complex
    fix_est: np.ndarray  # (B,N) its estimate at the fix, complex (D = est - fix_est)


class KnowledgeView(NamedTuple):
    """What each beacon last received (``SimState.k_*``), (B, N, ...)."""

    est: np.ndarray  # survey estimates (B,N,S,3)
    P: np.ndarray  # their horizontal covariance (B,N,S,2,2)
    wp_index: np.ndarray  # their waypoint index (B,N,S)
    age_s: np.ndarray  # time since that reply (B,N,S)
    range_age_s: np.ndarray  # time since its last fused range, as reported (B,N,S)
    peer: np.ndarray  # the other beacons' reported positions (B,N,N,3)


def survey_view(st: SimState) -> SurveyView:
    """The survey vehicles' arrays of ``st`` (references, not copies)."""
    return SurveyView(
        st.s_pos,
        st.s_est,
        st.s_P,
        st.s_dr,
        st.s_heading,
        st.s_wp_index,
        st.s_done,
        st.s_vel_true,
        st.s_vel_est,
        st.s_speed_model_mps,
        st.s_waypoints,
        st.s_n_waypoints,
        st.s_hover,
        st.s_thrust_n,
        st.s_speed_scale,
        st.s_compass_bias_rad,
        st.s_current_est,
        st.s_last_range_t_s,
        st.s_rejected_streak,
    )


def beacon_view(st: SimState) -> BeaconView:
    """The beacons' arrays of ``st`` (references) and their own estimates (computed)."""
    return BeaconView(
        st.b_pos,
        st.b_vel,
        st.b_heading,
        st.b_nav_err,
        st.b_nav_var_m2,
        st.b_pos + st.b_nav_err,
        st.b_nav_dev_m2,
        st.b_walk_var_m2,
        st.b_unlocked_s,
        st.b_travelled_m,
        st.b_turn_sum_m,
        st.b_fix_est,
    )


def knowledge_view(st: SimState) -> KnowledgeView:
    """What each beacon last received, from ``st`` (references)."""
    return KnowledgeView(st.k_est, st.k_P, st.k_wp_index, st.k_age_s, st.k_range_age_s, st.k_peer)


class ConsiderView(NamedTuple):
    """The survey filters' consider states and lock-out windows (``SimState.s_Pxb``,
    ``s_fix_seen``, ``s_win_*``) and the beacons' fix counters (``b_fix_count``):
    docs/scenarios/consider-fusion.md."""

    Pxb: np.ndarray  # (B,S,N,3,2) cross-covariance of survey error and beacon error
    fix_seen: np.ndarray  # (B,S,N) int: each beacon's fix counter as last heard
    fix_seen_t_s: np.ndarray  # (B,S,N): when it last changed, as heard
    fix_count: np.ndarray  # (B,N) int: the beacons' surfacing fix counters
    win_n: np.ndarray  # (B,S,N) int: ranges in each window
    win_z: np.ndarray  # (B,S,N,M)
    win_beacon: np.ndarray  # (B,S,N,M,2)
    win_dr: np.ndarray  # (B,S,N,M,2)
    win_dz: np.ndarray  # (B,S,N,M)
    win_t: np.ndarray  # (B,S,N,M)
    Pxd: np.ndarray  # (B,S,3,4) cross-covariance with the survey's own dead-reckoning biases (dr_bias.py)
    hyp_w: np.ndarray  # (B,S) the multipath hypotheses held since the last range (multipath.py, M5): weight
    hyp_d: np.ndarray  # (B,S,3) the direct path's step
    hyp_dP: np.ndarray  # (B,S,3,3) covariance difference
    hyp_dX: np.ndarray  # (B,S,N,3,2) Pxb difference
    hyp_dD: np.ndarray  # (B,S,3,4) Pxd difference
    var_seen: np.ndarray  # (B,S,N) each beacon's per-axis variance as last heard (eq. C8's projection)
    dev_seen: np.ndarray  # (B,S,N) complex: and its deviator (eq. C8')
    model_seen: np.ndarray  # (B,S,N,7) a beacon AUV's error-model state as last heard (eq. N2)


def consider_view(st: SimState) -> ConsiderView:
    """The consider states and windows of ``st`` (references)."""
    return ConsiderView(
        st.s_Pxb,
        st.s_fix_seen,
        st.s_fix_seen_t_s,
        st.b_fix_count,
        st.s_win_n,
        st.s_win_z,
        st.s_win_beacon,
        st.s_win_dr,
        st.s_win_dz,
        st.s_win_t,
        st.s_Pxd,
        st.s_hyp_w,
        st.s_hyp_d,
        st.s_hyp_dP,
        st.s_hyp_dX,
        st.s_hyp_dD,
        st.s_var_seen_m2,
        st.s_dev_seen_m2,
        st.s_model_seen,
    )
