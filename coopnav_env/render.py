"""Drawing an episode: recorded snapshots in, a matplotlib figure out.

Rendering keeps the simulator's snapshot after each step (``EpisodeRecorder``,
``core.contract.Snapshot``), so the simulator never knows it is being drawn. matplotlib is imported here only.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .core.information import error_ellipse

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from .core.contract import Snapshot
    from .scenarios import ScenarioConfig


class EpisodeRecorder:
    """Snapshots of one environment of the batch: true, dead-reckoned and EKF tracks,
    horizontal covariances and beacon positions, one per step."""

    t_s: list[float]
    true: list[np.ndarray]
    dr: list[np.ndarray]
    est: list[np.ndarray]
    P: list[np.ndarray]
    beacons: list[np.ndarray]

    def __init__(self, config: ScenarioConfig) -> None:
        self.config = config
        self.t_s, self.true, self.dr, self.est, self.P, self.beacons = [], [], [], [], [], []

    def record(self, snapshot: Snapshot, row: int = 0) -> None:
        """Keep row ``row`` of a ``core.contract.Snapshot`` (``sim.snapshot()``)."""
        self.t_s.append(float(snapshot.t_s[row]))
        self.true.append(snapshot.survey_true_m[row].copy())
        self.dr.append(snapshot.survey_dr_m[row].copy())
        self.est.append(snapshot.survey_est_m[row].copy())
        self.P.append(snapshot.survey_cov_en_m2[row].copy())
        self.beacons.append(snapshot.beacon_true_m[row].copy())
        self.waypoints = snapshot.waypoints_m[row]  # planned path in (east, north)
        self.n_waypoints = snapshot.n_waypoints[row]

    def arrays(self) -> tuple[np.ndarray, ...]:
        """(t (T,), true (T,S,3), dr, est, P (T,S,2,2), beacons (T,N,3))."""
        return (
            np.array(self.t_s),
            np.array(self.true),
            np.array(self.dr),
            np.array(self.est),
            np.array(self.P),
            np.array(self.beacons),
        )


def draw_episode(recorder: EpisodeRecorder, config: ScenarioConfig, fig: Figure | None = None) -> Figure:
    """Plan view: planned path, true / dead-reckoned / EKF tracks, beacon paths, and
    the current 2-sigma error ellipse of every survey vehicle."""
    from matplotlib.figure import Figure
    from matplotlib.patches import Ellipse

    t, true, dr, est, P, beacons = recorder.arrays()
    if fig is None:
        fig = Figure(figsize=(6.4, 5.6), dpi=100)
    fig.clear()
    ax = fig.add_subplot(1, 1, 1)
    S = true.shape[1]
    for s in range(S):
        wp = recorder.waypoints[s, : recorder.n_waypoints[s]]
        ax.plot(wp[:, 0], wp[:, 1], color="0.75", lw=1, ls=":", label="planned path" if s == 0 else None)
        ax.plot(true[:, s, 0], true[:, s, 1], color="k", lw=1.5, label="true" if s == 0 else None)
        ax.plot(dr[:, s, 0], dr[:, s, 1], color="tab:red", lw=1, ls="--", label="dead reckoning" if s == 0 else None)
        ax.plot(est[:, s, 0], est[:, s, 1], color="tab:blue", lw=1, label="EKF" if s == 0 else None)
        major, minor, bearing = error_ellipse(P[-1, s])
        ax.add_patch(
            Ellipse(
                (est[-1, s, 0], est[-1, s, 1]),
                2 * float(major),
                2 * float(minor),
                angle=float(np.degrees(np.pi / 2 - bearing)),
                fill=False,
                color="tab:blue",
                lw=1.5,
                label="2-sigma ellipse" if s == 0 else None,
            )
        )
    for n in range(beacons.shape[1]):
        ax.plot(beacons[:, n, 0], beacons[:, n, 1], color="tab:green", lw=1, label="beacon path" if n == 0 else None)
        ax.plot(beacons[-1, n, 0], beacons[-1, n, 1], "^", color="tab:green")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_title(f"{config.name}  t = {t[-1]:.0f} s")
    ax.legend(loc="upper right", fontsize=7)
    ax.grid(True, lw=0.3)
    return fig


def figure_to_rgb(fig: Figure) -> np.ndarray:
    """An (H, W, 3) uint8 array of a figure, drawn with the Agg backend."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()
