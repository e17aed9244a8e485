"""The policy interface shared by the baselines and learned policies.

A policy maps ONE beacon's observation vector to an action in [-1, 1]^2 and may
keep memory between calls (``reset`` clears it). It reads nothing but that vector
(decoded by :mod:`coopnav_env.obs_layout`) and the scenario config (ping interval,
maximum speed, depths, geofence, acoustic range, noise levels): never the
simulator's true state. Planners work in waypoints; :func:`waypoint_to_action`
turns "be at this point at the next ping" into the action.

    policy = make_policy("fim_a", env, seed=0)          # env, Simulator, config or name
    policy.reset()
    action = policy.act(obs["beacon_0"])
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from coopnav_env.core import measurements
from coopnav_env.obs_layout import ObsView, decode, obs_dim
from coopnav_env.scenarios import ScenarioConfig, resolve_config
from coopnav_env.views import check_observation

FENCE_MARGIN_M = 2.0  # plan this far inside the geofence
SAFETY_MARGIN_M = 2.0  # and this far beyond the safety distance
PENALTY_PER_M = 10.0  # planners' soft-constraint weight (metrics are O(1))
RANGE_MODELS = ("constant", "filter")  # the planners' range variance: see BeaconContext.range_variance_m2


@dataclass(frozen=True)
class BeaconContext:
    """What one beacon knows from the scenario config."""

    config: ScenarioConfig
    agent_index: int
    max_speed_mps: float
    ping_interval_s: float
    depth_m: float
    range_model: str = "constant"  # RANGE_MODELS: how the planners weigh a range (range_variance_m2)

    @classmethod
    def from_config(cls, config: ScenarioConfig, agent_index: int = 0) -> BeaconContext:
        if not 0 <= agent_index < config.n_beacons:
            raise ValueError(f"agent index {agent_index} out of range for {config.n_beacons} beacon(s)")
        kind = config.beacon_kinds[agent_index]
        return cls(
            config=config,
            agent_index=agent_index,
            max_speed_mps=config.max_speed_mps(kind),
            ping_interval_s=config.ping_interval_s,
            depth_m=config.beacon_auv_depth_m if kind == "beacon_auv" else 0.0,
        )

    @property
    def reach_m(self) -> float:
        """Radius of the reaching set between two pings (Sousa et al. III-B)."""
        return self.max_speed_mps * self.ping_interval_s

    def violation_m(self, cand: np.ndarray, survey_en: np.ndarray, depth_below: ArrayLike) -> np.ndarray:
        """Soft-constraint violation (metres, >= 0) of candidate positions cand (..., M, 2)
        against the geofence, the safety distance (3-D, to every survey position
        survey_en (S, 2) at depth_below (S,)) and the acoustic range."""
        c = self.config
        e0, n0, e1, n1 = c.geofence_m
        m = FENCE_MARGIN_M
        x, y = cand[..., 0], cand[..., 1]
        v = (
            np.maximum(e0 + m - x, 0)
            + np.maximum(x - (e1 - m), 0)
            + np.maximum(n0 + m - y, 0)
            + np.maximum(y - (n1 - m), 0)
        )
        d3 = slant_distance(cand, survey_en, depth_below)  # (..., M, S)
        v = v + np.maximum(c.safety_distance_m + SAFETY_MARGIN_M - d3, 0).sum(-1)
        v = v + np.maximum(d3 - self.acoustic_range_m, 0).sum(-1)
        return v

    @property
    def acoustic_range_m(self) -> float:
        """The farthest a ping is received with the scenario's sensor (``measurements.reach_m``:
        the modem's ``max_range_m``, the MLS array's ``mls_max_range_m``)."""
        return measurements.reach_m(self.config)

    def delivery_probability(self, distance_m: ArrayLike) -> np.ndarray:
        """Probability that a ping over ``distance_m`` arrives, as the scenario's sensor
        receives it (``measurements.arrival_probability``: the modem's loss model, the MLS
        array's all-or-nothing window)."""
        return measurements.arrival_probability(self.config, distance_m)

    def range_variance_m2(self, distance_m: ArrayLike, beacon_var_m2: ArrayLike) -> np.ndarray:
        """The variance R (m^2) the planners give a range over ``distance_m`` from this
        beacon with own position variance ``beacon_var_m2`` per axis.

        ``range_model="filter"``: the survey filter's own R(d)
        (``measurements.range_variance_m2``: for the modem the ranging noise, that
        variance, and the sound speed's scale error (d std(c)/c)^2, which grows with the
        distance), at the depth halfway between this beacon and the survey vehicles.
        ``"constant"`` (the default, the papers' and benchmark v7's): the same R at every
        distance, the filter's at d = 0 (the ranging noise and the beacon's variance).
        See docs/baselines/horizon.md#range-variance for what the choice changes."""
        mid_depth_m = 0.5 * (self.depth_m + self.config.depth_m)
        d = np.asarray(distance_m, float)
        if self.range_model == "constant":
            d = np.zeros_like(d)
        return measurements.range_variance_m2(self.config, d, beacon_var_m2, mid_depth_m)

    def with_range_model(self, range_model: str) -> BeaconContext:
        """This context with the planners' ``range_model`` (one of ``RANGE_MODELS``)."""
        if range_model not in RANGE_MODELS:
            raise ValueError(f"range_model must be one of {RANGE_MODELS}, got {range_model!r}")
        return replace(self, range_model=range_model)


def slant_distance(cand: np.ndarray, survey_en: np.ndarray, depth_below: ArrayLike) -> np.ndarray:
    """3-D distances (..., M, S) from beacon candidates (..., M, 2) at the beacon's depth
    to survey positions (S, 2) that lie depth_below (S,) deeper."""
    rel = cand[..., :, None, :] - survey_en
    return np.sqrt((rel**2).sum(-1) + np.asarray(depth_below) ** 2)


def waypoint_to_action(ctx: BeaconContext, own_en: ArrayLike, waypoint_en: ArrayLike) -> np.ndarray:
    """The action that heads for ``waypoint_en`` so as to reach it at the next ping:
    velocity = (waypoint - own) / ping interval, as a fraction of the maximum speed
    (norm clipped to 1); converted for ``action_mode="heading_speed"``."""
    v = (np.asarray(waypoint_en, float) - np.asarray(own_en, float)) / (ctx.ping_interval_s * ctx.max_speed_mps)
    norm = float(np.hypot(v[0], v[1]))
    if norm > 1.0:
        v = v / norm
        norm = 1.0
    if ctx.config.action_mode == "heading_speed":
        bearing = float(np.arctan2(v[0], v[1])) if norm > 1e-12 else 0.0  # clockwise from north
        return np.array([bearing / np.pi, 2.0 * norm - 1.0], dtype=np.float32)
    return np.clip(v, -1.0, 1.0).astype(np.float32)


def advance_along_waypoints(
    start_en: ArrayLike, waypoints_en: ArrayLike, distance_m: ArrayLike, min_leg_m: float = 1e-3
) -> tuple[np.ndarray, np.ndarray]:
    """Where a vehicle that follows its planned waypoints is after ``distance_m``.

    start_en (S, 2): where it is; waypoints_en (S, K, 2): its next planned
    waypoints, in order; distance_m (S,): how far it travels. The path is the
    polyline start -> W_1 -> ... -> W_K; with leg lengths l_i = |W_i - W_{i-1}|
    (W_0 = start) and c_j = l_1 + ... + l_j, a distance s with c_{j-1} <= s < c_j
    ends on leg j at

        p(s) = W_{j-1} + (s - c_{j-1}) (W_j - W_{j-1}) / l_j                      (B1)

    i.e. the vehicle turns at every waypoint: one at speed v that reaches W_1 after
    d metres goes v t - d along the next leg. Beyond W_K (s > c_K) it keeps the
    direction of the last leg, p = W_K + (s - c_K) u_K (B2), unless the plan ends
    there: the simulator repeats the final waypoint of a path (and a vehicle that
    holds station lists its station twice), so a last leg of zero length means
    "stops at W_K" (B3). Legs shorter than ``min_leg_m`` are skipped.

    Returns (positions (S, 2), known (S,) bool): ``known`` is False where no
    waypoint differs from the start (none observed, or the observation's default
    of the estimate itself); there the position is ``start_en``.
    """
    start = np.asarray(start_en, float)
    wp = np.asarray(waypoints_en, float)
    s_left = np.maximum(np.asarray(distance_m, float), 0.0).copy()
    S, K = wp.shape[0], wp.shape[1]
    pos = start.copy()
    known = np.zeros(S, dtype=bool)
    for s in range(S):
        prev, last_dir = start[s], None
        for k in range(K):
            leg = wp[s, k] - prev
            length = float(np.hypot(leg[0], leg[1]))
            if length < min_leg_m:
                continue
            known[s] = True
            last_dir = leg / length
            if s_left[s] <= length:  # (B1): ends on this leg
                pos[s] = prev + s_left[s] * last_dir
                s_left[s] = 0.0
                break
            s_left[s] -= length
            prev = wp[s, k]
        else:
            if last_dir is None:
                continue
            ends_here = K >= 2 and np.hypot(*(wp[s, -1] - wp[s, -2])) < min_leg_m
            pos[s] = prev if ends_here else prev + s_left[s] * last_dir  # (B3) / (B2)
    return pos, known


class SurveyTracker:
    """A model of each survey vehicle's motion from the estimates it sends.

    Keeps the latest ``window`` distinct replies (time of reply = now - reply age).
    Three predictors extrapolate the last reply p_n (sent at t_n) to t = now + ahead:

    * ``"chord"``: the velocity fitted by least squares to the kept replies,
      p(t) = p_n + v_LS (t - t_n) (T1). The fit over a few replies smooths the jumps
      that range updates put into the estimates, but on a curve its direction is
      the chord of the last few replies, which lags the heading: on a circle
      turning by an angle a per ping, the chord of three replies lags the heading
      at the last reply by a.
    * ``"heading"``: Sousa et al. IV-B, "the ROV keeps moving in the same direction
      until the next range": the direction u_n = (p_n - p_{n-1}) / |p_n - p_{n-1}|
      of the last two replies, p(t) = p_n + |v| u_n (t - t_n) (T2), |v| the path
      speed below. Its lag on a circle is a / 2.
    * :meth:`predict_along_path`: along the vehicle's planned waypoints (Gao &
      Chitre II-C plan with "the survey AUV's desired path"), eqs. (B1)-(B3) of
      :func:`advance_along_waypoints`, at the path speed.

    The path speed is the length of the polyline of the kept replies over their
    time span, |v| = sum_i |p_i - p_{i-1}| / (t_n - t_1) (T3): at a turn it is the
    speed along the path, where |v_LS| is only the chord's. With one reply every
    velocity is zero.
    """

    PREDICTORS = ("chord", "heading")

    def __init__(self, window: int = 3, max_speed_mps: float = 5.0) -> None:
        if window < 2:
            raise ValueError("window must be >= 2")
        self.window = int(window)
        self.max_speed_mps = max_speed_mps
        self.reset()

    def reset(self) -> None:
        self._t: np.ndarray | None = None  # (W, S) reply times, oldest first, NaN where empty
        self._p: Any = None  # (W, S, 3) replies (east, north, depth below beacon); an array once _t is

    def update(self, t_now: float, view: ObsView) -> None:
        pos = np.concatenate([view.survey_en_m, view.depth_below_m[:, None]], -1)  # (S, 3)
        t_reply = np.asarray(t_now - view.reply_age_s, dtype=float)
        if self._t is None:
            self._t = np.full((self.window,) + t_reply.shape, np.nan)
            self._p = np.zeros((self.window,) + pos.shape)
            self._t[-1], self._p[-1] = t_reply, pos
            return
        new = ~(t_reply <= self._t[-1] + 1e-6)  # a reply newer than the last kept
        self._t = np.where(new, np.roll(self._t, -1, axis=0), self._t)
        self._p = np.where(new[:, None], np.roll(self._p, -1, axis=0), self._p)
        self._t[-1] = np.where(new, t_reply, self._t[-1])
        self._p[-1] = np.where(new[:, None], pos, self._p[-1])

    def _cap(self, v):
        speed = np.linalg.norm(v[:, :2], axis=-1, keepdims=True)
        return np.where(speed > self.max_speed_mps, v * self.max_speed_mps / np.maximum(speed, 1e-12), v)

    def velocity(self) -> np.ndarray:
        """(S, 3) estimated velocity (east, north, depth rate): least squares over the kept replies (T1)."""
        if self._t is None:
            return np.zeros((0, 3))
        ok = np.isfinite(self._t)  # (W, S)
        n = ok.sum(0)
        t = np.where(ok, self._t, 0.0)
        t_mean = t.sum(0) / np.maximum(n, 1)
        dt = np.where(ok, self._t - t_mean, 0.0)  # (W, S)
        p_mean = (self._p * ok[..., None]).sum(0) / np.maximum(n, 1)[:, None]
        num = (dt[..., None] * (self._p - p_mean)).sum(0)
        den = (dt**2).sum(0)
        v = np.where((den > 0)[:, None], num / np.where(den > 0, den, 1.0)[:, None], 0.0)
        return self._cap(v)

    def speed(self) -> np.ndarray:
        """(S,) horizontal path speed (T3): polyline length of the kept replies over their span."""
        if self._t is None:
            return np.zeros(0)
        ok = np.isfinite(self._t)
        seg_ok = ok[1:] & ok[:-1]  # consecutive kept replies (the kept ones are the newest, contiguous)
        seg = np.linalg.norm(np.diff(self._p[..., :2], axis=0), axis=-1)  # (W-1, S)
        length = np.where(seg_ok, seg, 0.0).sum(0)
        span = np.where(ok.any(0), np.where(ok, self._t, -np.inf).max(0) - np.where(ok, self._t, np.inf).min(0), 0.0)
        v = np.where(span > 0, length / np.where(span > 0, span, 1.0), 0.0)
        return np.minimum(v, self.max_speed_mps)

    def heading_velocity(self) -> np.ndarray:
        """(S, 3) velocity of (T2): path speed (T3) along the direction of the last two
        replies; the depth rate of the last two replies."""
        if self._t is None:
            return np.zeros((0, 3))
        dt = self._t[-1] - self._t[-2]
        ok = np.isfinite(dt) & (dt > 0)
        d = self._p[-1] - self._p[-2]
        dist = np.linalg.norm(d[:, :2], axis=-1)
        u = np.where((dist > 1e-9)[:, None], d[:, :2] / np.maximum(dist, 1e-9)[:, None], 0.0)
        v = np.zeros(d.shape)
        v[:, :2] = np.where(ok[:, None], u * self.speed()[:, None], 0.0)
        v[:, 2] = np.where(ok, d[:, 2] / np.where(ok, dt, 1.0), 0.0)
        return self._cap(v)

    def predict(self, view: ObsView, ahead_s: float, predictor: str = "chord") -> tuple:
        """Survey (east, north) (S, 2) and depth below the beacon (S,) ``ahead_s`` after
        now, with the constant velocity of ``predictor`` ((T1) or (T2))."""
        if predictor not in self.PREDICTORS:
            raise ValueError(f"predictor must be one of {self.PREDICTORS}, got {predictor!r}")
        v = self.velocity() if predictor == "chord" else self.heading_velocity()
        dt = view.reply_age_s + ahead_s
        en = view.survey_en_m + v[:, :2] * dt[:, None]
        dz = view.depth_below_m + v[:, 2] * dt
        return en, dz

    def predict_along_path(self, view: ObsView, ahead_s: float) -> tuple:
        """As :meth:`predict`, along the observed planned waypoints (B1)-(B3) at the
        path speed (T3), from the last reply over reply age + ``ahead_s``; survey
        vehicles without observed waypoints fall back to the chord velocity (T1)."""
        en_cv, dz = self.predict(view, ahead_s, "chord")
        dt = view.reply_age_s + ahead_s
        en, known = advance_along_waypoints(view.survey_en_m, view.waypoints_en_m, self.speed() * dt)
        return np.where(known[:, None], en, en_cv), dz


def _checked_seed(seed: int | Sequence[int] | None) -> int | Sequence[int] | None:
    """A policy's seed (an integer, or a sequence of them such as (episode seed, beacon)),
    each in ``coopnav_env.seeds``' range; a one-line ``ValueError`` naming it else."""
    from coopnav_env.seeds import check_seed

    if seed is None:
        return None
    if isinstance(seed, (list, tuple, np.ndarray)):  # a sequence of them, kept as a tuple
        return tuple(check_seed(s, what="policy seed") for s in np.asarray(seed, dtype=object).reshape(-1))
    return check_seed(seed, what="policy seed")


class Policy:
    """Base class: ``act(obs) -> action`` in [-1, 1]^2, ``reset(seed=None)``.

    Subclasses implement :meth:`plan` (decoded observation -> waypoint, absolute
    east/north metres) or override :meth:`act`. ``self.t_s`` counts the time since
    reset (one call per acoustic cycle); ``self.last_waypoint`` is kept for plots.
    """

    name = "policy"
    networks: tuple[str, ...] = ("survey_beacons",)  # the scenario networks (ScenarioConfig.network) it can drive

    def __init__(self, config: ScenarioConfig, agent_index: int = 0, seed: int | Sequence[int] | None = None) -> None:
        if config.network not in self.networks:
            raise ValueError(
                f"policy {self.name!r} drives {' / '.join(self.networks)} scenarios, not "
                f"network={config.network!r} ({config.name}); policies for it: "
                f"{', '.join(list_policies(config=config))}"
            )
        self.config = config
        self.obs_dim = obs_dim(config)
        self.ctx = BeaconContext.from_config(config, agent_index)
        self.seed = _checked_seed(seed)
        self.reset(seed)

    def reset(self, seed: int | Sequence[int] | None = None) -> None:
        if seed is not None:
            self.seed = _checked_seed(seed)
        self.t_s = 0.0
        self.last_waypoint: np.ndarray | None = None

    def decode(self, obs: ArrayLike) -> ObsView:
        """One observation of shape (obs_dim,), decoded; a wrong shape or a NaN is one line
        (``coopnav_env.views.check_observation``), not a NaN action or a numpy error."""
        return decode(check_observation(obs, self.obs_dim), self.config)

    def plan(self, view: ObsView) -> np.ndarray:
        raise NotImplementedError

    def act(self, obs: ArrayLike) -> np.ndarray:
        view = self.decode(obs)
        wp = self.plan(view)
        self.last_waypoint = np.asarray(wp, dtype=float)
        self.t_s += self.ctx.ping_interval_s
        return waypoint_to_action(self.ctx, view.own_en_m, wp)

    def __call__(self, obs):
        return self.act(obs)


def tell_truth(
    policies: Sequence[Sequence[Any]] | Mapping[int, Sequence[Any]], sim: Any, rows: Iterable[int] | None = None
) -> None:
    """Before they act, give the privileged policies among ``policies[b][j]`` (the oracles:
    ``privileged = True``) the simulator's truth of their row b (``sim.snapshot()``, taken only
    if one of them is privileged), for rows ``rows`` (default: all; ``policies`` a mapping
    {row: its policies}: its rows). The one place a runner tells a reference policy what no
    real beacon knows."""
    if rows is None:
        rows = policies.keys() if isinstance(policies, Mapping) else range(len(policies))
    snap = None
    for b in rows:
        for p in policies[b]:
            if getattr(p, "privileged", False):
                snap = sim.snapshot() if snap is None else snap
                p.observe_truth(snap, b)


class TrackingPolicy(Policy):
    """A policy that follows the survey vehicle through its replies (``self.tracker``)."""

    def __init__(self, config: ScenarioConfig, agent_index: int = 0, seed: int | Sequence[int] | None = None) -> None:
        self.tracker = SurveyTracker()
        super().__init__(config, agent_index, seed)

    def reset(self, seed: int | Sequence[int] | None = None) -> None:
        super().reset(seed)
        self.tracker.reset()


# ------------------------------------------------------------------------------------
_POLICIES: dict = {}  # name -> the class registered first under it
_BY_NETWORK: dict = {}  # (name, network) -> the class that drives that network under the name


def register_policy(name: str) -> Callable[[type[Policy]], type[Policy]]:
    """Class decorator: register a ``Policy`` subclass as the planner ``name``
    (``make_policy(name, ...)``, ``list_policies()``, evaluate.py's policy names) for the
    networks it drives (``cls.networks``). One name may have one class per network: the
    receding-horizon planner ``horizon`` is ``baselines.horizon`` on the survey networks and
    ``baselines.boat_horizon`` on the moving network. A (name, network) is registered once;
    re-importing the same class (a module reload) is allowed."""

    def deco(cls: type[Policy]) -> type[Policy]:
        for net in cls.networks:
            old = _BY_NETWORK.get((name, net))
            if old is not None and (old.__module__, old.__qualname__) != (cls.__module__, cls.__qualname__):
                raise ValueError(
                    f"policy {name!r} is registered twice for network {net!r} ({old.__module__}."
                    f"{old.__qualname__} and {cls.__module__}.{cls.__qualname__})"
                )
        for net in cls.networks:
            _BY_NETWORK[(name, net)] = cls
        first = _POLICIES.get(name)
        if first is None or (first.__module__, first.__qualname__) == (cls.__module__, cls.__qualname__):
            _POLICIES[name] = cls
        cls.name = name
        return cls

    return deco


def unregister_policy(name: str) -> None:
    """Remove a registered planner, on every network (tests, plug-ins that clean up after themselves)."""
    _POLICIES.pop(name, None)
    for key in [k for k in _BY_NETWORK if k[0] == name]:
        del _BY_NETWORK[key]


def policy_class(name: str, network: str) -> type[Policy]:
    """The class registered as ``name`` for ``network`` (the one registered first under the name
    if none drives that network: its constructor then says which policies do)."""
    return _BY_NETWORK.get((name, network)) or _POLICIES[name]


def list_policies(network: str | None = None, config: ScenarioConfig | None = None) -> list:
    """Names of the baseline policies: those that can drive ``network``, if given (or the
    network of the scenario ``config``). The planner modules register themselves when
    ``baselines`` is imported."""
    if config is not None:
        network = config.network
    if network is None:
        return sorted(_POLICIES)
    return sorted({n for n, net in _BY_NETWORK if net == network})


def motion_name(name: str) -> str:
    """The motion planner of a planner name: ``"ellipse+clock"`` -> ``"ellipse"``, and
    ``"ellipse:range_model=filter"`` -> ``"ellipse"`` (a plain name is its own)."""
    return name.partition(":")[0].partition("+")[0]


def split_spec(spec: str) -> tuple[str, dict]:
    """A planner spec with keywords, ``"<name>:<key>=<value>:..."`` -> (name, keywords):
    ``"horizon:horizon=8:range_model=filter"`` -> ``("horizon", {"horizon": 8, "range_model":
    "filter"})``; values read as a command line's (``safe_load.parse_value_text``: numbers,
    true/false, lists, else the text). How a command line names a planner's settings
    (``evaluate.py --policies ellipse,ellipse:range_model=filter``)."""
    from coopnav_env.safe_load import UnsafeDataError, parse_value_text

    name, *items = spec.split(":")
    kwargs: dict = {}
    for item in items:
        key, eq, text = item.partition("=")
        if not eq or not key.isidentifier():
            raise ValueError(f"planner spec {spec!r}: a setting is <key>=<value>, got {item!r}")
        if key in kwargs:
            raise ValueError(f"planner spec {spec!r}: {key!r} is set twice")
        try:
            kwargs[key] = parse_value_text(text)
        except UnsafeDataError as err:
            raise ValueError(f"planner spec {spec!r}: {err}") from None
    return name, kwargs


def check_keywords(what: str, kwargs: dict, valid: Sequence[str]) -> None:
    """A ``ValueError`` naming the first keyword of ``kwargs`` not in ``valid`` (with the closest
    valid one and the list), instead of a ``TypeError`` from deep inside a constructor."""
    unknown = [k for k in kwargs if k not in valid]
    if not unknown:
        return
    from coopnav_env.names import did_you_mean

    hint = did_you_mean(unknown[0], list(valid))
    listed = f" its settings: {', '.join(valid)}" if valid else " it takes none"
    raise ValueError(f"{what} takes no setting {unknown[0]!r}{hint}{listed}")


def is_planner(name: str) -> bool:
    """Whether ``make_policy`` builds ``name``: a registered planner, or ``"<motion>+<schedule>"``
    of one (the schedule is checked when it is built)."""
    return motion_name(name) in _POLICIES


_SCHEDULER = None  # baselines.schedule.make_scheduled, set when that module is imported


def register_scheduler(fn: Callable[..., Policy]) -> Callable[..., Policy]:
    """Called by ``baselines.schedule`` (which imports this module, not the other way round)."""
    global _SCHEDULER
    _SCHEDULER = fn
    return fn


def make_policy(
    name: str, env_or_config: Any, seed: int | Sequence[int] | None = None, agent: int | str = 0, **kwargs: Any
) -> Policy:
    """A baseline policy by name for one beacon (``agent``: index or "beacon_k").

    With ``channel_mode="decide"`` a name ``"<motion>+<schedule>"`` combines a planner
    with a transmit schedule (``baselines.schedule``: clock, tdma, event), and a plain
    planner name gets ``schedule.DEFAULT_SCHEDULE``."""
    name, spec_kwargs = split_spec(name)
    kwargs = {**spec_kwargs, **kwargs}
    motion, plus, schedule = name.partition("+")
    if plus and not schedule.strip():  # else the default schedule, labelled as if none were meant
        raise ValueError(f"{name!r} names no transmit schedule after '+' (e.g. {motion}+clock, or {motion} alone)")
    if not is_planner(name):
        from coopnav_env.names import did_you_mean

        raise ValueError(
            f"unknown policy {motion!r}{did_you_mean(motion, _POLICIES)} valid policies: {', '.join(sorted(_POLICIES))}"
        )
    if isinstance(agent, str):
        if not agent.startswith("beacon_") or not agent[7:].isdigit():
            raise ValueError(f"agent must be an index or 'beacon_<k>', got {agent!r}")
        agent = int(agent[7:])
    config = resolve_config(env_or_config)
    if schedule or config.channel_mode == "decide":
        if _SCHEDULER is None:
            raise ValueError(f"{name!r}: transmit schedules need baselines.schedule imported (import baselines)")
        return _SCHEDULER(policy_class(motion, config.network), schedule, config, int(agent), seed, **kwargs)
    cls = policy_class(motion, config.network)
    settings = list(inspect.signature(cls).parameters)[3:]  # past (config, agent_index, seed)
    check_keywords(f"planner {motion!r}", kwargs, settings)
    return cls(config, agent_index=int(agent), seed=seed, **kwargs)
