"""The sections of a scenario config: every parameter, grouped by what it describes.

Each section is a frozen dataclass of ``param`` fields (``params.py``): default, unit,
range, source and meaning in one place. Defaults that come from
``shared/reference-values.md`` cite it by section; guesses are marked [U]. Which
sections a scenario has is ``config.SECTIONS``' business (a section that does not
apply is ``None``); the checks here concern one section's fields only.
"""

from __future__ import annotations

import numbers

from .params import Section, check, check_coordinates, finite, param, section
from .sections_beacons import DVL_LOCK_MODELS, SURFACING_MODES  # noqa: F401  (their home is sections_beacons)

BEACON_KINDS = ("beacon_auv", "asv", "boat")
NETWORKS = ("survey_beacons", "moving_lbl")
SURVEY_PATHS = ("stationary", "lawnmower", "circle", "spiral", "line", "waypoints")
RANGING_MODES = ("owtt", "twtt")
# ACOUSTIC_SENSORS: the registered sensors' names (core.measurements), read when asked (__getattr__ below)
ACTION_MODES = ("velocity", "heading_speed", "frame_velocity")
CHANNEL_MODES = ("clock", "decide")
BEACON_ERROR_FUSIONS = ("schmidt", "white", "ci")
LOCKOUT_RECOVERIES = ("window", "window_consensus", "nearest_point")
RANGE_OUTLIER_MODELS = ("mixture", "hold", "gate")
RANGE_LINEARIZATIONS = ("first_order", "second_order", "iterated", "split")
# the survey filter of the papers (Gao & Chitre 2010; Sousa et al.): the beacon's variance in R,
# hard gating, a nearest-point restart, white GPS errors. Paper reproductions set these.
PAPER_FILTER = {
    "beacon_error_fusion": "white",
    "range_outlier_model": "gate",
    "lockout_recovery": "nearest_point",
    "reinit_after_short_ranges": 0,
    "range_gate_short_probability": 0.0,
    "gps_error_time_constant_s": 0.0,
    "survey_bias_consider": False,
    "range_linearization": "first_order",
}
AREA_LIMIT_M = 20_000.0  # each side of the survey area
MAX_WAYPOINTS = 100_000  # a path that needs more is refused before it is built


@section
class Timing(Section):
    """Timing: the acoustic cycle (one decision step) and the episode's length."""

    ping_interval_s: float = param(
        20.0,
        unit="s",
        low=0,
        high=3600.0,
        open_low=True,
        doc="one decision step = one acoustic cycle (Gao & Chitre: 20 s)",
    )
    substep_s: float = param(
        1.0, unit="s", low=1e-3, high=60.0, doc="integration step inside a cycle (>= 1 ms: finer steps overflow)"
    )
    max_cycles: int = param(400, low=1, high=100000, doc="truncation")
    mission_duration_s: float = param(
        0.0, unit="s", low=0.0, high=1000000.0, doc="> 0: the survey's mission also ends after this time"
    )

    @property
    def substeps_per_cycle(self) -> int:
        return int(round(self.ping_interval_s / self.substep_s))  # noqa: RUF046 - numpy 1.x rounds a numpy float to a float

    def check(self) -> None:
        check(self.substep_s <= self.ping_interval_s, "substep_s must not exceed ping_interval_s")
        check(
            abs(self.substeps_per_cycle * self.substep_s - self.ping_interval_s) < 1e-9 * self.ping_interval_s,
            f"ping_interval_s ({self.ping_interval_s}) must be a whole multiple of substep_s ({self.substep_s})",
        )
        check(
            self.substeps_per_cycle <= 4095,
            f"substep_s ({self.substep_s:g}) gives {self.substeps_per_cycle} sub-steps per cycle; at most 4095",
        )


