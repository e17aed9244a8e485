"""Gao & Chitre (2010) sec. II-C: range along the major axis of the error ellipse.

"If the beacon AUV can move such that the next range measurement occurs along the
direction of the major axis of the error ellipse, the position error of the survey
AUV can be minimized." The planner predicts the survey vehicle's position and
covariance at the next ping (constant velocity from the estimates it sent; the
reported covariance plus the scenario's process noise for the elapsed time) and
picks the point of its reaching set that maximizes the expected information of the
next range,

    P(arrive | distance) * log(1 + h^T P h / R),

h the horizontal part of the 3-D unit range direction, R the range variance plus
the beacon's own position variance. h^T P h is largest along the major axis, so
the range falls along it; the slant factor and the arrival probability set how far
away (the acoustic-range concern of the paper), and soft constraints keep the
safety distance and the geofence (the paper's other two criteria).
"""

from __future__ import annotations

import numpy as np

from coopnav_env.core.information import maximize_on_disc

from .base import PENALTY_PER_M, BeaconContext, TrackingPolicy, register_policy, slant_distance


def ellipse_waypoint(ctx: BeaconContext, own_en, survey_en, depth_below, P, range_var_m2, **grid):
    """The point of the reaching disc whose range to the predicted survey position(s)
    survey_en (S, 2), depth_below (S,), covariance P (S, 2, 2) informs most.
    Returns (waypoint (2,), expected information at it)."""
    survey_en = np.atleast_2d(survey_en)
    depth_below = np.atleast_1d(np.asarray(depth_below, float))
    P = np.asarray(P, float).reshape(-1, 2, 2)

    def score(pts):
        rel = pts[..., :, None, :] - survey_en  # (M, S, 2) survey -> beacon
        d3 = slant_distance(pts, survey_en, depth_below)
        h = rel / np.maximum(d3, 1e-9)[..., None]
        var_along = np.einsum("...si,sij,...sj->...s", h, P, h)
        gain = ctx.delivery_probability(d3) * np.log1p(var_along / range_var_m2)
        return gain.sum(-1) - PENALTY_PER_M * ctx.violation_m(pts, survey_en, depth_below)

    return maximize_on_disc(score, np.asarray(own_en, float), ctx.reach_m, **grid)


@register_policy("ellipse")
class EllipsePolicy(TrackingPolicy):
    """Gao & Chitre: the next range along the major axis of the predicted error ellipse."""

    def plan(self, view):
        c, T = self.config, self.ctx.ping_interval_s
        self.tracker.update(self.t_s, view)
        en, dz = self.tracker.predict(view, T)
        grow = c.process_noise_horizontal_m2ps * (view.reply_age_s + T)
        P = view.cov_m2 + grow[:, None, None] * np.eye(2)
        R = c.range_noise_std_m ** 2 + float(view.own_std_m) ** 2
        wp, self.last_metric = ellipse_waypoint(self.ctx, view.own_en_m, en, dz, P, R)
        return wp
