"""The layout of one beacon's observation vector, decoded in one place.

``coopnav_env.core.observation`` builds the vector (and holds the layout's
constants); this module is the only code outside the simulator that reads it,
so policies and tools never index the vector by hand:

    view = decode(obs, config)          # obs (D,) or (..., D)
    view.own_en_m, view.survey_en_m, view.cov_m2, ...

Layout (positions divided by ``config.position_scale_m`` = L):

=====================  =====  =====================================================
own position            2      (east, north) estimate - geofence centre, / L
own heading             2      bearing as an (east, north) unit vector
own speed               1      fraction of the beacon's maximum speed
own position std        1      metres / 10
per survey vehicle s:
  estimate              3      (east, north) - own, / L; depth - own depth, / 100 m
  ellipse semi-axes     2      2-sigma major, minor, / 50 m
  ellipse orientation   2      (cos, sin) of twice the major-axis bearing
  ages                  2      of the reply, since its last fused range, / (10 T)
  next waypoints        2K     (east, north) - its estimate, / L (K = observed_waypoints)
per other beacon        2      last reported (east, north) - own, / L
=====================  =====  =====================================================

``encode`` is the inverse (hand-built observations for tests and tools). Values
clipped to [-OBS_BOUND, OBS_BOUND] by the simulator cannot be recovered beyond that bound.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from .core import observation as _layout
from .core.information import ellipse_to_covariance
from .core.observation import (
    AGE_SCALE_PINGS,
    DEPTH_SCALE_M,
    ELLIPSE_N_SIGMA,
    ELLIPSE_SCALE_M,
    OBS_BOUND,
    OWN_DIM,
    PER_SURVEY_FIXED,
    STD_SCALE_M,
)

if TYPE_CHECKING:
    from .scenarios import ScenarioConfig


def obs_dim(config: ScenarioConfig) -> int:
    """Length of one beacon's observation for ``config``."""
    if config.network == "moving_lbl":  # a mission in the world adds the river's fields
        from .core.moving_network import obs_dim_of

        return obs_dim_of(config)
    return _layout.obs_dim(config.n_survey, config.n_beacons, config.observed_waypoints)


def pad_slots(
    obs: np.ndarray, config: ScenarioConfig, survey_slots: int, beacon_slots: int | None = None
) -> np.ndarray:
    """Observations (..., D) of ``config`` laid out for a team of ``survey_slots`` survey
    vehicles and ``beacon_slots`` beacons (None: the team's own): the per-survey blocks of the
    vehicles it has, zeros for the ones it lacks, then the other beacons' entries it has and
    zeros for the ones it lacks, so a value sits at the same index whatever the team's makeup
    (a centralized critic trained over teams of other sizes reads them alike). Slots equal to
    the team's sizes return ``obs`` itself."""
    S, N = config.n_survey, config.n_beacons
    beacon_slots = N if beacon_slots is None else beacon_slots
    if survey_slots == S and beacon_slots == N:
        return obs
    if config.network == "moving_lbl" or survey_slots < S or beacon_slots < N:
        raise ValueError(
            f"slots must be >= the team's {S} survey vehicles and {N} beacons (and the moving network "
            f"has no slots to pad), got {survey_slots} and {beacon_slots}"
        )
    block = PER_SURVEY_FIXED + 2 * config.observed_waypoints
    end = OWN_DIM + S * block
    lead = obs.shape[:-1]
    surveys = np.zeros(lead + ((survey_slots - S) * block,), dtype=obs.dtype)
    peers = np.zeros(lead + (2 * (beacon_slots - N),), dtype=obs.dtype)  # after the team's own peers
    return np.concatenate([obs[..., :end], surveys, obs[..., end:], peers], -1)


def fence_center_m(config: ScenarioConfig) -> np.ndarray:
    e0, n0, e1, n1 = config.geofence_m
    return np.array([(e0 + e1) / 2, (n0 + n1) / 2])


@dataclass
class ObsView:
    """A decoded observation, in metres, seconds and radians (leading batch axes kept).

    own_en_m (..., 2): own estimated (east, north), absolute.
    heading_en (..., 2): own heading as an (east, north) unit vector.
    speed_fraction (...), own_std_m (...).
    survey_rel_m (..., S, 3): survey estimate minus own (east, north, depth).
    survey_en_m (..., S, 2): survey estimate, absolute (east, north).
    depth_below_m (..., S): survey depth minus own depth (positive: deeper).
    major_m, minor_m, bearing_rad (..., S): 2-sigma ellipse of the survey estimate.
    cov_m2 (..., S, 2, 2): the horizontal covariance rebuilt from the ellipse.
    reply_age_s, range_age_s (..., S).
    waypoints_en_m (..., S, K, 2): its next planned waypoints, absolute.
    peers_en_m (..., N-1, 2): other beacons' last reported positions, absolute.
    """

    own_en_m: np.ndarray
    heading_en: np.ndarray
    speed_fraction: np.ndarray
    own_std_m: np.ndarray
    survey_rel_m: np.ndarray
    survey_en_m: np.ndarray
    depth_below_m: np.ndarray
    major_m: np.ndarray
    minor_m: np.ndarray
    bearing_rad: np.ndarray
    cov_m2: np.ndarray
    reply_age_s: np.ndarray
    range_age_s: np.ndarray
    waypoints_en_m: np.ndarray
    peers_en_m: np.ndarray


