"""The receding-horizon planner and its oracle for the moving network's boats.

``horizon`` and ``oracle`` (``baselines.horizon``) plan a beacon against the survey
filter's predicted covariance. On the moving network (``network = "moving_lbl"``,
Matos & Cruz) the filter is the vehicle's moving-frame EKF, which fuses two ranges a
cycle, d1 from B1 and d2 from B2 (``core.moving_network.filter``), and the boats see
no covariance: their observation (``obs_layout.BoatView``) is their GPS, each other's
position by radio and the external tracking of the vehicle. This module is the same
optimiser for them, under the same names (``register_policy`` keeps one class per
network). At each cycle each boat plans **both** boats' velocities (the fix needs both):

1. **Coordinates**: the frame of the boats' GPS now (x along B1 -> B2, y clockwise),
   with the origin at the tracked vehicle (the oracle: at the vehicle filter's
   estimate). B1 = own position (or own minus the baseline), B2 = B1 + (l, 0).
2. **Candidates**: ``blocks`` velocity pairs (2, blocks, 2), each held for
   ``cycles_per_block`` cycles (fractions of ``boat_max_speed_mps`` inside the unit
   disc): boat m is at b_m(j) = b_m(0) + v_max T (the sum of its velocities up to cycle j).
3. **The vehicle at cycle j**, s(j): with a mission in the world (``matos_river``) it
   goes on at the tracked velocity, s(j) = v_trk j T (where the boats go does not move
   it); with the paper's mission in the frame (``matos_moving_lbl``) it moves with B1:
   s(j) = (v_trk - v_own) j T + b_1(j) - b_1(0) (the frame's rotation neglected).
4. **Score**: the vehicle filter's expected (x, y) covariance, eq. (H1) of
   ``baselines.horizon`` once for d1 and once for d2 each cycle, after the growth
   q T with q = ``frame_q_position_m2ps`` + (``speed_encoder_noise_mps``^2 +
   (v c_compass)^2) T (the filter's position random walk and a dead-reckoned velocity
   error held over the cycle; v the survey speed, c_compass the compass noise in
   radians); h the horizontal part of the slant direction (the vehicle is at its
   mission depth below the boats), R the two-way range variance
   (``acoustics.ranging_variance_m2``: the ranges are to the boats themselves, so their
   GPS error does not enter), and the arrival probability p = (1 - loss(d))^2, both
   legs of a two-way range over d (the exchange's loss curve). J = sum_j tr E[P_j] /
   sum_j tr P_j^0, eq. (H2). The boats do not see the filter's covariance: ``horizon``
   carries its own prediction of it from decision to decision (the expected covariance
   after the first cycle of the plan it applied), starting at R I. Not modelled: the
   filter's frame states (phi, l, the current) and their errors, and the tracker's.
5. **Constraints** (``PENALTY_PER_M`` per metre, averaged over the cycles, the reward's
   penalty terms with ``SAFETY_MARGIN_M`` inside each): a boat nearer the vehicle than
   ``safety_distance_m``; the baseline off ``baseline_target_m`` by more than half of
   ``baseline_tolerance_m`` (with the margin alone the boats, which follow their
   commands imperfectly, were outside the tolerance in 16 % of cycles); the vehicle
   nearer the baseline's line than ``min_baseline_distance_m``; on a river, a boat farther than
   ``river_width_m`` / 2 - ``bank_margin_m`` from the centerline, each boat's offset
   moved along the river's cross direction now (B2's offset is B1's plus the
   baseline's part across the river; the river's bend over the horizon is neglected).
6. **Cross-entropy method** over the (2, blocks, 2) pair as in ``horizon``: the last
   plan (the first time: the boats' velocities now) as the initial mean, a stop and
   full speed in eight directions for each boat (the other at the mean) and for both
   together; then a pattern search on each boat's first velocity. The boat applies its
   own first velocity. Both boats draw the same candidates (the episode's part of the
   seed) and see the same geometry, so they find the same plan.

Before the tracker's first fix both follow ``river_escort`` (``abeam`` with a mission in
the frame).

``oracle`` is given the simulator's snapshot (``observe_truth``, as the survey
network's): the filter's estimate (the origin), its covariance P0 and its error e0;
it scores eq. (H4) of ``baselines.horizon`` (H3 for W from W0 = e0 e0' beside H1) with
the channel at the true distances.

**The paper's mission in the frame** (``matos_moving_lbl``). The vehicle's mission moves
with the boats, so their common motion cannot change its geometry (``static`` boats tie
``abeam`` in the benchmark), and the paper's filter models neither the frame's rotation
nor a change of its velocity (it folds them into a slowly varying current). Plans over
both boats' free velocities misled it: on tuning episode 123000, 5.6-15.7 m mean error
against ``abeam``'s 1.27 m (the boats' velocity commands drifted with their measured
velocities and turned the frame). So the plans there are **spread plans**
(``project``): both boats at ``abeam``'s paced transit, B1 minus and B2 plus a planned
along-baseline velocity, which changes only the baseline's length. A stretch the filter
does not expect moves its range d2 by up to as much, so the score adds, at each cycle j,
the square of the stretch so far,

    J += (sum_{i<=j} (v_2,i - v_1,i)_x T)^2                                      (BH1)

Without (BH1) the spread plans were 1.49 m against ``abeam``'s 1.08 on tuning episodes
123000-123005 (more ranges rejected: 85 against 67 an episode); with it 1.09, and the
oracle 1.11: on this mission guidance has nothing to gain (the benchmark's headroom).

The candidates' costs are one compiled kernel (``boat_plan_costs``): a decision costs
about 3.5 ms of CPU (``python benchmarks/planner_cost.py --scenario matos_river``), against
0.1 ms for ``river_escort``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numba import njit

from coopnav_env.core.acoustics import packet_loss_probability, ranging_variance_m2

from .base import PENALTY_PER_M, SAFETY_MARGIN_M, register_policy
from .horizon import _FIXED, _disc, check_search_settings, cross_entropy, each_alone, pattern_search
from .moving_lbl import AbeamPolicy, RiverEscortPolicy

if TYPE_CHECKING:
    from coopnav_env.obs_layout import BoatView
    from coopnav_env.scenarios import ScenarioConfig


class BoatModel(NamedTuple):
    """What one decision scores against (frame axes, origin at the vehicle now; metres,
    seconds). ``limits`` = (safety distance + margin, target baseline, half its tolerance,
    minimum baseline distance + margin, the river's half width - the bank margin (< 0: no banks));
    ``loss`` = (packet_loss_near, packet_loss_far, max_range_m)."""

    start: np.ndarray  # (2, 2) B1, B2 now
    vehicle_v: np.ndarray  # (2,) the vehicle's tracked velocity (in the frame: minus this boat's own)
    dz: float  # the vehicle's depth below the boats
    P0: np.ndarray  # (2, 2) the filter's covariance now (horizon: its own prediction)
    W0: np.ndarray  # (2, 2) the known error's second moment e0 e0' (oracle), else zeros
    with_error: bool  # score eq. (H4) (oracle) instead of (H2)
    shift: np.ndarray  # (2,) the vehicle's true position minus the origin (oracle), else zeros
    grow_m2: float  # the filter's position variance growth per cycle
    R_m2: np.ndarray  # (2,) each boat's range variance
    loss: np.ndarray  # (3,)
    limits: np.ndarray  # (5,)
    bank: np.ndarray  # (4,) the boats' offsets from the centerline now, the river's cross direction (x, y)
    v_now: np.ndarray  # (2, 2) the first plan's velocities (this boat's own); in the frame: the common transit
    rides: bool  # the vehicle's mission is in the frame: it moves with B1


@njit(cache=True)
def _range_update(P: np.ndarray, W: np.ndarray, he: float, hn: float, p: float, R: float, with_error: bool) -> None:
    """Eqs. (H1) on P and (H3) on W (with_error), in place: one range along (he, hn), arriving
    with probability p, variance R (``baselines.horizon._h1_update``, ``_w_update``)."""
    a, b, c = P[0, 0], P[0, 1], P[1, 1]
    ue, un = a * he + b * hn, b * he + c * hn
    s = he * ue + hn * un + R
    ke, kn = ue / s, un / s
    if with_error:  # (H3): E[W+] = p (A W A' + R K K') + (1 - p) W, A = I - K h'
        a11, a12, a21, a22 = 1.0 - ke * he, -ke * hn, -kn * he, 1.0 - kn * hn
        wa, wb, wc = W[0, 0], W[0, 1], W[1, 1]
        m11, m12 = a11 * wa + a12 * wb, a11 * wb + a12 * wc
        m21, m22 = a21 * wa + a22 * wb, a21 * wb + a22 * wc
        q = 1.0 - p
        W[0, 0] = p * (m11 * a11 + m12 * a12 + R * ke * ke) + q * wa
        W[0, 1] = W[1, 0] = p * (m11 * a21 + m12 * a22 + R * ke * kn) + q * wb
        W[1, 1] = p * (m21 * a21 + m22 * a22 + R * kn * kn) + q * wc
    P[0, 0], P[1, 1] = a - p * ke * ue, c - p * kn * un  # (H1): P - p P h h' P / (h'Ph + R)
    P[0, 1] = P[1, 0] = b - p * ke * un


@njit(cache=True)
def _violation_m(b: np.ndarray, s: np.ndarray, start: np.ndarray, m: BoatModel) -> float:
    """Constraint violation (metres, >= 0) of boats b (2, 2) with the vehicle at s (2,)
    (the module docstring's step 5)."""
    lim = m.limits
    v = 0.0
    for k in range(2):
        d = np.sqrt((b[k, 0] - s[0]) ** 2 + (b[k, 1] - s[1]) ** 2 + m.dz * m.dz)
        v += max(lim[0] - d, 0.0)
    bx, by = b[1, 0] - b[0, 0], b[1, 1] - b[0, 1]
    length = max(np.sqrt(bx * bx + by * by), 1e-9)
    v += max(abs(length - lim[1]) - lim[2], 0.0)
    across = abs(bx * (s[1] - b[0, 1]) - by * (s[0] - b[0, 0])) / length  # the vehicle's distance to the line
    v += max(lim[3] - across, 0.0)
    if lim[4] >= 0.0:  # a river's banks
        for k in range(2):
            off = m.bank[k] + (b[k, 0] - start[k, 0]) * m.bank[2] + (b[k, 1] - start[k, 1]) * m.bank[3]
            v += max(abs(off) - lim[4], 0.0)
    return v


@njit(cache=True)
def _rollout(vel: np.ndarray, m: BoatModel, K: int, step_m: float, T: float, P_first: np.ndarray) -> float:
    """The cost of one candidate vel (2, blocks, 2) (eq. H2 or H4 plus the penalties);
    P_first (2, 2) gets the expected covariance after its first cycle."""
    P, W = m.P0.copy(), m.W0.copy()
    b, s = m.start.copy(), np.zeros(2)
    J, J0, viol, n, stretch = 0.0, 0.0, 0.0, 0, 0.0
    tr0 = m.P0[0, 0] + m.P0[1, 1] + (m.W0[0, 0] + m.W0[1, 1] if m.with_error else 0.0)
    grow = 2.0 * m.grow_m2 * (2.0 if m.with_error else 1.0)  # the trace of the growth, of P (and W)
    for blk in range(vel.shape[1]):
        for _ in range(K):
            n += 1
            for k in range(2):
                b[k, 0] += step_m * vel[k, blk, 0]
                b[k, 1] += step_m * vel[k, blk, 1]
            s[0], s[1] = m.vehicle_v[0] * n * T, m.vehicle_v[1] * n * T
            if m.rides:
                s[0], s[1] = s[0] + b[0, 0] - m.start[0, 0], s[1] + b[0, 1] - m.start[0, 1]
                stretch += (vel[1, blk, 0] - vel[0, blk, 0]) * step_m  # eq. (BH1)
            P[0, 0] += m.grow_m2
            P[1, 1] += m.grow_m2
            W[0, 0] += m.grow_m2
            W[1, 1] += m.grow_m2
            for k in range(2):  # d1 from B1, then d2 from B2
                re, rn = s[0] - b[k, 0], s[1] - b[k, 1]
                d = np.sqrt(re * re + rn * rn + m.dz * m.dz)
                dt = np.sqrt((re + m.shift[0]) ** 2 + (rn + m.shift[1]) ** 2 + m.dz * m.dz)
                a = 1.0 - packet_loss_probability(dt, m.loss[0], m.loss[1], m.loss[2])
                _range_update(P, W, re / d, rn / d, a * a, m.R_m2[k], m.with_error)
            if n == 1:
                P_first[:, :] = P
            J += P[0, 0] + P[1, 1] + (W[0, 0] + W[1, 1] if m.with_error else 0.0) + stretch * stretch
            J0 += tr0 + grow * n  # the filter's own growth, without (BH1): a plan's cost is in one unit
            viol += _violation_m(b, s, m.start, m)
    return J / max(J0, 1e-300) + PENALTY_PER_M * viol / n


@njit(cache=True)
def boat_plan_costs(v: np.ndarray, m: BoatModel, K: int, step_m: float, T: float, out: np.ndarray) -> None:
    """The costs out (N,) of candidates v (N, 2, blocks, 2) (``_rollout``)."""
    P_first = np.empty((2, 2))
    for i in range(v.shape[0]):
        out[i] = _rollout(v[i], m, K, step_m, T, P_first)


def _frame_of(view: BoatView) -> np.ndarray:
    """Rows: the frame's x and y axes in (east, north): en -> frame is this @ en."""
    x = np.asarray(view.x_axis_en, float)
    return np.stack([x, np.asarray(view.y_axis_en, float)])


@register_policy("horizon")
class BoatHorizonPolicy(RiverEscortPolicy):
    """Receding horizon for the moving network's boats (see the module docstring):
    ``blocks`` velocity pairs held ``cycles_per_block`` cycles each, the cross-entropy
    method's ``n_samples``, ``n_elite``, ``iterations``, ``init_std`` and the pattern
    search's ``refine_iters`` as ``baselines.horizon``."""

    def __init__(
        self,
        config: ScenarioConfig,
        agent_index: int = 0,
        seed: int | Sequence[int] | None = None,
        blocks: int = 4,
        cycles_per_block: int = 3,
        n_samples: int = 64,
        n_elite: int = 8,
        iterations: int = 4,
        init_std: float = 0.5,
        refine_iters: int = 6,
    ) -> None:
        check_search_settings(
            n_samples, n_elite, iterations, init_std, refine_iters, blocks=blocks, cycles_per_block=cycles_per_block
        )
        self.blocks, self.cycles_per_block = int(blocks), int(cycles_per_block)
        self.n_samples, self.n_elite, self.iterations = int(n_samples), int(n_elite), int(iterations)
        self.init_std, self.refine_iters = float(init_std), int(refine_iters)
        super().__init__(config, agent_index, seed)
        c = config
        T = c.ping_interval_s
        self.step_m = c.boat_max_speed_mps * T
        dv2 = c.speed_encoder_noise_mps**2 + (c.survey_speed_mps * np.deg2rad(c.compass_noise_deg)) ** 2
        self.grow_m2 = (c.frame_q_position_m2ps + dv2 * T) * T
        R = ranging_variance_m2(c.range_noise_std_m, True)
        self.R_m2 = np.full(2, R)
        self.depth_below_m = float(np.mean(np.asarray(c.waypoints_m, float)[:, 2]))

    def reset(self, seed: int | Sequence[int] | None = None) -> None:
        super().reset(seed)
        seed = self.seed if self.seed is not None else 0
        if isinstance(seed, Sequence) and not isinstance(seed, str) and len(seed) > 1:
            seed = list(seed)[:-1]  # the episode's part: both boats draw the same candidates
        self.rng = np.random.default_rng(seed)
        self.plan_v: np.ndarray | None = None  # (2, blocks, 2)
        self.P_pred: np.ndarray | None = None  # horizon's own prediction of the filter's covariance
        self.last_cost = float("nan")

    # -- the model of one decision ---------------------------------------------------------
    def limits(self) -> np.ndarray:
        """``BoatModel.limits`` from the config."""
        c, m = self.config, SAFETY_MARGIN_M
        return np.array(
            [
                c.safety_distance_m + m,
                c.baseline_target_m,
                0.5 * c.baseline_tolerance_m,
                c.min_baseline_distance_m + m,
                0.5 * c.river_width_m - self.bank_margin_m if c.mission_frame == "world" else -1.0,
            ]
        )

    def model(self, view: BoatView) -> BoatModel:
        """The decision's ``BoatModel`` from the boat's view (the origin: the tracked vehicle)."""
        c = self.config
        own = np.asarray(view.own_from_tracked_xy_m, float)
        length = float(view.baseline_m)
        b1 = own if view.is_b1 else own - np.array([length, 0.0])
        start = np.stack([b1, b1 + np.array([length, 0.0])])
        rides = c.mission_frame != "world"
        v_trk = np.asarray(view.tracked_velocity_xy_mps, float)
        bank = np.zeros(4)
        if not rides:
            assert view.river_direction_xy is not None and view.bank_offset_m is not None
            t = np.asarray(view.river_direction_xy, float)
            u = np.array([-t[1], t[0]])  # the cross section's right-hand direction (``river_escort``)
            own_off = float(view.bank_offset_m)
            other = start[1] - start[0] if view.is_b1 else start[0] - start[1]
            bank[:] = own_off, own_off, u[0], u[1]
            bank[1 if view.is_b1 else 0] = own_off + float(other @ u)
        if self.P_pred is None:
            self.P_pred = self.R_m2[0] * np.eye(2)
        return BoatModel(
            start=start,
            vehicle_v=v_trk - np.asarray(view.own_velocity_xy_mps, float) if rides else v_trk,
            dz=self.depth_below_m,
            P0=self.P_pred.copy(),
            W0=np.zeros((2, 2)),
            with_error=False,
            shift=np.zeros(2),
            grow_m2=float(self.grow_m2),
            R_m2=self.R_m2,
            loss=np.array([c.packet_loss_near, c.packet_loss_far, c.max_range_m], float),
            limits=self.limits(),
            bank=bank,
            v_now=np.stack([self.transit_xy(view) if rides else np.asarray(view.own_velocity_xy_mps, float)] * 2),
            rides=rides,
        )

    # -- the optimiser ---------------------------------------------------------------------
    def cost(self, v: np.ndarray, model: BoatModel) -> np.ndarray:
        """Costs (N,) of candidates v (N, 2, blocks, 2)."""
        out = np.empty(len(v))
        boat_plan_costs(
            np.ascontiguousarray(v), model, self.cycles_per_block, self.step_m, self.ctx.ping_interval_s, out
        )
        return out

    def transit_xy(self, view: BoatView) -> np.ndarray:
        """With a mission in the frame, the boats' common velocity: ``abeam``'s transit, paced on
        the tracked vehicle (its along-baseline spread is what the plan chooses instead)."""
        return np.array([0.0, AbeamPolicy.velocity_xy(self, view)[1]])

    def project(self, v: np.ndarray, model: BoatModel) -> np.ndarray:
        """Candidates (N, 2, blocks, 2) into the unit disc; with a mission in the frame, into the
        spread plans: both boats at their velocity now, B1 minus and B2 plus the mean of their
        along-baseline parts' difference (the module docstring's last paragraph)."""
        if model.rides:
            delta = 0.5 * (v[:, 1, :, 0] - v[:, 0, :, 0])
            v = np.repeat(
                np.repeat(model.v_now[None, :, None] / self.config.boat_max_speed_mps, len(v), 0), v.shape[2], 2
            )
            v[:, 0, :, 0] -= delta
            v[:, 1, :, 0] += delta
        return _disc(v)

    def optimise(self, model: BoatModel) -> np.ndarray:
        """The cross-entropy method and the pattern search; returns the best (2, blocks, 2)."""
        Hb = self.blocks
        if self.plan_v is None:  # the first plan starts from the boats' motion now
            mean = np.repeat(model.v_now[:, None] / self.config.boat_max_speed_mps, Hb, 1)
        else:
            mean = self.plan_v
        both = np.broadcast_to(_FIXED[:, None, None, :], (len(_FIXED),) + mean.shape)  # both boats together
        best_v, best_cost = cross_entropy(
            lambda v: self.cost(v, model),
            mean,
            self.rng,
            (self.n_samples, self.n_elite, self.iterations, self.init_std),
            np.concatenate([each_alone(mean), both]),
            lambda v: self.project(v, model),
        )
        best_v, best_cost = pattern_search(
            lambda c: self.cost(c, model), best_v, best_cost, self.refine_iters, lambda c, k: self.project(c, model)
        )
        self.last_cost = best_cost
        return best_v

    def decide(self, view: BoatView, model: BoatModel) -> np.ndarray:
        """Plan, keep the plan and the predicted covariance; returns this boat's velocity (m/s)."""
        self.plan_v = self.optimise(model)
        P_first = np.empty((2, 2))
        _rollout(self.plan_v, model, self.cycles_per_block, self.step_m, self.ctx.ping_interval_s, P_first)
        self.P_pred = P_first
        return self.plan_v[0 if view.is_b1 else 1, 0] * self.config.boat_max_speed_mps

    def velocity_xy(self, view: BoatView) -> np.ndarray:
        if not view.has_fix:
            return super().velocity_xy(view)
        return self.decide(view, self.model(view))


@register_policy("oracle")
class BoatOraclePolicy(BoatHorizonPolicy):
    """``horizon`` for the boats given the truth (see the module docstring): a reference,
    not a policy a user could field. Without a snapshot it is ``horizon``."""

    privileged = True

    def reset(self, seed: int | Sequence[int] | None = None) -> None:
        super().reset(seed)
        self._truth: dict | None = None

    def observe_truth(self, snapshot: Any, row: int) -> None:
        """Keep what the snapshot (``coopnav_env.core.contract.Snapshot``) says of batch row ``row``."""
        self._truth = {
            "est": np.asarray(snapshot.survey_est_m[row, 0, :2], float),
            "true": np.asarray(snapshot.survey_true_m[row, 0, :2], float),
            "cov": np.asarray(snapshot.survey_cov_en_m2[row, 0], float),
            "gps": np.asarray(snapshot.beacon_est_m[row, :, :2], float),
        }

    def velocity_xy(self, view: BoatView) -> np.ndarray:
        truth, self._truth = self._truth, None
        if truth is None or not view.has_fix:
            return super().velocity_xy(view)
        model = self.model(view)
        F = _frame_of(view)  # en -> frame axes
        e0 = F @ (truth["est"] - truth["true"])
        start = (F @ (truth["gps"] - truth["est"]).T).T  # the boats from the filter's estimate
        model = model._replace(
            start=np.ascontiguousarray(start),
            P0=F @ truth["cov"] @ F.T,
            W0=np.outer(e0, e0),
            with_error=True,
            shift=-e0,
        )
        return self.decide(view, model)
