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
from scipy.stats import chi2

from ..acoustics import (
    mackenzie_sound_speed,
    modem_range_variance,
    packet_loss_probability,
    sound_speed_rel_std_at,
    travel_time,
)
from ..beacon_nav import error_model
from ..consider import (
    CI,
    FUSIONS,
    SCHMIDT,
    ErrorModel,
    beacon_covariance,
    beacon_reset,
    beacon_variance_along,
    beacon_variance_los,
    carry_cross_covariance,
    ci_range_update,
    gauss_markov_factor,
    gps_share,
    schmidt_range_update,
    transport_cross_covariance,
)
from ..contract import SensorHost
from ..dr_bias import N_BIASES, current_error_std_mps
from ..iterated import RangeGeometry, iterated_range_model
from ..jit import parallel_twin, threaded
from ..kernel_records import beacon_view, consider_view, survey_view
from ..multipath import Held, Moments, blend_update, direct_path_weight, hold_hypotheses, reweigh_hypotheses
from ..navigation import (
    gated_update,
    innovation_variance,
    kalman_gain,
    moving_range_prediction,
    range_curvature,
    reinit_on_range,
)
from ..split_range import split_range_model
from . import FusionOutputs
from .lockout_window import Windows, remember, window_refix


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
    sends_current_mask: int  # bit j: beacon j's ping carries its current estimate (an int: performance.md#refcounts)
    fusion: int  # beacon_error_fusion: WHITE, SCHMIDT or CI
    window: bool  # lockout_recovery in ("window", "window_consensus")
    window_consensus: bool  # lockout_recovery == "window_consensus": which ranges by eq. R7, not R6'
    window_m: int  # recovery_window
    prior_std_m: float  # recovery_prior_std_m
    dr_rate_m2ps: float  # the survey's dead-reckoning variance growth per axis (process_noise_horizontal_m2ps)
    gps_tau_s: float  # gps_error_time_constant_s
    mixture: bool  # range_outlier_model in ("mixture", "hold"): eqs. M1-M3
    hold: bool  # range_outlier_model == "hold": the hypotheses held for the next range (M4-M7)
    window_chi2: tuple[float, ...]  # 7: the 99 % chi-square point of a window fix's residuals by dof = m - 2
    window_chi2_consensus: tuple[float, ...]  # 7: the same at 99.9 %, eq. R7's guard
    dr_scale_std: float  # survey_speed_scale_error_std: the window's shared shift scale error (R2')
    dr_heading_std_rad: float  # compass_bias_std_deg: its shared rotation (R2')
    dr_current_std_mps: float  # the added current's error per axis (dr_bias): its shared drift (R2')
    bias_consider: bool  # survey_bias_consider: the survey carries Pxd (dr_bias.py)
    second_order: bool  # range_linearization == "second_order": eqs. L1-L3 (navigation.range_curvature)
    iterated: bool  # range_linearization == "iterated": eqs. I1-I3 (core/iterated.py)
    reinit_after_short: int  # reinit_after_short_ranges: a lock-out after this many too short in a row (0: as any)
    gate_short: float  # the chi-square gate of a range shorter than predicted (range_gate_short_probability)
    split: bool  # range_linearization == "split": eqs. S1-S6 (core/split_range.py)
    gps_var_m2: float  # gps_noise_m^2: a fixed beacon's error variance per axis, var(g) of eq. C8'
    full_covariance: bool  # beacon_covariance == "full" with "schmidt": the transport of eq. N3 (Pbb: bv.nav_dev)
    dvl_mask: int  # bit j: beacon j is a beacon AUV (dead reckoning; eq. N3 applies)
    error_model: ErrorModel  # its error model's constants (eq. N2)


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
def _ping_range(s_pos, s_vel_true, b_pos, b_vel, temperature_c, noise_std_m, clock_s, n, prm, delays):
    """One ping's measured range (m, by ``modem_range``; ``delays`` filled), its loss
    probability (both legs for two-way) and the sound speed's relative uncertainty: the
    survey vehicle at s_pos moving at s_vel_true, the beacon at b_pos moving at b_vel,
    in water of ``temperature_c``; n the jitter's standard normal."""
    depth = 0.5 * (s_pos[2] + b_pos[2])
    c_true = mackenzie_sound_speed(temperature_c, prm.salinity_psu, depth)
    c_assumed = mackenzie_sound_speed(prm.nominal_temperature_c, prm.salinity_psu, depth)
    dx, dy, dz = s_pos[0] - b_pos[0], s_pos[1] - b_pos[1], s_pos[2] - b_pos[2]
    p_lost = packet_loss_probability(np.sqrt(dx * dx + dy * dy + dz * dz), prm.loss_near, prm.loss_far, prm.max_range_m)
    r = modem_range(
        s_pos,
        s_vel_true,
        b_pos,
        b_vel,
        c_true,
        c_assumed,
        noise_std_m / c_assumed,
        n,
        prm.two_way,
        prm.turnaround_s,
        clock_s,
        delays,
    )
    if prm.two_way:
        p_lost = 1.0 - (1.0 - p_lost) ** 2  # both legs must arrive
    return (
        r,
        p_lost,
        sound_speed_rel_std_at(
            c_assumed, prm.nominal_temperature_c, prm.salinity_psu, prm.temperature_uncertainty_c, depth
        ),
    )


