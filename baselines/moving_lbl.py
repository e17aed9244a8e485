"""Scripted boats for the moving LBL network (Matos & Cruz).

``perpendicular``: both boats at constant speed perpendicular to the baseline, as
in the paper's simulation (section VIII); the speed and its sign are the
scenario's ``boat_transit_speed_mps`` (positive: towards the vehicle's side).

``abeam``: the same transit, paced so that the vehicle's last heard position stays
abeam of the baseline at the mission's planned distance (the boats slow down when
the vehicle falls behind and hurry when it gains), while the two boats spread or
close along the baseline to hold ``baseline_target_m``. It reads only the boat's
observation: the other boat's GPS position (radio) and the external tracking.
"""

from __future__ import annotations

import numpy as np

from coopnav_env.obs_layout import decode_boat

from .base import Policy, register_policy, waypoint_to_action


@register_policy("perpendicular")
class PerpendicularPolicy(Policy):
    """Constant speed perpendicular to the baseline (Matos & Cruz sec. VIII)."""

    networks = ("moving_lbl",)

    def velocity_xy(self, view) -> np.ndarray:
        """Ground velocity (m/s) in the boats' frame: (along B1 -> B2, across)."""
        return np.array([0.0, self.config.boat_transit_speed_mps])

    def act(self, obs):
        view = decode_boat(obs, self.config)
        self.t_s += self.ctx.ping_interval_s
        v = self.velocity_xy(view)
        if self.config.action_mode == "frame_velocity":
            return np.clip(v / self.ctx.max_speed_mps, -1.0, 1.0).astype(np.float32)
        v_en = v[0] * view.x_axis_en + v[1] * view.y_axis_en
        return waypoint_to_action(self.ctx, np.zeros(2), v_en * self.ctx.ping_interval_s)


@register_policy("abeam")
class AbeamPolicy(PerpendicularPolicy):
    """Transit paced on the tracked vehicle, baseline length held (see the module docstring)."""

    def __init__(self, config, agent_index=0, seed=None, pace_gain_per_s=0.02, baseline_gain_per_s=0.05):
        if not (pace_gain_per_s >= 0 and baseline_gain_per_s >= 0):
            raise ValueError("gains must be >= 0")
        self.pace_gain_per_s, self.baseline_gain_per_s = float(pace_gain_per_s), float(baseline_gain_per_s)
        super().__init__(config, agent_index, seed)
        wp = np.asarray(config.waypoints_m, dtype=float)
        self.planned_y_m = float(wp[:, 1].mean())

    def velocity_xy(self, view):
        c = self.config
        along_y = c.boat_transit_speed_mps
        if view.has_fix:  # a vehicle further from the baseline than planned: move towards it
            along_y = along_y + self.pace_gain_per_s * (float(view.tracked_xy_m[1]) - self.planned_y_m)
        spread = 0.5 * self.baseline_gain_per_s * (c.baseline_target_m - float(view.baseline_m))
        sign = -1.0 if view.is_b1 else 1.0  # B1 moves along -x to lengthen the baseline, B2 along +x
        v = np.array([sign * spread, along_y])
        speed = float(np.linalg.norm(v))
        return v if speed <= c.boat_max_speed_mps else v * c.boat_max_speed_mps / speed
