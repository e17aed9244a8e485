"""A beacon's observation read as entities: the same shape for every team.

The flat observation (``coopnav_env.obs_layout``) grows with the team: a policy
trained on one survey vehicle and one beacon cannot read the vector of a team of
three and two. This view re-reads it (through ``obs_layout.decode``, never by
index) as the beacon's own state plus a padded set of entities, each with its kind,
so that one permutation-invariant policy (``agents.entity``) drives any team of up
to ``MAX_SURVEY`` survey vehicles and ``MAX_BEACONS`` beacons:

    from coopnav_env.entity_obs import entity_observation, unflatten_entities
    x = entity_observation(obs, config, agent=j)      # obs (..., D) -> (..., ENTITY_DIM) float32
    e = unflatten_entities(x)                         # e.own, e.survey, e.survey_mask, ...

numpy only, batched over any leading axes; ``agent`` (the beacon's index in its
team, an int or an array broadcast against the leading axes) gives the role input
and the other beacons' kinds (the flat vector lists them in team order, itself
left out).

Positions are divided by the scenario's ``position_scale_m`` = L and ages by ten
ping intervals, as in the flat vector, so the numbers a policy sees are the ones
the flat policies see. Kinds are one-hot over ``KINDS`` = (survey_auv, beacon_auv,
asv, boat): every survey vehicle is a ``survey_auv``; beacons take the scenario's
``beacon_kinds``.

Flat layout (``ENTITY_DIM`` = 117 numbers; ``LAYOUT`` holds the sizes):

======================  ========  ==================================================
own: position            2         (east, north) estimate - geofence centre, / L
own: heading             2         (east, north) unit vector
own: speed, std          2         fraction of its maximum speed; position std / 10 m
own: kind                4         one-hot over KINDS (the role: which vehicle it is)
own: index               3         one-hot of its index in the team (MAX_BEACONS):
                                   the role that tells symmetric agents apart
                                   (sousa_ping's two ASVs)
survey s (x MAX_SURVEY)  17 each   estimate - own (east, north / L; depth / 100 m) (3),
                                   2-sigma ellipse semi-axes / 50 m (2), (cos, sin)
                                   of twice its bearing (2), reply age and range age
                                   / (10 T) (2), its next ENTITY_WAYPOINTS waypoints -
                                   its estimate, / L (4), kind one-hot (4)
survey mask              5         1 for a survey vehicle of the team, 0 for padding
beacon m (x MAX_BEACONS-1) 6 each  last reported (east, north) - own, / L (2), kind (4)
beacon mask              2         1 for another beacon of the team, 0 for padding
======================  ========  ==================================================

Padding slots hold zeros (their mask 0). A scenario's ``observed_waypoints`` K
other than ``ENTITY_WAYPOINTS``: its first two are kept; with K = 1 the one
waypoint is repeated (as the core repeats the last waypoint of a path).

The moving long-baseline network (``network="moving_lbl"``, the matos scenarios)
has its own boat observation (``obs_layout.decode_boat``), which ``decode`` does not
read: ``check_team`` refuses it (``ValueError``), and so does everything here.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from .core.observation import AGE_SCALE_PINGS, DEPTH_SCALE_M, ELLIPSE_SCALE_M, OBS_BOUND, STD_SCALE_M
from .obs_layout import decode, fence_center_m

if TYPE_CHECKING:
    from gymnasium import spaces

    from .scenarios import ScenarioConfig

MAX_SURVEY = 5
MAX_BEACONS = 3
TEAM_KEYS = ("n_survey", "beacon_kinds")  # the team makeup: what changes a flat observation's size
MAX_TEAMS = 16  # teams of one mixed-team run (entity_views.MixedTeamVecEnv, a config's env.teams)
ENTITY_WAYPOINTS = 2
KINDS = ("survey_auv", "beacon_auv", "asv", "boat")

__all__ = [
    "ENTITY_DIM",
    "ENTITY_WAYPOINTS",
    "KINDS",
    "LAYOUT",
    "MAX_BEACONS",
    "MAX_SURVEY",
    "MAX_TEAMS",
    "TEAM_KEYS",
    "EntityLayout",
    "Entities",
    "check_team",
    "entities",
    "entity_observation",
    "entity_space",
    "flatten_entities",
    "row_agents",
    "team_problem",
    "unflatten_entities",
]


@dataclasses.dataclass(frozen=True)
class EntityLayout:
    """The sizes of the entity form (the table in the module docstring)."""

    max_survey: int = MAX_SURVEY
    max_beacons: int = MAX_BEACONS
    own_dim: int = 6 + len(KINDS) + MAX_BEACONS
    survey_dim: int = 9 + 2 * ENTITY_WAYPOINTS + len(KINDS)
    beacon_dim: int = 2 + len(KINDS)

    @property
    def max_peers(self) -> int:
        """Slots for the other beacons: ``max_beacons - 1``."""
        return self.max_beacons - 1

    @property
    def sections(self) -> tuple:
        """(name, shape) of each part of the flat vector, in order."""
        return (
            ("own", (self.own_dim,)),
            ("survey", (self.max_survey, self.survey_dim)),
            ("survey_mask", (self.max_survey,)),
            ("beacons", (self.max_peers, self.beacon_dim)),
            ("beacon_mask", (self.max_peers,)),
        )

    @property
    def flat_dim(self) -> int:
        return int(sum(np.prod(shape) for _, shape in self.sections))

    def to_dict(self) -> dict:
        """Plain data (saved with a policy, checked when it is loaded)."""
        return dataclasses.asdict(self)


LAYOUT = EntityLayout()
ENTITY_DIM = LAYOUT.flat_dim


@dataclasses.dataclass
class Entities:
    """One or more beacons' observations as entities (leading axes kept).

    own (..., own_dim); survey (..., MAX_SURVEY, survey_dim) and survey_mask
    (..., MAX_SURVEY) bool; beacons (..., MAX_BEACONS - 1, beacon_dim) and
    beacon_mask (..., MAX_BEACONS - 1) bool."""

    own: np.ndarray
    survey: np.ndarray
    survey_mask: np.ndarray
    beacons: np.ndarray
    beacon_mask: np.ndarray


def team_problem(config: ScenarioConfig) -> str | None:
    """Why ``config``'s team cannot be read as entities (None: it can)."""
    if config.network == "moving_lbl":
        return (
            f"scenario {config.name!r} (network='moving_lbl') has the boats' own observation "
            "(obs_layout.decode_boat), which the entity view does not read; entity policies drive "
            "network='survey_beacons' scenarios"
        )
    if config.n_survey > MAX_SURVEY:
        return f"n_survey={config.n_survey}: the entity view holds at most MAX_SURVEY={MAX_SURVEY} survey vehicles"
    if config.n_beacons > MAX_BEACONS:
        return (
            f"{config.n_beacons} beacons (beacon_kinds): the entity view holds at most MAX_BEACONS={MAX_BEACONS} "
            "beacons"
        )
    return None


