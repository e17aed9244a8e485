"""When to ping: transmit schedules for ``channel_mode="decide"`` (``core/channel.py``).

A schedule decides, once per decision slot, whether the beacon transmits; a motion
planner decides where it goes. ``make_policy("<motion>+<schedule>", env)`` combines
any registered motion planner with a schedule (``ScheduledPolicy``): the action is
the planner's (2,) motion plus a third component, +1 (transmit) or -1 (stay
silent); the environment transmits when ``action[2] > 0``. A plain planner name in a
decide-mode scenario gets ``DEFAULT_SCHEDULE``. The schedules:

* ``clock`` (``every=k``, ``offset=0``): transmit in slots k' with k' mod k == offset;
  k = 1 is the papers' fixed clock (with several beacons their pings collide);
* ``tdma``: beacon j transmits in slots k with k mod F == j mod F, F the scenario's
  ``tdma_frame_slots`` if set, else the number of beacons: beacons take turns and
  never collide;
* ``event`` (``threshold_nats``): transmit when the predicted information gain of a
  range from here exceeds the threshold. From the survey covariance P the last reply
  reported, grown by the filter's process noise over the reply's age and one slot
  (P' = P + q (age + T) I, q = ``process_noise_horizontal_m2ps``), a range along the
  horizontal line-of-sight h (the horizontal part of the unit slant vector) with
  variance R (``BeaconContext.range_variance_m2``: the ranging noise and the beacon's
  own position variance; with ``range_model="filter"`` also the sound speed's scale
  error over the slant distance d, as the survey filter) gains
  log det P' - log det P'^+ = log(1 + h' P' h / R) nats (the scalar Kalman update;
  the reward's ``info_gain`` measures the same quantity), summed over survey
  vehicles. Beacons that decide alone can still collide: two beacons near one
  survey vehicle see the same reported covariance and fire together;
* ``event_tdma``: ``event`` inside the beacon's own ``tdma`` slots (no collisions;
  silent when its turn brings too little).

Default thresholds: 0.5 nats, measured on ``sousa_ping`` with ``fim_a+tdma`` where
the predicted gain of the beacon whose turn it is runs 0.1-1.0 nats (mostly
0.4-0.7) [U: a starting point, not tuned].

Slots are counted by the policy itself from its ``reset()`` (one ``act`` per slot).
"""

from __future__ import annotations

import inspect
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from .base import BeaconContext, Policy, check_keywords, register_scheduler

if TYPE_CHECKING:
    from coopnav_env.obs_layout import ObsView
    from coopnav_env.scenarios import ScenarioConfig

DEFAULT_SCHEDULE = "tdma"


class Schedule:
    """Transmit or not, per slot: ``transmit(slot, view) -> bool``."""

    def __init__(self, config: ScenarioConfig, agent_index: int) -> None:
        self.config, self.agent_index = config, agent_index

    def transmit(self, slot: int, view: ObsView) -> bool:
        raise NotImplementedError


class ClockSchedule(Schedule):
    def __init__(self, config: ScenarioConfig, agent_index: int, every: int = 1, offset: int = 0) -> None:
        super().__init__(config, agent_index)
        if int(every) < 1 or not 0 <= int(offset) < int(every):
            raise ValueError(f"clock schedule needs every >= 1 and 0 <= offset < every, got {every}, {offset}")
        self.every, self.offset = int(every), int(offset)

    def transmit(self, slot: int, view: ObsView) -> bool:
        return slot % self.every == self.offset


class TdmaSchedule(Schedule):
    def __init__(self, config: ScenarioConfig, agent_index: int, frame: int = 0) -> None:
        super().__init__(config, agent_index)
        self.frame = int(frame) or config.tdma_frame_slots or config.n_beacons

    def transmit(self, slot: int, view: ObsView) -> bool:
        return slot % self.frame == self.agent_index % self.frame


def predicted_gain_nats(view: ObsView, ctx: BeaconContext) -> float:
    """The information a range from the beacon (``ctx``) at its position now would add
    to the survey filters (nats, summed over survey vehicles): see the module docstring."""
    c = ctx.config
    rel = np.asarray(view.survey_rel_m, float)  # (S, 3) survey minus own
    slant = np.maximum(np.linalg.norm(rel, axis=-1), 1e-6)
    h = rel[:, :2] / slant[:, None]
    grow = c.process_noise_horizontal_m2ps * (np.asarray(view.reply_age_s, float) + c.ping_interval_s)
    P = np.asarray(view.cov_m2, float) + grow[:, None, None] * np.eye(2)
    R = ctx.range_variance_m2(slant, float(view.own_std_m) ** 2)
    return float(np.log1p(np.einsum("si,sij,sj->s", h, P, h) / R).sum())


