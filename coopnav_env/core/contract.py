"""The simulator contract: what every batched simulator returns and what the views,
the trainers and the evaluation may read of it.

Two simulators implement it: ``core.sim.Simulator`` (survey vehicles and beacons in a
fixed navigation frame: Gao & Chitre, Sousa et al., the MLS school) and
``core.moving_network.MovingNetworkSimulator`` (one AUV in the frame of two boats:
Matos & Cruz). ``core.make_simulator(config, batch_size)`` picks one by
``config.network``; ``tests/test_contract.py`` runs every scenario through
``BatchedSimulator`` below.

Shapes: B environments (the batch), N beacons (the agents), S survey vehicles.

* ``step(actions (B, N, 2)) -> StepResult``: observations, the reward and its named
  terms, the episode ends, per-survey-vehicle infos, and the survey filters'
  horizontal covariance;
* ``reset(seeds, mask=None) -> obs``; ``reset_info()``: the infos of the state just
  reset, with the same keys as a step's (counts zero), so that views can return
  the same info keys from ``reset()`` as from ``step()``;
* ``snapshot() -> Snapshot``: positions (true, estimated, dead-reckoned), the
  covariance and the planned path in east/north, for figures and the evaluation;
* ``observe()``, ``global_state()``: what the agents see and what a centralized
  critic may see.

Nothing outside ``core/`` reads a simulator's ``state`` arrays except through these.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike

from ..scenarios.base import ScenarioConfig

if TYPE_CHECKING:
    from .kernel_records import SurveyParams  # kernel_records imports only state: no cycle


@dataclass
class StepResult:
    """Arrays of one batched step.

    * ``obs`` (B, N, obs_dim) float32: each beacon's observation after the step;
    * ``reward`` (B, N): ``core.reward.weighted_reward(terms, config)``;
    * ``terms``: reward term name -> (B, N) array, unweighted (``core.reward``
      lists them: ``info_gain`` in nats, the others 0/1 indicators);
    * ``terminated``, ``truncated`` (B,) bool;
    * ``info``: name -> (B, S, ...) array per survey vehicle (the simulator's
      ``info_keys``): scalars (B, S), and the vectors ``survey_error_en_m`` (B, S, 2),
      the estimate's true horizontal error, and ``survey_cov_en_m2`` (B, S, 2, 2), the
      filter's horizontal covariance (east/north; the moving network: its frame's x, y);
    * ``beacon_info``: name -> (B, N) array per beacon: ``beacon_error_m``, its own
      navigation's true horizontal error.
    """

    obs: np.ndarray
    reward: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    info: dict
    terms: dict
    beacon_info: dict


@dataclass
class Snapshot:
    """Where everything is, in east/north/depth metres, for every environment of the
    batch (figures, the evaluation's distances and ellipses).

    * ``t_s`` (B,): simulated time;
    * ``survey_true_m``, ``survey_est_m``, ``survey_dr_m`` (B, S, 3): true position,
      the filter's estimate and dead reckoning alone (the moving network maps its
      frame estimate to the world through the true frame, as the logged boat
      positions allow after the mission);
    * ``survey_cov_en_m2`` (B, S, 2, 2): horizontal covariance (east/north);
    * ``beacon_true_m``, ``beacon_est_m`` (B, N, 3): the beacons' true positions and
      their own navigation's estimate;
    * ``waypoints_m`` (B, S, W, 3), ``n_waypoints`` (B, S): each survey vehicle's
      planned path placed in the world (the moving network's mission lives in its
      frame: placed by the current true frame).
    """

    t_s: np.ndarray
    survey_true_m: np.ndarray
    survey_est_m: np.ndarray
    survey_dr_m: np.ndarray
    survey_cov_en_m2: np.ndarray
    beacon_true_m: np.ndarray
    beacon_est_m: np.ndarray
    waypoints_m: np.ndarray
    n_waypoints: np.ndarray


@runtime_checkable
class BatchedSimulator(Protocol):
    """What every batched simulator provides (see the module docstring)."""

    config: ScenarioConfig
    batch_size: int
    S: int  # survey vehicles
    N: int  # beacons (agents)
    state: Any  # the batch's state arrays (None before the first reset)
    obs_dim: int
    state_dim: int
    info_keys: tuple  # the keys of StepResult.info, in order
    beacon_info_keys: tuple  # the keys of StepResult.beacon_info
    reward_terms: tuple  # the keys of StepResult.terms, in order
    reward_weights: dict  # term -> the scenario's weight (core.reward.term_weights)
    variants: list  # the (survey_path, depth_m) choices of the domain randomization

    def reset(self, seeds: ArrayLike, mask: ArrayLike | None = None) -> np.ndarray: ...

    def reset_info(self) -> dict: ...

    def reset_beacon_info(self) -> dict: ...

    def step(self, actions: np.ndarray) -> StepResult: ...

    def observe(self) -> np.ndarray: ...

    def global_state(self) -> np.ndarray: ...

    def snapshot(self) -> Snapshot: ...

    def episode_variants(self) -> np.ndarray: ...


class SensorHost(Protocol):
    """What the survey network's acoustic sensors (``core.measurements``) and shared channel
    (``core.channel``) read of their simulator, ``core.sim.Simulator``: declared here because
    those modules must not import ``core.sim`` (it imports them). Read-only properties, so
    that a simulator's narrower attribute types (``state: SimState | None``) conform."""

    @property
    def config(self) -> ScenarioConfig: ...

    @property
    def batch_size(self) -> int: ...

    @property
    def N(self) -> int: ...

    @property
    def S(self) -> int: ...

    @property
    def state(self) -> Any: ...  # SimState after the first reset, else None

    @property
    def gate(self) -> float: ...  # the chi-square gate of every acoustic update

    @property
    def sends_current(self) -> np.ndarray: ...  # (N,) bool: beacons that send their current estimate

    @property
    def params(self) -> SurveyParams: ...  # the kernels' constants


