"""The survey network's beacons' sections: the DVL beacon AUV (its dead reckoning, bottom
lock, surfacing), the ASV (its GPS and command following) and where they start.
``sections.py`` holds the survey's and the shared ones; ``config.py`` assembles them."""

from __future__ import annotations

from .params import Section, param, section

SURFACING_MODES = ("timed", "instant")  # beacon_surfacing
BEACON_COVARIANCES = ("isotropic", "full")  # beacon_covariance
DVL_LOCK_MODELS = ("altitude", "fixed")  # dvl_lock_model


@section
class BeaconAUV(Section):
    """The DVL beacon AUV (``beacon_kinds`` entry ``"beacon_auv"``). Its DVL dead reckoning drifts with
    distance travelled (0.5-2 % of it with a magnetic compass): per episode and beacon a compass error
    b0 + b1 sin(heading + phase) (constant plus one-cycle, Hench & Rosman 2010) and a velocity scale error."""

    beacon_auv_max_speed_mps: float = param(
        1.5, unit="m/s", low=0, high=20.0, open_low=True, source="assumption [U]", doc="STARFISH <= 1.5 m/s [U]"
    )
    beacon_auv_max_turn_rate_dps: float = param(
        12.0, unit="deg/s", low=0, high=360.0, open_low=True, source="assumption [U]", doc="[U]"
    )
    beacon_auv_depth_m: float = param(
        2.0, unit="m", low=0.0, high=6000.0, source="assumption [U]", doc="the beacon AUV's constant depth [U]"
    )
    dvl_velocity_noise_mps: float = param(
        0.026,
        unit="m/s",
        low=0.0,
        high=10.0,
        source="reference-values.md §2",
        doc="HoloOcean DVL default, ref-values section 2",
    )
    dvl_lock_model: str = param(
        "altitude",
        choices=DVL_LOCK_MODELS,
        doc=(
            '"altitude": bottom lock from the altitude water_depth_m - depth against the DVL\'s range (core/'
            'beacon_nav.py); "fixed": lost with dvl_lock_loss_probability per cycle whatever the altitude'
        ),
    )
    dvl_lock_loss_probability: float = param(
        0.02,
        low=0.0,
        high=1.0,
        source="assumption [U]",
        doc="per cycle, well inside the DVL's range (altitude model) or always (fixed) [U]",
    )
    dvl_lock_regain_probability: float = param(
        0.5, low=0.0, high=1.0, source="assumption [U]", doc="per cycle, well inside the DVL's range [U]"
    )
    water_depth_m: float = param(
        20.0,
        unit="m",
        low=0,
        high=11000.0,
        open_low=True,
        source="assumption [U]",
        doc="the water's depth under the beacon AUV, a flat bottom (the Gao trials do not say; coastal [U])",
    )
    dvl_min_altitude_m: float = param(
        0.05, unit="m", low=0.0, high=1000.0, source="reference-values.md §2", doc="DVL A50: 0.05-50 m altitude"
    )
    dvl_max_altitude_m: float = param(
        50.0,
        unit="m",
        low=0,
        high=10000.0,
        open_low=True,
        source="reference-values.md §2",
        doc="DVL A50: bottom track to 50 m altitude (A125 to 125 m, Nortek ~75 m)",
    )
    dvl_lock_fade_fraction: float = param(
        0.2,
        low=0.0,
        high=1.0,
        source="assumption [U]",
        doc="the loss probability rises linearly to 1 over this last fraction of the DVL's range [U]",
    )
    beacon_current_estimate_error_mps: float = param(
        0.05,
        unit="m/s",
        low=0.0,
        high=10.0,
        source="assumption [U]",
        doc="its current estimate (DVL - thrust model) [U]",
    )
    beacon_dvl_heading_bias_std_deg: float = param(
        0.5,
        unit="deg",
        low=0.0,
        high=45.0,
        source="reference-values.md §2; assumption [U]",
        doc=(
            "the beacon AUV's DVL dead reckoning drifts with distance travelled (0.5-2 % of it with a magnetic "
            "compass): per episode and beacon a compass error b0 + b1 sin(heading + phase) (constant plus one-"
            "cycle, Hench & Rosman 2010) and a velocity scale error std of b0; residual bias 1-3 deg per run "
            "before calibration, ref-values section 2 [U]"
        ),
    )
    beacon_dvl_heading_cycle_deg: float = param(
        1.0,
        unit="deg",
        low=0.0,
        high=45.0,
        source="assumption [U]",
        doc=(
            "b1, random phase: heading-dependent compass error; Hench & Rosman 2010: <1 % of track after "
            "calibration [U]"
        ),
    )
    beacon_dvl_scale_error_std: float = param(
        0.01,
        low=0.0,
        high=0.5,
        source="reference-values.md §2",
        doc="DVL velocity scale error (A50 standard firmware ~1 %), ref-values section 2",
    )
    beacon_surface_every_s: float = param(
        0.0,
        unit="s",
        low=0.0,
        high=1000000.0,
        doc="> 0: the beacon AUV takes a GPS fix at the surface this often (0: never)",
    )
    beacon_surface_above_std_m: float = param(
        0.0, unit="m", low=0.0, high=10000.0, doc="> 0: ... and whenever its own position std exceeds this (0: never)"
    )
    beacon_surfacing: str = param(
        "timed",
        choices=SURFACING_MODES,
        doc=(
            '"timed": ascent, a dwell for the fix and descent, away from the survey meanwhile (core/beacon_nav.py); '
            '"instant": a fix the cycle it is due (the lake trial\'s beacon at the surface)'
        ),
    )
    beacon_vertical_speed_mps: float = param(
        0.5,
        unit="m/s",
        low=0,
        high=10.0,
        open_low=True,
        source="assumption [U]",
        doc="ascent and descent rate of a surfacing (~1.5 m/s at 15-20 deg pitch) [U]",
    )
    beacon_surface_dwell_s: float = param(
        30.0,
        unit="s",
        low=0.0,
        high=100000.0,
        source="assumption [U]",
        doc="time at the surface before the GPS fix is taken (acquisition and a settled solution) [U]",
    )
    beacon_ranging_min_depth_m: float = param(
        1.0,
        unit="m",
        low=0.0,
        high=6000.0,
        source="assumption [U]",
        doc="on a surfacing the beacon neither pings nor hears replies above this depth (the wave zone) [U]",
    )
    beacon_covariance: str = param(
        "isotropic",
        choices=BEACON_COVARIANCES,
        doc=(
            'the horizontal covariance the beacon AUV carries and sends: "isotropic", one variance per axis; '
            '"full", its 2x2 (eq. N1: the heading errors push its error across its track), which the survey '
            "filters project per line of sight, and its error model's state, with which they carry their "
            "cross-covariance from ping to ping (eqs. N2, N3). Measured and not the default: over two hours "
            "without surfacing the mean error falls 8 % but the tail is heavier "
            "(docs/scenarios/gao-chitre.md#full-covariance)"
        ),
    )