def check_team(config: ScenarioConfig) -> None:
    """Raise ``ValueError`` (``team_problem``'s reason) unless ``config`` fits the entity view."""
    problem = team_problem(config)
    if problem is not None:
        raise ValueError(problem)


def _one_hot(index: ArrayLike, n: int) -> np.ndarray:
    return (np.asarray(index)[..., None] == np.arange(n)).astype(np.float64)


def _agents(agent: ArrayLike, lead: tuple, n_beacons: int) -> np.ndarray:
    a = np.broadcast_to(np.asarray(agent), lead)
    if a.dtype.kind not in "iu" or (a.size and (a.min() < 0 or a.max() >= n_beacons)):
        raise ValueError(f"agent must be beacon indices in [0, {n_beacons - 1}], got {np.unique(a)[:5].tolist()}")
    return a.astype(np.int64)


def entities(obs: ArrayLike, config: ScenarioConfig, agent: ArrayLike = 0) -> Entities:
    """The entity form of flat observations ``obs`` (..., D) of ``config``, for beacon
    ``agent`` (an index or an array over the leading axes). See the module docstring."""
    check_team(config)
    view = decode(obs, config)
    lead = view.own_std_m.shape
    S, N = config.n_survey, config.n_beacons
    L, T = config.position_scale_m, config.ping_interval_s
    a = _agents(agent, lead, N)
    kinds = np.array([KINDS.index(k) for k in config.beacon_kinds])
    own = np.concatenate(
        [
            (view.own_en_m - fence_center_m(config)) / L,
            view.heading_en,
            view.speed_fraction[..., None],
            view.own_std_m[..., None] / STD_SCALE_M,
            _one_hot(kinds[a], len(KINDS)),
            _one_hot(a, MAX_BEACONS),
        ],
        -1,
    )
    K = view.waypoints_en_m.shape[-2]
    pick = np.minimum(np.arange(ENTITY_WAYPOINTS), K - 1)
    wp = (view.waypoints_en_m[..., pick, :] - view.survey_en_m[..., None, :]) / L
    age_scale = AGE_SCALE_PINGS * T
    per_survey = np.concatenate(
        [
            view.survey_rel_m[..., :2] / L,
            view.survey_rel_m[..., 2:3] / DEPTH_SCALE_M,
            view.major_m[..., None] / ELLIPSE_SCALE_M,
            view.minor_m[..., None] / ELLIPSE_SCALE_M,
            np.cos(2 * view.bearing_rad)[..., None],
            np.sin(2 * view.bearing_rad)[..., None],
            view.reply_age_s[..., None] / age_scale,
            view.range_age_s[..., None] / age_scale,
            wp.reshape(lead + (S, 2 * ENTITY_WAYPOINTS)),
            np.broadcast_to(_one_hot(KINDS.index("survey_auv"), len(KINDS)), lead + (S, len(KINDS))),
        ],
        -1,
    )
    survey = np.zeros(lead + (MAX_SURVEY, LAYOUT.survey_dim))
    survey[..., :S, :] = per_survey
    survey_mask = np.zeros(lead + (MAX_SURVEY,), dtype=bool)
    survey_mask[..., :S] = True
    beacons = np.zeros(lead + (LAYOUT.max_peers, LAYOUT.beacon_dim))
    beacon_mask = np.zeros(lead + (LAYOUT.max_peers,), dtype=bool)
    if N > 1:
        # the flat vector lists the other beacons in team order without the beacon itself:
        # slot i of beacon n is team member i + (i >= n)
        slot = np.arange(N - 1)
        peer_index = slot + (slot >= a[..., None])
        beacons[..., : N - 1, :2] = (view.peers_en_m - view.own_en_m[..., None, :]) / L
        beacons[..., : N - 1, 2:] = _one_hot(kinds[peer_index], len(KINDS))
        beacon_mask[..., : N - 1] = True
    clip = np.clip  # the flat vector's bound holds for every derived number too
    return Entities(
        own=clip(own, -OBS_BOUND, OBS_BOUND),
        survey=clip(survey, -OBS_BOUND, OBS_BOUND),
        survey_mask=survey_mask,
        beacons=clip(beacons, -OBS_BOUND, OBS_BOUND),
        beacon_mask=beacon_mask,
    )