@njit(cache=True, inline="always")
def _heard_fix_count(cv, prm, b, s, j, t_s):
    """The ping's 4-bit GPS fix counter: when it changed, beacon j has re-fixed at the
    surface since survey s last heard it, and its error is now its GPS receiver's, e' =
    phi g + w, g the GPS error of its last fix, phi = exp(-dt / tau) over the time dt
    between the fixes (``gps_error_time_constant_s``; dt between the changes the survey
    heard). The survey's error knew the beacon's old error e = g + d (d its dead reckoning
    since that fix) only through ranges, which see the sum, so its share of g is
    Cov(x, g) = Cov(x, e) var(g) / var(e):

        (C8') Pxb <- phi Pxb var(g) Sigma_seen^-1  (``consider.gps_share``),

    var(g) its GPS receiver's variance (``gps_noise_m``^2, not the variance this ping sends,
    which has grown again if the survey missed the pings since the fix), Sigma_seen the
    covariance last heard before the fix (var(e), per-axis variance and deviator; each
    eigenvalue of the share at most 1; with an isotropic Sigma_seen the scalar
    phi (var(g) / var_seen) Pxb). A review found the dead
    reckoning's part kept (Pxb <- phi Pxb, about 0.11 where this gives 0.02 at
    ``gao_sea``'s defaults), which can make the joint covariance indefinite; this keeps it
    positive semi-definite (phi^2 var(g) / var_seen^2 <= 1 / var_seen). With a white GPS
    error (tau = 0) or fixes far apart it is eq. (C8), Pxb <- 0. Called when the counter
    ``cv.fix_count[b, j] % 16`` differs from ``cv.fix_seen[b, s, j]``."""
    count = cv.fix_count[b, j] % 16
    if prm.gps_tau_s > 0.0:
        var, dev = cv.var_seen[b, s, j], cv.dev_seen[b, s, j]
        phi = gauss_markov_factor(t_s - cv.fix_seen_t_s[b, s, j], prm.gps_tau_s)
        gps_share(cv.Pxb[b, s, j], prm.gps_var_m2, var, dev, phi)
        if prm.hold:  # the held hypotheses' difference too (M5)
            gps_share(cv.hyp_dX[b, s, j], prm.gps_var_m2, var, dev, phi)
    else:
        beacon_reset(cv.Pxb[b, s, j])
        if prm.hold:
            beacon_reset(cv.hyp_dX[b, s, j])
    cv.fix_seen[b, s, j] = count
    cv.fix_seen_t_s[b, s, j] = t_s


@njit(cache=True, inline="always")
def _carry_to_this_ping(bv, b, j, Pxb, dX, seen, prm, fixed, model_now):
    """With ``beacon_covariance="full"``: beacon AUV j's ping carries its error model's state
    (eq. N2, into ``model_now``); a survey filter carries its cross-covariance Pxb (3, 2) with
    the beacon's error from the ping it last heard (state ``seen``) to this one (eq. N3, in
    place of eq. C7's phi = 1; the held hypotheses' difference dX too), unless the beacon has
    fixed since (eq. C8' did that), and keeps this ping's state in ``seen``."""
    d = bv.est[b, j, 0] + 1j * bv.est[b, j, 1] - bv.fix_est[b, j]
    g = bv.turn_sum_m[b, j]
    model_now[0], model_now[1], model_now[2] = d.real, d.imag, bv.travelled_m[b, j]
    model_now[3], model_now[4], model_now[5], model_now[6] = g.real, g.imag, bv.unlocked_s[b, j], bv.walk_var[b, j]
    if not fixed:
        transport_cross_covariance(Pxb, model_now, seen, prm.error_model)
        if prm.hold:
            transport_cross_covariance(dX, model_now, seen, prm.error_model)
    seen[:] = model_now