def decode(obs: ArrayLike, config: ScenarioConfig) -> ObsView:
    """Decode observations (..., D) of ``config`` into an :class:`ObsView`."""
    obs = np.asarray(obs, dtype=float)
    D = obs_dim(config)
    if obs.shape[-1:] != (D,):
        raise ValueError(f"observation of length {obs.shape[-1:]} does not match the scenario's layout ({D})")
    lead = obs.shape[:-1]
    S, K, N = config.n_survey, config.observed_waypoints, config.n_beacons
    L, T = config.position_scale_m, config.ping_interval_s
    own = fence_center_m(config) + L * obs[..., 0:2]
    per = obs[..., OWN_DIM : OWN_DIM + S * (PER_SURVEY_FIXED + 2 * K)].reshape(lead + (S, PER_SURVEY_FIXED + 2 * K))
    rel = np.concatenate([L * per[..., 0:2], DEPTH_SCALE_M * per[..., 2:3]], -1)
    survey_en = own[..., None, :] + rel[..., :2]
    major, minor = ELLIPSE_SCALE_M * per[..., 3], ELLIPSE_SCALE_M * per[..., 4]
    bearing = np.mod(0.5 * np.arctan2(per[..., 6], per[..., 5]), np.pi)
    wp = survey_en[..., None, :] + L * per[..., 9:].reshape(lead + (S, K, 2))
    peers_rel = obs[..., OWN_DIM + S * (PER_SURVEY_FIXED + 2 * K) :].reshape(lead + (N - 1, 2))
    return ObsView(
        own_en_m=own,
        heading_en=obs[..., 2:4].copy(),
        speed_fraction=obs[..., 4].copy(),
        own_std_m=STD_SCALE_M * obs[..., 5],
        survey_rel_m=rel,
        survey_en_m=survey_en,
        depth_below_m=rel[..., 2],
        major_m=major,
        minor_m=minor,
        bearing_rad=bearing,
        cov_m2=ellipse_to_covariance(major, minor, bearing, n_sigma=ELLIPSE_N_SIGMA),
        reply_age_s=AGE_SCALE_PINGS * T * per[..., 7],
        range_age_s=AGE_SCALE_PINGS * T * per[..., 8],
        waypoints_en_m=wp,
        peers_en_m=own[..., None, :] + L * peers_rel,
    )


def encode(
    config: ScenarioConfig,
    own_en_m: ArrayLike,
    survey_rel_m: ArrayLike,
    major_m: ArrayLike = 4.0,
    minor_m: ArrayLike = 4.0,
    bearing_rad: ArrayLike = 0.0,
    heading_en: ArrayLike = (0.0, 1.0),
    speed_fraction: float = 0.0,
    own_std_m: float = 2.0,
    reply_age_s: ArrayLike = 0.0,
    range_age_s: ArrayLike = 0.0,
    waypoints_en_m: ArrayLike | None = None,
    peers_en_m: ArrayLike | None = None,
) -> np.ndarray:
    """Build one beacon's observation (D,) float32 from quantities in metres (the
    inverse of :func:`decode`). survey_rel_m: (S, 3) survey estimate minus own
    (east, north, depth); waypoints default to the survey's own estimate."""
    S, K, N = config.n_survey, config.observed_waypoints, config.n_beacons
    L, T = config.position_scale_m, config.ping_interval_s
    own = np.asarray(own_en_m, dtype=float)
    rel = np.asarray(survey_rel_m, dtype=float).reshape(S, 3)
    b = np.broadcast_to(np.asarray(bearing_rad, float), (S,))
    survey_en = own + rel[:, :2]
    if waypoints_en_m is None:
        waypoints_en_m = np.broadcast_to(survey_en[:, None, :], (S, K, 2))
    wp_rel = (np.asarray(waypoints_en_m, float).reshape(S, K, 2) - survey_en[:, None, :]) / L
    per = np.concatenate(
        [
            rel[:, :2] / L,
            rel[:, 2:3] / DEPTH_SCALE_M,
            np.broadcast_to(np.asarray(major_m, float), (S,))[:, None] / ELLIPSE_SCALE_M,
            np.broadcast_to(np.asarray(minor_m, float), (S,))[:, None] / ELLIPSE_SCALE_M,
            np.cos(2 * b)[:, None],
            np.sin(2 * b)[:, None],
            np.broadcast_to(np.asarray(reply_age_s, float), (S,))[:, None] / (AGE_SCALE_PINGS * T),
            np.broadcast_to(np.asarray(range_age_s, float), (S,))[:, None] / (AGE_SCALE_PINGS * T),
            wp_rel.reshape(S, 2 * K),
        ],
        -1,
    )
    parts = [
        (own - fence_center_m(config)) / L,
        np.asarray(heading_en, float),
        [speed_fraction],
        [own_std_m / STD_SCALE_M],
        per.reshape(-1),
    ]
    if N > 1:
        peers = np.zeros((N - 1, 2)) if peers_en_m is None else np.asarray(peers_en_m, float).reshape(N - 1, 2) - own
        parts.append((peers / L).reshape(-1))
    return np.clip(np.concatenate([np.ravel(p) for p in parts]), -OBS_BOUND, OBS_BOUND).astype(np.float32)


