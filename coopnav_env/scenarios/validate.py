"""The checks between sections of a scenario config (each section checks its own
fields in ``sections.py``): what a network, a sensor or a channel mode needs of the
rest, and what scales with the values (the number of waypoints a path needs)."""

from __future__ import annotations

import math
from typing import Any

from .params import check
from .sections import MAX_WAYPOINTS

SLOWEST_SOUND_SPEED_MPS = (
    1400.0  # below any sea water's (Mackenzie 1981 at -2 degC, 25 ppt: ~1430 m/s): bounds a packet's flight time
)


def waypoint_count(c: Any, path: str) -> int:
    """How many waypoints ``guidance.build_path`` makes for ``path`` (before repeats)."""
    if path == "lawnmower":
        return 2 * (math.floor(c.survey_area_m[1] / c.lawnmower_spacing_m + 1e-9) + 1)
    if path in ("circle", "spiral"):
        return max(math.ceil(c.circle_laps * 24), 2) + 1
    if path == "waypoints":
        return len(c.waypoints_m)
    return 2


def validate(c: Any) -> None:
    """Raise a one-line ``ValueError`` naming the parameters of the first check ``c`` fails."""
    from ..core.measurements import check_sensor

    check_sensor(c)  # the registered sensor: its name, its networks, its own checks
    if c.network == "moving_lbl":
        _check_moving_network(c)
    else:
        check("boat" not in c.beacon_kinds, "beacon_kinds: the kind 'boat' belongs to network='moving_lbl'")
        check(c.action_mode != "frame_velocity", "action_mode='frame_velocity' belongs to network='moving_lbl'")
    if c.channel_mode == "decide":
        _check_decision_slot(c)
    check(
        c.range_linearization == "first_order" or (c.network == "survey_beacons" and c.acoustic_sensor == "modem"),
        f"range_linearization={c.range_linearization!r} is the modem filter's (network='survey_beacons', "
        "acoustic_sensor='modem'); "
        f"network={c.network!r} with acoustic_sensor={c.acoustic_sensor!r} fuses its ranges to first order: "
        "use range_linearization='first_order'",
    )
    # what scales with the values: the number of waypoints a path needs
    randomized = c.randomize_survey_path if c.randomization is not None else ()
    for path in set(randomized or (c.survey_path,)):
        n = waypoint_count(c, path) * (c.path_repeats if path != "stationary" else 1)
        check(
            n <= MAX_WAYPOINTS,
            f"survey_path={path!r} with these parameters needs {n} waypoints (at most "
            f"{MAX_WAYPOINTS}): raise lawnmower_spacing_m or lower circle_laps/path_repeats",
        )


def _check_moving_network(c: Any) -> None:
    """network='moving_lbl': two boats, one vehicle on a waypoint mission, two-way ranges."""
    check(
        c.beacon_kinds == ("boat", "boat"),
        f"network='moving_lbl' needs beacon_kinds=('boat', 'boat') (B1, B2), got {c.beacon_kinds!r}",
    )
    check(c.n_survey == 1, f"network='moving_lbl' simulates one vehicle, got n_survey={c.n_survey}")
    check(
        c.survey_path == "waypoints",
        f"network='moving_lbl' needs survey_path='waypoints' ({c.mission_frame} coordinates)",
    )
    off = next((w for w in c.waypoints_m if w[2] != c.depth_m), None)
    if off is not None:
        check(
            False,
            f"waypoints_m: network='moving_lbl' holds the vehicle at one depth, depth_m ({c.depth_m:g} m), which the "
            f"boats' tracking assumes; waypoint {off!r} is at another (give depth_m={off[2]:g} with them; depth_m "
            "alone moves every waypoint to it)",
        )
    if c.mission_frame == "frame":
        check(
            all(w[1] > 0 for w in c.waypoints_m),
            "waypoints_m: network='moving_lbl' needs y > 0 in every waypoint (the vehicle must not cross the baseline)",
        )
    check(
        abs(c.boat_transit_speed_mps) <= c.boat_max_speed_mps,
        f"boat_transit_speed_mps ({c.boat_transit_speed_mps}) exceeds boat_max_speed_mps ({c.boat_max_speed_mps})",
    )
    check(c.ranging_mode == "twtt", "network='moving_lbl' ranges by two-way travel time: ranging_mode='twtt'")


def _check_decision_slot(c: Any) -> None:
    """channel_mode='decide': the survey network with modem OWTT, and a slot long enough
    for the pings, their flight, the turn-around, the replies and theirs."""
    check(
        c.network == "survey_beacons" and c.acoustic_sensor == "modem" and c.ranging_mode == "owtt",
        "channel_mode='decide' needs network='survey_beacons', acoustic_sensor='modem' and ranging_mode='owtt' "
        "(a beacon's ping is the one-way range)",
    )
    # the noise model's band (the channel computes the noise on either link)
    from ..core.link import band_problem

    problem = band_problem(c.band_center_khz, c.band_width_hz)
    check(problem is None, f"band_center_khz, band_width_hz: {problem}")
    from ..core.link_framing import slot_timing

    t = slot_timing(c, SLOWEST_SOUND_SPEED_MPS)
    check(
        t.need_s <= c.ping_interval_s,
        f"channel_mode='decide': a slot of ping_interval_s={c.ping_interval_s:g} s cannot hold the exchange; "
        f"the minimum is {t.need_s:.3f} s (link_model={c.link_model!r}: ping {t.ping_s:g} s, last ping offset "
        f"{t.last_offset_s:g} s ({c.ping_offsets}), max_range_m / {SLOWEST_SOUND_SPEED_MPS:g} m/s, turnaround_s, "
        f"reply {t.reply_s:g} s and its flight); raise ping_interval_s or modem_bit_rate_bps, or lower max_range_m, "
        f"turnaround_s, the beacons (beacon_kinds) or the packets' bits (a ping of {c.ping_bits}: "
        "ping_packet_bits, with beacon_error_fusion's and beacon_covariance's fields; reply_packet_bits)",
    )