@njit(cache=True, inline="always")
def _count_rejection(sv, cv, out, prm, b, s, j, H, meas, t_s):
    """A range the gate rejected: the streak counts rejected ranges in a row whose
    innovations share a sign (a filter that has drifted sees them all too long or all
    too short; multipath outliers are too long only, between fused ranges): +k or -k.
    After ``reinit_after`` of them the filter restarts (lock-out): from a window of
    beacon j's ranges (``lockout_recovery="window"`` or ``"window_consensus"``), else from the range at the nearest
    point of its circle (``navigation.reinit_on_range``, R with the beacon's variance).
    meas: (r, h, R without the beacon's variance, R with it, the beacon's Pbb (2, 2), and the
    curvature's bias and variance (L2, L3) that h and both R hold, 0 to first order).
    A restart leaves the locked-out filter's covariance behind, so it uses h and R
    without the curvature's terms."""
    r, h, R, R_white, Pbb, bias, var = meas
    h, R, R_white = h - bias, R - var, R_white - var
    sign = 1 if r > h else -1
    streak = sv.rejected_streak[b, s]
    sv.rejected_streak[b, s] = streak + sign if streak * sign >= 0 else sign
    short = sign < 0 and 0 < prm.reinit_after_short <= -sv.rejected_streak[b, s]  # R8: only a drift makes it short
    if not (short or 0 < prm.reinit_after <= abs(sv.rejected_streak[b, s])):
        return
    if prm.window and window_refix(sv, cv, prm, b, s, j, R, Pbb, t_s):
        restarted = True
    else:
        R_all = R + beacon_variance_along(Pbb, H[0], H[1]) if prm.fusion == SCHMIDT else R_white
        restarted = reinit_on_range(sv.est[b, s], sv.P[b, s], r, h, H, R_all)
        if restarted:
            cv.Pxb[b, s] = 0.0
            cv.Pxd[b, s] = 0.0  # (D4)
    if restarted:
        sv.rejected_streak[b, s] = 0  # locked out: restarted
        out.restarts[b, s] += 1


@njit(cache=True, inline="always")
def _gate_of(prm, y):
    """The chi-square gate of a range whose innovation is y: (G8) no longer path makes a
    range short, so one shorter than predicted has its own (``gate_short``)."""
    return prm.gate if y >= 0.0 else prm.gate_short


@njit(cache=True, inline="always")
def _kalman(f, prm, j, H, meas, K, gated):
    """The gated update of survey filter f (``multipath.Moments``: views of its x, P, Pxb,
    Pxd) with beacon j's range (row H; meas as ``_count_rejection``'s): ``"white"`` with
    the beacon's variance in R (Gao & Chitre eqs. 9-13); ``"schmidt"`` with it as consider
    states (eqs. C2-C6); ``"ci"`` by covariance intersection (CI3, CI5) with R as white's.
    Each carries the survey's dead-reckoning-bias cross-covariance Pxd through its gain
    (``dr_bias.py``, eq. D3). K (3,): scratch; meas[4] the beacon's Pbb (2, 2). Returns
    (fused, the innovation's variance S). gated: the range passed its gate already (eq. I3),
    so none is applied here."""
    r, h, R, R_white, Pbb = meas[:5]
    y = r - h
    gate = np.inf if gated else _gate_of(prm, y)
    if prm.fusion == SCHMIDT:
        nis, fused = schmidt_range_update(f.x, f.P, f.X[j], Pbb, y, H, R, gate, K)
        if fused:
            for j2 in range(f.X.shape[0]):
                if j2 != j:
                    carry_cross_covariance(f.X[j2], K, H)  # (C6)
            carry_cross_covariance(f.D, K, H)  # (D3)
        return fused, y * y / nis if nis > 0.0 else 0.0
    S = innovation_variance(f.P, H, R_white)
    if prm.fusion == CI:
        if not y * y / S <= gate:  # a NaN y too
            return False, S
        x0 = f.x.copy()
        ci_range_update(f.x, f.P, y, H, R_white, False)
        if y != 0.0:  # (D3) with the CI gain K (CI3), recovered from the step it took: x - x0 = K y
            for i in range(3):
                K[i] = (f.x[i] - x0[i]) / y
            carry_cross_covariance(f.D, K, H)
        return True, S
    kalman_gain(f.P, H, S, K)  # eq. (12), before the update
    fused = gated_update(f.x, f.P, r, h, H, R_white, gate)
    if fused:
        carry_cross_covariance(f.D, K, H)  # (D3)
    return fused, S


