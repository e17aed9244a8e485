"""A receding-horizon planner: the cross-entropy method over the next H pings.

The shipped planners look one ping ahead (``fim_a``, ``fim_b``, ``ellipse``). Tan,
Gao & Chitre (IEEE JOE 2014) plan the beacon's path over a horizon, minimising the
survey vehicle's accumulated positioning error, with the cross-entropy method. This
is that planner for the survey scenarios. At each decision:

1. **Prediction of the survey vehicle.** Its positions at the next H pings,
   s_1..s_H, are those of ``ellipse``: the last reply moved along its observed
   planned waypoints at its path speed (``SurveyTracker.predict_along_path``,
   eqs. B1-B3 of ``base.advance_along_waypoints``), the depth with the depth rate of
   its replies.
2. **Candidates.** A candidate is a sequence of H velocities v_1..v_H of the beacon,
   each a fraction of its maximum speed inside the unit disc (heading and speed
   together; the reaching set of ``fim``/``ellipse`` ping by ping): the beacon pings
   from b_j = b_{j-1} + v_j v_max T (T the ping interval, b_0 its own estimate).
   The turn limit (12 deg/s for a beacon AUV, 30 for an ASV) allows >= 150 deg per
   ping in every survey scenario, so, like the greedy planners, it is not modelled.
3. **Score: the survey filter's expected covariance.** From the covariance P the
   last reply reported (rebuilt from its ellipse), each ping j grows it by the
   filter's process noise, P^- = P + q dt I (Gao & Chitre eq. 6; dt = reply age + T
   for the first ping, T after), and updates it with the range from b_j to s_j:
   h the horizontal part of the unit slant vector (the survey vehicle is dz deeper;
   its depth is known), R = the ranging noise plus the beacon's own position variance
   (as ``ellipse``: ``BeaconContext.range_variance_m2``; with ``range_model="filter"``
   the survey filter's R(d), which adds the sound speed's scale error growing with the
   slant distance d), and p = the scenario's arrival probability at that distance.
   The range arrives with probability p, so the expected covariance after the ping
   is exactly

       E[P^+] = p (P^- - P^- h h^T P^- / (h^T P^- h + R)) + (1 - p) P^-
              = P^- - p P^- h h^T P^- / (h^T P^- h + R)                        (H1)

   The criterion is the trace, summed over the horizon and the survey vehicles,

       J = sum_j tr E[P_j^+] / sum_j tr P_j^0                                  (H2)

   (P_j^0 the covariance with no range at all, so J is in (0, 1]): the trace is the
   expected squared position error, and the benchmark scores the error averaged
   over every step, so the accumulated trace is the quantity it measures (Tan, Gao
   & Chitre's accumulated positioning error). ``criterion="logdet"`` uses the sum of
   log det E[P_j^+] - log det P_j^0 instead (the D-optimal criterion of the FIM
   planners); log det rewards shrinking the minor axis as much as the major one,
   which the squared error does not; ``criterion="sqrt_trace"`` sums sqrt(tr E[P_j^+])
   (the scale of the error itself, which the benchmark averages, rather than its
   square), and ``terminal_weight`` counts the last ping more (the pings after the
   horizon). Soft constraints (geofence, safety distance,
   acoustic range: ``BeaconContext.violation_m`` at every ping, averaged over the
   horizon) add ``PENALTY_PER_M`` per metre, as in the greedy planners.
   With other beacons (teams), ``team="joint"`` optimises every
   beacon's sequence together: a candidate is M sequences (M, H, 2), beacon m
   starting from its reported position (this one: its own estimate) with its own
   maximum speed and depth, all M ranging at every ping (eq. H1 applied for each
   range in index order, ``team_expected_covariances``). This is decentralised
   joint planning: each beacon computes the joint plan from what it knows (its own
   estimate, the others' reported positions, the survey vehicles' replies) with the
   episode's common random numbers (its seed without the beacon index), so with the
   same knowledge every beacon finds the same plan, and each applies its own first
   step; they exchange no plans, so where their knowledge differs (a peer's position
   report a ping old, a reply one of them missed) their plans may differ.
   ``team="peers"`` (the default: on the team tasks, joint planning was no better,
   even given the truth; ``docs/baselines/horizon.md``) plans this beacon's sequence
   only, the others assumed to stay at their last reported position and to range
   every ping before this one; ``"alone"`` ignores them.
4. **Cross-entropy method.** A Gaussian over the (H, 2) velocity sequence: draw
   ``n_samples`` sequences (projected into the unit disc), keep the ``n_elite``
   cheapest, refit mean and std, ``iterations`` times. The first iteration also
   scores the previous plan shifted by one ping (its last step repeated: the warm
   start, also the initial mean), a stop, and full speed straight in eight
   directions (jointly: for each beacon in turn, the others at the mean). The
   cheapest sequence seen is the plan; a pattern search then polishes its first
   step (``refine_iters`` rounds, the rest of the plan fixed; jointly, every
   beacon's first step in index order each round), and this beacon's is applied.

Random numbers come from the policy's seed (``reset``): the planner is deterministic
given the seed, so it runs under common random numbers like the other planners.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from .base import PENALTY_PER_M, BeaconContext, TrackingPolicy, register_policy

if TYPE_CHECKING:
    from coopnav_env.obs_layout import ObsView
    from coopnav_env.scenarios import ScenarioConfig

CRITERIA = ("trace", "sqrt_trace", "logdet")
TEAMS = ("joint", "peers", "alone")
PREDICTORS = ("path", "chord", "stationary")


def _disc(v: np.ndarray) -> np.ndarray:
    """Project velocity fractions (..., 2) into the unit disc."""
    norm = np.sqrt((v**2).sum(-1, keepdims=True))
    return v / np.maximum(norm, 1.0)


def _h1_update(a, b, c, he, hn, p, R):
    """Eq. (H1) on (var_east, cov, var_north) = (a, b, c): the expected covariance after one
    range along the unit horizontal direction (he, hn), arriving with probability p, variance R."""
    ue, un = a * he + b * hn, b * he + c * hn  # P h
    k = p / (he * ue + hn * un + R)  # p / (h'Ph + R), eq. (H1)
    return a - k * ue * ue, b - k * ue * un, c - k * un * un


def _no_range(P0: np.ndarray, grow_m2: np.ndarray) -> np.ndarray:
    """P_none (H, S, 3): the reported covariances P0 (S, 2, 2) grown by grow_m2 (H, S), no range."""
    H, S = grow_m2.shape[0], P0.shape[0]
    none = np.empty((H, S, 3))
    none_a, none_b, none_c = P0[:, 0, 0].copy(), P0[:, 0, 1].copy(), P0[:, 1, 1].copy()
    for j in range(H):
        none_a, none_c = none_a + grow_m2[j], none_c + grow_m2[j]
        none[j] = np.stack([none_a, none_b, none_c], -1)
    return none


def _w_update(wa, wb, wc, a, b, c, he, hn, p, R):
    """Eq. (H3) on the error's second moment W = (wa, wb, wc) (var_east, cov, var_north):
    the filter, with prior covariance P = (a, b, c), fuses a range along (he, hn) with
    its gain K = P h / (h'Ph + R), arriving with probability p, variance R:

        A = I - K h^T,  E[W^+] = p (A W A^T + R K K^T) + (1 - p) W            (H3)

    With W = P this is eq. (H1) (the Joseph form at the optimal gain)."""
    ue, un = a * he + b * hn, b * he + c * hn  # P h
    s = he * ue + hn * un + R
    ke, kn = ue / s, un / s  # K
    a11, a12, a21, a22 = 1.0 - ke * he, -ke * hn, -kn * he, 1.0 - kn * hn  # A
    m11, m12 = a11 * wa + a12 * wb, a11 * wb + a12 * wc  # A W
    m21, m22 = a21 * wa + a22 * wb, a21 * wb + a22 * wc
    q = 1.0 - p
    return (
        p * (m11 * a11 + m12 * a12 + R * ke * ke) + q * wa,
        p * (m11 * a21 + m12 * a22 + R * ke * kn) + q * wb,
        p * (m21 * a21 + m22 * a22 + R * kn * kn) + q * wc,
    )


def _team_loop(beacon_en, survey_en, survey_dz, P0, grow_m2, beacon_var_m2, ctx, W0=None, channel_shift=None):
    """The loop of ``team_expected_covariances`` (eq. H1) and, given W0 (S, 2, 2),
    ``team_expected_errors`` (eq. H3 beside it): (P (N, H, S, 3), W (N, H, S, 3) or None).
    ``channel_shift`` (S, 2): where the survey vehicles truly are relative to the
    positions given (the oracle's -e0): the channel (delivery) at the true distance,
    the filter's update at its own geometry."""
    N, M, H = beacon_en.shape[:3]
    S = survey_en.shape[1]
    rel = survey_en[None, None] - beacon_en[..., None, :]  # (N, M, H, S, 2)
    d3 = np.sqrt((rel**2).sum(-1) + survey_dz[None] ** 2)
    h = rel / np.maximum(d3, 1e-9)[..., None]
    if channel_shift is None:
        p = ctx.delivery_probability(d3)  # (N, M, H, S)
    else:
        p = ctx.delivery_probability(np.sqrt(((rel + channel_shift) ** 2).sum(-1) + survey_dz[None] ** 2))
    var = np.broadcast_to(np.asarray(beacon_var_m2, float), (M,))
    R = ctx.range_variance_m2(d3, var[None, :, None, None])  # (N, M, H, S), by ctx.range_model
    a = np.broadcast_to(P0[:, 0, 0], (N, S)).copy()
    b = np.broadcast_to(P0[:, 0, 1], (N, S)).copy()
    c = np.broadcast_to(P0[:, 1, 1], (N, S)).copy()
    out = np.empty((N, H, S, 3))
    out_w = None if W0 is None else np.empty((N, H, S, 3))
    if W0 is not None:
        wa = np.broadcast_to(W0[:, 0, 0], (N, S)).copy()
        wb = np.broadcast_to(W0[:, 0, 1], (N, S)).copy()
        wc = np.broadcast_to(W0[:, 1, 1], (N, S)).copy()
    for j in range(H):
        a, c = a + grow_m2[j], c + grow_m2[j]
        if out_w is not None:
            wa, wc = wa + grow_m2[j], wc + grow_m2[j]
        for m in range(M):
            he, hn = h[:, m, j, :, 0], h[:, m, j, :, 1]
            if out_w is not None:  # (H3) with the filter's prior P of this range
                wa, wb, wc = _w_update(wa, wb, wc, a, b, c, he, hn, p[:, m, j], R[:, m, j])
            a, b, c = _h1_update(a, b, c, he, hn, p[:, m, j], R[:, m, j])
        out[:, j, :, 0], out[:, j, :, 1], out[:, j, :, 2] = a, b, c
        if out_w is not None:
            out_w[:, j, :, 0], out_w[:, j, :, 1], out_w[:, j, :, 2] = wa, wb, wc
    return out, out_w


def team_expected_covariances(
    beacon_en: np.ndarray,
    survey_en: np.ndarray,
    survey_dz: np.ndarray,
    P0: np.ndarray,
    grow_m2: np.ndarray,
    beacon_var_m2: np.ndarray,
    ctx: BeaconContext,
) -> tuple[np.ndarray, np.ndarray]:
    """Eq. (H1) with M beacons ranging at every ping, in index order.

    beacon_en (N, M, H, 2): each candidate's ping positions of every beacon;
    survey_en (H, S, 2); survey_dz (M, H, S): the survey vehicles' depth below each
    beacon; P0 (S, 2, 2); grow_m2 (H, S); beacon_var_m2 (M,): each beacon's own
    position variance per axis, from which each range's R(d) (``ctx.range_variance_m2``). The
    ranges of one ping are independent, each arriving with its own probability
    p_m, and are applied one after the other (the expectation of each update over
    its arrival, eq. H1, in turn). Returns (P (N, H, S, 3), P_none (H, S, 3)) as
    ``expected_covariances``."""
    P, _ = _team_loop(beacon_en, survey_en, survey_dz, P0, grow_m2, beacon_var_m2, ctx)
    return P, _no_range(P0, grow_m2)


def team_expected_errors(
    beacon_en: np.ndarray,
    survey_en: np.ndarray,
    survey_dz: np.ndarray,
    P0: np.ndarray,
    grow_m2: np.ndarray,
    beacon_var_m2: np.ndarray,
    ctx: BeaconContext,
    W0: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """The survey filters' expected squared errors when their errors now are known
    (``oracle``): eq. (H3) beside (H1), from W0 (S, 2, 2) = e0 e0^T, e0 the error of
    each filter now (estimate minus truth). The filter's gains come from its own
    covariance (H1), the error's second moment W follows them; the noise to come
    (process noise grow_m2, range variance R) is not known. Arguments and shapes as
    ``team_expected_covariances``; returns (W (N, H, S, 3), W_none (H, S, 3): no range)."""
    _, W = _team_loop(beacon_en, survey_en, survey_dz, P0, grow_m2, beacon_var_m2, ctx, W0)
    assert W is not None
    return W, _no_range(np.asarray(W0, float), grow_m2)


def expected_covariances(
    beacon_en: np.ndarray,
    survey_en: np.ndarray,
    survey_dz: np.ndarray,
    P0: np.ndarray,
    grow_m2: np.ndarray,
    beacon_var_m2: float,
    ctx: BeaconContext,
    peers_en: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The survey filters' expected covariances after each ping, eq. (H1).

    beacon_en (N, H, 2): each candidate's ping positions; survey_en (H, S, 2) and
    survey_dz (H, S): the survey vehicles at those pings; P0 (S, 2, 2): the
    reported covariances; grow_m2 (H, S): the process-noise variance added before
    each ping (q dt); peers_en (M, 2): other beacons, ranging from there every ping.
    Returns (P (N, H, S, 3) as (var_east, cov, var_north) after each ping, P_none
    (H, S, 3) with no range at all).
    """
    N, H = beacon_en.shape[:2]
    peers = np.zeros((0, 2)) if peers_en is None else np.asarray(peers_en, float).reshape(-1, 2)
    held = np.broadcast_to(peers[None, :, None, :], (N, len(peers), H, 2))  # the peers range first
    beacons = np.concatenate([held, np.asarray(beacon_en, float)[:, None]], axis=1)  # (N, K + 1, H, 2)
    dz = np.broadcast_to(survey_dz[None], (len(peers) + 1,) + survey_dz.shape)
    var = np.full(len(peers) + 1, float(beacon_var_m2))
    return team_expected_covariances(beacons, survey_en, dz, P0, grow_m2, var, ctx)


def horizon_cost(
    P: np.ndarray, P_none: np.ndarray, criterion: str = "trace", terminal_weight: float = 0.0
) -> np.ndarray:
    """Eq. (H2) (``"trace"``), the summed root of the trace (``"sqrt_trace"``: the
    expected error's scale, sum_j sqrt(tr E[P_j^+]) / sum_j sqrt(tr P_j^0)) or the
    summed log-det reduction (``"logdet"``) of expected covariances P (N, H, S, 3),
    P_none (H, S, 3) -> (N,). ``terminal_weight`` w counts the last ping's term 1 + w
    times (the pings after the horizon, as if the covariance stayed there)."""
    H = P.shape[1]
    w = np.ones(H)
    w[-1] += terminal_weight
    if criterion in ("trace", "sqrt_trace"):
        tr, tr0 = P[..., 0] + P[..., 2], P_none[..., 0] + P_none[..., 2]
        if criterion == "sqrt_trace":
            tr, tr0 = np.sqrt(np.maximum(tr, 0.0)), np.sqrt(np.maximum(tr0, 0.0))
        return (tr * w[:, None]).sum((1, 2)) / max(float((tr0 * w[:, None]).sum()), 1e-300)
    if criterion == "logdet":
        det = np.maximum(P[..., 0] * P[..., 2] - P[..., 1] ** 2, 1e-300)
        det0 = np.maximum(P_none[..., 0] * P_none[..., 2] - P_none[..., 1] ** 2, 1e-300)
        return ((np.log(det) - np.log(det0)) * w[:, None]).sum((1, 2))
    raise ValueError(f"criterion must be one of {CRITERIA}, got {criterion!r}")


HORIZON_S = 30.0  # the default horizon looks at least this far ahead, in 4 to 6 pings


MAX_HORIZON, MAX_SAMPLES, MAX_ITERATIONS = 50, 4096, 100  # the planner's knobs' upper bounds


def check_search_settings(
    n_samples: Any, n_elite: Any, iterations: Any, init_std: Any, refine_iters: Any, **lengths: Any
) -> None:
    """A one-line ValueError unless the cross-entropy search's settings are whole numbers in
    a range whose cost per step stays bounded (``lengths``: the plan's, in pings or blocks, in
    [1, MAX_HORIZON]; samples x iterations rollouts of the filter each step) and init_std a
    finite number > 0: a float, a bool or 1e9 was taken (truncated) or planned for hours (an
    input audit). ``HorizonPolicy`` and ``BoatHorizonPolicy`` call it."""
    checks = [(name, value, 1, MAX_HORIZON) for name, value in lengths.items()]
    checks += [
        ("n_samples", n_samples, 1, MAX_SAMPLES),
        ("n_elite", n_elite, 1, MAX_SAMPLES),
        ("iterations", iterations, 1, MAX_ITERATIONS),
        ("refine_iters", refine_iters, 0, MAX_ITERATIONS),
    ]
    for name, value, low, high in checks:
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not low <= value <= high:
            raise ValueError(f"{name} must be a whole number in [{low}, {high}], got {value!r}")
    if n_elite > n_samples:
        raise ValueError(f"n_elite must be at most n_samples ({n_samples}), got {n_elite}")
    if isinstance(init_std, bool) or not isinstance(init_std, (int, float)) or not 0 < init_std < np.inf:
        raise ValueError(f"init_std must be a finite number > 0 (the first samples' spread), got {init_std!r}")


def default_horizon(ping_interval_s: float) -> int:
    """The default number of pings H: enough to look ``HORIZON_S`` ahead, at least 4 and at
    most 6, H = min(6, max(4, ceil(30 s / T))): 4 at a 20 s ping (80 s ahead: the Gao
    scenarios, ``sousa_ping``), 6 at 5 s (``sousa_asv``: 30 s, where 4 pings, 20 s, were
    short on its spirals and circles) and at 2 s (``swarm_mls``: 12 s). Tuning runs in
    ``docs/baselines/horizon.md``."""
    return int(min(6, max(4, np.ceil(HORIZON_S / float(ping_interval_s) - 1e-9))))


# the first iteration's fixed candidates: stop, and full speed straight in eight directions
_ANGLES = 2 * np.pi * np.arange(8) / 8
_FIXED = np.concatenate([np.zeros((1, 2)), np.stack([np.sin(_ANGLES), np.cos(_ANGLES)], -1)])
_G = np.arange(-2, 3)
_PATTERN = np.stack(np.meshgrid(_G, _G, indexing="ij"), -1).reshape(-1, 2).astype(float)  # (25, 2)


def each_alone(mean: np.ndarray) -> np.ndarray:
    """The first iteration's fixed candidates for plans mean (M, H, 2): each member in turn
    stops or goes full speed straight in eight directions, the others at the mean."""
    M = mean.shape[0]
    fixed = np.repeat(mean[None], M * len(_FIXED), 0)
    for m in range(M):
        fixed[m * len(_FIXED) : (m + 1) * len(_FIXED), m] = _FIXED[:, None, :]
    return fixed


def cross_entropy(
    cost: Callable, mean: np.ndarray, rng: np.random.Generator, sizes: tuple, extra: np.ndarray, project: Callable
) -> tuple[np.ndarray, float]:
    """The cross-entropy method (step 4 of the module docstring) over plans shaped like mean
    (M, H, 2): ``sizes`` = (n_samples, n_elite, iterations, init_std); each iteration draws
    n_samples plans around the mean (the first is the mean), the first adds ``extra``, all go
    through ``project`` (into the unit disc), and the n_elite cheapest (``cost``: (N, M, H, 2)
    -> (N,)) refit the mean and std. Returns the cheapest plan seen and its cost."""
    n_samples, n_elite, iterations, init_std = sizes
    std = np.full(mean.shape, init_std)
    best_v, best_cost = mean, np.inf
    for it in range(iterations):
        v = mean + std * rng.standard_normal((n_samples,) + mean.shape)
        v[0] = mean
        if it == 0:
            v = np.concatenate([v, extra])
        v = project(v)
        c = cost(v)
        order = np.argsort(c, kind="stable")
        if c[order[0]] < best_cost:
            best_v, best_cost = v[order[0]], float(c[order[0]])
        elite = v[order[:n_elite]]
        mean, std = elite.mean(0), elite.std(0) + 0.02
    return best_v, best_cost


def pattern_search(
    cost: Callable, v: np.ndarray, best_cost: float, rounds: int, project_step: Callable
) -> tuple[np.ndarray, float]:
    """A pattern search on the first step of every member of plan v (M, H, 2), the rest fixed:
    a 5x5 pattern around it, ``project_step(candidates, m)`` after member m's step is moved,
    its spacing halved every round from 0.1 of the maximum speed, members in index order."""
    step = 0.1
    for _ in range(rounds):
        for m in range(v.shape[0]):
            cand = np.repeat(v[None], len(_PATTERN), 0)
            cand[:, m, 0] = v[m, 0] + step * _PATTERN
            cand = project_step(cand, m)
            c = cost(cand)
            k = int(np.argmin(c))
            if c[k] < best_cost:
                v, best_cost = cand[k], float(c[k])
        step *= 0.5
    return v, best_cost


def _disc_step(cand: np.ndarray, m: int) -> np.ndarray:
    """``pattern_search``'s projection for free plans: member m's moved first step into the disc."""
    cand[:, m, 0] = _disc(cand[:, m, 0])
    return cand


@register_policy("horizon")
class HorizonPolicy(TrackingPolicy):
    """Receding horizon: the cross-entropy method over the beacon's next ``horizon``
    velocities, minimising the survey filter's expected accumulated covariance
    (see the module docstring). Constructor arguments: ``horizon`` pings (default
    ``default_horizon`` of the ping interval), CEM sizes
    ``n_samples``, ``n_elite``, ``iterations``, the sampling std ``init_std``
    (fraction of the maximum speed), ``criterion`` ("trace" or "logdet"),
    ``team`` (with several beacons: "joint" plans every beacon's sequence together,
    "peers", the default, plans its own around the others held at their reported positions,
    "alone" ignores them), ``refine_iters`` (pattern-search rounds on the applied
    step), ``predictor`` of the survey path ("path", "chord", "stationary"),
    ``terminal_weight`` (``horizon_cost``) and ``range_model`` ("constant", the default,
    or "filter": the survey filter's R(d), ``BeaconContext.range_variance_m2``)."""

    def __init__(
        self,
        config: ScenarioConfig,
        agent_index: int = 0,
        seed: int | Sequence[int] | None = None,
        horizon: int | None = None,
        n_samples: int = 64,
        n_elite: int = 8,
        iterations: int = 4,
        init_std: float = 0.5,
        criterion: str = "trace",
        team: str = "peers",
        refine_iters: int = 8,
        predictor: str = "path",
        terminal_weight: float = 0.0,
        range_model: str = "constant",
    ) -> None:
        if predictor not in PREDICTORS:
            raise ValueError(f"predictor must be one of {PREDICTORS}, got {predictor!r}")
        self.predictor = predictor
        if criterion not in CRITERIA:
            raise ValueError(f"criterion must be one of {CRITERIA}, got {criterion!r}")
        if team not in TEAMS:
            raise ValueError(f"team must be one of {TEAMS}, got {team!r}")
        if horizon is None:
            horizon = default_horizon(config.ping_interval_s)
        check_search_settings(n_samples, n_elite, iterations, init_std, refine_iters, horizon=horizon)
        if isinstance(terminal_weight, bool) or not np.isfinite(terminal_weight) or terminal_weight < 0:
            raise ValueError(f"terminal_weight must be a finite number >= 0, got {terminal_weight!r}")
        self.horizon, self.n_samples, self.n_elite = int(horizon), int(n_samples), int(n_elite)
        self.iterations, self.init_std = int(iterations), float(init_std)
        self.criterion, self.team, self.refine_iters = criterion, team, int(refine_iters)
        self.terminal_weight = float(terminal_weight)
        super().__init__(config, agent_index, seed)
        self.ctx = self.ctx.with_range_model(range_model)
        joint = team == "joint" and config.n_beacons > 1
        # the beacons this one plans for, in index order, and where it is among them
        self.planned = list(range(config.n_beacons)) if joint else [agent_index]
        self.me = agent_index if joint else 0
        self.team_ctx = [BeaconContext.from_config(config, m).with_range_model(range_model) for m in self.planned]
        self.step_m = np.array([c.max_speed_mps * c.ping_interval_s for c in self.team_ctx])  # (M,)

    def reset(self, seed: int | Sequence[int] | None = None) -> None:
        super().reset(seed)
        self.rng = np.random.default_rng(self._rng_seed())
        self.plan_v: np.ndarray | None = None  # (M, H, 2) the last plan, velocity fractions
        self.last_cost = float("nan")

    def _rng_seed(self) -> Any:
        """The random stream: the policy's seed; planning jointly, the episode's part of it
        (``(episode, beacon)`` -> episode), so that every beacon draws the same candidates."""
        seed = self.seed if self.seed is not None else 0
        joint = self.team == "joint" and self.config.n_beacons > 1
        if joint and isinstance(seed, Sequence) and not isinstance(seed, str) and len(seed) > 1:
            return list(seed)[:-1]
        return seed

    def predict(self, view: ObsView, ahead_s: float) -> tuple[np.ndarray, np.ndarray]:
        """The survey vehicles' (east, north) (S, 2) and depth below (S,) ``ahead_s`` after now."""
        if self.predictor == "path":
            return self.tracker.predict_along_path(view, ahead_s)
        if self.predictor == "chord":
            return self.tracker.predict(view, ahead_s, "chord")
        return np.asarray(view.survey_en_m, float), np.asarray(view.depth_below_m, float)

    def survey_model(self, view: ObsView) -> dict:
        """What one decision scores against: the survey vehicles at the next H pings
        (``en`` (H, S, 2), depth below each planned beacon ``dz`` (M, H, S)), the reported
        covariance ``P0`` (S, 2, 2), the process noise before each ping ``grow`` (H, S),
        each planned beacon's own position variance ``beacon_var`` (M,; its ranges' R(d)
        follow from it), where the planned beacons start
        (``start`` (M, 2): its own estimate, the others' reported positions) and the other
        beacons held fixed (``fixed`` (K, 2), team="peers")."""
        c, T, H = self.config, self.ctx.ping_interval_s, self.horizon
        preds = [self.predict(view, (j + 1) * T) for j in range(H)]
        en = np.stack([e for e, _ in preds])
        dz_own = np.stack([d for _, d in preds])  # (H, S) below this beacon
        # below beacon m: its nominal depth instead of this one's (an ASV at 0, a beacon AUV at its depth)
        dz = np.stack([dz_own + (self.ctx.depth_m - bc.depth_m) for bc in self.team_ctx])  # own: exactly dz_own
        q = c.process_noise_horizontal_m2ps
        grow = np.full(dz_own.shape, q * T)
        grow[0] = q * (np.asarray(view.reply_age_s, float) + T)
        var = np.full(len(self.planned), float(view.own_std_m) ** 2)  # the beacons' own variance (peers: as its own)
        own = np.asarray(view.own_en_m, float)
        peers = np.asarray(view.peers_en_m, float).reshape(-1, 2)
        start = np.insert(peers, self.me, own, axis=0) if len(self.planned) > 1 else own[None]
        fixed = peers if self.team == "peers" and len(self.planned) == 1 else np.zeros((0, 2))
        return {
            "en": en,
            "dz": dz,
            "P0": np.asarray(view.cov_m2, float),
            "grow": grow,
            "beacon_var": var,
            "start": start,
            "fixed": fixed,
        }

    def cost(self, v: np.ndarray, model: dict) -> np.ndarray:
        """Cost (N,) of velocity sequences v (N, M, H, 2): eq. (H2) plus the constraint penalty."""
        beacon = model["start"][None, :, None, :] + self.step_m[None, :, None, None] * np.cumsum(v, axis=2)
        en, dz, var = model["en"], model["dz"], model["beacon_var"]
        fixed = model["fixed"]
        if len(fixed):  # team="peers": the others range from where they were, before this beacon, every ping
            held = np.broadcast_to(fixed[None, :, None, :], (len(v), len(fixed), self.horizon, 2))
            beacon = np.concatenate([held, beacon], axis=1)
            dz = np.concatenate([np.broadcast_to(dz[:1], (len(fixed),) + dz.shape[1:]), dz])
            var = np.concatenate([np.full(len(fixed), var[0]), var])
        P, P_none = self.expected(beacon, en, dz, var, model)
        viol = sum(
            bc.violation_m(beacon[:, len(fixed) + m, j], en[j], model["dz"][m, j])
            for m, bc in enumerate(self.team_ctx)
            for j in range(self.horizon)
        )
        cost = horizon_cost(P, P_none, self.criterion, self.terminal_weight)
        return cost + PENALTY_PER_M * viol / self.horizon

    def expected(
        self, beacon: np.ndarray, en: np.ndarray, dz: np.ndarray, beacon_var: np.ndarray, model: dict
    ) -> tuple[np.ndarray, np.ndarray]:
        """What eq. (H2) sums, per candidate: the survey filters' expected covariances (H1)."""
        return team_expected_covariances(beacon, en, dz, model["P0"], model["grow"], beacon_var, self.ctx)

    def optimise(self, view: ObsView) -> np.ndarray:
        """The cross-entropy method; returns the best (M, H, 2) velocity sequences."""
        self.tracker.update(self.t_s, view)
        model = self.survey_model(view)
        M, H = len(self.planned), self.horizon
        if self.plan_v is None:
            mean = np.zeros((M, H, 2))
        else:
            mean = np.concatenate([self.plan_v[:, 1:], self.plan_v[:, -1:]], axis=1)  # warm start: shifted
        best_v, best_cost = cross_entropy(
            lambda v: self.cost(v, model),
            mean,
            self.rng,
            (self.n_samples, self.n_elite, self.iterations, self.init_std),
            each_alone(mean),
            _disc,
        )
        best_v, self.last_cost = self.refine_first_step(model, best_v, best_cost)
        return best_v

    def refine_first_step(self, model: dict, v: np.ndarray, cost: float) -> tuple[np.ndarray, float]:
        """A pattern search on the first step (the one applied), the rest of the plan
        fixed: a 5x5 pattern around it, projected into the unit disc, its spacing
        halved every round from 0.1 of the maximum speed (``refine_iters`` rounds);
        planning jointly, on each beacon's first step in index order every round.
        The CEM's elite mean is coarse where the cost is flat (near an optimum of the
        trace the cost is quadratic in the heading); this polishes the step it applies."""
        return pattern_search(lambda c: self.cost(c, model), v, cost, self.refine_iters, _disc_step)

    def plan(self, view: ObsView) -> np.ndarray:
        self.plan_v = self.optimise(view)
        return np.asarray(view.own_en_m, float) + self.ctx.reach_m * self.plan_v[self.me, 0]


@register_policy("oracle")
class OraclePolicy(HorizonPolicy):
    """``horizon`` given the truth: a reference for what guidance can achieve, not a
    policy a user could field.

    Before each decision the evaluation (``evaluation.episodes.run_episodes``: every
    policy with ``privileged = True``) passes the simulator's snapshot
    (``observe_truth``). The oracle then knows, now and exactly, what ``horizon``
    knows only from the last reply: each survey filter's estimate and covariance (no
    reply age) and the other beacons' positions; and what no beacon can know, each
    filter's error e0 = estimate - truth. The geometry is the filter's (its estimate
    and the beacons' own estimates: where the filter linearises), and it scores a
    candidate by

        J = sum_j tr(E[W_j] + E[P_j]) / sum_j tr(W_j^0 + P_j^0)                  (H4)

    E[W_j] the expected squared error after ping j given e0 (eq. H3,
    ``team_expected_errors``: the error the oracle can foresee, corrected along each
    range's line of sight by the filter's own gain), E[P_j] the filter's expected
    covariance (H1): the error to come, which the oracle cannot foresee and a filter
    with a smaller covariance will correct faster. W alone is myopic: once the known
    error is corrected, each further range adds its noise (R K K') and the horizon's
    few pings of process noise cannot repay it, so it steered away from the survey
    vehicle (135 m against horizon's 43 m on gao_lawnmower) and was 9 % worse than
    ``horizon``. The noise to come (process, ranges, losses) is not known, nor is the
    current (the beacon's velocity is commanded through the water, as for every
    planner). Without a snapshot (the PettingZoo env, a batch without the hook) it
    is ``horizon``. Validation runs: ``docs/baselines/horizon.md#the-oracle``.

    Until benchmark v4 the oracle planned eq. (H1) with the true positions in place
    of the estimates: neither the filter's geometry nor its error; on gao_lawnmower
    (benchmark v4) it was within its interval of ``horizon`` on every task.
    """

    privileged = True

    def reset(self, seed: int | Sequence[int] | None = None) -> None:
        super().reset(seed)
        self._truth: dict | None = None
        self._W0: np.ndarray | None = None
        self._shift: np.ndarray | None = None

    def observe_truth(self, snapshot: Any, row: int) -> None:
        """Keep what the snapshot (``coopnav_env.core.contract.Snapshot``) says of batch row ``row``."""
        me = self.ctx.agent_index
        own = np.asarray(snapshot.beacon_est_m[row, me], float)
        est = np.asarray(snapshot.survey_est_m[row], float)
        true = np.asarray(snapshot.survey_true_m[row], float)
        others = [m for m in range(snapshot.beacon_est_m.shape[1]) if m != me]
        e0 = est[:, :2] - true[:, :2]
        self._W0 = e0[:, :, None] * e0[:, None, :]  # (S, 2, 2)
        self._shift = -e0  # the channel at the true distance
        self._truth = {
            "peers_en_m": np.asarray(snapshot.beacon_est_m[row, others, :2], float).reshape(-1, 2),
            "survey_en_m": est[:, :2].copy(),
            "depth_below_m": est[:, 2] - own[2],
            "cov_m2": np.asarray(snapshot.survey_cov_en_m2[row], float).copy(),
        }

    def expected(
        self, beacon: np.ndarray, en: np.ndarray, dz: np.ndarray, beacon_var: np.ndarray, model: dict
    ) -> tuple[np.ndarray, np.ndarray]:
        """Eq. (H4)'s terms: the expected squared errors (H3) plus the expected covariances
        (H1), and the same with no range; (H1) alone without a snapshot."""
        if model.get("W0") is None:
            return super().expected(beacon, en, dz, beacon_var, model)
        # one pass of the loop gives both (H1) and (H3): the filter's gains are computed once
        P, W = _team_loop(
            beacon, en, dz, model["P0"], model["grow"], beacon_var, self.ctx, model["W0"], model.get("channel_shift")
        )
        assert W is not None
        none = _no_range(model["P0"], model["grow"]) + _no_range(np.asarray(model["W0"], float), model["grow"])
        return W + P, none

    def survey_model(self, view: ObsView) -> dict:
        """``horizon``'s, with the filters' errors now as W0 (S, 2, 2) (None without a snapshot)."""
        model = super().survey_model(view)
        model["W0"] = self._W0
        model["channel_shift"] = self._shift if self._W0 is not None else None
        return model

    def plan(self, view: ObsView) -> np.ndarray:
        if self._truth is None:
            self._W0 = None
            return super().plan(view)
        now = dataclasses.replace(view, reply_age_s=np.zeros_like(view.reply_age_s), **self._truth)
        self._truth = None
        self.plan_v = self.optimise(now)
        self._W0 = None
        return np.asarray(view.own_en_m, float) + self.ctx.reach_m * self.plan_v[self.me, 0]  # the same velocity