# --- the boats of the moving LBL network (network="moving_lbl") -------------------------
@dataclass
class BoatView:
    """A decoded boat observation (``core.moving_network.OBS_FIELDS``), in metres,
    seconds and radians. Vectors are in the frame of the boats' GPS positions (x
    from B1 to B2, y 90 degrees clockwise from x)."""

    is_b1: np.ndarray  # (...) bool: this boat is B1 (the frame's origin)
    own_velocity_xy_mps: np.ndarray  # (..., 2)
    baseline_m: np.ndarray  # GPS baseline length
    tracked_xy_m: np.ndarray  # (..., 2) the vehicle as tracked
    tracked_velocity_xy_mps: np.ndarray  # (..., 2)
    fix_age_s: np.ndarray
    has_fix: np.ndarray
    x_axis_en: np.ndarray  # (..., 2) unit (east, north) of the frame's x axis: (sin phi, cos phi)
    own_from_tracked_xy_m: np.ndarray | None = None  # (..., 2) own GPS position minus the tracked vehicle
    # a mission in the world (mission_frame="world", ``core.moving_network.RIVER_OBS_FIELDS``); else None
    bank_offset_m: np.ndarray | None = None  # (...) own GPS offset from the centerline, + right of the mission
    river_direction_xy: np.ndarray | None = None  # (..., 2) unit direction of the mission along the river ahead
    river_ahead_from_own_xy_m: np.ndarray | None = None  # (..., 2) that river point minus own (RIVER_LEAD_BASELINES L
    # ahead of the tracked vehicle)

    @property
    def y_axis_en(self) -> np.ndarray:
        """Unit vector of the y axis, 90 degrees clockwise from x: u(phi + 90) = (cos phi, -sin phi)."""
        x = self.x_axis_en
        return np.stack([x[..., 1], -x[..., 0]], -1)


def decode_boat(obs: ArrayLike, config: ScenarioConfig) -> BoatView:
    """Decode boat observations (..., obs_dim(config)) of a moving-network scenario."""
    from .core.moving_network import obs_fields

    if config.network != "moving_lbl":
        raise ValueError(f"decode_boat needs a network='moving_lbl' scenario, not {config.name!r}")
    obs = np.asarray(obs, dtype=float)
    part, i = {}, 0
    for name, n in obs_fields(config):
        part[name] = obs[..., i : i + n]
        i += n
    if obs.shape[-1] != i:
        raise ValueError(f"a boat observation has {i} values, got {obs.shape[-1]}")
    L = config.baseline_target_m
    river = {}
    if "bank_offset" in part:
        river = dict(
            bank_offset_m=part["bank_offset"][..., 0] * 0.5 * config.river_width_m,
            river_direction_xy=part["river_direction_xy"],
            river_ahead_from_own_xy_m=part["river_ahead_from_own_xy"] * L,
        )
    return BoatView(
        is_b1=part["role"][..., 0] > 0,
        own_velocity_xy_mps=part["own_velocity_xy"] * config.boat_max_speed_mps,
        baseline_m=(1.0 + part["baseline_error"][..., 0]) * L,
        tracked_xy_m=part["tracked_xy"] * L,
        tracked_velocity_xy_mps=part["tracked_velocity_xy"] * config.survey_speed_mps,
        fix_age_s=part["fix_age"][..., 0] * AGE_SCALE_PINGS * config.ping_interval_s,
        has_fix=part["has_fix"][..., 0] > 0.5,
        x_axis_en=part["frame_bearing"],
        own_from_tracked_xy_m=part["own_from_tracked_xy"] * L,
        **river,
    )