def flatten_entities(e: Entities) -> np.ndarray:
    """(..., ENTITY_DIM) float32 of ``e``, in the order of the module docstring's table."""
    lead = e.own.shape[:-1]
    parts = [
        e.own,
        e.survey.reshape(lead + (-1,)),
        e.survey_mask,
        e.beacons.reshape(lead + (-1,)),
        e.beacon_mask,
    ]
    return np.concatenate([np.asarray(p, dtype=np.float32) for p in parts], -1)


def unflatten_entities(x: ArrayLike, layout: EntityLayout = LAYOUT) -> Entities:
    """The inverse of ``flatten_entities``: (..., flat_dim) -> ``Entities`` (masks: value > 0.5)."""
    x = np.asarray(x)
    if x.shape[-1:] != (layout.flat_dim,):
        raise ValueError(f"an entity observation has {layout.flat_dim} numbers, got shape {x.shape}")
    lead, out, i = x.shape[:-1], {}, 0
    for name, shape in layout.sections:
        n = int(np.prod(shape))
        out[name] = x[..., i : i + n].reshape(lead + shape)
        i += n
    return Entities(
        own=out["own"],
        survey=out["survey"],
        survey_mask=out["survey_mask"] > 0.5,
        beacons=out["beacons"],
        beacon_mask=out["beacon_mask"] > 0.5,
    )


def entity_observation(obs: ArrayLike, config: ScenarioConfig, agent: ArrayLike = 0) -> np.ndarray:
    """``flatten_entities(entities(obs, config, agent))``: (..., D) -> (..., ENTITY_DIM) float32."""
    return flatten_entities(entities(obs, config, agent))


def row_agents(rows: int, n_beacons: int) -> np.ndarray:
    """The beacon index of each row of a ``CoopNavVecEnv`` (row ``e * n_beacons + j`` is beacon j)."""
    return np.arange(rows, dtype=np.int64) % int(n_beacons)


def entity_space() -> spaces.Box:
    """The entity observation's space: ``Box(-OBS_BOUND, OBS_BOUND, (ENTITY_DIM,), float32)``."""
    from gymnasium import spaces

    return spaces.Box(-OBS_BOUND, OBS_BOUND, shape=(ENTITY_DIM,), dtype=np.float32)


def describe() -> list[Any]:
    """[(section, shape)] of the flat vector (``LAYOUT.sections``), for docs and tools."""
    return list(LAYOUT.sections)