@section
class Roster(Section):
    """Who takes part: survey vehicles, the beacons (one per learning agent) and how they are commanded."""

    n_survey: int = param(
        1, low=1, high=16, doc="survey vehicles (each flies its own copy of the path, survey_spacing_m apart)"
    )
    beacon_kinds: tuple = param(
        ("beacon_auv",), doc='one entry per learning agent: "beacon_auv" | "asv" (survey_beacons), "boat" (moving_lbl)'
    )
    action_mode: str = param(
        "velocity",
        choices=ACTION_MODES,
        doc=(
            '"velocity": (v_east, v_north)/max; "heading_speed"; "frame_velocity" (moving_lbl only): (v_x, '
            "v_y)/max in the boats' frame, x along B1 -> B2 as their GPS gives it"
        ),
    )

    def check(self) -> None:
        check(len(self.beacon_kinds) >= 1, "beacon_kinds must be a non-empty tuple")
        check(len(self.beacon_kinds) <= 16, f"at most 16 beacons, got {len(self.beacon_kinds)}")
        for k in self.beacon_kinds:
            check(
                isinstance(k, str) and k in BEACON_KINDS,
                f"beacon_kinds: unknown beacon kind {k!r}; valid kinds: {', '.join(BEACON_KINDS)}",
            )


@section
class SurveyPath(Section):
    """The survey's mission, planned in the navigation frame (east, north, depth)."""

    survey_path: str = param(
        "lawnmower", choices=SURVEY_PATHS, doc="the path the survey vehicles fly (its size: the fields below)"
    )
    survey_origin_m: tuple = param((0.0, 0.0), unit="m", doc="south-west corner of the survey area")
    survey_area_m: tuple = param((130.0, 100.0), unit="m", doc="east extent, north extent")
    lawnmower_spacing_m: float = param(25.0, unit="m", low=0.1, high=10000.0, doc="track spacing")
    depth_m: float = param(
        5.0,
        unit="m",
        low=0.0,
        high=6000.0,
        doc="mission depth (start depth of a spiral; on the moving network the vehicle's one depth, which "
        "its waypoints carry: overriding depth_m alone moves them)",
    )
    spiral_end_depth_m: float = param(
        0.0, unit="m", low=0.0, high=6000.0, doc="spiral: depth at the end; <= depth_m means depth_m + 20"
    )
    circle_radius_m: float = param(
        40.0, unit="m", low=0.0, high=10000.0, doc='survey_path="circle": radius around the area\'s centre'
    )
    circle_laps: float = param(2.0, low=0, high=1000.0, open_low=True, doc='survey_path="circle": laps flown')
    line_length_m: float = param(
        100.0, unit="m", low=0, high=20000.0, open_low=True, doc='survey_path="line": back and forth along east'
    )
    path_repeats: int = param(
        1, low=1, high=1000, doc="the path is flown this many times, alternately forward and back"
    )
    waypoints_m: tuple = param((), unit="m", doc='survey_path="waypoints": ((east, north, depth), ...)')
    survey_spacing_m: float = param(
        30.0, unit="m", low=0.0, high=10000.0, doc="offset between the paths of several survey vehicles"
    )
    waypoint_acceptance_m: float = param(
        3.0,
        unit="m",
        low=0,
        high=1000.0,
        open_low=True,
        doc="a waypoint counts as reached within this horizontal distance",
    )
    los_alpha: float = param(0.5, low=0.0, high=1.0, doc="Matos & Cruz Fig. 5: |W_i Q| = alpha |W_i P|")

    def check(self) -> None:
        check_coordinates("survey_origin_m", self.survey_origin_m, 2)
        check_coordinates("survey_area_m", self.survey_area_m, 2)
        check(
            all(0 < v <= AREA_LIMIT_M for v in self.survey_area_m),
            f"scenario parameter survey_area_m must be two lengths in (0, {AREA_LIMIT_M:g}] m, "
            f"got {self.survey_area_m!r}",
        )
        check(len(self.waypoints_m) <= MAX_WAYPOINTS, f"waypoints_m has more than {MAX_WAYPOINTS} entries")
        for w in self.waypoints_m:
            check(isinstance(w, tuple) and len(w) == 3, f"waypoints_m entries must be (east, north, depth), got {w!r}")
            check_coordinates("waypoints_m", w, 3)
            check(0 <= w[2] <= 6000, f"waypoints_m depths must be in [0, 6000] m, got {w!r}")
        check(
            self.survey_path != "waypoints" or len(self.waypoints_m) >= 2,
            "survey_path='waypoints' needs at least two waypoints_m entries (east, north, depth)",
        )


