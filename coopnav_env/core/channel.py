"""The acoustic channel as a shared, costly resource, simulated in time over one slot.

Used by ``channel_mode="decide"`` (``ScenarioConfig``); with ``"clock"`` (the
default, the papers' setting) none of this runs and every beacon pings every cycle
on a free channel.

One decision slot of ``ping_interval_s``, times relative to the slot's ping instant
(the end of the vehicles' motion over the slot, when the modem model measures its
ranges); ``link_framing.slot_timing`` gathers the numbers, the scenario's validation checks that
the slot holds them (``scenarios.validate``):

1. **Pings.** Every beacon that decided to transmit starts its ping at its offset in
   the slot (``ping_offsets``): "staggered", beacon j at j x (D_ping + max_range_m /
   1400 m/s), so that every ping has left every receiver within ``max_range_m``
   before the next starts; "random", uniform over the same span, drawn each slot
   (``ping_offset_u``, the last of the cycle's draws); "zero", all at t = 0. The
   ping is the one-way range (the survey vehicle timestamps its arrival) and tells
   the other beacons the sender's position.
2. **Replies.** Every survey vehicle that decoded at least one ping by then replies
   once per slot with one broadcast packet (its estimate, covariance, waypoint index,
   range age) at ``t_reply`` = the last ping offset + D_ping + max_range_m / 1400 m/s +
   ``turnaround_s``: when every ping from within ``max_range_m`` has arrived. A ping
   from farther (the sonar link hears it) still arriving then is lost to the reply
   (half duplex); one that is alone is measured, and no reply is sent.
3. **Propagation** (``link.slot_timeline``, the one home of the slot's physics): a
   packet sent at t by vehicle v reaches w at t + tau, tau the time of flight from
   v's position at t to w moving at constant velocity (``acoustics.travel_time``) at
   the true sound speed of the pair's mean depth (Mackenzie 1981). It occupies w's
   receiver over [t + tau, t + tau + D].
4. **Losses**, by ``link_model``:

   - ``"sonar"`` (the default): packets last what the WHOI Micro-Modem's framing
     makes them (``link_framing.message_duration_s``: cycle-init, probe, frames; 5 s
     at 80 bps); every sender is heard everywhere at RL = SL - TL (spherical spreading
     + Thorp absorption at the band); a reception overlapped by others survives if
     its SIR over their power sum reaches ``capture_threshold_db`` (capture); a
     receiver that transmits during it loses it (half duplex); what survives is
     decoded with P = P(detect | SNR) x (1 - PER), SNR = RL - NL over the band
     (Wenz/Coates noise), drawn on the modem's own uniform (``acoustic_u[..., 0]``
     for a ping at a survey vehicle, counted in ``packets_lost`` when it fails) and
     the messages' (``message_u``) for replies and pings at other beacons: lost if
     u < 1 - P. The modem's and messages' range loss is then off.
   - ``"range"`` (the earlier model, kept for reproductions): packets last bits /
     bit rate; a sender beyond ``max_range_m`` (straight line at its start) is
     neither heard nor interferes; any overlap loses both packets (capture off);
     half duplex; what survives meets the quadratic range loss
     (``acoustics.packet_loss_probability``) inside the modem and message kernels.
5. **Energy.** A ping costs its electrical energy: ``"sonar"``, 10^((SL - 170.8) /
   10) W / ``transmit_efficiency`` x D_ping (Urick 1983; 526 J at 185 dB, 25 %,
   5 s); ``"range"``, ``transmit_power_w`` x D_ping.

``tests/test_channel.py`` checks the wired channel against hand-computed cases.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from ..scenarios.base import SLOWEST_SOUND_SPEED_MPS
from . import fusion
from .acoustics import mackenzie_sound_speed
from .jit import threaded
from .kernel_records import beacon_view, knowledge_view, survey_view
from .link import (
    PowerModel,
    SlotOutcome,
    SlotTransmissions,
    band_noise_db,
    slot_timeline,
    transmit_energy_j,
)
from .link_budget import link_params, on_sonar_link
from .link_framing import framing, message_bits, slot_timing

if TYPE_CHECKING:
    from ..scenarios.base import ScenarioConfig
    from .contract import SensorHost  # not .sim: sim imports this module


def ping_energy_j(config: ScenarioConfig) -> float:
    """Electrical energy of one ping (J): from the source level and efficiency on the
    sonar link (Urick 1983), else (the range link, the fixed clock) transmit power x
    bits / bit rate."""
    c = config
    if on_sonar_link(c):
        power = PowerModel(efficiency=float(c.transmit_efficiency))
        return float(transmit_energy_j(c.source_level_db, slot_timing(c, SLOWEST_SOUND_SPEED_MPS).ping_s, power))
    return float(c.transmit_power_w * c.ping_bits / c.modem_bit_rate_bps)


class SlotResult(NamedTuple):
    """One slot at every receiver, (B, V, V) [sender, receiver], V = N beacons then S
    survey vehicles: ``arrival`` (NaN: not sent or not heard), ``delivered`` (the pings
    at the survey vehicles decoded; elsewhere reached intact, before the message's draw),
    ``collided`` (overlapped and not captured), ``deaf`` (the receiver was
    transmitting), ``lost`` (reached the receiver intact but not decoded: the sonar
    link's draw of P(decode) at the SINR), the whole ``link.SlotOutcome``, and ``ended`` (the reception had
    ended by the survey vehicles' reply time: only such a ping can be replied to)."""

    arrival: np.ndarray
    delivered: np.ndarray
    collided: np.ndarray
    deaf: np.ndarray
    lost: np.ndarray
    outcome: SlotOutcome
    ended: np.ndarray


class Channel:
    """The channel of one simulator in ``channel_mode="decide"``: the scenario's packet
    timing, link budget and energy per ping gathered once; ``pings`` and ``replies``
    resolve a slot in two passes (the replies depend on which pings were decoded by the
    reply time, and a late ping on whether its receiver replies)."""

    def __init__(self, sim: SensorHost) -> None:
        c = sim.config
        self.sim = sim
        self.N, self.S = sim.N, sim.S
        self.sonar = c.link_model == "sonar"
        self.timing = slot_timing(c, SLOWEST_SOUND_SPEED_MPS)
        self.ping_s, self.reply_s, self.reply_at_s = self.timing.ping_s, self.timing.reply_s, self.timing.reply_at_s
        self.ping_energy_j = ping_energy_j(c)
        self.link = link_params(c)
        self.noise_db = band_noise_db(self.link.band, self.link.noise)
        self.tx_dur = np.concatenate([np.full(self.N, self.ping_s), np.full(self.S, self.reply_s)])
        f = framing(c)  # the PER counts the frames' bits (a frame is sent whole)
        self.tx_bits = np.concatenate(
            [
                np.full(self.N, message_bits(f, c.ping_bits)),
                np.full(self.S, message_bits(f, c.reply_packet_bits)),
            ]
        )
        self.parallel = threaded(sim.batch_size)
        self._k_exchange = fusion.exchange_messages_parallel if self.parallel else fusion.exchange_messages
        self._exchange_params = sim.params
        if self.sonar:  # the link decides every loss: the modem's and the messages' range loss off
            sim.sensor.params = sim.sensor.params._replace(loss_near=0.0, loss_far=0.0, max_range_m=math.inf)  # type: ignore[attr-defined]
            self._exchange_params = sim.params._replace(loss_near=0.0, loss_far=0.0, max_range_m=math.inf)

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

    def offsets_s(self, draws: dict[str, np.ndarray]) -> np.ndarray:
        """(B, N) each beacon's ping start in this slot (``ping_offsets``)."""
        mode, t = self.sim.config.ping_offsets, self.timing
        B = draws["ping_offset_u"].shape[0]
        if mode == "random":
            return draws["ping_offset_u"] * t.last_offset_s
        step = 0.0 if mode == "zero" else t.step_s
        return np.broadcast_to(np.arange(self.N) * step, (B, self.N))

    def _timeline(self, beacon_tx: np.ndarray, survey_tx: np.ndarray, draws: dict[str, np.ndarray]) -> SlotOutcome:
        """The slot through ``link.slot_timeline``: the pings at their offsets, the replies
        at the reply time, the sound speed of each pair at its mean depth at the send."""
        st, c = self.sim.state, self.sim.config
        assert st is not None, "the simulator is reset before its channel is used"
        B = st.b_pos.shape[0]
        pos = np.concatenate([st.b_pos, st.s_pos], 1)
        vel = np.concatenate([st.b_vel, st.s_vel_true], 1)
        start = np.concatenate(
            [np.where(beacon_tx, self.offsets_s(draws), np.nan), np.where(survey_tx, self.reply_at_s, np.nan)], 1
        )
        src_z = pos[..., 2] + vel[..., 2] * start  # (B, V): the sender's depth at its start
        rcv_z = pos[:, None, :, 2] + vel[:, None, :, 2] * start[:, :, None]  # (B, V, V): each receiver's then
        c_pair = mackenzie_sound_speed(
            st.temperature_c[:, None, None], c.salinity_psu, 0.5 * (src_z[:, :, None] + rcv_z)
        )
        V = self.N + self.S
        tx = SlotTransmissions(
            pos,
            vel,
            start,
            np.broadcast_to(self.tx_dur, (B, V)),
            np.full((B, V), self.link.source_level_db),
            self.tx_bits,
        )
        return slot_timeline(tx, c_pair, self.link, self.noise_db, self.parallel)

    def _decode(self, o: SlotOutcome, u: np.ndarray, sl: tuple) -> tuple[np.ndarray, np.ndarray]:
        """The block ``sl`` of the slot's receptions, indexed as ``u`` (its uniforms):
        (decoded, lost). Reached: captured and not deaf; on the sonar link decoded if
        u >= 1 - P (lost if u < 1 - P, the modem kernel's convention), on the range
        link every reached one (the kernels draw their own range loss)."""
        reach = (o.captured & ~o.deaf)[sl]
        if not self.sonar:
            return reach, np.zeros_like(reach)
        ok = reach & (u >= 1.0 - o.p_success[sl])  # lost if u < 1 - P, the modem's convention
        return ok, reach & ~ok

    def pings(self, beacon_tx: np.ndarray, draws: dict[str, np.ndarray]) -> tuple[np.ndarray, SlotResult]:
        """The pings the survey vehicles measure: (B, N, S) decoded, and the slot
        (``SlotResult``; its ``lost`` the pings the sonar link's SNR draw lost). A survey
        vehicle replies at the reply time if it decoded a ping that had ended by then, and
        a ping still arriving at one that replies is lost to its own reply (half duplex;
        on the sonar link a ping from beyond ``max_range_m``, for which the reply time is
        laid out): the slot is then resolved again with those replies (a review found the
        measured pings taken from the silent slot alone)."""
        pings = (slice(None), slice(None, self.N), slice(self.N, None))
        u = draws["acoustic_u"][..., 0]
        o = self._timeline(beacon_tx, np.zeros((beacon_tx.shape[0], self.S), dtype=bool), draws)
        ok, lost = self._decode(o, u, pings)
        ended = o.end_s <= self.reply_at_s  # NaN (not sent): False
        replying: np.ndarray = np.asarray((ok & ended[pings]).any(1))  # (B, S)
        if replying.any():
            # the slot with the replies in it, for every environment (each row only its own:
            # a batch row stays the environment alone); the replies start after every ended
            # ping, so those decode as before and only the late change (deaf, or overlapped)
            o = self._timeline(beacon_tx, replying, draws)
            ok, lost = self._decode(o, u, pings)
        return ok, self._result(o, ok, lost, ended)

    def _result(self, o: SlotOutcome, ok: np.ndarray, lost: np.ndarray, ended: np.ndarray) -> SlotResult:
        N = self.N
        delivered = o.captured & ~o.deaf
        delivered[:, N:, :] = False  # the replies are the second pass's (``replies``)
        delivered[:, :N, N:] = ok
        full_lost = np.zeros_like(delivered)
        full_lost[:, :N, N:] = lost
        return SlotResult(o.arrival_s, delivered, o.overlapped & ~o.captured, o.deaf, full_lost, o, ended)

    def replies(
        self,
        beacon_tx: np.ndarray,
        survey_tx: np.ndarray,
        draws: dict[str, np.ndarray],
        pinged: SlotResult | None = None,
    ) -> tuple[np.ndarray, np.ndarray, SlotOutcome]:
        """The whole slot with the replies of ``survey_tx`` (B, S): (reply_ok (B, N, S),
        peer_ok (B, N, N) [receiver, sender], the slot's ``link.SlotOutcome``). ``pinged``:
        ``pings``' result of this slot, whose outcome is reused when it was resolved with
        these very replies (those of the pings decoded by the reply time), not computed again."""
        N, S = self.N, self.S
        if pinged is not None and np.array_equal(
            survey_tx, (pinged.delivered[:, :N, N:] & pinged.ended[:, :N, N:]).any(1)
        ):
            o = pinged.outcome
        else:
            o = self._timeline(beacon_tx, survey_tx, draws)
        # [receiver, sender] as the message kernel reads them
        o_rs = o._replace(captured=np.swapaxes(o.captured, 1, 2), deaf=np.swapaxes(o.deaf, 1, 2))
        o_rs = o_rs._replace(p_success=np.swapaxes(o.p_success, 1, 2))
        u = draws["message_u"]
        reply_ok, _ = self._decode(o_rs, u[..., :S], (slice(None), slice(None, N), slice(N, None)))
        peer_ok, _ = self._decode(o_rs, u[..., S:], (slice(None), slice(None, N), slice(None, N)))
        return np.ascontiguousarray(reply_ok), np.ascontiguousarray(peer_ok), o

    def exchange(self, draws: dict[str, np.ndarray], reply_ok: np.ndarray, peer_ok: np.ndarray) -> None:
        """The replies and the peers' positions as ``Simulator._exchange_messages`` does
        them, through the channel's masks (on the sonar link the kernel's own loss is off)."""
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
            self._exchange_params,
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
