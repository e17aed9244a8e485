"""The moving network's state and the named records its kernels pass.

``FrameState`` holds every array of the batch (leading axis B). The kernels do not
take its arrays one by one: each step of the cycle takes the few records it needs,
numba ``NamedTuple`` s of views of the state (built per call by ``vehicle_of``,
``filter_of``, ``tracker_of``: cheap, and never stale when the state is replaced;
they cross from Python as plain tuples, ``packed``, and are named again inside),
the scenario's numbers as ``CycleParams`` / ``VehicleParams`` / ``ObserveParams``
(built once in ``MovingNetworkSimulator.__init__``), and write their per-cycle
results into the structured arrays ``CYCLE_OUT`` (floats) and ``CYCLE_COUNTS``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple, TypeVar, cast

import numpy as np

from ..sim import INFO_KEYS
from ..state import BatchArrays

if TYPE_CHECKING:
    from ...scenarios.base import ScenarioConfig

# ellipse_major_m / ellipse_minor_m: ELLIPSE_N_SIGMA (2-sigma) semi-axes of the filter's (x, y)
# covariance, as in the observations, evaluate.py's steps and the plots
FRAME_INFO_KEYS = INFO_KEYS + (
    "error_x_m",
    "error_y_m",
    "phi_error_deg",
    "baseline_error_m",
    "ellipse_major_m",
    "ellipse_minor_m",
    "vehicle_y_m",
)
# one boat's observation, in this order (see MovingNetworkSimulator.observe)
OBS_FIELDS = (
    ("role", 1),
    ("own_velocity_xy", 2),
    ("baseline_error", 1),
    ("tracked_xy", 2),
    ("tracked_velocity_xy", 2),
    ("fix_age", 1),
    ("has_fix", 1),
    ("frame_bearing", 2),
    ("own_from_tracked_xy", 2),
    ("elapsed", 1),
)
OBS_DIM = sum(n for _, n in OBS_FIELDS)
TRACKER_ALPHA, TRACKER_BETA = 0.5, 0.2  # the boats' alpha-beta tracker on the fixes [U]
# the tracker's gate on a fix's distance from its prediction: a fix's error (~1-3 m) and the
# vehicle's speed changes over the fix's age [U]
TRACKER_GATE_M, TRACKER_GATE_SPEED_MPS = 10.0, 1.0
REINIT_AFTER_CYCLES = 3  # one range gated out this many cycles in a row: the recovery consults its window of fixes
# appended for a mission in the world (mission_frame="world"; see MovingNetworkSimulator.observe)
RIVER_OBS_FIELDS = (("bank_offset", 1), ("river_direction_xy", 2), ("river_ahead_from_own_xy", 2))
RIVER_OBS_DIM = sum(n for _, n in RIVER_OBS_FIELDS)
RIVER_LEAD_BASELINES = 0.5  # the river point the boats observe (and start at) lies this many baselines
# ahead of the vehicle along the river: the paper's geometry, the vehicle 50 m from a 100 m baseline
RIVER_STATE_DIM = 2  # global_state's extra values for a world mission: the boats' offsets from the centerline


def obs_fields(config: ScenarioConfig) -> tuple[tuple[str, int], ...]:
    """One boat's observation fields for ``config``: ``OBS_FIELDS``, and ``RIVER_OBS_FIELDS``
    after them for a mission in the world."""
    return OBS_FIELDS + (RIVER_OBS_FIELDS if config.mission_frame == "world" else ())


def obs_dim_of(config: ScenarioConfig) -> int:
    """The length of one boat's observation for ``config``."""
    return sum(n for _, n in obs_fields(config))