@section
class SurveyVehicle(Section):
    """The survey vehicle's thrust model (Gao & Chitre eq. 1) and its autopilot limits."""

    survey_mass_kg: float = param(
        45.0,
        unit="kg",
        low=0,
        high=100000.0,
        open_low=True,
        source="reference-values.md §1; assumption [U]",
        doc="STARFISH 40-60 kg [U], ref-values section 1",
    )
    survey_drag_coefficient: float = param(
        0.42,
        low=1e-3,
        high=10.0,
        source="reference-values.md §1",
        doc="Allen et al. 2000, ref-values section 1",
    )
    survey_cross_section_m2: float = param(
        0.0284,
        unit="m²",
        low=1e-4,
        high=100.0,
        source="reference-values.md §1",
        doc="REMUS frontal area, ref-values section 1",
    )
    water_density_kgpm3: float = param(
        1026.0,
        unit="kg/m³",
        low=900.0,
        high=1100.0,
        source="reference-values.md §1",
        doc="sea water's density, ref-values section 1",
    )
    max_thrust_n: float = param(
        14.0,
        unit="N",
        low=0,
        high=100000.0,
        open_low=True,
        source="assumption [U]",
        doc="full thrust; 1.5 m/s at 100 % with this section's mass, drag and area [U, derived]",
    )
    survey_thrust_percent: float = param(60.0, unit="%", low=0.0, high=100.0, doc="lake trial: 60 %, sea trial: 70 %")
    survey_speed_scale_error_std: float = param(
        0.05, low=0.0, high=0.5, source="assumption [U]", doc="true/modelled water speed - 1, per episode [U 5-10 %]"
    )
    survey_max_turn_rate_dps: float = param(
        12.0, unit="deg/s", low=0, high=360.0, open_low=True, source="assumption [U]", doc="[U]"
    )
    survey_max_pitch_deg: float = param(
        20.0, unit="deg", low=0, high=90.0, open_low=True, source="assumption [U]", doc="[U]"
    )
    survey_depth_gain_per_m: float = param(
        0.2,
        unit="1/m",
        low=0.0,
        high=100.0,
        source="assumption [U]",
        doc="pitch command (rad) per metre of depth error [U]",
    )


@section
class SurveySensors(Section):
    """The survey vehicle's dead-reckoning sensors and GPS."""

    compass_noise_deg: float = param(
        1.0,
        unit="deg",
        low=0.0,
        high=45.0,
        source="reference-values.md §2",
        doc="OS5000, <30 deg tilt, ref-values section 2",
    )
    compass_bias_std_deg: float = param(
        1.0, unit="deg", low=0.0, high=45.0, source="assumption [U]", doc="residual heading bias per run [U 1-3 deg]"
    )
    attitude_noise_deg: float = param(
        0.3, unit="deg", low=0.0, high=45.0, source="assumption [U]", doc="pitch/roll [U 0.2-0.5 deg]"
    )
    depth_noise_m: float = param(
        0.05, unit="m", low=0.0, high=100.0, source="assumption [U]", doc="Bar30 resolution is 2 mm; noise [U]"
    )
    gps_noise_m: float = param(
        2.1,
        unit="m",
        low=0.0,
        high=1000.0,
        source="reference-values.md §2",
        doc="u-blox M8, 1-sigma per axis, ref-values section 2",
    )
    gps_max_depth_m: float = param(0.3, unit="m", low=0.0, high=100.0, doc="GPS fixes only this close to the surface")
    sensor_nan_probability: float = param(0.0, low=0.0, high=1.0, doc="fault injection: a measurement is NaN")


