"""Kottege & Zimmer's MLS array as a measurement model: range and bearing from one
sender per cycle (``acoustic_sensor="mls"``, scenario ``swarm_mls``).

The sender is beacon ``cycle % N`` (a round robin stands in for the paper's radio
scheduling). ``measure`` runs the sensor's analytic mode (``core.mls``): the azimuth
is measured in the receiver's frame (anticlockwise positive, folded to the front
half-plane: two hydrophones cannot tell front from back); the survey vehicle turns
it into a bearing with its compass and unfolds it with its own estimate. Senders
beyond the sensor's window, or nearer than its array, are not heard. The fusion
kernel then updates each filter with the range (R = the sensor's bound + the
sender's position variance) and the bearing, whose residual is wrapped to
(-pi, pi] (``navigation.gated_update_residual``), each behind its own gate.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

from ..consider import beacon_covariance, beacon_variance_los
from ..contract import SensorHost
from ..jit import parallel_twin, threaded
from ..kernel_records import beacon_view, survey_view
from ..navigation import gated_update, gated_update_residual, range_prediction
from . import FusionOutputs, arrival_probability

NOT_SENT, NOT_HEARD, HEARD = 0, 1, 2


@njit(cache=True)
def bearing_residual(z: float, h: float) -> float:
    """A bearing's innovation z - h wrapped to [-pi, pi)."""
    return (z - h + np.pi) % (2.0 * np.pi) - np.pi


class MLSMeasurement(NamedTuple):
    """One cycle's MLS measurements, (B, N, S) each: whether sent and heard
    (NOT_SENT, NOT_HEARD or HEARD), the range (m), the world bearing (rad, clockwise
    from north) and their variances."""

    state: np.ndarray
    range_m: np.ndarray
    bearing_rad: np.ndarray
    range_var: np.ndarray
    bearing_var: np.ndarray


@njit(cache=True, inline="always")
def _bearing_update(x, P, beacon, Pbb, bearing_rad, bearing_var, gate, H):
    """A sender's bearing ``bearing_rad`` (variance ``bearing_var``) at the survey filter
    (x, P), gated and fused with its residual wrapped (h = atan2(east, north) of the
    sender's reported position ``beacon`` (horizontal covariance ``Pbb``: its variance across
    the line of sight, over the range squared, joins R) minus x, and
    its Jacobian H); returns whether it was fused. Rows, not records: numba counts a
    reference to every array of a record at each call (docs/performance.md#refcounts)."""
    de = beacon[0] - x[0]
    dn = beacon[1] - x[1]
    rho2 = max(de * de + dn * dn, 1e-6)
    hb = np.arctan2(de, dn)
    H[0] = -dn / rho2  # d bearing / d survey east
    H[1] = de / rho2
    H[2] = 0.0
    R = bearing_var + beacon_variance_los(Pbb, -dn, de) / rho2
    y = bearing_residual(bearing_rad, hb)
    return gated_update_residual(x, P, y, H, R, gate)


