"""The moving LBL network's sections (Matos & Cruz): the boats, the moving frame's
filter and reward, and the river of a world mission. Present only with
``network="moving_lbl"`` (the river also needs ``mission_frame="world"``); see
``sections.py`` for the survey network's sections and ``config.py`` for how sections
are assembled."""

from __future__ import annotations

import itertools

from .params import Section, check, check_coordinates, param, section

MISSION_FRAMES = ("frame", "world")  # where a moving-network mission's waypoints live (mission_frame)
MAX_RIVER_POINTS = 10_000  # vertices of river_centerline_m


@section
class Boat(Section):
    """The beacon boats of the moving LBL network (``beacon_kinds=("boat", "boat")``)."""

    boat_max_speed_mps: float = param(
        1.5,
        unit="m/s",
        low=0,
        high=20.0,
        open_low=True,
        source="assumption [U]",
        doc="small outboard boat at survey pace [U]",
    )
    boat_max_turn_rate_dps: float = param(
        20.0, unit="deg/s", low=0, high=360.0, open_low=True, source="assumption [U]", doc="[U]"
    )
    boat_transit_speed_mps: float = param(
        0.5,
        unit="m/s",
        low=-20.0,
        high=20.0,
        source="assumption [U]",
        doc="boats' speed along the frame's y axis (signed) [U: \"constant speed\"]",
    )
    boat_surge_noise_mps: float = param(
        0.15,
        unit="m/s",
        low=0.0,
        high=5.0,
        source="assumption [U]",
        doc=("m/s, stationary std of each boat's ground-speed fluctuation along its heading, Gauss-Markov [U 0.1-0.2]"),
    )
    boat_steering_noise_deg: float = param(
        5.0,
        unit="deg",
        low=0.0,
        high=90.0,
        source="assumption [U]",
        doc="deg, stationary std of each boat's course-over-ground error, Gauss-Markov [U]",
    )
    boat_noise_time_constant_s: float = param(
        30.0,
        unit="s",
        low=0.0,
        high=100000.0,
        source="assumption [U]",
        doc="s, correlation time of the surge and course errors (0: white per cycle) [U]",
    )
    boat_velocity_noise_mps: float = param(
        0.05,
        unit="m/s",
        low=0.0,
        high=5.0,
        source="assumption [U]",
        doc=(
            "std per axis of each boat's GPS (Doppler) velocity error, held over a cycle: the noise of the frame "
            "motion the boats telemeter with frame_motion_telemetry [U: 0.05 m/s, a receiver's velocity accuracy]"
        ),
    )
    boat_current_response: float = param(
        0.2,
        low=0.0,
        high=1.0,
        source="assumption [U]",
        doc="fraction of the water current the boats' ground-speed control does not cancel [U]",
    )


