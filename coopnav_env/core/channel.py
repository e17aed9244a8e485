"""The acoustic channel as a shared, costly resource, simulated in time over one slot.

Used by ``channel_mode="decide"`` (``ScenarioConfig``); with ``"clock"`` (the
default, the papers' setting) none of this runs and every beacon pings every cycle
on a free channel.

One decision slot of ``ping_interval_s``, times relative to the slot's ping instant
(the end of the vehicles' motion over the slot, when the modem model measures its
ranges):

1. **Pings.** Every beacon that decided to transmit starts its ping at t = 0; it
   lasts ``D_ping = ping_packet_bits / modem_bit_rate_bps`` (a packet's duration is
   its bits over the bit rate). The ping is the one-way range (the survey vehicle
   timestamps its arrival) and tells the other beacons the sender's position.
2. **Replies.** Every survey vehicle that decoded at least one ping replies once per
   slot, with one broadcast packet of ``D_reply = reply_packet_bits /
   modem_bit_rate_bps`` (its estimate, covariance, waypoint index, range age), at the
   fixed time ``t_reply = D_ping + max_range_m / SLOWEST_SOUND_SPEED_MPS +
   turnaround_s``: when every ping from within acoustic range has arrived, plus the
   modem's turn-around. A fixed reply time keeps the reply out of the way of the
   pings it answers; the scenario's validation makes the slot long enough to hold
   it and its flight (``scenarios.base._validate``).
3. **Propagation.** A packet sent at t by vehicle v reaches vehicle w at t + tau,
   tau the time of flight from v's position at t to w moving at constant velocity
   (``acoustics.travel_time``, the modem's time of flight, at the true sound speed
   of the pair's mean depth). It occupies w's receiver over [t + tau, t + tau + D].
4. **Losses.** A packet from beyond ``max_range_m`` is not heard (and too weak to
   disturb others). A packet is lost at w if (a) another heard packet's arrival
   overlaps it at w: a collision, both are lost; (b) w transmits during any part of
   it: half-duplex, a modem cannot hear while it sends. Intervals that only touch
   do not overlap. What survives still meets the range-dependent random loss
   (``acoustics.packet_loss_probability``) with the draws the fixed clock uses:
   ``acoustic_u[..., 0]`` for the ping at a survey vehicle (inside the modem
   model), ``message_u`` for replies and for pings heard by other beacons.
5. **Energy.** A transmission costs ``transmit_power_w x D`` joules.

The timeline is resolved by :func:`resolve_slot` over all V = N + S vehicles of
each environment (beacons first, then survey vehicles), with at most one packet per
vehicle per slot, which is exactly the slot above. ``tests/test_channel.py`` checks
it against hand-computed timelines.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numba import njit, prange

from ..scenarios.base import SLOWEST_SOUND_SPEED_MPS
from . import fusion
from .acoustics import mackenzie_sound_speed, travel_time
from .kernel_records import beacon_view, knowledge_view, survey_view

if TYPE_CHECKING:
    from ..scenarios.base import ScenarioConfig
    from .contract import SensorHost  # not .sim: sim imports this module


def packet_duration_s(bits: float | np.ndarray, bit_rate_bps: float | np.ndarray) -> float | np.ndarray:
    """How long a packet of ``bits`` occupies the channel at ``bit_rate_bps`` (s): bits / bit rate."""
    d = np.asarray(bits, dtype=float) / np.asarray(bit_rate_bps, dtype=float)
    return float(d) if d.ndim == 0 else d


def transmit_energy_j(
    power_w: float | np.ndarray, duration_s: float | np.ndarray, packets: int | np.ndarray = 1
) -> float | np.ndarray:
    """Electrical energy of ``packets`` transmissions of ``duration_s`` each at ``power_w`` (J)."""
    return packets * power_w * duration_s


def reply_time_s(config: ScenarioConfig) -> float:
    """When a survey vehicle's reply starts, after the slot's ping instant (s): the ping's
    duration, the longest flight from within acoustic range and the turn-around."""
    c = config
    return (
        packet_duration_s(c.ping_bits, c.modem_bit_rate_bps) + c.max_range_m / SLOWEST_SOUND_SPEED_MPS + c.turnaround_s
    )


def _resolve_slot(
    pos, vel, tx_start, tx_dur, temperature_c, salinity_psu, max_range_m, arrival, delivered, collided, deaf
):
    """One slot's packets at every receiver, in place.

    pos, vel (B, V, 3): positions at t = 0 and constant velocities; tx_start (B, V):
    when each vehicle starts its one packet (NaN: silent); tx_dur (B, V) its duration;
    temperature_c (B,): the true water temperature (sound speed, Mackenzie 1981).
    Outputs (B, V, V), [sender, receiver]: ``arrival`` start of the packet at the
    receiver (NaN: not sent or out of range), ``delivered`` (heard, no collision, the
    receiver not transmitting), ``collided`` (another heard arrival overlaps it),
    ``deaf`` (the receiver transmits while it arrives).
    """
    B, V = pos.shape[0], pos.shape[1]
    for b in prange(B):
        src = np.empty(3)
        rcv = np.empty(3)
        for v in range(V):
            for w in range(V):
                arrival[b, v, w] = np.nan
                delivered[b, v, w] = False
                collided[b, v, w] = False
                deaf[b, v, w] = False
        for v in range(V):
            t0 = tx_start[b, v]
            if not np.isfinite(t0):
                continue
            for w in range(V):
                if w == v:
                    continue
                for k in range(3):
                    src[k] = pos[b, v, k] + vel[b, v, k] * t0
                    rcv[k] = pos[b, w, k] + vel[b, w, k] * t0
                d = np.sqrt((rcv[0] - src[0]) ** 2 + (rcv[1] - src[1]) ** 2 + (rcv[2] - src[2]) ** 2)
                if d > max_range_m:
                    continue
                c = mackenzie_sound_speed(temperature_c[b], salinity_psu, 0.5 * (src[2] + rcv[2]))
                arrival[b, v, w] = t0 + travel_time(src, rcv, vel[b, w], c)
        for w in range(V):
            for v in range(V):
                a = arrival[b, v, w]
                if not np.isfinite(a):
                    continue
                e = a + tx_dur[b, v]
                # half-duplex: the receiver's own transmission overlaps the arrival
                t_own = tx_start[b, w]
                if np.isfinite(t_own) and t_own < e and a < t_own + tx_dur[b, w]:
                    deaf[b, v, w] = True
                for u in range(V):
                    a2 = arrival[b, u, w]
                    if u != v and np.isfinite(a2) and a2 < e and a < a2 + tx_dur[b, u]:
                        collided[b, v, w] = True
                        break
                delivered[b, v, w] = not (deaf[b, v, w] or collided[b, v, w])


resolve_slot_kernel = njit(cache=True)(_resolve_slot)
resolve_slot_kernel_parallel = njit(cache=True, parallel=True)(_resolve_slot)


def resolve_slot(
    pos: np.ndarray,
    vel: np.ndarray,
    tx_start: np.ndarray,
    tx_dur: np.ndarray,
    temperature_c: np.ndarray,
    salinity_psu: float,
    max_range_m: float,
    parallel: bool = False,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_resolve_slot` on fresh output arrays: (arrival, delivered, collided, deaf), each (B, V, V)."""
    pos, vel = np.ascontiguousarray(pos, float), np.ascontiguousarray(vel, float)
    tx_start, tx_dur = np.ascontiguousarray(tx_start, float), np.ascontiguousarray(tx_dur, float)
    B, V = pos.shape[:2]
    arrival = np.empty((B, V, V))
    flags = [np.empty((B, V, V), dtype=bool) for _ in range(3)]
    kernel = resolve_slot_kernel_parallel if parallel else resolve_slot_kernel
    kernel(
        pos,
        vel,
        tx_start,
        tx_dur,
        np.ascontiguousarray(temperature_c, float),
        float(salinity_psu),
        float(max_range_m),
        arrival,
        *flags,
    )
    return arrival, flags[0], flags[1], flags[2]


