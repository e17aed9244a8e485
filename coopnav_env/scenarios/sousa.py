"""Sousa, Ferreira & Cruz, "Guidance of an Autonomous Surface Vehicle for Underwater
Navigation Aid" (INESC TEC / FEUP): one ASV guides itself to help an ROV.

The survey vehicle (an ROV in the paper) estimates its position by dead reckoning
from its speed, attitude and depth sensors and fuses ranges to the ASV in an EKF
(paper sec. III-A, eq. 1): the core's survey vehicle does exactly that. The ASV is
GPS-positioned (sec. II-A: "small uncertainty ... same order of magnitude as GPS")
with a maximum speed of 2 m/s (sec. IV-A); its reaching set between two pings is
the disc of radius max speed x ping interval (sec. III-B). The ROV follows one of
the four paths of Fig. 8, ``survey_path = stationary | lawnmower | circle |
spiral`` (the spiral descends, Fig. 9b), at ``depth_m`` (the paper: 1, 5, 20, 50 m,
Tables I-II). The ASV starts at the horizontal distance that maximizes the best
det of the two-range information matrix in its reaching set for that depth and
speed (Fig. 11, "the ASV in the optimal starting position"):
``beacon_start_distance_m = 0`` makes the simulator compute it
(``core.information.optimal_start_distance_m``).

What the paper does not give is marked [U]: the ping interval, the ROV's speed,
the sizes of the Fig. 8 paths and the mission length. The paper's illustration of
approach B (Fig. 6) moves the ROV 20 m between two ranges; a 20 s cycle at about
1 m/s does that.
"""

from .base import ScenarioConfig, register

SOUSA_ASV = ScenarioConfig(
    name="sousa_asv",
    beacon_kinds=("asv",),
    asv_max_speed_mps=2.0,  # sec. IV-A: "a maximum velocity of 2 m/s"
    ping_interval_s=20.0,  # [U] with ~1 m/s ROV this is Fig. 6's 20 m between ranges
    beacon_start_distance_m=0.0,  # 0: the FIM-optimal start distance (Fig. 11), computed
    survey_path="stationary",  # Fig. 8: stationary | lawnmower | circle | spiral
    depth_m=20.0,  # Tables I-II use 1, 5, 20 and 50 m; Figs. 4-6 use 20 m
    spiral_end_depth_m=0.0,  # <= depth_m: the spiral descends 20 m over its laps [U]
    survey_origin_m=(0.0, 0.0),  # sec. IV-A: the ROV starts near the horizontal origin
    survey_area_m=(100.0, 100.0),  # [U] Fig. 8's extents are not given
    lawnmower_spacing_m=20.0,  # [U]
    path_repeats=2,  # [U] long enough that every path lasts the whole mission
    circle_radius_m=30.0,  # [U]
    circle_laps=7.0,  # [U] ~1300 m, longer than the mission
    survey_thrust_percent=45.0,  # ~1.0 m/s with the thrust model [U, ROV speed not given]
    mission_duration_s=1200.0,  # [U] 20 min: every path runs the same time
    max_cycles=60,
)

register("sousa_asv", SOUSA_ASV)
