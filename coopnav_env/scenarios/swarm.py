"""A small school under acoustic relative localisation (Kottege & Zimmer's MLS sensor).

Three survey AUVs fly parallel lawnmower tracks 15 m apart; one well-navigated
vehicle (a DVL beacon AUV, the learning agent) sends a maximum-length-sequence
event each cycle and every survey vehicle within the sensor's window measures its
range and azimuth (``core/mls/``, analytic mode; the heading it also measures is
not fused: it says nothing about the receiver's own position). With several
agents (``beacon_kinds=("beacon_auv",) * k``) they send in turn, a round robin
standing in for the paper's radio scheduling. The agent is rewarded, as in every
scenario, for the information the others' filters gain. All vehicles run at one
depth (the sensor is a 2-D array). What the paper does not give is [U].
"""

from .base import ScenarioConfig, register

SWARM_MLS = ScenarioConfig(
    name="swarm_mls",
    beacon_kinds=("beacon_auv",),
    n_survey=3,
    acoustic_sensor="mls",
    ranging_mode="owtt",  # the MLS range assumes radio-synchronised clocks (the paper's radio)
    ping_interval_s=2.0,  # [U] one sending event per cycle
    substep_s=1.0,
    max_cycles=300,
    survey_path="lawnmower",
    survey_area_m=(120.0, 40.0),  # [U]
    lawnmower_spacing_m=40.0,
    survey_spacing_m=15.0,  # the school: parallel tracks 15 m apart [U]
    depth_m=5.0,
    beacon_auv_depth_m=5.0,  # one depth for all: the 2-D array
    survey_thrust_percent=45.0,  # ~1 m/s
    beacon_start_distance_m=20.0,
    mls_snr_db_at_1m=30.0,  # [U] -> heard to ~60 m
    mls_max_range_m=60.0,
    safety_distance_m=3.0,  # small vehicles in formation
    geofence_margin_m=60.0,
    process_noise_horizontal_m2ps=0.2,  # [U] the school is slow (~1 m/s), currents weak
    current_speed_mps=0.05,
)

register("swarm_mls", SWARM_MLS)
