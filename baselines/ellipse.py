"""Gao & Chitre (2010) sec. II-C: range along the major axis of the error ellipse.

"If the beacon AUV can move such that the next range measurement occurs along the
direction of the major axis of the error ellipse, the position error of the survey
AUV can be minimized." The planner predicts the survey vehicle's position and
covariance at the next ping and picks the point of its reaching set that
maximizes the expected information of the next range,

    P(arrive | distance) * log(1 + h^T P h / R),

h the horizontal part of the 3-D unit range direction, R the range variance plus
the beacon's own position variance. h^T P h is largest along the major axis, so
the range falls along it; the slant factor and the arrival probability set how far
away (the acoustic-range concern of the paper), and soft constraints keep the
safety distance and the geofence (the paper's other two criteria).

The prediction. The beacon "plans its path based on the knowledge of the survey
path" (Gao & Chitre, sec. I and II-C): the observation carries the next
``observed_waypoints`` planned waypoints of each survey vehicle, so its position
at the next ping is its last reported estimate moved along that plan, turning at
the waypoints, by path speed x (reply age + ping interval)
(``SurveyTracker.predict_along_path``, eqs. B1-B3 of
``base.advance_along_waypoints``; the speed is eq. T3 of ``SurveyTracker``). A
vehicle at speed v that reaches its next waypoint after d metres is predicted
v T - d along the following leg (eq. B1), where a constant velocity puts it
v T - d past the waypoint on the old leg's line: sqrt(2) (v T - d) off at a
right-angle lawnmower turn (~20 m with 20 s pings). Without
observed waypoints the prediction is the constant velocity fitted to the
estimates it sent (eq. T1); ``predictor="chord"`` forces that (the planner
before the plan was used). The covariance is the reported one plus the
scenario's process noise for the elapsed time (Gao & Chitre eq. 6,
P_{k+1|k} = P_k + Q_k).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from coopnav_env.core.information import maximize_on_disc

from .base import PENALTY_PER_M, BeaconContext, TrackingPolicy, register_policy, slant_distance

if TYPE_CHECKING:
    from coopnav_env.obs_layout import ObsView
    from coopnav_env.scenarios import ScenarioConfig


def ellipse_waypoint(
    ctx: BeaconContext,
    own_en: ArrayLike,
    survey_en: np.ndarray,
    depth_below: ArrayLike,
    P: np.ndarray,
    beacon_var_m2: float,
    **grid: int,
) -> tuple[np.ndarray, np.ndarray]:
    """The point of the reaching disc whose range to the predicted survey position(s)
    survey_en (S, 2), depth_below (S,), covariance P (S, 2, 2) informs most: the most
    expected information log(1 + h'Ph / R), R the variance of a range over the slant
    distance from a beacon of position variance ``beacon_var_m2``
    (``BeaconContext.range_variance_m2``: the same at every distance by default, the survey
    filter's R(d) with ``range_model="filter"``). Returns (waypoint (2,), expected information at it)."""
    survey_en = np.atleast_2d(survey_en)
    depth_below = np.atleast_1d(np.asarray(depth_below, float))
    P = np.asarray(P, float).reshape(-1, 2, 2)

    def score(pts):
        rel = pts[..., :, None, :] - survey_en  # (M, S, 2) survey -> beacon
        d3 = slant_distance(pts, survey_en, depth_below)
        h = rel / np.maximum(d3, 1e-9)[..., None]
        var_along = np.einsum("...si,sij,...sj->...s", h, P, h)
        gain = ctx.delivery_probability(d3) * np.log1p(var_along / ctx.range_variance_m2(d3, beacon_var_m2))
        return gain.sum(-1) - PENALTY_PER_M * ctx.violation_m(pts, survey_en, depth_below)

    return maximize_on_disc(score, np.asarray(own_en, float), ctx.reach_m, **grid)


@register_policy("ellipse")
class EllipsePolicy(TrackingPolicy):
    """Gao & Chitre: the next range along the major axis of the predicted error ellipse.

    predictor: ``"path"`` (default) predicts the survey vehicle along its observed
    planned waypoints, ``"chord"`` with the constant velocity of its last replies.
    range_model: ``"constant"`` (default: one R at every distance, as the paper) or
    ``"filter"`` (the survey filter's R(d), ``BeaconContext.range_variance_m2``).
    """

    PREDICTORS = ("path", "chord")

    def __init__(
        self,
        config: ScenarioConfig,
        agent_index: int = 0,
        seed: int | Sequence[int] | None = None,
        predictor: str = "path",
        range_model: str = "constant",
    ) -> None:
        if predictor not in self.PREDICTORS:
            raise ValueError(f"ellipse predictor must be one of {self.PREDICTORS}, got {predictor!r}")
        self.predictor = predictor
        super().__init__(config, agent_index, seed)
        self.ctx = self.ctx.with_range_model(range_model)

    def predict(self, view: ObsView, ahead_s: float) -> tuple[np.ndarray, np.ndarray]:
        """The survey vehicles' (east, north) (S, 2) and depth below (S,) ``ahead_s`` after now."""
        if self.predictor == "path":
            return self.tracker.predict_along_path(view, ahead_s)
        return self.tracker.predict(view, ahead_s, "chord")

    def plan(self, view: ObsView) -> np.ndarray:
        c, T = self.config, self.ctx.ping_interval_s
        self.tracker.update(self.t_s, view)
        en, dz = self.predict(view, T)
        grow = c.process_noise_horizontal_m2ps * (view.reply_age_s + T)
        P = view.cov_m2 + grow[:, None, None] * np.eye(2)
        wp, self.last_metric = ellipse_waypoint(self.ctx, view.own_en_m, en, dz, P, float(view.own_std_m) ** 2)
        return wp