def _fuse(sv, bv, m, t_s, gate, out):
    """Fuse this cycle's MLS measurements m (``MLSMeasurement``), in place: sv.est, P,
    last_range_t_s (``kernel_records.SurveyView``) and the flags of out (``FusionOutputs``);
    bv: ``kernel_records.BeaconView`` (the senders' own estimates and variances); t_s (B,)."""
    B, N, S = bv.est.shape[0], bv.est.shape[1], sv.est.shape[1]
    for b in prange(B):
        delays = np.zeros(1)
        H, Pb = np.zeros(3), np.zeros((2, 2))  # Pb: the sender's Pbb
        for s in range(S):
            any_fused = False
            for j in range(N):
                if m.state[b, j, s] == NOT_SENT:
                    continue
                if m.state[b, j, s] == NOT_HEARD:
                    out.lost[b, j, s] = True
                    continue
                h, Hr = range_prediction(sv.est[b, s], sv.vel_est[b, s], delays, bv.est[b, j])
                beacon_covariance(bv.nav_var[b, j], bv.nav_dev[b, j], Pb)
                R = m.range_var[b, j, s] + beacon_variance_los(Pb, Hr[0], Hr[1])  # along the line of sight
                if gated_update(sv.est[b, s], sv.P[b, s], m.range_m[b, j, s], h, Hr, R, gate):
                    out.fused[b, j, s] = True
                    any_fused = True
                else:
                    out.rejected[b, j, s] = True
                bearing, bearing_var = m.bearing_rad[b, j, s], m.bearing_var[b, j, s]
                if _bearing_update(sv.est[b, s], sv.P[b, s], bv.est[b, j], Pb, bearing, bearing_var, gate, H):
                    out.fused[b, j, s] = True
                    any_fused = True
                else:
                    out.rejected[b, j, s] = True
            if any_fused:
                sv.last_range_t_s[b, s] = t_s[b]


fuse_kernel = njit(cache=True)(_fuse)
fuse_kernel_parallel = parallel_twin(_fuse)


