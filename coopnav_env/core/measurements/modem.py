"""Acoustic-modem ranges between moving vehicles (one-way or two-way travel time).

Every beacon pings every survey vehicle each cycle. The true range comes from the
time of flight between the moving vehicles at the true sound speed; the vehicles
convert it back with the speed they assume (nominal temperature): ``modem_range``.
The filter's R is ``modem_range_variance``: the ranging noise of the one jitter
convention (``acoustics.ranging_variance_m2``), the beacon's own position variance
(below Gao & Chitre eq. 7) and the sound speed's share. What arrives is gated and
fused (eqs. 7-13); after ``reinit_after_rejected_ranges`` ranges in a row rejected
with innovations of one sign the filter restarts from the range
(``navigation.reinit_on_range``).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..acoustics import mackenzie_sound_speed, packet_loss_probability, ranging_variance_m2, travel_time
from ..navigation import gated_update, range_prediction, reinit_on_range


@njit(cache=True)
def modem_range(s_pos, s_vel_true, b_pos, b_vel, c_true, c_assumed, jitter_s, n, two_way, turnaround_s, clock_s,
                delays):
    """The range a modem measures between a beacon and a survey vehicle (m), from the
    time of flight between the moving vehicles at the true sound speed, turned back
    into a range with the assumed one; ``delays`` gets the legs' times for the
    filter's prediction. ``jitter_s`` is sigma_t, one detection's timing jitter; ``n``
    a standard normal.

    One-way: the beacon transmits at t = 0; one detection at the survey, whose clock
    is off by ``clock_s``: r = c_assumed (tau + clock + sigma_t n).
    Two-way: the survey interrogates, the beacon replies after ``turnaround_s``; the
    beacon's and the survey's detections each add a jitter, so the round trip is late
    by sqrt(2) sigma_t n and r = c_assumed (t_rt - TAT) / 2 has variance
    (c sigma_t)^2 / 2 (``acoustics.ranging_variance_m2``).
    """
    if two_way:
        tau1 = travel_time(s_pos, b_pos, b_vel, c_true)
        lag = tau1 + turnaround_s
        tau2 = travel_time(b_pos + b_vel * lag, s_pos + s_vel_true * lag, s_vel_true, c_true)
        t_rt = lag + tau2 + jitter_s * np.sqrt(2.0) * n
        delays[0] = 0.0
        delays[1] = t_rt
        return 0.5 * c_assumed * (t_rt - turnaround_s)
    tau = travel_time(b_pos, s_pos, s_vel_true, c_true)
    r = c_assumed * (tau + clock_s + jitter_s * n)
    delays[0] = r / c_assumed
    return r


@njit(cache=True)
def modem_range_variance(detection_std_m, two_way, beacon_var_m2, predicted_range_m, sound_speed_rel_std):
    """R of a modem range (m^2): the ranging noise (``acoustics.ranging_variance_m2``),
    the beacon's own horizontal position variance (below Gao & Chitre eq. 7), and the
    sound speed's relative uncertainty as a scale error of the predicted range."""
    scale = predicted_range_m * sound_speed_rel_std
    return ranging_variance_m2(detection_std_m, two_way) + beacon_var_m2 + scale * scale