@njit(cache=True, inline="always")
def _update(f, held, prm, j, H, meas, scratch, gated):
    """``_kalman``; with ``range_outlier_model="mixture"`` a fused range moves the filter
    only by the direct path's posterior probability (``multipath``, eqs. M1-M3); with
    ``"hold"`` the two hypotheses it merged are held in ``held`` (``multipath.Held``) for
    the next range to re-weigh (M5). scratch: (K (3,), Pbb (2, 2), x0 (3,), P0 (3, 3),
    Pxb0 (N, 3, 2), Pxd0 (3, 4)); gated: as ``_kalman``'s. Returns (fused, the weight now
    held: 1 for none)."""
    K, _, x0, P0, X0, D0 = scratch
    if prm.mixture:
        x0[:] = f.x
        P0[:, :] = f.P
        X0[:, :, :] = f.X
        D0[:, :] = f.D
    fused, S = _kalman(f, prm, j, H, meas, K, gated)
    w_held = 1.0
    if fused and prm.mixture and S > 0.0:
        w = direct_path_weight(meas[0] - meas[1], S, prm.outlier_probability, prm.outlier_mean_excess_m)
        if prm.hold:  # (M5): both hypotheses kept until the next range
            w_held = hold_hypotheses(w, Moments(x0, P0, X0, D0), f, held)
        blend_update(w, x0, P0, X0, f.x, f.P, f.X)
        for i in range(3):  # (M3) for the dead-reckoning biases' cross-covariance
            for a in range(D0.shape[1]):
                f.D[i, a] = w * f.D[i, a] + (1.0 - w) * D0[i, a]
    return fused, w_held


@njit(cache=True, inline="always")
def _relinearized(f, prm, j, H, meas, scratch, geo):
    """(gated, H, meas): the first-order model (gated False: ``_kalman`` gates it), or with
    ``range_linearization`` "iterated" (eqs. I1-I3) or "split" (eqs. S1-S6) the range gated
    once on its first-order innovation at the prior and, if it passed, the model those
    re-linearizations give (one that fails keeps its model, and ``_kalman`` refuses it).
    Covariance intersection keeps the first-order model."""
    if prm.fusion == CI or not (prm.iterated or prm.split):
        return False, H, meas
    gate, sch = _gate_of(prm, meas[0] - meas[1]), prm.fusion == SCHMIDT
    if prm.iterated:
        gated, Hi, mi = iterated_range_model(f, j, H, meas, scratch, geo, gate, sch)
    else:
        gated, Hi, mi = split_range_model(f, j, H, meas, scratch[1], scratch[0], geo, gate, sch)
    return (True, Hi, mi) if gated else (False, H, meas)


@njit(cache=True, inline="always")
def _range_model(f, vel_est, beacon, beacon_vel, Pbb, noise_std, prm, j, delays, sound_speed_rel_std):
    """Survey filter f's (``multipath.Moments``) prediction of beacon j's range: (h, H, R
    without the beacon's variance, R with it, the curvature's bias and variance); with
    ``range_linearization="second_order"`` h and both R hold the curvature's terms (eqs.
    L2, L3), else those are 0. The beacon: at ``beacon`` moving at ``beacon_vel``, as its
    message says, with horizontal covariance ``Pbb`` (2, 2; R with it: its variance along the
    line of sight, ``consider.beacon_variance_los``)."""
    h, H = moving_range_prediction(f.x, vel_est, beacon, beacon_vel, delays)
    R = modem_range_variance(noise_std, prm.two_way, 0.0, h, sound_speed_rel_std)
    beacon_var = beacon_variance_los(Pbb, H[0], H[1])
    R_white = modem_range_variance(noise_std, prm.two_way, beacon_var, h, sound_speed_rel_std)
    bias, var = 0.0, 0.0
    if prm.second_order:  # eqs. (L2), (L3)
        bias, var = range_curvature(f.P, f.X[j], Pbb, H, h)
    return h + bias, H, R + var, R_white + var, bias, var


