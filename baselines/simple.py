"""Floors: ``static`` (stay put), ``circle`` (orbit the survey vehicle's estimate,
as many field crews do) and ``random`` (uniform random actions)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from .base import Policy, TrackingPolicy, register_policy

if TYPE_CHECKING:
    from coopnav_env.obs_layout import ObsView
    from coopnav_env.scenarios import ScenarioConfig


@register_policy("static")
class StaticPolicy(Policy):
    """Hold position: the zero action (in heading/speed mode, speed 0)."""

    networks = ("survey_beacons", "moving_lbl")

    def act(self, obs: ArrayLike) -> np.ndarray:
        self.t_s += self.ctx.ping_interval_s
        if self.config.action_mode == "heading_speed":
            return np.array([0.0, -1.0], dtype=np.float32)
        return np.zeros(2, dtype=np.float32)


@register_policy("circle")
class CirclePolicy(TrackingPolicy):
    """Orbit the survey vehicle's predicted position anticlockwise at ``radius_m``,
    advancing by up to 90 % of the reaching set per ping (at most 60 degrees)."""

    def __init__(
        self,
        config: ScenarioConfig,
        agent_index: int = 0,
        seed: int | Sequence[int] | None = None,
        radius_m: float = 40.0,
    ) -> None:
        if not radius_m > 0:
            raise ValueError(f"radius_m must be > 0, got {radius_m!r}")
        self.radius_m = float(radius_m)
        super().__init__(config, agent_index, seed)

    def plan(self, view: ObsView) -> np.ndarray:
        self.tracker.update(self.t_s, view)
        en, _ = self.tracker.predict(view, self.ctx.ping_interval_s)
        centre = en[0] if len(en) == 1 else en.mean(0)
        rel = view.own_en_m - centre
        angle = float(np.arctan2(rel[1], rel[0]))  # from east, anticlockwise
        step = min(0.9 * self.ctx.reach_m / self.radius_m, np.pi / 3)
        a = angle + step
        return centre + self.radius_m * np.array([np.cos(a), np.sin(a)])


@register_policy("random")
class RandomPolicy(Policy):
    """Uniform random actions in [-1, 1]^2 from a generator seeded by ``seed``."""

    networks = ("survey_beacons", "moving_lbl")

    def reset(self, seed: int | Sequence[int] | None = None) -> None:
        super().reset(seed)
        self.rng = np.random.default_rng(self.seed)

    def act(self, obs: ArrayLike) -> np.ndarray:
        self.t_s += self.ctx.ping_interval_s
        return self.rng.uniform(-1.0, 1.0, 2).astype(np.float32)