def _fuse(est, P, s_pos, s_vel_true, s_vel_est, b_pos, b_vel, b_est, b_var, temperature_c, t_s, clock_offset_s,
          clock_drift, acoustic_n, acoustic_u, current_sent, sends_current, current_est, last_range_t_s,
          rejected_streak, range_noise_std_m, params, heard, fused, rejected, lost, nan_count, restarts):
    """Every beacon j pings every survey vehicle s; what arrives is gated and fused, in
    place (est, P, current_est, last_range_t_s, rejected_streak; the flags). ``params``:
    the scenario's scalars in ``PARAMS`` order; range_noise_std_m (B,) per environment
    (domain randomization scales it); ``heard`` (B, N, S) bool: the pings the channel
    delivers (``core.channel``; all True on the fixed clock's free channel), the others
    are neither measured nor counted lost."""
    (reinit_after, two_way, turnaround_s, max_range_m, loss_near, loss_far, outlier_probability,
     outlier_mean_excess_m, nan_probability, nominal_temperature_c, salinity_psu, temperature_uncertainty_c,
     gate) = params
    B, N, S = b_pos.shape[0], b_pos.shape[1], est.shape[1]
    for b in prange(B):
        delays = np.zeros(2 if two_way else 1)
        for s in range(S):
            any_fused = False
            for j in range(N):
                if not heard[b, j, s]:
                    continue
                depth = 0.5 * (s_pos[b, s, 2] + b_pos[b, j, 2])
                c_true = mackenzie_sound_speed(temperature_c[b], salinity_psu, depth)
                c_assumed = mackenzie_sound_speed(nominal_temperature_c, salinity_psu, depth)
                dc_dT = mackenzie_sound_speed(nominal_temperature_c + 1.0, salinity_psu, depth) - c_assumed
                jitter_s = range_noise_std_m[b] / c_assumed
                dx = s_pos[b, s, 0] - b_pos[b, j, 0]
                dy = s_pos[b, s, 1] - b_pos[b, j, 1]
                dz = s_pos[b, s, 2] - b_pos[b, j, 2]
                p_lost = packet_loss_probability(np.sqrt(dx * dx + dy * dy + dz * dz), loss_near, loss_far,
                                                 max_range_m)
                clock = clock_offset_s[b, s, j] + clock_drift[b, s, j] * t_s[b]
                r = modem_range(s_pos[b, s], s_vel_true[b, s], b_pos[b, j], b_vel[b, j], c_true, c_assumed, jitter_s,
                                acoustic_n[b, j, s, 0], two_way, turnaround_s, clock, delays)
                if two_way:
                    p_lost = 1.0 - (1.0 - p_lost) ** 2  # both legs must arrive
                u = acoustic_u[b, j, s]
                if u[0] < p_lost:
                    lost[b, j, s] = True
                    continue
                if u[1] < outlier_probability:  # multipath: a longer path arrives
                    r += -outlier_mean_excess_m * np.log(u[2])
                if u[3] < nan_probability:
                    r = np.nan
                if sends_current[j]:  # the ping carries the beacon's current estimate (Gao II-A)
                    current_est[b, s] = current_sent[b, j]
                if not np.isfinite(r):
                    nan_count[b, s] += 1
                    continue
                h, H = range_prediction(est[b, s], s_vel_est[b, s], delays, b_est[b, j])
                R = modem_range_variance(range_noise_std_m[b], two_way, b_var[b, j], h,
                                         temperature_uncertainty_c * dc_dT / c_assumed)
                if not gated_update(est[b, s], P[b, s], r, h, H, R, gate):
                    rejected[b, j, s] = True
                    # the streak counts rejected ranges in a row whose innovations share a sign (a
                    # filter that has drifted sees them all too long or all too short; multipath
                    # outliers are too long only, between fused ranges): +k or -k
                    sign = 1 if r > h else -1
                    streak = rejected_streak[b, s]
                    rejected_streak[b, s] = streak + sign if streak * sign >= 0 else sign
                    if (0 < reinit_after <= abs(rejected_streak[b, s])
                            and reinit_on_range(est[b, s], P[b, s], r, h, H, R)):
                        rejected_streak[b, s] = 0  # locked out: restarted from this range
                        restarts[b, s] += 1
                    continue
                rejected_streak[b, s] = 0
                fused[b, j, s] = True
                any_fused = True
            if any_fused:
                last_range_t_s[b, s] = t_s[b]


fuse_kernel = njit(cache=True)(_fuse)
fuse_kernel_parallel = njit(cache=True, parallel=True)(_fuse)

PARAMS = ("reinit_after_rejected_ranges", "two_way", "turnaround_s", "max_range_m", "packet_loss_near",
          "packet_loss_far", "outlier_probability", "outlier_mean_excess_m", "sensor_nan_probability",
          "water_temperature_c", "salinity_psu", "temperature_uncertainty_c", "gate")


class ModemRanging:
    """The modem model of one simulator (its scalars gathered once)."""

    def __init__(self, sim):
        c = sim.config
        named = {"two_way": c.ranging_mode == "twtt", "gate": float(sim.gate)}
        self.params = tuple(named[k] if k in named else getattr(c, k) for k in PARAMS)
        self.params = (int(self.params[0]), bool(self.params[1])) + tuple(float(v) for v in self.params[2:])
        self.kernel = fuse_kernel_parallel if sim.batch_size >= 256 else fuse_kernel
        self.sim = sim
        self._all_heard = None

    def heard_mask(self, cycle):
        """(B, N): beacons that ping this cycle: all of them (None). With
        ``channel_mode="decide"`` the simulator masks by the beacons' transmit decisions."""
        return None

    def fuse(self, draws, out, heard=None):
        """Fuse this cycle's ranges; ``heard`` (B, N, S): the pings the channel delivered
        (None: every ping, the fixed clock)."""
        sim = self.sim
        if heard is None:
            if self._all_heard is None or self._all_heard.shape[0] != sim.batch_size:
                self._all_heard = np.ones((sim.batch_size, sim.N, sim.S), dtype=bool)
            heard = self._all_heard
        c, st = sim.config, sim.state
        self.kernel(st.s_est, st.s_P, st.s_pos, st.s_vel_true, st.s_vel_est, st.b_pos, st.b_vel, st.b_pos + st.b_nav_err,
                    st.b_nav_var_m2, st.temperature_c, st.t_s, st.clock_offset_s, st.clock_drift, draws["acoustic_n"],
                    draws["acoustic_u"], st.current_mean[:, None] + st.current_gm[:, None] + st.b_current_err,
                    sim.sends_current, st.s_current_est, st.s_last_range_t_s, st.s_rejected_streak,
                    c.range_noise_std_m * st.ep_noise_scale, self.params, heard, out.fused, out.rejected, out.lost,
                    out.nan_count, out.restarts)


def build(sim):
    return ModemRanging(sim)
