"""The simulation state: numpy arrays with a leading batch axis.

B environments, S survey vehicles, N beacons, W waypoints per path. Positions are
(east, north, depth) in metres; in the horizontal plane some fields are complex
(east + 1j*north), see core/dynamics.py. Nothing here knows PettingZoo.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, ClassVar, TypeVar

import numpy as np

_Rows = TypeVar("_Rows", bound="BatchArrays")


class BatchArrays:
    """Row operations shared by the state dataclasses: every field has a leading batch axis."""

    # declared for the type checker (the subclasses are dataclasses and have a t_s field)
    __dataclass_fields__: ClassVar[dict[str, Any]]
    t_s: np.ndarray

    @property
    def batch_size(self) -> int:
        return self.t_s.shape[0]

    def assign(self, mask: np.ndarray, other: BatchArrays) -> None:
        """Overwrite the rows where ``mask`` is True with ``other``'s rows (in order)."""
        for f in dataclasses.fields(self):
            getattr(self, f.name)[mask] = getattr(other, f.name)

    def row(self: _Rows, index: int) -> _Rows:
        """A batch-of-one copy of row ``index``."""
        return type(self)(**{f.name: getattr(self, f.name)[index : index + 1].copy() for f in dataclasses.fields(self)})


@dataclass
class SimState(BatchArrays):
    # clocks and random-number keys, (B,)
    t_s: np.ndarray
    cycle: np.ndarray
    keys: np.ndarray
    # this episode's randomized scenario values (domain randomization), (B,)
    ep_variant: np.ndarray  # index into Simulator.variants: (survey_path, depth_m)
    ep_noise_scale: np.ndarray  # factor on the sensor and range noise levels
    # survey vehicles, (B, S, ...)
    s_pos: np.ndarray  # true position (B,S,3)
    s_heading: np.ndarray  # true heading, complex unit east + 1j*north (B,S)
    s_speed_model_mps: np.ndarray  # eq. (1) water speed the vehicle believes (B,S)
    s_speed_scale: np.ndarray  # true water speed / modelled (B,S)
    s_thrust_n: np.ndarray  # (B,S)
    s_compass_bias_rad: np.ndarray  # (B,S)
    s_vel_true: np.ndarray  # true ground velocity at the end of the last sub-step (B,S,3)
    s_vel_est: np.ndarray  # dead-reckoned velocity at the end of the last sub-step (B,S,3)
    s_waypoints: np.ndarray  # (B,S,W,3)
    s_n_waypoints: np.ndarray  # (B,S) int
    s_wp_index: np.ndarray  # index of the waypoint being steered to (B,S) int
    s_hover: np.ndarray  # holds station (stationary path) (B,S) bool
    s_done: np.ndarray  # path finished (B,S) bool
    s_est: np.ndarray  # EKF estimate (B,S,3)
    s_P: np.ndarray  # EKF covariance (B,S,3,3)
    s_dr: np.ndarray  # dead-reckoning-only track (B,S,3)
    s_last_range_t_s: np.ndarray  # time of the last fused range (B,S)
    s_rejected_streak: np.ndarray  # ranges rejected in a row, signed by their innovations' sign (B,S) int
    s_current_est: np.ndarray  # water current last received from a beacon AUV, complex (B,S)
    # beacons, (B, N, ...)
    b_pos: np.ndarray  # true (B,N,3)
    b_heading: np.ndarray  # complex unit (B,N)
    b_vel: np.ndarray  # true ground velocity (B,N,3)
    b_nav_err: np.ndarray  # own navigation estimate minus truth (B,N,3)
    b_nav_var_m2: np.ndarray  # own per-axis position variance, carried (B,N)
    b_walk_var_m2: np.ndarray  # its white part: start fix plus DVL velocity noise (B,N)
    b_unlocked_s: np.ndarray  # time spent without bottom lock (B,N)
    b_dvl_lock: np.ndarray  # (B,N) bool
    b_current_err: np.ndarray  # error of the current estimate used without lock, complex (B,N)
    b_dvl_scale_error: np.ndarray  # this episode's DVL velocity scale error (fraction) (B,N)
    b_dvl_heading_bias_rad: np.ndarray  # this episode's constant compass error of the DVL dead reckoning (B,N)
    b_dvl_heading_phase_rad: np.ndarray  # the phase of its one-cycle (heading-dependent) part (B,N)
    b_travelled_m: np.ndarray  # distance travelled since the last fix (B,N)
    b_turn_sum_m: np.ndarray  # sum of |d| e^{-2i heading} over the cycles since the last fix, complex (B,N)
    b_fix_est: np.ndarray  # own position estimate at the last GPS fix (start or surfacing), complex (B,N)
    b_since_fix_s: np.ndarray  # time since that fix (B,N)
    b_surfacings: np.ndarray  # GPS fixes taken at the surface this cycle (B,N) int
    b_surfacing: np.ndarray  # on a surfacing (ascent, dwell, descent) (B,N) bool
    b_excursion_s: np.ndarray  # time since that surfacing's ascent began (B,N)
    b_away_s: np.ndarray  # time of this cycle it spent above the ranging depth on a surfacing (B,N)
    b_away: np.ndarray  # above the ranging depth on a surfacing now: no ping, no reply (B,N) bool
    b_surge: np.ndarray  # ASV: its ground-speed error along its heading, Gauss-Markov, m/s (B,N)
    b_steer: np.ndarray  # ASV: its course error, Gauss-Markov, rad (B,N)
    b_pings: np.ndarray  # packets it transmitted this cycle (channel_mode="decide"; else 0) (B,N) int
    b_collisions: np.ndarray  # its pings lost to a collision at a survey vehicle this cycle (B,N) int
    b_energy_j: np.ndarray  # transmit energy it spent this cycle, J (B,N)
    # acoustics
    clock_offset_s: np.ndarray  # OWTT clock offset survey - beacon at t=0 (B,S,N)
    clock_drift: np.ndarray  # its drift, s/s (B,S,N)
    temperature_c: np.ndarray  # true water temperature (B,)
    # water current, complex (B,)
    current_mean: np.ndarray
    current_gm: np.ndarray
    # what each beacon last received
    k_est: np.ndarray  # survey estimate (B,N,S,3)
    k_P: np.ndarray  # its horizontal covariance (B,N,S,2,2)
    k_wp_index: np.ndarray  # its waypoint index (B,N,S)
    k_age_s: np.ndarray  # time since that reply (B,N,S)
    k_range_age_s: np.ndarray  # time since its last fused range, as reported (B,N,S)
    k_peer: np.ndarray  # peers' last reported positions (B,N,N,3)
    # the beacons' GPS error and fix counter, the survey filters' consider states and lock-out window
    # (docs/scenarios/consider-fusion.md; appended last)
    b_gps_err: np.ndarray  # the GPS receiver's Gauss-Markov error, complex (B,N)
    b_fix_count: np.ndarray  # surfacing GPS fixes so far, sent modulo 16 (eq. C8) (B,N) int
    s_Pxb: np.ndarray  # cross-covariance of each survey filter's error with each beacon's (B,S,N,3,2)
    s_fix_seen: np.ndarray  # each beacon's fix counter as last heard (B,S,N) int
    s_fix_seen_t_s: np.ndarray  # when that counter last changed, as heard (B,S,N)
    s_var_seen_m2: np.ndarray  # each beacon's per-axis variance as last heard (B,S,N): eq. C8's projection
    s_win_n: np.ndarray  # ranges in the lock-out window, per beacon (B,S,N) int
    s_win_z: np.ndarray  # the window's ranges, oldest first (B,S,N,M)
    s_win_beacon: np.ndarray  # the beacon's reported horizontal position at each (B,S,N,M,2)
    s_win_dr: np.ndarray  # the survey's dead-reckoned position when each was received (B,S,N,M,2)
    s_win_dz: np.ndarray  # survey depth estimate minus the beacon's at each (B,S,N,M)
    s_win_t: np.ndarray  # time of each (B,S,N,M)
    # the survey filters' cross-covariance with their own dead-reckoning biases (core/dr_bias.py; appended last)
    s_Pxd: np.ndarray  # E[e phi^T], phi = (speed-scale error, compass bias, told current error e, n) (B,S,3,4)
    # the multipath hypotheses each survey filter merged at its last range, held until the next one
    # (core/multipath.py, eqs. M5-M7; appended last)
    s_hyp_w: np.ndarray  # the direct path's weight w of that range; 1.0: nothing held (B,S)
    s_hyp_d: np.ndarray  # the direct path's step x1 - x0 (B,S,3)
    s_hyp_dP: np.ndarray  # P0 - P1: the multipath hypothesis' covariance minus the direct path's (B,S,3,3)
    s_hyp_dX: np.ndarray  # the same for the beacons' cross-covariances Pxb (B,S,N,3,2)
    s_hyp_dD: np.ndarray  # and for the dead-reckoning biases' Pxd (B,S,3,4)
    # the anisotropic part of each beacon's carried covariance, and as each survey last heard it
    # (beacon_nav.covariance_deviator; appended last)
    b_nav_dev_m2: np.ndarray  # (Sxx - Syy) / 2 + 1j Sxy of its own horizontal covariance, complex (B,N)
    s_dev_seen_m2: np.ndarray  # each beacon's deviator as last heard (B,S,N), complex: eq. C8''s projection
    s_model_seen: np.ndarray  # each beacon AUV's error-model state as last heard (B,S,N,7): eq. N2 (consider.py)
