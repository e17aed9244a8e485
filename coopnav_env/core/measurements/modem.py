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

from typing import NamedTuple

import numpy as np
from numba import njit, prange

from ..acoustics import mackenzie_sound_speed, packet_loss_probability, ranging_variance_m2, travel_time
from ..contract import SensorHost
from ..jit import parallel_twin
from ..kernel_records import beacon_view, survey_view
from ..navigation import gated_update, moving_range_prediction, reinit_on_range
from . import FusionOutputs


@njit(cache=True)
def modem_range(
    s_pos: np.ndarray,
    s_vel_true: np.ndarray,
    b_pos: np.ndarray,
    b_vel: np.ndarray,
    c_true: float,
    c_assumed: float,
    jitter_s: float,
    n: float,
    two_way: bool,
    turnaround_s: float,
    clock_s: float,
    delays: np.ndarray,
) -> float:
    """The range a modem measures between a beacon and a survey vehicle (m), from the
    time of flight between the moving vehicles at the true sound speed, turned back
    into a range with the assumed one; ``delays`` (2, L) gets the legs' times for the
    filter's prediction (``navigation.moving_range_prediction``: row 0 at the survey
    vehicle, row 1 at the beacon). ``jitter_s`` is sigma_t, one detection's timing
    jitter; ``n`` a standard normal.

    One-way: the beacon transmits at t = 0; one detection at the survey, whose clock
    is off by ``clock_s``: r = c_assumed (tau + clock + sigma_t n).
    Two-way: the survey interrogates at t = 0, the beacon hears it at tau1 where it is
    then, replies after ``turnaround_s`` from where it is then, and the reply reaches
    the survey at t_rt: each leg from its own geometry. The beacon's and the survey's
    detections each add a jitter, so the round trip is late by sqrt(2) sigma_t n and
    r = c_assumed (t_rt - TAT) / 2 has variance (c sigma_t)^2 / 2
    (``acoustics.ranging_variance_m2``). The filter knows t_rt and TAT, not tau1: it
    places the beacon's legs at e1 = (t_rt - TAT) / 2 and e2 = e1 + TAT (the legs
    differ by |v| tau / c, millimetres).
    """
    if two_way:
        tau1 = travel_time(s_pos, b_pos, b_vel, c_true)
        lag = tau1 + turnaround_s
        tau2 = travel_time(b_pos + b_vel * lag, s_pos + s_vel_true * lag, s_vel_true, c_true)
        t_rt = lag + tau2 + jitter_s * np.sqrt(2.0) * n
        delays[0, 0] = 0.0
        delays[0, 1] = t_rt
        delays[1, 0] = 0.5 * (t_rt - turnaround_s)
        delays[1, 1] = delays[1, 0] + turnaround_s
        return 0.5 * c_assumed * (t_rt - turnaround_s)
    tau = travel_time(b_pos, s_pos, s_vel_true, c_true)
    r = c_assumed * (tau + clock_s + jitter_s * n)
    delays[0, 0] = r / c_assumed
    delays[1, 0] = 0.0
    return r


@njit(cache=True)
def modem_range_variance(
    detection_std_m: float, two_way: bool, beacon_var_m2: float, predicted_range_m: float, sound_speed_rel_std: float
) -> float:
    """R of a modem range (m^2): the ranging noise (``acoustics.ranging_variance_m2``),
    the beacon's own horizontal position variance (below Gao & Chitre eq. 7), and the
    sound speed's relative uncertainty as a scale error of the predicted range."""
    scale = predicted_range_m * sound_speed_rel_std
    return ranging_variance_m2(detection_std_m, two_way) + beacon_var_m2 + scale * scale


class ModemParams(NamedTuple):
    """The modem model's scenario constants (built once per simulator)."""

    reinit_after: int  # reinit_after_rejected_ranges (0: never restart)
    two_way: bool  # ranging_mode == "twtt"
    turnaround_s: float
    max_range_m: float
    loss_near: float  # packet_loss_near
    loss_far: float  # packet_loss_far
    outlier_probability: float
    outlier_mean_excess_m: float
    nan_probability: float  # sensor_nan_probability
    nominal_temperature_c: float  # water_temperature_c: the sound speed the vehicles assume
    salinity_psu: float
    temperature_uncertainty_c: float
    gate: float  # the chi-square gate (Simulator.gate)
    sends_current: np.ndarray  # (N,) bool: the beacon's ping carries its current estimate