@section
class SurveyEKF(Section):
    """The survey vehicle's EKF (Gao & Chitre eqs. 4-13)."""

    initial_position_std_m: float = param(
        2.0, unit="m", low=0, high=10000.0, open_low=True, doc="GPS fix before diving"
    )
    process_noise_horizontal_m2ps: float = param(
        1.0,
        unit="m²/s",
        low=0.0,
        high=10000.0,
        doc=(
            "Q per second, east and north: the dead-reckoning error the filter models as white; with "
            "survey_bias_consider the speed-scale error, compass bias and told current's error are consider states "
            "(core/dr_bias.py) and Q is what is left (gao_lawnmower 0.05, sousa_asv 0.001); without, Q stands for "
            "them too"
        ),
    )
    process_noise_vertical_m2ps: float = param(0.002, unit="m²/s", low=0.0, high=10000.0, doc="Q per second, depth")
    range_gate_probability: float = param(
        0.99, low=0, high=0.999999, open_low=True, doc="chi-square innovation gate (1 dof)"
    )
    range_gate_short_probability: float = param(
        0.0,
        low=0.0,
        high=0.999999,
        doc=(
            "modem sensor: the gate of a range shorter than predicted, which no longer path explains "
            "(docs/scenarios/consider-fusion.md#one-sided-gate); 0: range_gate_probability, one gate both ways "
            "(sousa_asv and sousa_ping: 0.9999)"
        ),
    )
    reinit_after_rejected_ranges: int = param(
        3, low=0, high=1000, doc="survey filter: restart from the range after this many gated out in a row (0: never)"
    )
    reinit_after_short_ranges: int = param(
        0,
        low=0,
        high=1000,
        doc=(
            "modem sensor: restart already after this many gated out in a row that were all shorter than predicted "
            "(multipath only lengthens a range, so only a drifted filter explains them: eq. R8, "
            "docs/scenarios/consider-fusion.md#short-ranges); 0: they count like any (reinit_after_rejected_ranges)"
        ),
    )
    survey_uses_beacon_current: bool = param(True, doc="add the current a DVL beacon AUV sends (Gao II-A)")
    beacon_error_fusion: str = param(
        "schmidt",
        choices=BEACON_ERROR_FUSIONS,
        doc=(
            "how a modem range's beacon position error enters the survey EKF: 'schmidt', consider states with "
            "their cross-covariance (docs/scenarios/consider-fusion.md, eqs. C1-C8; the ping grows by 20 bits); "
            "'white', its variance added to R each ping (Gao & Chitre below eq. 7, the papers' filter); 'ci', "
            "covariance intersection of each range (Julier & Uhlmann 1997)"
        ),
    )
    survey_bias_consider: bool = param(
        True,
        doc=(
            "carry the survey's own speed-scale error and compass bias (survey_speed_scale_error_std, "
            "compass_bias_std_deg) and the error of the current a beacon AUV tells it "
            "(beacon_current_estimate_error_mps) as consider states of its EKF (core/dr_bias.py, eqs. D1-D4; the "
            "modem sensor only); False: only the white process noise stands for them (the papers' filter)"
        ),
    )
    lockout_recovery: str = param(
        "window",
        choices=LOCKOUT_RECOVERIES,
        doc=(
            "after reinit_after_rejected_ranges rejected ranges: 'window', a least-squares fix from the locked-out "
            "beacon's last recovery_window ranges (eqs. R1-R5; a fix that fails its chi-square test drops its worst "
            "range, R6'; the nearest point when fewer than 3 are left); 'window_consensus', the same fix from the "
            "most probable labelling of the window's ranges as direct or longer paths under the multipath model, "
            "R7, with the prior of the lock-out's two causes, R7' (better after multipath streaks on gao_lawnmower "
            "and after drifts in a current on sousa_asv: docs/scenarios/consider-fusion.md#consensus, #r7-sousa; "
            "the gao and Sousa scenarios' default); "
            "'nearest_point', a restart at the nearest point of the last range's circle (the papers' runs)"
        ),
    )
    range_outlier_model: str = param(
        "mixture",
        choices=RANGE_OUTLIER_MODELS,
        doc=(
            "a modem range that passes the gate: 'mixture', fused with the direct path's posterior probability "
            "given the multipath model outlier_probability / outlier_mean_excess_m (PDA; core/multipath.py, "
            "M1-M3); 'hold', the same with both hypotheses held until the next range re-weighs them (M4-M7; "
            "the gao scenarios' default); "
            "'gate', fused as good (the papers' filter)"
        ),
    )
    range_linearization: str = param(
        "first_order",
        choices=RANGE_LINEARIZATIONS,
        doc=(
            "a modem range's model in the survey filter: 'first_order', the EKF's linearization (the papers); "
            "'second_order', with the range's curvature (the Gaussian second-order filter, "
            "core/navigation.range_curvature, eqs. L1-L3): the prediction's bias and the variance the "
            "linearization leaves, which matter when the estimate's error is not small against the range; "
            "'iterated', the iterated EKF's update (Gauss-Newton steps re-linearizing at its own result, "
            "core/iterated.py, eqs. I1-I3); 'split', where the range bends over the prior, the range fitted "
            "over its posterior (the prior split into Gaussians across the line of sight, each updated at its "
            "own point) and that fit fused by the ordinary update (core/split_range.py, eqs. S1-S6) "
            "(the modem sensor of network='survey_beacons' only)"
        ),
    )
    recovery_window: int = param(
        6, low=3, high=6, doc="ranges of one beacon the lock-out window fix uses, at most (eqs. R1-R5)"
    )
    recovery_prior_std_m: float = param(
        50.0,
        unit="m",
        low=0,
        high=100000.0,
        open_low=True,
        source="assumption [U]",
        doc="floor of the lock-out prior's std (eq. R3): it picks the branch, it must not pull the fix [U]",
    )