class EventSchedule(Schedule):
    def __init__(
        self, config: ScenarioConfig, agent_index: int, threshold_nats: float = 0.5, range_model: str = "constant"
    ) -> None:
        super().__init__(config, agent_index)
        if not threshold_nats >= 0:
            raise ValueError(f"threshold_nats must be >= 0, got {threshold_nats!r}")
        self.threshold_nats = float(threshold_nats)
        self.ctx = BeaconContext.from_config(config, agent_index).with_range_model(range_model)

    def transmit(self, slot: int, view: ObsView) -> bool:
        return predicted_gain_nats(view, self.ctx) > self.threshold_nats


class EventTdmaSchedule(EventSchedule):
    def __init__(
        self,
        config: ScenarioConfig,
        agent_index: int,
        threshold_nats: float = 0.5,
        frame: int = 0,
        range_model: str = "constant",
    ) -> None:
        super().__init__(config, agent_index, threshold_nats, range_model)
        self.turns = TdmaSchedule(config, agent_index, frame)

    def transmit(self, slot: int, view: ObsView) -> bool:
        return self.turns.transmit(slot, view) and super().transmit(slot, view)


SCHEDULES = {"clock": ClockSchedule, "tdma": TdmaSchedule, "event": EventSchedule, "event_tdma": EventTdmaSchedule}


def list_schedules() -> list:
    return sorted(SCHEDULES)


class ScheduledPolicy(Policy):
    """A motion planner plus a transmit schedule: the action (3,) is the planner's
    motion and +1 (transmit) or -1 (silent)."""

    def __init__(self, motion: Policy, schedule: Schedule) -> None:
        self.motion, self.schedule = motion, schedule
        self.name = f"{motion.name}+{type(schedule).__name__.removesuffix('Schedule').lower()}"
        super().__init__(motion.config, motion.ctx.agent_index, motion.seed)

    @property
    def privileged(self) -> bool:
        """A reference motion planner (``oracle``) stays one under a schedule."""
        return bool(getattr(self.motion, "privileged", False))

    def observe_truth(self, snapshot: Any, row: int) -> None:
        """Pass the evaluation's truth to the motion planner (``oracle``)."""
        self.motion.observe_truth(snapshot, row)  # type: ignore[attr-defined]  # privileged planners have it

    def reset(self, seed: int | Sequence[int] | None = None) -> None:
        super().reset(seed)
        self.slot = 0
        self.last_transmit: bool | None = None
        if hasattr(self, "motion"):
            self.motion.reset(seed)

    def act(self, obs: ArrayLike) -> np.ndarray:
        move = np.asarray(self.motion.act(obs), dtype=np.float32)
        self.last_waypoint = self.motion.last_waypoint
        self.last_transmit = bool(self.schedule.transmit(self.slot, self.decode(obs)))
        self.slot += 1
        self.t_s += self.ctx.ping_interval_s
        return np.append(move, np.float32(1.0 if self.last_transmit else -1.0)).astype(np.float32)


@register_scheduler
def make_scheduled(
    motion_cls: type[Policy],
    schedule_name: str,
    config: ScenarioConfig,
    agent_index: int,
    seed: int | Sequence[int] | None = None,
    **kwargs: Any,
) -> ScheduledPolicy:
    """``motion_cls`` with the schedule ``schedule_name`` ("" or None: ``DEFAULT_SCHEDULE``);
    ``kwargs`` go to the schedule and to the planner that take them (every, offset, frame,
    threshold_nats to the schedule; ``range_model`` to both the planner and an event
    schedule, which weighs a range as the planner does); one neither takes is refused."""
    schedule_name = schedule_name or DEFAULT_SCHEDULE
    if config.channel_mode != "decide":
        raise ValueError(
            f"transmit schedules need channel_mode='decide'; {config.name} pings on the fixed clock "
            f"(use the planner {motion_cls.name!r} alone)"
        )
    if schedule_name not in SCHEDULES:
        raise ValueError(f"unknown schedule {schedule_name!r}; valid schedules: {', '.join(list_schedules())}")
    schedule_cls = SCHEDULES[schedule_name]
    sched_params = list(inspect.signature(schedule_cls).parameters)[2:]  # past (config, agent_index)
    motion_params = list(inspect.signature(motion_cls).parameters)[3:]  # past (config, agent_index, seed)
    settings = list(dict.fromkeys([*motion_params, *sched_params]))  # range_model may be in both
    check_keywords(f"{motion_cls.name}+{schedule_name}", kwargs, settings)
    sched_kw = {k: v for k, v in kwargs.items() if k in sched_params}
    motion_kw = {k: v for k, v in kwargs.items() if k in motion_params}  # range_model: to both that take it
    motion = motion_cls(config, agent_index=agent_index, seed=seed, **motion_kw)
    return ScheduledPolicy(motion, schedule_cls(config, agent_index, **sched_kw))