class Channel:
    """The channel of one simulator in ``channel_mode="decide"``: the scenario's packet
    durations, reply time and energy per ping gathered once; ``pings`` and ``replies``
    resolve a slot in two passes (the replies depend on which pings were decoded)."""

    def __init__(self, sim: SensorHost) -> None:
        c = sim.config
        self.sim = sim
        self.N, self.S = sim.N, sim.S
        self.ping_s = packet_duration_s(c.ping_bits, c.modem_bit_rate_bps)
        self.reply_s = packet_duration_s(c.reply_packet_bits, c.modem_bit_rate_bps)
        self.reply_at_s = reply_time_s(c)
        self.ping_energy_j = transmit_energy_j(c.transmit_power_w, self.ping_s)
        self.tx_dur = np.concatenate([np.full(self.N, self.ping_s), np.full(self.S, self.reply_s)])
        self.parallel = sim.batch_size >= 256
        self._k_exchange = fusion.exchange_messages_parallel if self.parallel else fusion.exchange_messages

    def transmit_mask(self, actions: np.ndarray, cycle: np.ndarray) -> np.ndarray:
        """(B, N) bool: who transmits this slot. The third action component > 0; a
        two-component action (the motion alone) transmits every slot, as the fixed clock;
        with ``tdma_frame_slots`` F > 0, beacon j only in slots k with k mod F == j mod F."""
        c = self.sim.config
        B, N = actions.shape[0], actions.shape[1]
        tx = actions[..., 2] > 0.0 if actions.shape[-1] > 2 else np.ones((B, N), dtype=bool)
        if c.tdma_frame_slots > 0:
            F = c.tdma_frame_slots
            tx = tx & ((np.asarray(cycle)[:, None] % F) == (np.arange(N)[None, :] % F))
        return tx

    def _timeline(
        self, beacon_tx: np.ndarray, survey_tx: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        st, c = self.sim.state, self.sim.config
        assert st is not None, "the simulator is reset before its channel is used"
        B = st.b_pos.shape[0]
        pos = np.concatenate([st.b_pos, st.s_pos], 1)
        vel = np.concatenate([st.b_vel, st.s_vel_true], 1)
        start = np.concatenate([np.where(beacon_tx, 0.0, np.nan), np.where(survey_tx, self.reply_at_s, np.nan)], 1)
        return resolve_slot(
            pos,
            vel,
            start,
            np.broadcast_to(self.tx_dur, (B, self.N + self.S)),
            st.temperature_c,
            c.salinity_psu,
            c.max_range_m,
            self.parallel,
        )

    def pings(self, beacon_tx: np.ndarray) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
        """The pings alone: (B, N, S) delivered at the survey vehicles (before the random
        loss), and the whole resolution (arrival, delivered, collided, deaf)."""
        N = self.N
        out = self._timeline(beacon_tx, np.zeros((beacon_tx.shape[0], self.S), dtype=bool))
        return out[1][:, :N, N:], out

    def replies(
        self, beacon_tx: np.ndarray, survey_tx: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
        """The whole slot with the replies of ``survey_tx`` (B, S): (reply_ok (B, N, S),
        peer_ok (B, N, N) [receiver, sender], resolution)."""
        N = self.N
        out = self._timeline(beacon_tx, survey_tx)
        delivered = out[1]
        return (
            np.ascontiguousarray(np.swapaxes(delivered[:, N:, :N], 1, 2)),
            np.ascontiguousarray(np.swapaxes(delivered[:, :N, :N], 1, 2)),
            out,
        )

    def exchange(self, draws: dict[str, np.ndarray], reply_ok: np.ndarray, peer_ok: np.ndarray) -> None:
        """The replies and the peers' positions as ``Simulator._exchange_messages`` does
        them, through the channel's masks."""
        st = self.sim.state
        assert st is not None, "the simulator is reset before its channel is used"
        self._k_exchange(
            survey_view(st),
            beacon_view(st),
            knowledge_view(st),
            st.t_s,
            draws["message_u"],
            reply_ok,
            peer_ok,
            self.sim.params,
        )


# ------------------------------------------------------------------------------------
# the registry of channel models: a scenario's ``channel_mode`` names one


@dataclass(frozen=True)
class ChannelModel:
    """One registered channel model (see :func:`register_channel_model`)."""

    name: str
    build: Callable[[Any], Any]
    action_dim: int = 2
    beacon_info_keys: tuple = ()
    doc: str = ""


_CHANNEL_MODELS: dict[str, ChannelModel] = {}


def register_channel_model(
    name: str, build: Callable[[Any], Any], *, action_dim: int = 2, beacon_info_keys: tuple = (), doc: str = ""
) -> ChannelModel:
    """Register the channel model ``name`` (a scenario's ``channel_mode``) and return it.

    ``build(sim)``: the simulator's channel object (None: the free channel of the fixed
    clock, every ping and reply delivered but for the random loss; else an object with
    ``transmit_mask``, ``pings``, ``replies``, ``exchange`` and ``ping_energy_j`` as
    :class:`Channel`); ``action_dim``: components of a beacon's action (3: the third
    decides whether to transmit); ``beacon_info_keys``: the per-beacon infos it adds.
    Its reward terms register in ``core.reward`` with ``modes={"channel_mode": (name,)}``.
    """
    if name in _CHANNEL_MODELS:
        raise ValueError(f"channel model {name!r} is registered twice")
    model = ChannelModel(name, build, int(action_dim), tuple(beacon_info_keys), doc)
    _CHANNEL_MODELS[name] = model
    return model


def channel_model(name: str) -> ChannelModel:
    """The registered channel model ``name`` (``ValueError`` listing the valid ones)."""
    if name not in _CHANNEL_MODELS:
        raise ValueError(f"unknown channel_mode {name!r}; valid modes: {', '.join(_CHANNEL_MODELS)}")
    return _CHANNEL_MODELS[name]


def channel_model_names() -> tuple[str, ...]:
    """The registered channel models' names: the valid values of ``channel_mode``."""
    return tuple(_CHANNEL_MODELS)


register_channel_model(
    "clock", lambda sim: None, doc="the papers' fixed clock: every beacon pings every cycle on a free channel"
)
register_channel_model(
    "decide",
    Channel,
    action_dim=3,
    beacon_info_keys=("pings", "collisions", "energy_J"),
    doc="a decision slot per step on a shared channel in time (this module's docstring)",
)