class ModemCycle(NamedTuple):
    """One cycle's inputs of the modem model besides the vehicles' state."""

    t_s: np.ndarray  # time (B,)
    temperature_c: np.ndarray  # true water temperature (B,)
    clock_offset_s: np.ndarray  # OWTT clock offset survey - beacon at t=0 (B,S,N)
    clock_drift: np.ndarray  # (B,S,N)
    range_noise_std_m: np.ndarray  # (B,): domain randomization scales it
    current_sent: np.ndarray  # the current estimate each beacon sends, complex (B,N)
    acoustic_n: np.ndarray  # (B,N,S,2) normals
    acoustic_u: np.ndarray  # (B,N,S,4) uniforms: loss, outlier, its excess, NaN
    heard: np.ndarray  # (B,N,S) bool: the pings the channel delivers


@njit(cache=True, inline="always")
def _ping_range(sv, bv, cyc, prm, b, s, j, delays):
    """Beacon j's ping at survey vehicle s of environment b: the measured range (m, by
    ``modem_range``; ``delays`` filled), its loss probability (both legs for two-way)
    and the sound speed's relative uncertainty."""
    depth = 0.5 * (sv.pos[b, s, 2] + bv.pos[b, j, 2])
    c_true = mackenzie_sound_speed(cyc.temperature_c[b], prm.salinity_psu, depth)
    c_assumed = mackenzie_sound_speed(prm.nominal_temperature_c, prm.salinity_psu, depth)
    dc_dT = mackenzie_sound_speed(prm.nominal_temperature_c + 1.0, prm.salinity_psu, depth) - c_assumed
    jitter_s = cyc.range_noise_std_m[b] / c_assumed
    dx = sv.pos[b, s, 0] - bv.pos[b, j, 0]
    dy = sv.pos[b, s, 1] - bv.pos[b, j, 1]
    dz = sv.pos[b, s, 2] - bv.pos[b, j, 2]
    p_lost = packet_loss_probability(np.sqrt(dx * dx + dy * dy + dz * dz), prm.loss_near, prm.loss_far, prm.max_range_m)
    clock = cyc.clock_offset_s[b, s, j] + cyc.clock_drift[b, s, j] * cyc.t_s[b]
    r = modem_range(
        sv.pos[b, s],
        sv.vel_true[b, s],
        bv.pos[b, j],
        bv.vel[b, j],
        c_true,
        c_assumed,
        jitter_s,
        cyc.acoustic_n[b, j, s, 0],
        prm.two_way,
        prm.turnaround_s,
        clock,
        delays,
    )
    if prm.two_way:
        p_lost = 1.0 - (1.0 - p_lost) ** 2  # both legs must arrive
    return r, p_lost, prm.temperature_uncertainty_c * dc_dT / c_assumed


@njit(cache=True, inline="always")
def _count_rejection(sv, out, b, s, r, h, H, R, prm):
    """A range the gate rejected: the streak counts rejected ranges in a row whose
    innovations share a sign (a filter that has drifted sees them all too long or all
    too short; multipath outliers are too long only, between fused ranges): +k or -k.
    After ``reinit_after`` of them the filter restarts from the range (lock-out)."""
    sign = 1 if r > h else -1
    streak = sv.rejected_streak[b, s]
    sv.rejected_streak[b, s] = streak + sign if streak * sign >= 0 else sign
    if 0 < prm.reinit_after <= abs(sv.rejected_streak[b, s]) and reinit_on_range(sv.est[b, s], sv.P[b, s], r, h, H, R):
        sv.rejected_streak[b, s] = 0  # locked out: restarted from this range
        out.restarts[b, s] += 1


@njit(cache=True, inline="always")
def _fuse_ping(sv, bv, cyc, prm, out, b, s, j, delays):
    """Beacon j's ping at survey vehicle s of environment b: lost, an outlier or NaN at
    random, then gated and fused (eqs. 7-13), in place; returns whether it was fused."""
    r, p_lost, sound_speed_rel_std = _ping_range(sv, bv, cyc, prm, b, s, j, delays)
    u = cyc.acoustic_u[b, j, s]
    if u[0] < p_lost:
        out.lost[b, j, s] = True
        return False
    if u[1] < prm.outlier_probability:  # multipath: a longer path arrives
        r += -prm.outlier_mean_excess_m * np.log(u[2])
    if u[3] < prm.nan_probability:
        r = np.nan
    if prm.sends_current[j]:  # the ping carries the beacon's current estimate (Gao II-A)
        sv.current_est[b, s] = cyc.current_sent[b, j]
    if not np.isfinite(r):
        out.nan_count[b, s] += 1
        return False
    h, H = moving_range_prediction(sv.est[b, s], sv.vel_est[b, s], bv.est[b, j], bv.vel[b, j], delays)
    R = modem_range_variance(cyc.range_noise_std_m[b], prm.two_way, bv.nav_var[b, j], h, sound_speed_rel_std)
    if not gated_update(sv.est[b, s], sv.P[b, s], r, h, H, R, prm.gate):
        out.rejected[b, j, s] = True
        _count_rejection(sv, out, b, s, r, h, H, R, prm)
        return False
    sv.rejected_streak[b, s] = 0
    out.fused[b, j, s] = True
    return True