@section
class ASV(Section):
    """The GPS-positioned surface vehicle (``beacon_kinds`` entry ``"asv"``)."""

    asv_max_speed_mps: float = param(2.0, unit="m/s", low=0, high=20.0, open_low=True, doc="Sousa et al.")
    asv_max_turn_rate_dps: float = param(
        30.0, unit="deg/s", low=0, high=360.0, open_low=True, source="assumption [U]", doc="[U]"
    )
    asv_surge_noise_mps: float = param(
        0.15,
        unit="m/s",
        low=0.0,
        high=5.0,
        source="assumption [U]",
        doc="stationary std of the ASV's ground-speed error along its heading, Gauss-Markov (the boats' value) [U]",
    )
    asv_steering_noise_deg: float = param(
        5.0,
        unit="deg",
        low=0.0,
        high=90.0,
        source="assumption [U]",
        doc="stationary std of the ASV's course-over-ground error, Gauss-Markov (the boats' value) [U]",
    )
    asv_noise_time_constant_s: float = param(
        30.0,
        unit="s",
        low=0.0,
        high=100000.0,
        source="assumption [U]",
        doc="correlation time of the ASV's surge and course errors (0: white per cycle; the boats' value) [U]",
    )
    asv_current_response: float = param(
        0.2,
        low=0.0,
        high=1.0,
        source="assumption [U]",
        doc="fraction of the water current the ASV's ground-speed control does not cancel (the boats' value) [U]",
    )
    gps_error_time_constant_s: float = param(
        300.0,
        unit="s",
        low=0.0,
        high=1000000.0,
        source="assumption [U]: GPS position errors are correlated over minutes (multipath, ionosphere)",
        doc=(
            "a beacon's GPS error (an ASV every cycle, a beacon AUV at its surfacing) is first-order Gauss-Markov "
            "with this time constant and gps_noise_m as its std; 0: white, a fresh error each fix (the papers')"
        ),
    )


@section
class BeaconStart(Section):
    """Where the survey network's beacons start, relative to the survey's start point."""

    beacon_start_distance_m: float = param(
        60.0, unit="m", low=0.0, high=20000.0, doc="from the survey's start point; 0: the FIM-optimal distance"
    )
    beacon_start_bearing_deg: float = param(
        225.0, unit="deg", low=-360.0, high=360.0, doc="bearing of the beacon from the survey start"
    )
    beacon_start_bearing_spread_deg: float = param(
        30.0, unit="deg", low=0.0, high=360.0, doc="randomized per episode, +/-"
    )
