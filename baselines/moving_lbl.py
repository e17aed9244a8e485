"""Scripted boats for the moving LBL network (Matos & Cruz).

``perpendicular``: both boats at constant speed perpendicular to the baseline, as
in the paper's simulation (section VIII); the speed and its sign are the
scenario's ``boat_transit_speed_mps`` (positive: towards the vehicle's side).

``abeam``: the same transit, paced so that the vehicle's last heard position stays
abeam of the baseline at the mission's planned distance (the boats slow down when
the vehicle falls behind and hurry when it gains), while the two boats spread or
close along the baseline to hold ``baseline_target_m``. It reads only the boat's
observation: the other boat's GPS position (radio) and the external tracking.

``river_escort`` (a mission in the world, ``matos_river``): each boat holds its end
of a cross section of the river half a baseline ahead of the tracked vehicle
(``core.moving_network.RIVER_LEAD_BASELINES``), B1 on the left and B2 on the right
of the mission direction, ``baseline_target_m`` apart and inside the banks: a
feed-forward of the tracked vehicle's velocity plus a proportional pull onto that
point. The vehicle then stays at the paper's geometry (50 m from the middle of a
100 m baseline) all the way down the river. On a mission in the frame it is
``abeam``.

With a mission in the world ``abeam`` paces the vehicle at half a baseline (where the
boats start) instead of the mean y of the waypoints, which are then east/north.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from coopnav_env.obs_layout import decode_boat
from coopnav_env.views import check_observation

from .base import Policy, register_policy, waypoint_to_action

if TYPE_CHECKING:
    from coopnav_env.obs_layout import BoatView
    from coopnav_env.scenarios import ScenarioConfig


def _speed_limited(v, max_speed_mps):
    """Velocity v (m/s) scaled down to max_speed_mps if faster."""
    speed = float(np.linalg.norm(v))
    return v if speed <= max_speed_mps else v * max_speed_mps / speed


@register_policy("perpendicular")
class PerpendicularPolicy(Policy):
    """Constant speed perpendicular to the baseline (Matos & Cruz sec. VIII)."""

    networks = ("moving_lbl",)

    def velocity_xy(self, view: BoatView) -> np.ndarray:
        """Ground velocity (m/s) in the boats' frame: (along B1 -> B2, across)."""
        return np.array([0.0, self.config.boat_transit_speed_mps])

    def act(self, obs: ArrayLike) -> np.ndarray:
        view = decode_boat(check_observation(obs, self.obs_dim), self.config)
        self.t_s += self.ctx.ping_interval_s
        v = self.velocity_xy(view)
        if self.config.action_mode == "frame_velocity":
            return np.clip(v / self.ctx.max_speed_mps, -1.0, 1.0).astype(np.float32)
        v_en = v[0] * view.x_axis_en + v[1] * view.y_axis_en
        return waypoint_to_action(self.ctx, np.zeros(2), v_en * self.ctx.ping_interval_s)


@register_policy("abeam")
class AbeamPolicy(PerpendicularPolicy):
    """Transit paced on the tracked vehicle, baseline length held (see the module docstring)."""

    def __init__(
        self,
        config: ScenarioConfig,
        agent_index: int = 0,
        seed: int | Sequence[int] | None = None,
        pace_gain_per_s: float = 0.02,
        baseline_gain_per_s: float = 0.05,
    ) -> None:
        if not (pace_gain_per_s >= 0 and baseline_gain_per_s >= 0):
            raise ValueError("gains must be >= 0")
        self.pace_gain_per_s, self.baseline_gain_per_s = float(pace_gain_per_s), float(baseline_gain_per_s)
        super().__init__(config, agent_index, seed)
        wp = np.asarray(config.waypoints_m, dtype=float)
        if config.mission_frame == "world":
            from coopnav_env.core.moving_network import RIVER_LEAD_BASELINES

            self.planned_y_m = RIVER_LEAD_BASELINES * config.baseline_target_m
        else:
            self.planned_y_m = float(wp[:, 1].mean())

    def velocity_xy(self, view: BoatView) -> np.ndarray:
        c = self.config
        along_y = c.boat_transit_speed_mps
        if view.has_fix:  # a vehicle further from the baseline than planned: move towards it
            along_y = along_y + self.pace_gain_per_s * (float(view.tracked_xy_m[1]) - self.planned_y_m)
        spread = 0.5 * self.baseline_gain_per_s * (c.baseline_target_m - float(view.baseline_m))
        sign = -1.0 if view.is_b1 else 1.0  # B1 moves along -x to lengthen the baseline, B2 along +x
        v = np.array([sign * spread, along_y])
        return _speed_limited(v, c.boat_max_speed_mps)


@register_policy("river_escort")
class RiverEscortPolicy(AbeamPolicy):
    """Each boat at its end of a river cross section ahead of the tracked vehicle (see the
    module docstring). Gains [U]: ``gain_per_s`` pulls the boat onto its point (time
    constant 1 / gain), ``bank_margin_m`` keeps its target that far inside the bank when
    the river is narrower than the baseline allows."""

    def __init__(
        self,
        config: ScenarioConfig,
        agent_index: int = 0,
        seed: int | Sequence[int] | None = None,
        gain_per_s: float = 0.1,
        bank_margin_m: float = 10.0,
        **kwargs: Any,
    ) -> None:
        if not (gain_per_s > 0 and bank_margin_m >= 0):
            raise ValueError("gain_per_s must be > 0 and bank_margin_m >= 0")
        self.gain_per_s, self.bank_margin_m = float(gain_per_s), float(bank_margin_m)
        super().__init__(config, agent_index, seed, **kwargs)

    def velocity_xy(self, view: BoatView) -> np.ndarray:
        c = self.config
        if c.mission_frame != "world":
            return super().velocity_xy(view)
        # in the GPS frame: the mission's direction t ahead of the vehicle, and the cross
        # section's right-hand direction u = t turned 90 degrees clockwise, in frame
        # components (t_x, t_y) -> (-t_y, t_x) (y is clockwise from x, see obs_layout.BoatView)
        t = np.asarray(view.river_direction_xy, dtype=float)
        u = np.array([-t[1], t[0]])
        side = -1.0 if view.is_b1 else 1.0
        half = min(0.5 * c.baseline_target_m, max(0.5 * c.river_width_m - self.bank_margin_m, 0.0))
        to_target = np.asarray(view.river_ahead_from_own_xy_m, dtype=float) + side * half * u
        v = np.asarray(view.tracked_velocity_xy_mps, dtype=float) + self.gain_per_s * to_target
        return _speed_limited(v, c.boat_max_speed_mps)
