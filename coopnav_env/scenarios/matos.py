"""Matos & Cruz, "AUV navigation and guidance in a moving acoustic network"
(FEUP / ISR Porto): two beacon boats define a moving frame in which a REMUS-class
AUV (Isurus) navigates by spherical LBL.

The scenario is the paper's simulation (section VIII): the beacons 100 m apart
move at constant speed perpendicular to the baseline; the vehicle goes back and
forth along a 100 m line parallel to the baseline at 50 m, at 1 m/s; ranges carry
1 m standard deviation of white noise. The vehicle's mission is given in the
moving frame (x from B1 towards B2, y clockwise from x). The agents are the two
boats (``beacon_0`` = B1, ``beacon_1`` = B2). What the paper does not give is
marked [U]: the boats' speed, the cycle period, the vehicle's depth, the mission
length and its sensor noise levels (REMUS-class values from
shared/reference-values.md section 2).
"""

import math

from .base import ScenarioConfig, register

MATOS_MOVING_LBL = ScenarioConfig(
    name="matos_moving_lbl",
    network="moving_lbl",
    beacon_kinds=("boat", "boat"),
    action_mode="frame_velocity",  # (along the baseline, across it): the same for any river direction
    ranging_mode="twtt",  # the vehicle interrogates, the transponders reply (section V)
    ping_interval_s=2.0,  # [U] one positioning cycle; the exchange itself takes ~0.2 s
    substep_s=0.5,
    max_cycles=400,
    survey_path="waypoints",  # in the moving frame: (x, y, depth)
    waypoints_m=((0.0, 50.0, 2.0), (100.0, 50.0, 2.0)),  # sec. VIII: 100 m line, 50 m from the baseline
    path_repeats=6,  # [U] three round trips, ~650 s
    depth_m=2.0,  # [U] a shallow river survey
    survey_speed_mps=1.0,  # sec. VIII: 1 m/s
    survey_max_turn_rate_dps=12.0,  # [U]
    baseline_target_m=100.0,  # sec. VIII: 100 m apart
    boat_transit_speed_mps=-0.5,  # [U] "constant speed", not given; negative: the boats lead, the vehicle follows
    frame_orientation_deg=90.0,  # B1 -> B2 points east; the vehicle is south of the baseline
    # sec. VIII: 1 m white noise on the ranges; a two-way range halves the variance of
    # the per-detection jitter that range_noise_std_m states, so sqrt(2) m per detection
    range_noise_std_m=math.sqrt(2.0),
    outlier_probability=0.0,  # sec. VIII simulates white noise only
    packet_loss_near=0.0,  # idem; --set packet_loss_near=0.05 packet_loss_far=0.5 adds losses
    packet_loss_far=0.0,
    max_range_m=1000.0,
    water_temperature_c=15.0,  # [U] a Portuguese river
    salinity_psu=0.0,  # fresh water
    safety_distance_m=10.0,
    initial_position_std_m=1.0,  # the vehicle starts from an LBL fix
    # The boats follow their commands imperfectly (base.py's boat_* defaults: surge 0.15 m/s,
    # course 5 deg, both Gauss-Markov with tau = 30 s; 0.2 of the current). The filter's Q,
    # tuned to them: the random walks that match those processes are, with sigma_c ~ 0.15 m/s
    # the apparent velocity of the frame at the vehicle (the baseline's local speed across
    # itself), sigma_w = sqrt(2) 0.15 / 100 rad/s the frame's rotation rate and
    # sigma_l' = sqrt(2) 0.5 m/s x 5 deg the baseline's rate of change:
    # q_c = 2 sigma_c^2 / tau = 1.5e-3 m^2/s^3, q_phi = 2 sigma_w^2 tau = 2.7e-4 rad^2/s,
    # q_l = 2 sigma_l'^2 tau = 0.23 m^2/s. These are upper bounds (a random walk outgrows an
    # integrated Gauss-Markov process over horizons shorter than tau, and the frame's
    # apparent velocity is below 0.15 m/s away from the line's ends): with them the filter
    # is conservative (average NEES 1.8 for (x, y), 4.6 for all six). Scaled down by 2/3
    # (c) and 1/2 (phi, l, position) the 100-run average NEES sits at its dof: 2.0 for
    # (x, y), 5.8 for all six (tests/test_matos.py, docs/scenarios/matos-cruz.md#nees).
    frame_q_position_m2ps=0.005,
    frame_q_current_m2ps3=1e-3,
    frame_q_orientation_rad2ps=1.5e-4,
    frame_q_baseline_m2ps=0.12,
)

register("matos_moving_lbl", MATOS_MOVING_LBL)