def _fuse(sv, bv, cv, cyc, prm, out):
    """Every beacon j pings every survey vehicle s; what arrives is lost, an outlier or
    NaN at random, then gated and fused (eqs. 7-13 or C1-C6), in place (sv.est, P,
    current_est, last_range_t_s, rejected_streak; the consider states and windows of cv;
    the flags and counts of out, ``FusionOutputs``). sv, bv, cv:
    ``kernel_records.SurveyView``, ``BeaconView``, ``ConsiderView``;
    cyc: ``ModemCycle``, whose ``heard`` (B, N, S) are the pings the channel delivers
    (``core.channel``; all True on the fixed clock's free channel), the others are
    neither measured nor counted lost; prm: ``ModemParams``.

    The helpers of a ping take the rows they read, not the records: numba counts a
    reference to every array of a record at each call of an inlined helper, and those
    atomic counts were most of the simulator's time (docs/performance.md#refcounts)."""
    B, N, S = bv.pos.shape[0], bv.pos.shape[1], sv.est.shape[1]
    win = Windows(cv.win_z, cv.win_dz, cv.win_t, cv.win_beacon, cv.win_dr, cv.win_n)
    for b in prange(B):
        delays = np.zeros((2, 2 if prm.two_way else 1))
        # Pb: the ranging beacon's Pbb; model_now: a beacon AUV's error-model state in its ping (eq. N2)
        K, Pbb, Pb, model_now = np.zeros(3), np.zeros((2, 2)), np.zeros((2, 2)), np.zeros(7)
        scratch = (K, Pbb, np.zeros(3), np.zeros((3, 3)), np.zeros((N, 3, 2)), np.zeros((3, N_BIASES)))
        t_s = cyc.t_s[b]
        for s in range(S):
            f = Moments(sv.est[b, s], sv.P[b, s], cv.Pxb[b, s], cv.Pxd[b, s])  # survey s's filter (views)
            held = Held(cv.hyp_d[b, s], cv.hyp_dP[b, s], cv.hyp_dX[b, s], cv.hyp_dD[b, s])
            any_fused = False
            for j in range(N):
                if not cyc.heard[b, j, s]:
                    continue
                clock = cyc.clock_offset_s[b, s, j] + cyc.clock_drift[b, s, j] * t_s
                temp, noise_std, n = cyc.temperature_c[b], cyc.range_noise_std_m[b], cyc.acoustic_n[b, j, s, 0]
                r, p_lost, rel_std = _ping_range(
                    sv.pos[b, s], sv.vel_true[b, s], bv.pos[b, j], bv.vel[b, j], temp, noise_std, clock, n, prm, delays
                )
                u = cyc.acoustic_u[b, j, s]
                if u[0] < p_lost:
                    out.lost[b, j, s] = True
                    continue
                fixed = cv.fix_count[b, j] % 16 != cv.fix_seen[b, s, j]
                if fixed:
                    _heard_fix_count(cv, prm, b, s, j, t_s)
                cv.var_seen[b, s, j], cv.dev_seen[b, s, j] = bv.nav_var[b, j], bv.nav_dev[b, j]
                if prm.full_covariance and (prm.dvl_mask >> j) & 1:  # eq. N3
                    _carry_to_this_ping(bv, b, j, f.X[j], held.dX[j], cv.model_seen[b, s, j], prm, fixed, model_now)
                # multipath: a longer path arrives; or the sensor's NaN
                r += -prm.outlier_mean_excess_m * np.log(u[2]) if u[1] < prm.outlier_probability else 0.0
                r = np.nan if u[3] < prm.nan_probability else r
                if (prm.sends_current_mask >> j) & 1:  # the ping carries the beacon's current estimate (Gao II-A)
                    sv.current_est[b, s] = cyc.current_sent[b, j]
                if not np.isfinite(r):
                    out.nan_count[b, s] += 1
                    continue
                beacon, beacon_vel = bv.est[b, j], bv.vel[b, j]
                beacon_covariance(bv.nav_var[b, j], bv.nav_dev[b, j], Pb)
                vel_est = sv.vel_est[b, s]
                m = _range_model(f, vel_est, beacon, beacon_vel, Pb, noise_std, prm, j, delays, rel_std)
                h, H, R, R_white, bias, var = m
                if cv.hyp_w[b, s] < 1.0:  # (M6, M7): this range re-weighs the last one's hypotheses, then they merge
                    sch, p, mu = prm.fusion == SCHMIDT, prm.outlier_probability, prm.outlier_mean_excess_m
                    reweigh_hypotheses(
                        cv.hyp_w[b, s], held, f, H, r - h, R if sch else R_white, p, mu, j if sch else -1, Pb
                    )
                    cv.hyp_w[b, s] = 1.0
                    m = _range_model(f, vel_est, beacon, beacon_vel, Pb, noise_std, prm, j, delays, rel_std)
                    h, H, R, R_white, bias, var = m
                meas = (r, h, R, R_white, Pb, bias, var)
                if prm.window:
                    remember(win, b, s, j, r, beacon, f.x[2], sv.dr[b, s], vel_est, delays, t_s)
                geo = RangeGeometry(vel_est, beacon, beacon_vel, noise_std, delays, rel_std, prm.two_way)
                gated, H, meas = _relinearized(f, prm, j, H, meas, scratch, geo)
                fused, w_held = _update(f, held, prm, j, H, meas, scratch, gated)
                if not fused:
                    out.rejected[b, j, s] = True
                    _count_rejection(sv, cv, out, prm, b, s, j, H, meas, t_s)
                    continue
                cv.hyp_w[b, s] = w_held
                sv.rejected_streak[b, s] = 0
                out.fused[b, j, s] = True
                any_fused = True
            if any_fused:
                sv.last_range_t_s[b, s] = t_s


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
        c, gate = sim.config, float(sim.gate)  # the chi-square gate, both ways unless G8 sets the short side
        scalars = [getattr(c, k) for k in CONFIG_FIELDS]
        # _make: the fields by position, which mypy cannot count through the starred floats
        self.params = ModemParams._make(
            [
                int(scalars[0]),
                c.ranging_mode == "twtt",
                *(float(v) for v in scalars[2:]),
                gate,
                sum(1 << j for j, sends in enumerate(np.asarray(sim.sends_current, dtype=bool)) if sends),
                FUSIONS[c.beacon_error_fusion],
                c.lockout_recovery in ("window", "window_consensus"),
                c.lockout_recovery == "window_consensus",
                int(c.recovery_window),
                float(c.recovery_prior_std_m),
                float(c.process_noise_horizontal_m2ps),
                float(c.gps_error_time_constant_s),
                c.range_outlier_model in ("mixture", "hold"),
                c.range_outlier_model == "hold",
                tuple(float(v) for v in chi2.ppf(0.99, np.maximum(np.arange(7), 1))),
                tuple(float(v) for v in chi2.ppf(0.999, np.maximum(np.arange(7), 1))),
                float(c.survey_speed_scale_error_std),
                float(np.radians(c.compass_bias_std_deg)),
                current_error_std_mps(c),
                bool(c.survey_bias_consider),
                c.range_linearization == "second_order",
                c.range_linearization == "iterated",
                int(c.reinit_after_short_ranges),
                float(chi2.ppf(c.range_gate_short_probability, 1)) if c.range_gate_short_probability else gate,
                c.range_linearization == "split",
                float(c.gps_noise_m) ** 2,
                c.beacon_covariance == "full" and c.beacon_error_fusion == "schmidt",
                sum(1 << j for j, kind in enumerate(c.beacon_kinds) if kind == "beacon_auv"),
                error_model(c),
            ]
        )
        self.kernel = fuse_kernel_parallel if threaded(sim.batch_size) else fuse_kernel
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
        self.kernel(survey_view(st), beacon_view(st), consider_view(st), cyc, self.params, out)


def build(sim: SensorHost) -> ModemRanging:
    """The modem model of simulator ``sim`` (``measurements.build``)."""
    return ModemRanging(sim)