def _fuse(sv, bv, cyc, prm, out):
    """Every beacon j pings every survey vehicle s; what arrives is gated and fused, in
    place (sv.est, P, current_est, last_range_t_s, rejected_streak; the flags and counts
    of out, ``FusionOutputs``). sv, bv: ``kernel_records.SurveyView``, ``kernel_records.BeaconView``;
    cyc: ``ModemCycle``, whose ``heard`` (B, N, S) are the pings the channel delivers
    (``core.channel``; all True on the fixed clock's free channel), the others are
    neither measured nor counted lost; prm: ``ModemParams``."""
    B, N, S = bv.pos.shape[0], bv.pos.shape[1], sv.est.shape[1]
    for b in prange(B):
        delays = np.zeros((2, 2 if prm.two_way else 1))
        for s in range(S):
            any_fused = False
            for j in range(N):
                if cyc.heard[b, j, s] and _fuse_ping(sv, bv, cyc, prm, out, b, s, j, delays):
                    any_fused = True
            if any_fused:
                sv.last_range_t_s[b, s] = cyc.t_s[b]


fuse_kernel = njit(cache=True)(_fuse)
fuse_kernel_parallel = parallel_twin(_fuse)

# ModemParams' scenario fields in order, by their config names
CONFIG_FIELDS = (
    "reinit_after_rejected_ranges",
    "ranging_mode",
    "turnaround_s",
    "max_range_m",
    "packet_loss_near",
    "packet_loss_far",
    "outlier_probability",
    "outlier_mean_excess_m",
    "sensor_nan_probability",
    "water_temperature_c",
    "salinity_psu",
    "temperature_uncertainty_c",
)


class ModemRanging:
    """The modem model of one simulator (its scalars gathered once)."""

    def __init__(self, sim: SensorHost) -> None:
        c = sim.config
        scalars = [getattr(c, k) for k in CONFIG_FIELDS]
        # _make: the fields by position, which mypy cannot count through the starred floats
        self.params = ModemParams._make(
            [
                int(scalars[0]),
                c.ranging_mode == "twtt",
                *(float(v) for v in scalars[2:]),
                float(sim.gate),
                np.asarray(sim.sends_current, dtype=bool),
            ]
        )
        self.kernel = fuse_kernel_parallel if sim.batch_size >= 256 else fuse_kernel
        self.sim = sim
        self._all_heard: np.ndarray | None = None  # (B, N, S) all True, kept across cycles

    def heard_mask(self, cycle: np.ndarray) -> np.ndarray | None:
        """(B, N): beacons that ping this cycle: all of them (None). With
        ``channel_mode="decide"`` the simulator masks by the beacons' transmit decisions."""
        return None

    def fuse(self, draws: dict, out: FusionOutputs, heard: np.ndarray | None = None) -> None:
        """Fuse this cycle's ranges; ``heard`` (B, N, S): the pings the channel delivered
        (None: every ping, the fixed clock)."""
        sim = self.sim
        if heard is None:
            all_heard = self._all_heard
            if all_heard is None or all_heard.shape[0] != sim.batch_size:
                all_heard = self._all_heard = np.ones((sim.batch_size, sim.N, sim.S), dtype=bool)
            heard = all_heard
        c, st = sim.config, sim.state
        cyc = ModemCycle(
            st.t_s,
            st.temperature_c,
            st.clock_offset_s,
            st.clock_drift,
            c.range_noise_std_m * st.ep_noise_scale,
            st.current_mean[:, None] + st.current_gm[:, None] + st.b_current_err,
            draws["acoustic_n"],
            draws["acoustic_u"],
            heard,
        )
        self.kernel(survey_view(st), beacon_view(st), cyc, self.params, out)


def build(sim: SensorHost) -> ModemRanging:
    """The modem model of simulator ``sim`` (``measurements.build``)."""
    return ModemRanging(sim)