class MLSArray:
    """The MLS model of one simulator: the sensor (built once per survey depth, ~0.2 s each)
    and the kernel.

    The sensor's errors depend on the depth (the surface image's path, the sound speed), so
    with ``randomize_depth_m`` each episode's row is measured by the sensor of its own depth
    (``Simulator.variants``); without it there is one sensor, the scenario's ``depth_m``'s."""

    def __init__(self, sim: SensorHost) -> None:
        from ..mls import MLSConfig, MLSSensor

        c = sim.config
        self.sim = sim
        variants = getattr(sim, "variants", None) or [(c.survey_path, c.depth_m)]
        self.depths_m = sorted({float(depth) for _, depth in variants})
        self.sensors = {
            depth: MLSSensor(
                MLSConfig(
                    snr_db_at_1m=c.mls_snr_db_at_1m,
                    max_range_m=c.mls_max_range_m,
                    water_temperature_c=c.water_temperature_c,
                    salinity_psu=c.salinity_psu,
                    depth_m=depth,
                )
            )
            for depth in self.depths_m
        }
        # each path variant's sensor index (into depths_m)
        self._variant_sensor = np.array([self.depths_m.index(float(depth)) for _, depth in variants])
        # the scenario's own depth's sensor where it is one of them (its geometry, the window's
        # minimum range, is the same at every depth)
        self.sensor = self.sensors.get(float(c.depth_m), self.sensors[self.depths_m[0]])
        self.kernel = fuse_kernel_parallel if threaded(sim.batch_size) else fuse_kernel

    def heard_mask(self, cycle: np.ndarray) -> np.ndarray:
        """(B, N): the beacon whose turn it is to send in ``cycle`` (round robin)."""
        N = self.sim.N
        return (cycle % N)[:, None] == np.arange(N)[None, :]

    def measure(self, draws: dict) -> MLSMeasurement:
        """This cycle's sending event: state (B,N,S), range, world bearing and their variances."""
        from ..mls import wrap_angle_rad

        sim = self.sim
        c, st = sim.config, sim.state
        B, N, S = sim.batch_size, sim.N, sim.S
        shape = (B, N, S)
        sends = self.heard_mask(st.cycle - 1)  # the cycle counter has advanced already
        j = np.argmax(sends, axis=1)  # (B,)
        rows = np.arange(B)
        sender_en = st.b_pos[rows, j, :2][:, None].repeat(S, 1)  # (B,S,2)
        sender_h = np.angle(st.b_heading[rows, j])[:, None].repeat(S, 1)
        obs_en, obs_h = st.s_pos[..., :2], np.angle(st.s_heading)
        dist = np.linalg.norm(sender_en - obs_en, axis=-1)
        # the sender's height above each survey vehicle (0 at the scenario's one depth for all,
        # where hypot(x, 0) = |x| exactly: nothing below changes a one-depth scenario)
        dz = st.s_pos[..., 2] - st.b_pos[rows, j, 2][:, None]  # (B,S)
        slant = np.hypot(dist, dz)
        heard = (dist > self.sensor.min_range_m) & (arrival_probability(c, slant) > 0.0)  # the window
        n = draws["mls_n"]  # (B,S,14)
        az = np.zeros((B, S))
        rng_m = np.zeros((B, S))
        var_r = np.ones((B, S))
        var_az = np.ones((B, S))
        # each row's sensor: its episode's depth (one sensor, every row, without randomize_depth_m)
        which = self._variant_sensor[st.ep_variant][:, None] if len(self.depths_m) > 1 else None
        for k, depth in enumerate(self.depths_m):
            rows_k = heard if which is None else heard & (which == k)
            if not rows_k.any():
                continue
            m, (b_az, b_r, _) = self.sensors[depth].measure_analytic_with_bounds(
                sender_en[rows_k], sender_h[rows_k], obs_en[rows_k], obs_h[rows_k], normals=n[rows_k][:, :13]
            )
            az[rows_k], rng_m[rows_k] = m.azimuth_rad, m.range_m
            var_r[rows_k], var_az[rows_k] = np.square(b_r), np.square(b_az)
        # The range is a time of flight, so between depths it is the slant range (what the
        # filters predict, eq. 7): the 2-D sensor's horizontal range lifted by the depth
        # difference, its variance scaled by (d slant / d horizontal)^2 = (r / slant)^2. Until
        # 2026-12-04 the horizontal range went to the filters as it was: with the school at 50 m
        # and the sender at 5 m the gate rejected almost every range.
        lifted = np.hypot(rng_m, dz)
        var_r[heard] *= np.square(rng_m[heard] / lifted[heard])
        rng_m[heard] = lifted[heard]
        # the compass: bearing (clockwise from north) = pi/2 - heading angle (anticlockwise from east)
        compass_std = np.radians(c.compass_noise_deg) * st.ep_noise_scale[:, None]
        compass = np.pi / 2 - obs_h + st.s_compass_bias_rad + compass_std * n[..., 13]
        # unfold with the survey's estimate: a sender predicted behind is mirrored back
        de = st.b_pos[rows, j, 0][:, None] + st.b_nav_err[rows, j, 0][:, None] - st.s_est[..., 0]
        dn = st.b_pos[rows, j, 1][:, None] + st.b_nav_err[rows, j, 1][:, None] - st.s_est[..., 1]
        predicted_az = wrap_angle_rad(compass - np.arctan2(de, dn))  # anticlockwise positive
        az = np.where(np.abs(predicted_az) > np.pi / 2, np.where(az >= 0, np.pi - az, -np.pi - az), az)
        bearing = compass - az  # a sender to port (positive azimuth) has a smaller bearing
        state = np.where(sends[..., None], np.where(heard, HEARD, NOT_HEARD)[:, None, :], NOT_SENT).astype(np.int8)
        bcast = lambda a: np.broadcast_to(a[:, None, :], shape).copy()
        return MLSMeasurement(state, bcast(rng_m), bcast(bearing), bcast(var_r), bcast(var_az + compass_std**2))

    def fuse(self, draws: dict, out: FusionOutputs, heard: np.ndarray | None = None) -> None:
        """Measure this cycle's sender and fuse its range and bearing (``_fuse``); ``heard``
        (B, N, S): False where a sender's ping is not sent (its beacon away on a surfacing)."""
        st = self.sim.state
        m = self.measure(draws)
        if heard is not None:
            m.state[~heard] = NOT_SENT
        self.kernel(survey_view(st), beacon_view(st), m, st.t_s, self.sim.gate, out)


def build(sim: SensorHost) -> MLSArray:
    """The MLS model of simulator ``sim`` (``measurements.build``)."""
    return MLSArray(sim)