@section
class Acoustics(Section):
    """The acoustic ranges. ``acoustic_sensor="modem"``: every beacon pings every survey vehicle each
    cycle (range only); ``"mls"``: Kottege & Zimmer's MLS array (core/mls/, analytic mode): one beacon sends
    per cycle (round robin) and each survey vehicle measures its range and azimuth. ``channel_mode="clock"``:
    every beacon pings every cycle and the channel is free (the papers); ``"decide"``: each ping_interval_s is
    a decision slot, a beacon transmits when its action's third component is > 0, and the packets share one
    half-duplex channel in time (core/channel.py)."""

    acoustic_sensor: str = param(
        "modem",  # a registered sensor (core.measurements): checked by validate
        doc='"modem": range-only pings; "mls": range and azimuth from an MLS array (section mls); or a '
        "registered plug-in sensor",
    )
    ranging_mode: str = param("owtt", choices=RANGING_MODES, doc="one-way (synchronized clocks) or two-way travel time")
    channel_mode: str = param(
        "clock",
        choices=CHANNEL_MODES,
        doc='"clock": every beacon pings every cycle; "decide": the beacons decide (section channel)',
    )
    range_noise_std_m: float = param(
        1.0,
        unit="m",
        low=0,
        high=1000.0,
        open_low=True,
        source="assumption [U]",
        doc=(
            "one detection's timing jitter as range, c sigma_t: a one-way range's std; a two-way range has "
            "1/sqrt(2) of it [U: Micro-Modem OWTT 1-3 m]"
        ),
    )
    turnaround_s: float = param(
        0.015,
        unit="s",
        low=0.0,
        high=10.0,
        source="reference-values.md §3",
        doc="transponder turn-around delay, ref-values section 3",
    )
    max_range_m: float = param(
        1500.0,
        unit="m",
        low=0,
        high=100000.0,
        open_low=True,
        source="assumption [U]",
        doc="no packet arrives beyond this range [U]",
    )
    packet_loss_near: float = param(
        0.05, low=0.0, high=1.0, source="assumption [U]", doc="loss probability at zero range [U, 10-50 %]"
    )
    packet_loss_far: float = param(
        0.5, low=0.0, high=1.0, source="assumption [U]", doc="loss probability at max_range_m [U]"
    )
    outlier_probability: float = param(
        0.03,
        low=0.0,
        high=1.0,
        source="reference-values.md §3; assumption [U]",
        doc="multipath, ref-values section 3 [U 1-10 %]",
    )
    outlier_mean_excess_m: float = param(
        30.0, unit="m", low=0.0, high=10000.0, doc="multipath ranges are too long by Exp(this)"
    )
    water_temperature_c: float = param(28.0, unit="°C", low=-2.0, high=40.0, doc="Singapore waters")
    salinity_psu: float = param(30.0, unit="PSU", low=0.0, high=45.0, doc="for the sound speed (Mackenzie 1981)")
    temperature_uncertainty_c: float = param(
        0.5, unit="°C", low=0.0, high=20.0, doc="true temperature differs per episode"
    )
    clock_offset_std_s: float = param(0.0001, unit="s", low=0.0, high=10.0, doc="OWTT clock offset at start (0.15 m)")
    clock_drift_ppm: float = param(
        0.01, unit="ppm", low=0.0, high=10000.0, source="assumption [U]", doc="OWTT clock drift, per episode +/- [U]"
    )