@dataclass
class FrameState(BatchArrays):
    """Arrays of the moving network, leading batch axis B; one vehicle (axis S = 1
    kept where the views expect it), two boats (N = 2)."""

    t_s: np.ndarray
    cycle: np.ndarray
    keys: np.ndarray
    ep_variant: np.ndarray  # always 0: one (path, depth) variant
    ep_noise_scale: np.ndarray
    ep_phi0_rad: np.ndarray  # the frame's initial orientation (the boats' reference)
    # the vehicle (world truth; mission in the frame)
    s_pos: np.ndarray  # (B,1,3) east, north, depth
    s_heading: np.ndarray  # (B,) complex unit
    s_vel_true: np.ndarray  # (B,1,3)
    s_speed_scale: np.ndarray  # true water speed / commanded (B,)
    s_compass_bias_rad: np.ndarray  # (B,)
    s_heading_meas_rad: np.ndarray  # last compass reading (B,)
    s_speed_meas_mps: np.ndarray  # last encoder reading (B,)
    s_waypoints: np.ndarray  # (B,1,W,3) frame x, y, depth
    s_n_waypoints: np.ndarray  # (B,1)
    s_wp_index: np.ndarray  # (B,1)
    s_done: np.ndarray  # (B,1)
    s_dr: np.ndarray  # dead reckoning alone, world (B,1,3)
    f_E: np.ndarray  # the moving-frame EKF (B,6): x, y, phi, c_x, c_y, l
    f_P: np.ndarray  # (B,6,6)
    f_rejected_cycles: np.ndarray  # per range (d1, d2, l): consecutive cycles it arrived and was gated out (B,3)
    # the window of recent fixes (recovery): residual fix - estimate in (x, y, l) (B,W,3), its
    # covariance (B,W,3,3), its age in cycles (B,W), -1 an empty slot; W = frame_restart_window_cycles
    f_window_r: np.ndarray
    f_window_S: np.ndarray
    f_window_age: np.ndarray
    # the boats
    b_pos: np.ndarray  # (B,2,3)
    b_heading: np.ndarray  # (B,2) complex unit
    b_vel: np.ndarray  # (B,2,3)
    b_gps_err: np.ndarray  # this cycle's GPS error (B,2,2)
    b_surge: np.ndarray  # each boat's ground-speed fluctuation along its heading, Gauss-Markov (B,2) m/s
    b_steer: np.ndarray  # each boat's course-over-ground error, Gauss-Markov (B,2) rad
    # the boats' tracker of the vehicle (shared over their radio link)
    k_pos: np.ndarray  # (B,2) east, north at the last update
    k_vel: np.ndarray  # (B,2)
    k_age_s: np.ndarray  # time since the last fix (B,)
    k_has_fix: np.ndarray  # (B,) bool
    k_outlier: np.ndarray  # the last fix the gate set aside: east, north, 1 if the last fix was set aside (B,3)
    # water
    temperature_c: np.ndarray
    current_mean: np.ndarray  # complex (B,)
    current_gm: np.ndarray


# --- records of state views ---------------------------------------------------------------
class Vehicle(NamedTuple):
    """The vehicle's arrays: world truth, mission and sensors (``FrameState``'s s_*)."""

    pos: np.ndarray  # (B,1,3)
    heading: np.ndarray  # (B,) complex unit
    vel_true: np.ndarray  # (B,1,3)
    wp_index: np.ndarray  # (B,1)
    done: np.ndarray  # (B,1)
    waypoints: np.ndarray  # (B,1,W,3) frame x, y, depth
    n_waypoints: np.ndarray  # (B,1)
    speed_scale: np.ndarray  # (B,)
    compass_bias_rad: np.ndarray  # (B,)
    dr: np.ndarray  # (B,1,3)
    heading_meas_rad: np.ndarray  # (B,)
    speed_meas_mps: np.ndarray  # (B,)


class Filter(NamedTuple):
    """The moving-frame EKF: E (B,6) = (x, y, phi, c_x, c_y, l), P (B,6,6), per range (d1, d2,
    l) the count of consecutive cycles it was gated out (B,3), and the window of recent fixes
    (``recovery``): residuals (B,W,3), covariances (B,W,3,3), ages in cycles (B,W)."""

    E: np.ndarray
    P: np.ndarray
    rejected_cycles: np.ndarray
    window_r: np.ndarray
    window_S: np.ndarray
    window_age: np.ndarray


class Tracker(NamedTuple):
    """The boats' alpha-beta tracker of the vehicle: (east, north) at the last update and
    velocity (B,2), time since the last fix and whether there was one (B,), the last fix its
    gate set aside (east, north, flag) (B,3)."""

    pos: np.ndarray
    vel: np.ndarray
    age_s: np.ndarray
    has_fix: np.ndarray
    outlier: np.ndarray


class Boats(NamedTuple):
    """The boats this cycle: true positions and velocities (B,2,3); the true frame
    (bearing phi and baseline length (B,)) and the GPS frame (GPS positions (B,2,2), its
    bearing and length), phi from numpy's arctan2 (``lbl.baseline``); the frame's motion over
    the cycle as the boats telemeter it (B,4): B1's displacement in the frame at the cycle's
    start, the rotation and the baseline's change (``frame_motion``; zeros without
    ``frame_motion_telemetry``)."""

    pos: np.ndarray
    vel: np.ndarray
    phi: np.ndarray
    length: np.ndarray
    gps: np.ndarray
    phi_gps: np.ndarray
    length_gps: np.ndarray
    motion: np.ndarray


class CycleDraws(NamedTuple):
    """The cycle's random numbers for the exchange: the water's true temperature and the
    episode's noise scale (B,); depth cell normals (B,1), detection jitters (B,7), uniforms
    (B,7,3) (loss, outlier, multipath) and the logarithms of the multipath ones (B,7)."""

    temperature_c: np.ndarray
    noise_scale: np.ndarray
    depth: np.ndarray
    jitter: np.ndarray
    acoustic_u: np.ndarray
    log_u: np.ndarray


_Record = TypeVar("_Record", bound=tuple)


def packed(record: _Record) -> _Record:
    """A record as the plain tuple a kernel's entry point takes from Python, which names it
    again (``Vehicle(*v)``): numba types the arrays of a plain tuple in C, a NamedTuple's in
    Python (about half a microsecond an array, every call), so passing the records as
    NamedTuples cost a batch of one ~20% of its step. Inside the kernels they are named."""
    return cast(_Record, tuple(record))  # typed as the record: the kernel names it again