class BatchSimulator:
    """What every batched simulator shares: ``reset`` over the batch or a masked part of
    it, and the initial infos. Subclasses set ``batch_size`` and ``state`` and implement
    ``_initial_state(seeds)``, ``observe()`` and ``_state_info()`` (the infos that
    follow from the state alone: errors and the like)."""

    if TYPE_CHECKING:  # what the subclasses set and implement
        batch_size: int
        S: int
        info_keys: tuple
        state: Any

        def _initial_state(self, seeds: np.ndarray) -> Any: ...

        def observe(self) -> np.ndarray: ...

        def _state_info(self) -> dict: ...

        def _beacon_info(self) -> dict: ...

    def reset(self, seeds: ArrayLike, mask: ArrayLike | None = None) -> np.ndarray:
        """(Re)start the environments in ``mask`` (all if None) with integer ``seeds``
        (one per environment reset). Returns the observations of the whole batch."""
        seeds = np.atleast_1d(np.asarray(seeds, dtype=np.int64))
        if mask is None:
            if len(seeds) != self.batch_size:
                raise ValueError(f"need {self.batch_size} seeds, got {len(seeds)}")
            self.state = self._initial_state(seeds)
        else:
            mask = np.asarray(mask, dtype=bool)
            if int(mask.sum()) != len(seeds):
                raise ValueError("one seed per environment to reset")
            if mask.any():
                self.state.assign(mask, self._initial_state(seeds))
        return self.observe()

    def reset_info(self) -> dict:
        """The infos of the current state with the step's keys: what follows from the
        state (errors, covariance) as a step would report it, every count of this
        cycle's events (ranges fused, rejected, lost) zero. Call after ``reset``."""
        if self.state is None:
            raise RuntimeError("reset_info() before reset()")
        shape = (self.batch_size, self.S)
        info = {"range_ok": np.zeros(shape, dtype=bool)}
        for key in ("ranges_fused", "outliers_rejected", "nan_rejected", "packets_lost", "filter_restarts"):
            info[key] = np.zeros(shape, dtype=np.int64)
        info.update(self._state_info())
        return {key: info[key] for key in self.info_keys}

    def reset_beacon_info(self) -> dict:
        """``StepResult.beacon_info`` of the current state (after ``reset``)."""
        if self.state is None:
            raise RuntimeError("reset_beacon_info() before reset()")
        return self._beacon_info()

    def episode_variants(self) -> np.ndarray:
        """(B,) index into ``variants`` of each environment's current episode."""
        if self.state is None:
            raise RuntimeError("episode_variants() before reset()")
        return self.state.ep_variant