@section
class Current(Section):
    """The ocean current: a constant part drawn per episode plus a first-order Gauss-Markov part."""

    current_speed_mps: float = param(0.05, unit="m/s", low=0.0, high=10.0, doc="mean speed of the constant part")
    current_speed_spread_mps: float = param(
        0.03, unit="m/s", low=0.0, high=10.0, doc="uniform +/- around current_speed_mps"
    )
    current_direction_deg: float = param(
        90.0, unit="deg", low=-360.0, high=360.0, doc="direction the water flows TO, clockwise from north"
    )
    current_direction_spread_deg: float = param(
        45.0, unit="deg", low=0.0, high=360.0, doc="uniform +/- around current_direction_deg"
    )
    current_gm_std_mps: float = param(
        0.02, unit="m/s", low=0.0, high=10.0, doc="stationary std of the varying part, per axis"
    )
    current_gm_time_constant_s: float = param(
        600.0, unit="s", low=0, high=10000000.0, open_low=True, doc="correlation time of the varying part"
    )


@section
class Reward(Section):
    """The reward's weights and thresholds common to every network."""

    safety_distance_m: float = param(
        10.0, unit="m", low=0.0, high=10000.0, doc='a beacon nearer a survey vehicle (3-D) than this is "too close"'
    )
    geofence_margin_m: float = param(
        300.0, unit="m", low=0.0, high=100000.0, doc="fence = survey area grown by this much"
    )
    safety_penalty: float = param(
        1.0, low=0.0, high=1000000.0, doc='reward weight of the "safety" term (per cycle too close)'
    )
    geofence_penalty: float = param(
        1.0, low=0.0, high=1000000.0, doc='reward weight of the "geofence" term (per cycle outside)'
    )
    contact_penalty: float = param(0.2, low=0.0, high=1000000.0, doc="no range of this beacon fused this cycle")


@section
class Randomization(Section):
    """Domain randomization of the survey network, drawn per episode from the episode's seed."""

    randomize_survey_path: tuple = param((), doc="choices of survey_path; () keeps survey_path")
    randomize_depth_m: tuple = param((), unit="m", doc="choices of depth_m; () keeps depth_m")
    randomize_noise_scale: tuple = param(
        (),
        doc=(
            "(low, high): uniform factor on range noise, compass noise and bias, attitude noise and speed-scale "
            "error; () keeps 1"
        ),
    )

    def check(self) -> None:
        paths = [p for p in SURVEY_PATHS if p != "waypoints"]
        for k in self.randomize_survey_path:
            check(isinstance(k, str) and k in paths, f"randomize_survey_path: {k!r} is not one of {', '.join(paths)}")
        check(len(self.randomize_depth_m) <= 64, "randomize_depth_m: at most 64 depths")
        for d in self.randomize_depth_m:
            check(
                isinstance(d, numbers.Real) and not isinstance(d, bool) and finite(d) and 0 <= float(d) <= 6000,
                f"randomize_depth_m: depths must be numbers in [0, 6000] m, got {d!r}",
            )
        scale = self.randomize_noise_scale
        check(
            scale == ()
            or (
                len(scale) == 2
                and all(
                    isinstance(v, numbers.Real) and not isinstance(v, bool) and finite(v) and 0 <= float(v) <= 100
                    for v in scale
                )
                and scale[0] <= scale[1]
            ),
            f"randomize_noise_scale must be () or (low, high) with 0 <= low <= high <= 100, got {scale!r}",
        )


@section
class Observation(Section):
    """What the beacons observe."""

    observed_waypoints: int = param(2, low=1, high=64, doc="the survey's next planned waypoints in the observation")


def __getattr__(name: str) -> tuple:
    if name == "ACOUSTIC_SENSORS":  # the registry's, so a sensor registered later is valid
        from ..core.measurements import sensor_names

        return tuple(sensor_names())
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