def vehicle_of(st: FrameState) -> Vehicle:
    """The vehicle's record of views of ``st``."""
    return Vehicle(
        st.s_pos,
        st.s_heading,
        st.s_vel_true,
        st.s_wp_index,
        st.s_done,
        st.s_waypoints,
        st.s_n_waypoints,
        st.s_speed_scale,
        st.s_compass_bias_rad,
        st.s_dr,
        st.s_heading_meas_rad,
        st.s_speed_meas_mps,
    )


def filter_of(st: FrameState) -> Filter:
    """The filter's record of views of ``st``."""
    return Filter(st.f_E, st.f_P, st.f_rejected_cycles, st.f_window_r, st.f_window_S, st.f_window_age)


def tracker_of(st: FrameState) -> Tracker:
    """The tracker's record of views of ``st``."""
    return Tracker(st.k_pos, st.k_vel, st.k_age_s, st.k_has_fix, st.k_outlier)


# --- records of the scenario's numbers ----------------------------------------------------
class CycleParams(NamedTuple):
    """The scenario's numbers the per-cycle kernel uses (``cycle_params``)."""

    salinity_psu: float
    water_temperature_c: float  # nominal: the sound speed the vehicle assumes
    range_noise_std_m: float
    outlier_probability: float
    outlier_mean_excess_m: float
    packet_loss_near: float
    packet_loss_far: float
    max_range_m: float
    turnaround_s: float
    depth_noise_m: float
    gate1: float  # chi-square gates on the normalized innovation squared, 1 and 2 dof
    gate2: float
    depth_m: float
    ping_interval_s: float
    safety_distance_m: float
    baseline_target_m: float
    baseline_tolerance_m: float
    min_baseline_distance_m: float
    frame_restart_min_fixes: float
    frame_q_position_m2ps: float  # the filter's Q, for the dead-reckoned drift of a stored fix
    frame_q_baseline_m2ps: float
    survey_speed_mps: float
    frame_bearing_fusion: float  # 1.0: fuse the telemetered frame bearing (filter.update_phi), 0.0: the paper's filter
    gps_noise_m: float  # the boats' GPS error per axis: the telemetered bearing's noise (eq. B1)
    frame_motion_telemetry: float  # 1.0: carry the telemetered frame motion into the filter (frame_motion), 0.0: not
    boat_velocity_noise_mps: float  # the boats' GPS velocity error per axis: the telemetered motion's noise (eq. M3)
    frame_restart_velocity_std_mps: float  # the recovery's prior on a locked-out filter's velocity error (eq. F5)


def cycle_params(config: ScenarioConfig, gate1: float, gate2: float) -> CycleParams:
    """``CycleParams`` of a scenario, with its gates (1 and 2 dof)."""
    named = {"gate1": gate1, "gate2": gate2}
    return CycleParams(*(float(named[k] if k in named else getattr(config, k)) for k in CycleParams._fields))


class VehicleParams(NamedTuple):
    """The scenario's numbers for the vehicle's sub-steps (``vehicle.integrate_vehicle``)."""

    speed_mps: float  # commanded water speed
    dt: float  # sub-step
    los_alpha: float
    acceptance_m: float
    turn_cos: float  # the heading's largest turn per sub-step, cosine and sine
    turn_sin: float
    Q: np.ndarray  # the filter's process noise per second (6,6)
    K: int  # sub-steps per cycle


class ObserveParams(NamedTuple):
    """The scales of the boats' observation (``observe.observe_boats``)."""

    L: float  # baseline_target_m
    boat_max_speed_mps: float
    survey_speed_mps: float
    age_scale_s: float
    max_cycles: int


# --- what the per-cycle kernel writes, per environment ---------------------------------------
# floats, in the columns the kernel wrote before these were named (numpy reads the fields
# as views with the same strides, so its transcendental functions take the same paths)
CYCLE_OUT = np.dtype(
    [
        ("det", "f8", (2,)),  # det of the filter's (x, y) covariance before and after the updates
        ("survey_error", "f8"),
        ("dr_error", "f8"),
        ("error_x", "f8"),
        ("error_y", "f8"),
        ("baseline_error", "f8"),
        ("major", "f8"),
        ("minor", "f8"),
        ("vehicle_y", "f8"),
        # reward terms (unweighted, 0/1): safety per boat, then the team's contact, baseline, approach
        ("safety", "f8", (2,)),
        ("contact", "f8"),
        ("phi_err_sin", "f8"),
        ("phi_err_cos", "f8"),  # the frame-orientation error, wrapped by numpy
        ("baseline_off", "f8"),
        ("approach", "f8"),
    ]
)
CYCLE_COUNTS = np.dtype(
    [
        ("ranges_fused", "i8"),
        ("outliers_rejected", "i8"),
        ("packets_lost", "i8"),
        ("filter_restarts", "i8"),
        ("range_ok", "?"),
    ]
)
