"""The scenario description: one frozen dataclass that the batched core reads.

A scenario is data. ``ScenarioConfig`` holds every parameter of the simulation
(vehicles, sensors, acoustics, current, reward) with units in its names;
``scenarios/<name>.py`` files register named instances of it. Overriding a
parameter is ``make_config("gao_sea", ping_interval_s=10.0)``. Unknown scenario
or parameter names are a ``ValueError`` that lists the valid ones, so a typo
never passes silently (the VMAS habit). Defaults that come from
``shared/reference-values.md`` cite it by section; guesses are marked [U].
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import numbers
from dataclasses import dataclass
from typing import Callable

BEACON_KINDS = ("beacon_auv", "asv", "boat")
NETWORKS = ("survey_beacons", "moving_lbl")
SURVEY_PATHS = ("stationary", "lawnmower", "circle", "spiral", "line", "waypoints")
RANGING_MODES = ("owtt", "twtt")
# ACOUSTIC_SENSORS: the registered sensors' names (core.measurements), read when asked (__getattr__ below)
ACTION_MODES = ("velocity", "heading_speed", "frame_velocity")
CHANNEL_MODES = ("clock", "decide")
MISSION_FRAMES = ("frame", "world")  # where a moving-network mission's waypoints live (mission_frame)
MAX_RIVER_POINTS = 10_000  # vertices of river_centerline_m
SLOWEST_SOUND_SPEED_MPS = 1400.0  # below any sea water's (Mackenzie 1981 at -2 degC, 25 ppt: ~1430 m/s): bounds a packet's flight time


@dataclass(frozen=True)
class ScenarioConfig:
    """Every parameter of a coopnav scenario. See the field comments for units."""

    name: str = "custom"  # the scenario's name (make_config sets it)
    # which simulator reads this config: "survey_beacons" (survey vehicles in a fixed
    # navigation frame, beacons that ping them: Gao & Chitre, Sousa et al.) or
    # "moving_lbl" (one AUV in the frame of two beacon boats: Matos & Cruz)
    network: str = "survey_beacons"  # which simulator: see NETWORKS

    # --- timing ---------------------------------------------------------------------
    ping_interval_s: float = 20.0  # one decision step = one acoustic cycle (Gao & Chitre: 20 s)
    substep_s: float = 1.0  # integration step inside a cycle
    max_cycles: int = 400  # truncation
    mission_duration_s: float = 0.0  # > 0: the survey's mission also ends after this time

    # --- roster ---------------------------------------------------------------------
    n_survey: int = 1  # survey vehicles (each flies its own copy of the path, survey_spacing_m apart)
    beacon_kinds: tuple = ("beacon_auv",)  # one entry per learning agent: "beacon_auv" | "asv"

    # --- survey path (the mission, planned in the navigation frame: east, north, depth)
    survey_path: str = "lawnmower"  # one of SURVEY_PATHS
    survey_origin_m: tuple = (0.0, 0.0)  # south-west corner of the survey area
    survey_area_m: tuple = (130.0, 100.0)  # east extent, north extent
    lawnmower_spacing_m: float = 25.0  # track spacing
    depth_m: float = 5.0  # mission depth (start depth of a spiral)
    spiral_end_depth_m: float = 0.0  # spiral: depth at the end; <= depth_m means depth_m + 20
    circle_radius_m: float = 40.0  # survey_path="circle": radius around the area's centre
    circle_laps: float = 2.0  # survey_path="circle": laps flown
    line_length_m: float = 100.0  # survey_path="line": back and forth along east
    path_repeats: int = 1  # the path is flown this many times, alternately forward and back
    waypoints_m: tuple = ()  # survey_path="waypoints": ((east, north, depth), ...)
    survey_spacing_m: float = 30.0  # offset between the paths of several survey vehicles
    waypoint_acceptance_m: float = 3.0  # a waypoint counts as reached within this horizontal distance
    los_alpha: float = 0.5  # Matos & Cruz Fig. 5: |W_i Q| = alpha |W_i P|

    # --- survey vehicle: thrust model of Gao & Chitre eq. (1) ---------------------
    survey_mass_kg: float = 45.0  # STARFISH 40-60 kg [U], ref-values section 1
    survey_drag_coefficient: float = 0.42  # Allen et al. 2000, ref-values section 1
    survey_cross_section_m2: float = 0.0284  # REMUS frontal area, ref-values section 1
    water_density_kgpm3: float = 1026.0  # ref-values section 1
    max_thrust_n: float = 14.0  # full thrust; 1.5 m/s at 100 % with the above [U, derived]
    survey_thrust_percent: float = 60.0  # lake trial: 60 %, sea trial: 70 %
    survey_speed_scale_error_std: float = 0.05  # true/modelled water speed - 1, per episode [U 5-10 %]
    survey_max_turn_rate_dps: float = 12.0  # [U]
    survey_max_pitch_deg: float = 20.0  # [U]
    survey_depth_gain_per_m: float = 0.2  # pitch command (rad) per metre of depth error [U]

    # --- survey sensors -------------------------------------------------------------
    compass_noise_deg: float = 1.0  # OS5000, <30 deg tilt, ref-values section 2
    compass_bias_std_deg: float = 1.0  # residual heading bias per run [U 1-3 deg]
    attitude_noise_deg: float = 0.3  # pitch/roll [U 0.2-0.5 deg]
    depth_noise_m: float = 0.05  # Bar30 resolution is 2 mm; noise [U]
    gps_noise_m: float = 2.1  # u-blox M8, 1-sigma per axis, ref-values section 2
    gps_max_depth_m: float = 0.3  # GPS fixes only this close to the surface
    sensor_nan_probability: float = 0.0  # fault injection: a measurement is NaN

    # --- survey EKF (Gao & Chitre eqs. 4-13) ---------------------------------------
    initial_position_std_m: float = 2.0  # GPS fix before diving
    process_noise_horizontal_m2ps: float = 1.0  # Q per second, east and north: tuned so that the
    # NEES of gao_lawnmower sits in its chi-square band (tests/test_ekf.py); it stands for the
    # biases the filter does not model (speed scale, compass bias, current estimate)
    process_noise_vertical_m2ps: float = 0.002  # Q per second, depth
    range_gate_probability: float = 0.99  # chi-square innovation gate (1 dof)
    reinit_after_rejected_ranges: int = 3  # survey filter: restart from the range after this many gated out in a row (0: never)
    survey_uses_beacon_current: bool = True  # add the current a DVL beacon AUV sends (Gao II-A)

    # --- beacon AUV (DVL) -----------------------------------------------------------
    beacon_auv_max_speed_mps: float = 1.5  # STARFISH <= 1.5 m/s [U]
    beacon_auv_max_turn_rate_dps: float = 12.0  # [U]
    beacon_auv_depth_m: float = 2.0  # the beacon AUV's constant depth [U]
    dvl_velocity_noise_mps: float = 0.026  # HoloOcean DVL default, ref-values section 2
    dvl_lock_loss_probability: float = 0.02  # per cycle [U]
    dvl_lock_regain_probability: float = 0.5  # per cycle [U]
    beacon_current_estimate_error_mps: float = 0.05  # its current estimate (DVL - thrust model) [U]
    # the beacon AUV's DVL dead reckoning drifts with distance travelled (0.5-2 % of it with a
    # magnetic compass): per episode and beacon a compass error b0 + b1 sin(heading + phase)
    # (constant plus one-cycle, Hench & Rosman 2010) and a velocity scale error
    beacon_dvl_heading_bias_std_deg: float = 0.5  # std of b0; residual bias 1-3 deg per run before calibration, ref-values section 2 [U]
    beacon_dvl_heading_cycle_deg: float = 1.0  # b1, random phase: heading-dependent compass error; Hench & Rosman 2010: <1 % of track after calibration [U]
    beacon_dvl_scale_error_std: float = 0.01  # DVL velocity scale error (A50 standard firmware ~1 %), ref-values section 2
    beacon_surface_every_s: float = 0.0  # > 0: the beacon AUV takes a GPS fix at the surface this often (0: never)
    beacon_surface_above_std_m: float = 0.0  # > 0: ... and whenever its own position std exceeds this (0: never)

    # --- ASV (GPS) ------------------------------------------------------------------
    asv_max_speed_mps: float = 2.0  # Sousa et al.
    asv_max_turn_rate_dps: float = 30.0  # [U]

    # --- boat (GPS; the beacons of the moving LBL network) -------------------------------
    boat_max_speed_mps: float = 1.5  # small outboard boat at survey pace [U]
    boat_max_turn_rate_dps: float = 20.0  # [U]

    beacon_start_distance_m: float = 60.0  # from the survey's start point; 0: the FIM-optimal distance
    beacon_start_bearing_deg: float = 225.0  # bearing of the beacon from the survey start
    beacon_start_bearing_spread_deg: float = 30.0  # randomized per episode, +/-
    action_mode: str = "velocity"  # "velocity": (v_east, v_north)/max; "heading_speed"; "frame_velocity"
    # (moving_lbl only): (v_x, v_y)/max in the boats' frame, x along B1 -> B2 as their GPS gives it

    # --- acoustics ------------------------------------------------------------------
    # "modem": every beacon pings every survey vehicle each cycle (range only);
    # "mls": Kottege & Zimmer's MLS array (core/mls/, analytic mode): one beacon sends
    # per cycle (round robin) and each survey vehicle measures its range and azimuth
    acoustic_sensor: str = "modem"  # one of ACOUSTIC_SENSORS (see above)
    mls_snr_db_at_1m: float = 30.0  # in-band SNR per sample at 1 m [U]; falls 20 log10(r)
    mls_max_range_m: float = 60.0  # receive window; farther senders are not heard [U]
    ranging_mode: str = "owtt"  # one-way (synchronized clocks) or two-way travel time
    range_noise_std_m: float = 1.0  # one detection's timing jitter as range, c sigma_t: a one-way range's std; a two-way range has 1/sqrt(2) of it [U: Micro-Modem OWTT 1-3 m]
    turnaround_s: float = 0.015  # transponder turn-around delay, ref-values section 3
    max_range_m: float = 1500.0  # no packet arrives beyond this range [U]
    packet_loss_near: float = 0.05  # loss probability at zero range [U, 10-50 %]
    packet_loss_far: float = 0.5  # loss probability at max_range_m [U]
    outlier_probability: float = 0.03  # multipath, ref-values section 3 [U 1-10 %]
    outlier_mean_excess_m: float = 30.0  # multipath ranges are too long by Exp(this)
    water_temperature_c: float = 28.0  # Singapore waters
    salinity_psu: float = 30.0  # for the sound speed (Mackenzie 1981)
    temperature_uncertainty_c: float = 0.5  # true temperature differs per episode
    clock_offset_std_s: float = 1e-4  # OWTT clock offset at start (0.15 m)
    clock_drift_ppm: float = 0.01  # OWTT clock drift, per episode +/- [U]

    # --- the acoustic channel as a shared, costly resource (core/channel.py) -----------
    # "clock": every beacon pings every cycle and the channel is free (the papers);
    # "decide": each ping_interval_s is a decision slot, a beacon transmits when its
    # action's third component is > 0, and the packets share one half-duplex channel in
    # time (collisions, propagation delays, transmit energy); needs modem OWTT ranging
    channel_mode: str = "clock"  # one of CHANNEL_MODES (see above)
    modem_bit_rate_bps: float = 80.0  # WHOI Micro-Modem FH-FSK, the slowest of its 80-5400 bps, ref-values section 3
    ping_packet_bits: int = 64  # a beacon's ping: id, send time, own position and variance [U]
    reply_packet_bits: int = 128  # a survey vehicle's reply: estimate, covariance, waypoint index, range age [U]
    transmit_power_w: float = 40.0  # electrical power while a modem transmits [U: tens of watts]
    ping_penalty: float = 0.0  # reward weight of the "ping" term (per ping a beacon transmits)
    tdma_frame_slots: int = 0  # > 0: beacon j may transmit only in slots k with k mod this == j mod this (0: any slot)

    # --- ocean current (constant + first-order Gauss-Markov), per episode ------------
    current_speed_mps: float = 0.05  # mean speed of the constant part
    current_speed_spread_mps: float = 0.03  # uniform +/- around current_speed_mps
    current_direction_deg: float = 90.0  # direction the water flows TO, clockwise from north
    current_direction_spread_deg: float = 45.0  # uniform +/- around current_direction_deg
    current_gm_std_mps: float = 0.02  # stationary std of the varying part, per axis
    current_gm_time_constant_s: float = 600.0  # correlation time of the varying part

    # --- reward -----------------------------------------------------------------------
    safety_distance_m: float = 10.0  # a beacon nearer a survey vehicle (3-D) than this is "too close"
    geofence_margin_m: float = 300.0  # fence = survey area grown by this much
    safety_penalty: float = 1.0  # reward weight of the "safety" term (per cycle too close)
    geofence_penalty: float = 1.0  # reward weight of the "geofence" term (per cycle outside)
    contact_penalty: float = 0.2  # no range of this beacon fused this cycle

    # --- moving LBL network (network="moving_lbl"; Matos & Cruz) --------------------------
    # The survey waypoints are then in the boats' frame: x from B1 towards B2, y 90 deg
    # clockwise from x (the vehicle stays at y > 0); depth as usual.
    frame_orientation_deg: float = 90.0  # initial bearing of the frame's x axis (B1 -> B2)
    frame_orientation_spread_deg: float = 0.0  # randomized per episode, +/-
    baseline_target_m: float = 100.0  # the boats' intended separation (paper: 100 m)
    boat_transit_speed_mps: float = 0.5  # boats' speed along the frame's y axis (signed) [U: "constant speed"]
    boat_surge_noise_mps: float = 0.15  # m/s, stationary std of each boat's ground-speed fluctuation along its heading, Gauss-Markov [U 0.1-0.2]
    boat_steering_noise_deg: float = 5.0  # deg, stationary std of each boat's course-over-ground error, Gauss-Markov [U]
    boat_noise_time_constant_s: float = 30.0  # s, correlation time of the surge and course errors (0: white per cycle) [U]
    boat_current_response: float = 0.2  # fraction of the water current the boats' ground-speed control does not cancel [U]
    survey_speed_mps: float = 1.0  # water speed held by the vehicle's speed controller (paper: 1 m/s)
    speed_encoder_noise_mps: float = 0.02  # propeller-encoder water-speed noise, per sub-step [U]
    initial_frame_orientation_std_deg: float = 5.0  # the filter's prior on phi [U]
    initial_frame_orientation_error_deg: float = 0.0  # a fixed error added to the prior mean (tests)
    initial_current_std_mps: float = 0.5  # prior on the frame-relative current (boats' speed unknown)
    initial_baseline_std_m: float = 5.0  # prior on l
    frame_q_position_m2ps: float = 0.01  # Q of the moving-frame EKF, per second: x and y [U, tuned]
    frame_q_orientation_rad2ps: float = 1e-6  # phi
    frame_q_current_m2ps3: float = 1e-4  # c_x, c_y (boat speed changes, current variation)
    frame_q_baseline_m2ps: float = 0.02  # l: a random walk that follows a boat-speed mismatch (tests/test_matos.py)
    baseline_tolerance_m: float = 10.0  # reward: |l - target| beyond this costs baseline_penalty
    baseline_penalty: float = 1.0  # reward weight of the "baseline" term
    frame_rotation_tolerance_deg: float = 10.0  # reward: the frame turned further than this from its
    rotation_penalty: float = 1.0  # start costs rotation_penalty (the filter models phi as constant)
    min_baseline_distance_m: float = 15.0  # reward: the vehicle closer than this to the baseline
    approach_penalty: float = 1.0  # (the fix degenerates on the baseline) costs approach_penalty
    # where the vehicle's mission lives: "frame", waypoints_m in the boats' frame (x, y, depth), the
    # paper's; "world", waypoints_m in (east, north, depth), re-expressed in the frame every cycle
    # through the boats' GPS (they telemeter B1's position and the bearing to B2): a river survey
    mission_frame: str = "frame"  # one of MISSION_FRAMES (moving_lbl only; see above)
    river_centerline_m: tuple = ()  # mission_frame="world": the river's centerline ((east, north), ...), listed downstream; its current flows along it
    river_width_m: float = 150.0  # mission_frame="world": bank to bank; a boat farther than half of it from the centerline is on the bank [U]
    bank_penalty: float = 1.0  # reward weight of the "bank" term (per boat and cycle outside the river)

    # --- domain randomization: drawn per episode from the episode's seed --------------
    randomize_survey_path: tuple = ()  # choices of survey_path; () keeps survey_path
    randomize_depth_m: tuple = ()  # choices of depth_m; () keeps depth_m
    randomize_noise_scale: tuple = ()  # (low, high): uniform factor on range noise, compass
    # noise and bias, attitude noise and speed-scale error; () keeps 1

    # --- observation --------------------------------------------------------------------
    observed_waypoints: int = 2  # the survey's next planned waypoints in the observation

    def __post_init__(self):
        # numbers may come as numpy scalars (sweeps, YAML): store plain ints and floats;
        # lists (YAML, JSON) become tuples. Anything else is left for _validate to refuse.
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            kind = type(f.default)
            if kind is int and isinstance(v, numbers.Integral) and not isinstance(v, bool):
                object.__setattr__(self, f.name, int(v))
            elif kind is float and isinstance(v, numbers.Real) and not isinstance(v, bool):
                object.__setattr__(self, f.name, float(v))
            elif kind is tuple and isinstance(v, list):
                object.__setattr__(self, f.name, tuple(tuple(x) if isinstance(x, list) else x for x in v))
        _validate(self)

    # derived quantities, computed in one place --------------------------------------
    @property
    def n_beacons(self) -> int:
        return len(self.beacon_kinds)

    @property
    def substeps_per_cycle(self) -> int:
        return int(round(self.ping_interval_s / self.substep_s))

    @property
    def geofence_m(self) -> tuple:
        """(east_min, north_min, east_max, north_max) of the geofence."""
        e0, n0 = self.survey_origin_m
        w, h = self.survey_area_m
        m = self.geofence_margin_m
        return (e0 - m, n0 - m, e0 + w + m, n0 + h + m)

    @property
    def position_scale_m(self) -> float:
        """Length that normalizes positions in observations."""
        w, h = self.survey_area_m
        return float(max(w, h) / 2 + self.geofence_margin_m)

    def max_speed_mps(self, kind: str) -> float:
        """A beacon's maximum speed through the water by its kind (``BEACON_KINDS``):
        the one place that maps a kind to its speed parameter."""
        speeds = {"beacon_auv": self.beacon_auv_max_speed_mps, "asv": self.asv_max_speed_mps,
                  "boat": self.boat_max_speed_mps}
        if kind not in speeds:
            raise ValueError(f"unknown beacon kind {kind!r}; valid: {', '.join(speeds)}")
        return float(speeds[kind])

    @property
    def beacon_max_speeds_mps(self) -> tuple:
        """The maximum speed of each beacon, in ``beacon_kinds`` order."""
        return tuple(self.max_speed_mps(k) for k in self.beacon_kinds)

    def replace(self, **overrides) -> "ScenarioConfig":
        return dataclasses.replace(self, **check_overrides(overrides))


def parameter_names() -> list:
    return [f.name for f in dataclasses.fields(ScenarioConfig)]


def check_overrides(overrides: dict) -> dict:
    """Refuse unknown parameter names, naming the valid ones (and the closest)."""
    valid = parameter_names()
    unknown = [k for k in overrides if k not in valid]
    if unknown:
        hints = []
        for k in unknown:
            close = difflib.get_close_matches(k, valid, n=1)
            hints.append(f"{k!r}" + (f" (did you mean {close[0]!r}?)" if close else ""))
        raise ValueError(
            f"unknown scenario parameter(s) {', '.join(hints)}; valid parameters: {', '.join(valid)}"
        )
    return overrides


def _check(cond: bool, message: str):
    if not cond:
        raise ValueError(message)


def _finite(x) -> bool:
    try:
        return math.isfinite(float(x))
    except (TypeError, ValueError, OverflowError):
        return False


# Every number's physical range, (low, high) inclusive; a low of OPEN_ZERO means "> 0".
# Upper bounds keep what scales with a value (path length, waypoints, area, noise the
# filter must represent) within the acoustic and mission scale of these simulations.
OPEN_ZERO = "(0"
LIMITS = {
    "ping_interval_s": (OPEN_ZERO, 3600.0), "substep_s": (OPEN_ZERO, 60.0), "max_cycles": (1, 100_000),
    "mission_duration_s": (0.0, 1e6), "n_survey": (1, 16),
    "lawnmower_spacing_m": (OPEN_ZERO, 10_000.0), "depth_m": (0.0, 6000.0), "spiral_end_depth_m": (0.0, 6000.0),
    "circle_radius_m": (0.0, 10_000.0), "circle_laps": (OPEN_ZERO, 1000.0), "line_length_m": (OPEN_ZERO, 20_000.0),
    "path_repeats": (1, 1000), "survey_spacing_m": (0.0, 10_000.0), "waypoint_acceptance_m": (OPEN_ZERO, 1000.0),
    "los_alpha": (0.0, 1.0), "survey_mass_kg": (OPEN_ZERO, 1e5), "survey_drag_coefficient": (OPEN_ZERO, 10.0),
    "survey_cross_section_m2": (OPEN_ZERO, 100.0), "water_density_kgpm3": (900.0, 1100.0),
    "max_thrust_n": (OPEN_ZERO, 1e5), "survey_thrust_percent": (0.0, 100.0), "survey_speed_scale_error_std": (0.0, 0.5),
    "survey_max_turn_rate_dps": (OPEN_ZERO, 360.0), "survey_max_pitch_deg": (OPEN_ZERO, 90.0),
    "survey_depth_gain_per_m": (0.0, 100.0), "compass_noise_deg": (0.0, 45.0), "compass_bias_std_deg": (0.0, 45.0),
    "attitude_noise_deg": (0.0, 45.0), "depth_noise_m": (0.0, 100.0), "gps_noise_m": (0.0, 1000.0),
    "gps_max_depth_m": (0.0, 100.0), "sensor_nan_probability": (0.0, 1.0), "initial_position_std_m": (OPEN_ZERO, 10_000.0),
    "process_noise_horizontal_m2ps": (0.0, 10_000.0), "process_noise_vertical_m2ps": (0.0, 10_000.0),
    "range_gate_probability": (OPEN_ZERO, 0.999999), "reinit_after_rejected_ranges": (0, 1000),
    "beacon_auv_max_speed_mps": (OPEN_ZERO, 20.0), "beacon_auv_max_turn_rate_dps": (OPEN_ZERO, 360.0),
    "beacon_auv_depth_m": (0.0, 6000.0), "dvl_velocity_noise_mps": (0.0, 10.0), "dvl_lock_loss_probability": (0.0, 1.0),
    "dvl_lock_regain_probability": (0.0, 1.0), "beacon_current_estimate_error_mps": (0.0, 10.0),
    "beacon_dvl_heading_bias_std_deg": (0.0, 45.0), "beacon_dvl_heading_cycle_deg": (0.0, 45.0),
    "beacon_dvl_scale_error_std": (0.0, 0.5), "beacon_surface_every_s": (0.0, 1e6),
    "beacon_surface_above_std_m": (0.0, 10_000.0), "asv_max_speed_mps": (OPEN_ZERO, 20.0),
    "asv_max_turn_rate_dps": (OPEN_ZERO, 360.0), "boat_max_speed_mps": (OPEN_ZERO, 20.0),
    "boat_max_turn_rate_dps": (OPEN_ZERO, 360.0), "beacon_start_distance_m": (0.0, 20_000.0),
    "beacon_start_bearing_deg": (-360.0, 360.0), "beacon_start_bearing_spread_deg": (0.0, 360.0),
    "mls_snr_db_at_1m": (-50.0, 150.0), "mls_max_range_m": (1.0, 10_000.0), "range_noise_std_m": (OPEN_ZERO, 1000.0),
    "turnaround_s": (0.0, 10.0), "max_range_m": (OPEN_ZERO, 100_000.0), "packet_loss_near": (0.0, 1.0),
    "packet_loss_far": (0.0, 1.0), "outlier_probability": (0.0, 1.0), "outlier_mean_excess_m": (0.0, 10_000.0),
    "water_temperature_c": (-2.0, 40.0), "salinity_psu": (0.0, 45.0), "temperature_uncertainty_c": (0.0, 20.0),
    "clock_offset_std_s": (0.0, 10.0), "clock_drift_ppm": (0.0, 10_000.0), "current_speed_mps": (0.0, 10.0),
    "current_speed_spread_mps": (0.0, 10.0), "current_direction_deg": (-360.0, 360.0),
    "current_direction_spread_deg": (0.0, 360.0), "current_gm_std_mps": (0.0, 10.0),
    "current_gm_time_constant_s": (OPEN_ZERO, 1e7), "safety_distance_m": (0.0, 10_000.0),
    "geofence_margin_m": (0.0, 100_000.0), "safety_penalty": (0.0, 1e6), "geofence_penalty": (0.0, 1e6),
    "contact_penalty": (0.0, 1e6), "frame_orientation_deg": (-360.0, 360.0), "frame_orientation_spread_deg": (0.0, 360.0),
    "baseline_target_m": (OPEN_ZERO, 10_000.0), "boat_transit_speed_mps": (-20.0, 20.0),
    "boat_surge_noise_mps": (0.0, 5.0), "boat_steering_noise_deg": (0.0, 90.0),
    "boat_noise_time_constant_s": (0.0, 1e5), "boat_current_response": (0.0, 1.0),
    "survey_speed_mps": (OPEN_ZERO, 20.0), "speed_encoder_noise_mps": (0.0, 5.0),
    "initial_frame_orientation_std_deg": (OPEN_ZERO, 180.0), "initial_frame_orientation_error_deg": (-180.0, 180.0),
    "initial_current_std_mps": (OPEN_ZERO, 10.0), "initial_baseline_std_m": (OPEN_ZERO, 1000.0),
    "frame_q_position_m2ps": (0.0, 10_000.0), "frame_q_orientation_rad2ps": (0.0, 10.0),
    "frame_q_current_m2ps3": (0.0, 100.0), "frame_q_baseline_m2ps": (0.0, 10_000.0),
    "baseline_tolerance_m": (0.0, 10_000.0), "baseline_penalty": (0.0, 1e6), "frame_rotation_tolerance_deg": (0.0, 360.0),
    "rotation_penalty": (0.0, 1e6), "min_baseline_distance_m": (0.0, 10_000.0), "approach_penalty": (0.0, 1e6),
    "river_width_m": (OPEN_ZERO, 10_000.0), "bank_penalty": (0.0, 1e6),
    "observed_waypoints": (1, 64), "modem_bit_rate_bps": (OPEN_ZERO, 1e6), "ping_packet_bits": (1, 1_000_000),
    "reply_packet_bits": (1, 1_000_000), "transmit_power_w": (0.0, 10_000.0), "ping_penalty": (0.0, 1e6),
    "tdma_frame_slots": (0, 1024),
}
COORDINATE_LIMIT_M = 1e6  # |east|, |north| of origins and waypoints
AREA_LIMIT_M = 20_000.0  # each side of the survey area
MAX_WAYPOINTS = 100_000  # a path that needs more is refused before it is built


def _range_text(lo, hi) -> str:
    return f"(0, {hi:g}]" if lo is OPEN_ZERO else f"[{lo:g}, {hi:g}]"


def _check_number(name, v, kind):
    """Type, finiteness and range of one number field."""
    if kind is int:
        _check(isinstance(v, numbers.Integral) and not isinstance(v, bool),
               f"scenario parameter {name} must be an integer, got {v!r}")
    else:
        _check(isinstance(v, numbers.Real) and not isinstance(v, bool),
               f"scenario parameter {name} must be a number, got {v!r}")
        _check(_finite(v), f"scenario parameter {name} must be finite, got {v!r}")
    lo, hi = LIMITS[name]
    ok = (v > 0 if lo is OPEN_ZERO else v >= lo) and v <= hi
    _check(ok, f"scenario parameter {name} must be in {_range_text(lo, hi)}, got {v!r}")


def _check_coordinates(name, values, n):
    _check(isinstance(values, tuple) and len(values) == n,
           f"scenario parameter {name} must be {n} numbers, got {values!r}")
    for v in values:
        _check(isinstance(v, numbers.Real) and not isinstance(v, bool) and _finite(v) and abs(v) <= COORDINATE_LIMIT_M,
               f"scenario parameter {name} must hold finite numbers within +-{COORDINATE_LIMIT_M:g} m, got {values!r}")


def _check_river(c):
    """mission_frame="world": the river's centerline, a polyline of at least two distinct
    consecutive (east, north) points."""
    pts = c.river_centerline_m
    _check(2 <= len(pts) <= MAX_RIVER_POINTS,
           f"scenario parameter river_centerline_m must hold 2 to {MAX_RIVER_POINTS} (east, north) points for "
           f"mission_frame='world', got {len(pts)}")
    for p in pts:
        _check(isinstance(p, tuple), f"river_centerline_m entries must be (east, north), got {p!r}")
        _check_coordinates("river_centerline_m", p, 2)
    _check(all(a != b for a, b in zip(pts, pts[1:])),
           "scenario parameter river_centerline_m must not repeat a point twice in a row")


def waypoint_count(c, path: str) -> int:
    """How many waypoints ``guidance.build_path`` makes for ``path`` (before repeats)."""
    if path == "lawnmower":
        return 2 * (int(math.floor(c.survey_area_m[1] / c.lawnmower_spacing_m + 1e-9)) + 1)
    if path in ("circle", "spiral"):
        return max(int(math.ceil(c.circle_laps * 24)), 2) + 1
    if path == "waypoints":
        return len(c.waypoints_m)
    return 2


def _validate(c: ScenarioConfig):
    # every field by the type of its default: numbers against LIMITS, strings, flags
    for f in dataclasses.fields(c):
        v, kind = getattr(c, f.name), type(f.default)
        if kind in (int, float):
            _check_number(f.name, v, kind)
        elif kind is str:
            _check(isinstance(v, str), f"scenario parameter {f.name} must be a string, got {v!r}")
        elif kind is bool:
            _check(isinstance(v, bool), f"scenario parameter {f.name} must be True or False, got {v!r}")
        elif kind is tuple:
            _check(isinstance(v, tuple), f"scenario parameter {f.name} must be a tuple (or list), got {v!r}")
    _check(c.substep_s <= c.ping_interval_s, "substep_s must not exceed ping_interval_s")
    _check(abs(c.substeps_per_cycle * c.substep_s - c.ping_interval_s) < 1e-9 * c.ping_interval_s,
           f"ping_interval_s ({c.ping_interval_s}) must be a whole multiple of substep_s ({c.substep_s})")
    _check(c.substeps_per_cycle <= 4095,
           f"substep_s ({c.substep_s:g}) gives {c.substeps_per_cycle} sub-steps per cycle; at most 4095")
    _check(len(c.beacon_kinds) >= 1, "beacon_kinds must be a non-empty tuple")
    _check(len(c.beacon_kinds) <= 16, f"at most 16 beacons, got {len(c.beacon_kinds)}")
    for k in c.beacon_kinds:
        _check(isinstance(k, str) and k in BEACON_KINDS,
               f"beacon_kinds: unknown beacon kind {k!r}; valid kinds: {', '.join(BEACON_KINDS)}")
    from ..core.measurements import check_sensor

    check_sensor(c)  # the registered sensor: its name, its networks, its own checks
    _check(c.network in NETWORKS, f"unknown network {c.network!r}; valid networks: {', '.join(NETWORKS)}")
    _check_coordinates("survey_origin_m", c.survey_origin_m, 2)
    _check_coordinates("survey_area_m", c.survey_area_m, 2)
    _check(all(0 < v <= AREA_LIMIT_M for v in c.survey_area_m),
           f"scenario parameter survey_area_m must be two lengths in (0, {AREA_LIMIT_M:g}] m, got {c.survey_area_m!r}")
    _check(len(c.waypoints_m) <= MAX_WAYPOINTS, f"waypoints_m has more than {MAX_WAYPOINTS} entries")
    for w in c.waypoints_m:
        _check(isinstance(w, tuple) and len(w) == 3, f"waypoints_m entries must be (east, north, depth), got {w!r}")
        _check_coordinates("waypoints_m", w, 3)
        _check(0 <= w[2] <= 6000, f"waypoints_m depths must be in [0, 6000] m, got {w!r}")
    if c.network == "moving_lbl":
        _check(c.beacon_kinds == ("boat", "boat"),
               f"network='moving_lbl' needs beacon_kinds=('boat', 'boat') (B1, B2), got {c.beacon_kinds!r}")
        _check(c.n_survey == 1, f"network='moving_lbl' simulates one vehicle, got n_survey={c.n_survey}")
        _check(c.mission_frame in MISSION_FRAMES,
               f"unknown mission_frame {c.mission_frame!r}; valid: {', '.join(MISSION_FRAMES)}")
        _check(c.survey_path == "waypoints",
               f"network='moving_lbl' needs survey_path='waypoints' ({c.mission_frame} coordinates)")
        if c.mission_frame == "frame":
            _check(all(w[1] > 0 for w in c.waypoints_m),
                   "waypoints_m: network='moving_lbl' needs y > 0 in every waypoint (the vehicle must not cross the baseline)")
            _check(c.river_centerline_m == (),
                   "river_centerline_m needs mission_frame='world' (a frame mission ignores the river); valid: ()")
        else:
            _check_river(c)
        _check(abs(c.boat_transit_speed_mps) <= c.boat_max_speed_mps,
               f"boat_transit_speed_mps ({c.boat_transit_speed_mps}) exceeds boat_max_speed_mps ({c.boat_max_speed_mps})")
        _check(c.ranging_mode == "twtt", "network='moving_lbl' ranges by two-way travel time: ranging_mode='twtt'")
    else:
        _check("boat" not in c.beacon_kinds, "beacon_kinds: the kind 'boat' belongs to network='moving_lbl'")
        _check(c.action_mode != "frame_velocity", "action_mode='frame_velocity' belongs to network='moving_lbl'")
        _check(c.mission_frame == "frame",
               f"mission_frame={c.mission_frame!r} belongs to network='moving_lbl'; valid: frame")
        _check(c.river_centerline_m == (),
               "river_centerline_m belongs to network='moving_lbl' with mission_frame='world'")
    _check(c.channel_mode in CHANNEL_MODES,
           f"unknown channel_mode {c.channel_mode!r}; valid modes: {', '.join(CHANNEL_MODES)}")
    if c.channel_mode == "decide":
        _check(c.network == "survey_beacons" and c.acoustic_sensor == "modem" and c.ranging_mode == "owtt",
               "channel_mode='decide' needs network='survey_beacons', acoustic_sensor='modem' and ranging_mode='owtt' "
               "(a beacon's ping is the one-way range)")
        # the slot holds the pings, their flight, the turn-around, the replies and theirs
        need = ((c.ping_packet_bits + c.reply_packet_bits) / c.modem_bit_rate_bps
                + 2.0 * c.max_range_m / SLOWEST_SOUND_SPEED_MPS + c.turnaround_s)
        _check(need <= c.ping_interval_s,
               f"channel_mode='decide': a slot of ping_interval_s={c.ping_interval_s:g} s cannot hold a ping and a reply "
               f"({need:.3f} s: (ping_packet_bits + reply_packet_bits) / modem_bit_rate_bps + 2 max_range_m / "
               f"{SLOWEST_SOUND_SPEED_MPS:g} m/s + turnaround_s); raise the bit rate or the slot, or lower max_range_m")
    _check(c.survey_path in SURVEY_PATHS,
           f"unknown survey_path {c.survey_path!r}; valid paths: {', '.join(SURVEY_PATHS)}")
    _check(c.ranging_mode in RANGING_MODES,
           f"unknown ranging_mode {c.ranging_mode!r}; valid modes: {', '.join(RANGING_MODES)}")
    _check(c.action_mode in ACTION_MODES,
           f"unknown action_mode {c.action_mode!r}; valid modes: {', '.join(ACTION_MODES)}")
    _check(c.survey_path != "waypoints" or len(c.waypoints_m) >= 2,
           "survey_path='waypoints' needs at least two waypoints_m entries (east, north, depth)")
    for k in c.randomize_survey_path:
        _check(isinstance(k, str) and k in SURVEY_PATHS and k != "waypoints",
               f"randomize_survey_path: {k!r} is not one of {', '.join(p for p in SURVEY_PATHS if p != 'waypoints')}")
    _check(len(c.randomize_depth_m) <= 64, "randomize_depth_m: at most 64 depths")
    for d in c.randomize_depth_m:
        _check(isinstance(d, numbers.Real) and not isinstance(d, bool) and _finite(d) and 0 <= d <= 6000,
               f"randomize_depth_m: depths must be numbers in [0, 6000] m, got {d!r}")
    _check(c.randomize_noise_scale == () or (len(c.randomize_noise_scale) == 2 and all(
        isinstance(v, numbers.Real) and not isinstance(v, bool) and _finite(v) and 0 <= v <= 100
        for v in c.randomize_noise_scale) and c.randomize_noise_scale[0] <= c.randomize_noise_scale[1]),
        f"randomize_noise_scale must be () or (low, high) with 0 <= low <= high <= 100, got {c.randomize_noise_scale!r}")
    # what scales with the values: the number of waypoints a path needs
    for path in set(c.randomize_survey_path or (c.survey_path,)):
        n = waypoint_count(c, path) * (c.path_repeats if path != "stationary" else 1)
        _check(n <= MAX_WAYPOINTS, f"survey_path={path!r} with these parameters needs {n} waypoints (at most "
                                   f"{MAX_WAYPOINTS}): raise lawnmower_spacing_m or lower circle_laps/path_repeats")


def __getattr__(name: str) -> tuple:
    if name == "ACOUSTIC_SENSORS":  # the registry's, so a sensor registered later is valid
        from ..core.measurements import sensor_names

        return sensor_names()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


# ------------------------------------------------------------------------------------
# the registry of named scenarios
_REGISTRY: dict = {}


def register(name: str, factory: Callable[[], ScenarioConfig] | ScenarioConfig):
    if name in _REGISTRY:
        raise ValueError(f"scenario {name!r} is registered twice")
    _REGISTRY[name] = factory


def list_scenarios() -> list:
    return sorted(_REGISTRY)


def make_config(scenario="gao_lawnmower", **overrides) -> ScenarioConfig:
    """The named scenario's config with ``overrides`` applied (unknown keys are an error)."""
    if isinstance(scenario, ScenarioConfig):
        base = scenario
    else:
        if scenario not in _REGISTRY:
            raise ValueError(f"unknown scenario {scenario!r}; valid scenarios: {', '.join(list_scenarios())}")
        entry = _REGISTRY[scenario]
        base = entry() if callable(entry) else entry
    return base.replace(**overrides) if overrides else base


def resolve_config(env_or_config) -> ScenarioConfig:
    """A ScenarioConfig from an env (any view with ``.config``), a simulator, a config
    or a scenario name."""
    if isinstance(env_or_config, ScenarioConfig):
        return env_or_config
    if isinstance(env_or_config, str):
        return make_config(env_or_config)
    for obj in (env_or_config, getattr(env_or_config, "unwrapped", None)):
        cfg = getattr(obj, "config", None)
        if isinstance(cfg, ScenarioConfig):
            return cfg
    raise TypeError(f"cannot find a scenario config in {type(env_or_config).__name__}")