@section
class MovingNetwork(Section):
    """The moving LBL network (``network="moving_lbl"``; Matos & Cruz). The survey waypoints are in
    the boats' frame (``mission_frame="frame"``): x from B1 towards B2, y 90 deg clockwise from x (the
    vehicle stays at y > 0); depth as usual. With ``mission_frame="world"`` they are (east, north, depth),
    re-expressed in the frame every cycle through the boats' GPS: a river survey (section ``river``)."""

    mission_frame: str = param(
        "frame",
        choices=MISSION_FRAMES,
        doc=(
            "where the vehicle's mission lives: \"frame\", waypoints_m in the boats' frame (x, y, depth), the "
            'paper\'s; "world", waypoints_m in (east, north, depth), re-expressed in the frame every cycle '
            "through the boats' GPS (they telemeter B1's position and the bearing to B2): a river survey"
        ),
    )
    frame_orientation_deg: float = param(
        90.0, unit="deg", low=-360.0, high=360.0, doc="initial bearing of the frame's x axis (B1 -> B2)"
    )
    frame_orientation_spread_deg: float = param(0.0, unit="deg", low=0.0, high=360.0, doc="randomized per episode, +/-")
    baseline_target_m: float = param(
        100.0, unit="m", low=0, high=10000.0, open_low=True, doc="the boats' intended separation (paper: 100 m)"
    )
    survey_speed_mps: float = param(
        1.0,
        unit="m/s",
        low=0,
        high=20.0,
        open_low=True,
        doc="water speed held by the vehicle's speed controller (paper: 1 m/s)",
    )
    speed_encoder_noise_mps: float = param(
        0.02,
        unit="m/s",
        low=0.0,
        high=5.0,
        source="assumption [U]",
        doc="propeller-encoder water-speed noise, per sub-step [U]",
    )
    initial_frame_orientation_std_deg: float = param(
        5.0, unit="deg", low=0, high=180.0, open_low=True, source="assumption [U]", doc="the filter's prior on phi [U]"
    )
    initial_frame_orientation_error_deg: float = param(
        0.0, unit="deg", low=-180.0, high=180.0, doc="a fixed error added to the prior mean (tests)"
    )
    initial_current_std_mps: float = param(
        0.5,
        unit="m/s",
        low=0,
        high=10.0,
        open_low=True,
        doc="prior on the frame-relative current (boats' speed unknown)",
    )
    initial_baseline_std_m: float = param(5.0, unit="m", low=0, high=1000.0, open_low=True, doc="prior on l")
    frame_q_position_m2ps: float = param(
        0.01,
        unit="m²/s",
        low=0.0,
        high=10000.0,
        source="assumption [U]",
        doc="Q of the moving-frame EKF, per second: x and y [U, tuned]",
    )
    frame_q_orientation_rad2ps: float = param(1e-06, unit="rad²/s", low=0.0, high=10.0, doc="phi")
    frame_q_current_m2ps3: float = param(
        0.0001, unit="m²/s³", low=0.0, high=100.0, doc="c_x, c_y (boat speed changes, current variation)"
    )
    frame_q_baseline_m2ps: float = param(
        0.02,
        unit="m²/s",
        low=0.0,
        high=10000.0,
        doc="l: a random walk that follows a boat-speed mismatch (tests/test_matos.py)",
    )
    frame_bearing_fusion: bool = param(
        False,
        doc=(
            "the moving-frame EKF also fuses, every cycle, the frame's bearing phi that the boats telemeter with the "
            "exchange (the bearing of B2's GPS position from B1's), with variance 2 gps_noise_m^2 / l^2 "
            "(core/moving_network/filter.py, eq. B1); False: the paper's filter, which infers phi from the ranges "
            "and the compass alone (section VII)"
        ),
    )
    frame_motion_telemetry: bool = param(
        False,
        doc=(
            "the boats also telemeter the frame's motion over each cycle (B1's displacement, the rotation, the "
            "baseline's change, from their GPS velocities) and the moving-frame EKF carries its estimate with it, so "
            "c is the water's current alone (core/moving_network/frame_motion.py, eqs. M1-M3); False: the paper's "
            "filter, in which c and Q absorb the boats' motion (section VII)"
        ),
    )
    frame_restart_window_cycles: int = param(
        8,
        low=1,
        high=64,
        source="assumption [U]",
        doc=(
            "the recovery's window: the last this many cycles' spherical fixes, each with its geometry's "
            "covariance, from which a locked-out filter restarts (core/moving_network/recovery.py) [U]"
        ),
    )
    frame_restart_min_fixes: int = param(
        4,
        low=1,
        high=64,
        source="assumption [U]",
        doc=(
            "the fewest mutually consistent fixes of the window (chi-square: 2 dof on x, y, 1 dof on l) the "
            "recovery restarts from "
            "or checks the filter against [U]"
        ),
    )
    frame_restart_velocity_std_mps: float = param(
        0.3,
        unit="m/s",
        low=0,
        high=10.0,
        open_low=True,
        source="assumption [U]",
        doc=(
            "the recovery's prior std on a locked-out filter's frame-relative velocity error; a line through the "
            "window's fixes proposing ten times it is no hypothesis (core/moving_network/recovery.py, eqs. F4-F5) "
            "[U: 0.3, the boats' speed fluctuation and a river frame's turn, for the paper's filter]"
        ),
    )
    baseline_tolerance_m: float = param(
        10.0, unit="m", low=0.0, high=10000.0, doc="reward: |l - target| beyond this costs baseline_penalty"
    )
    baseline_penalty: float = param(1.0, low=0.0, high=1000000.0, doc='reward weight of the "baseline" term')
    frame_rotation_tolerance_deg: float = param(
        10.0,
        unit="deg",
        low=0.0,
        high=360.0,
        doc="reward: the frame turned further than this from its start costs rotation_penalty",
    )
    rotation_penalty: float = param(
        1.0, low=0.0, high=1000000.0, doc='reward weight of the "rotation" term (the filter models phi as constant)'
    )
    min_baseline_distance_m: float = param(
        15.0,
        unit="m",
        low=0.0,
        high=10000.0,
        doc="reward: the vehicle closer than this to the baseline costs approach_penalty",
    )
    approach_penalty: float = param(
        1.0, low=0.0, high=1000000.0, doc='reward weight of the "approach" term (the fix degenerates on the baseline)'
    )

    def check(self) -> None:
        """The recovery needs no more consistent fixes than its window holds."""
        check(
            self.frame_restart_min_fixes <= self.frame_restart_window_cycles,
            f"scenario parameter frame_restart_min_fixes ({self.frame_restart_min_fixes}) must not exceed "
            f"frame_restart_window_cycles ({self.frame_restart_window_cycles})",
        )


@section
class River(Section):
    """The river of a world mission (``network="moving_lbl"``, ``mission_frame="world"``)."""

    river_centerline_m: tuple = param(
        (),
        unit="m",
        doc=(
            'mission_frame="world": the river\'s centerline ((east, north), ...), listed downstream; its current '
            "flows along it"
        ),
    )
    river_width_m: float = param(
        150.0,
        unit="m",
        low=1.0,
        high=10000.0,
        source="assumption [U]",
        doc=(
            'mission_frame="world": bank to bank; a boat farther than half of it from the centerline is on the bank [U]'
        ),
    )
    bank_penalty: float = param(
        1.0, low=0.0, high=1000000.0, doc='reward weight of the "bank" term (per boat and cycle outside the river)'
    )

    def check(self) -> None:
        """The centerline: a polyline of at least two distinct consecutive (east, north) points."""
        pts = self.river_centerline_m
        check(
            2 <= len(pts) <= MAX_RIVER_POINTS,
            f"scenario parameter river_centerline_m must hold 2 to {MAX_RIVER_POINTS} (east, north) points for "
            f"mission_frame='world', got {len(pts)}",
        )
        for p in pts:
            check(isinstance(p, tuple), f"river_centerline_m entries must be (east, north), got {p!r}")
            check_coordinates("river_centerline_m", p, 2)
        check(
            all(a != b for a, b in itertools.pairwise(pts)),
            "scenario parameter river_centerline_m must not repeat a point twice in a row",
        )
