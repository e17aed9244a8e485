"""The modem's packets on the water for ``core.link`` (which re-exports all of it): the
WHOI Micro-Modem's framing (how long a packet lasts) and where packets start within a
slot (staggered or drawn, not all at t = 0). Split from ``link`` to keep each module of
the core readable in one sitting (``tests/test_kernel_shape.py``)."""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np


class MicroModemFraming(NamedTuple):
    """Timing constants of one WHOI Micro-Modem packet (default: FH-FSK rate 0).

    A packet on the water is: [cycle-init packet + gap] + probe + null + frames, with
    ``inter_frame_gap_s`` between frames.

    - ``bit_rate_bps`` 80: FH-FSK rate 0 (acomms.whoi.edu "80-5400 bps"; Freitag et
      al. 2005).
    - ``frame_bytes`` 32 and ``max_frames`` 1: rate 0's frame size and frame count
      (goby-acomms ``MMDriver::PACKET_SIZE[0]``, ``PACKET_FRAME_COUNT[0]``). A frame
      is sent whole (padded), so it lasts 8 x 32 / 80 = 3.2 s (derived).
    - ``probe_s`` 0.2 and ``probe_gap_s`` 0.1: their sum, 0.30 s, is the probe + null
      of acomms.whoi.edu's packet table (rate 6: 3.25 s signal, 2.95 s packet,
      derived); the split between them is [U], and that FSK packets have the same
      probe as PSK ones is [U].
    - ``cycle_init_s`` 1.0 and ``cycle_init_gap_s`` 0.5: the cycle-init packet that
      precedes data (issue 21; Singh et al. 2006) and the pause after it; durations
      [U].
    - ``inter_frame_gap_s`` 0.0 [U]: immaterial for rate 0 (one frame).
    - ``with_cycle_init`` True: a cycle-init precedes the data (a modem that sends a
      data packet without one, as a mini-packet ping might, sets False).
    """

    bit_rate_bps: float = 80.0
    frame_bytes: int = 32
    max_frames: int = 1
    probe_s: float = 0.2
    probe_gap_s: float = 0.1
    cycle_init_s: float = 1.0
    cycle_init_gap_s: float = 0.5
    inter_frame_gap_s: float = 0.0
    with_cycle_init: bool = True


DEFAULT_FRAMING = MicroModemFraming()


# ------------------------------------------------------------------ packet timing


def frames_needed(framing: MicroModemFraming, payload_bits: int) -> int:
    """How many frames carry ``payload_bits`` (at least one; a frame is sent whole)."""
    frame_bits = 8 * framing.frame_bytes
    n = max(1, -(-int(payload_bits) // frame_bits))
    if n > framing.max_frames:
        raise ValueError(
            f"{payload_bits} bits need {n} frames of {framing.frame_bytes} bytes; this rate carries "
            f"at most {framing.max_frames}"
        )
    return n


def packet_duration_s(framing: MicroModemFraming = DEFAULT_FRAMING, payload_bits: int = 256) -> float:
    """How long one Micro-Modem packet occupies the water (s):
    [cycle-init + gap] + probe + null + n x frame + (n - 1) x inter-frame gap, with
    frame = 8 x frame_bytes / bit rate. Default (FH-FSK rate 0, one 32-byte frame):
    1.0 + 0.5 + 0.2 + 0.1 + 3.2 = 5.0 s."""
    n = frames_needed(framing, payload_bits)
    frame_s = 8.0 * framing.frame_bytes / framing.bit_rate_bps
    head_s = framing.cycle_init_s + framing.cycle_init_gap_s if framing.with_cycle_init else 0.0
    return head_s + framing.probe_s + framing.probe_gap_s + n * frame_s + (n - 1) * framing.inter_frame_gap_s


def message_duration_s(framing: MicroModemFraming = DEFAULT_FRAMING, payload_bits: int = 256) -> float:
    """How long a message of ``payload_bits`` occupies the water (s): as many packets
    of at most ``max_frames`` frames as it needs, back to back [U], each with its probe
    and null, after one cycle-init. One packet: ``packet_duration_s``."""
    frame_bits = 8 * framing.frame_bytes
    frames = max(1, -(-int(payload_bits) // frame_bits))
    packets = -(-frames // framing.max_frames)
    head_s = framing.cycle_init_s + framing.cycle_init_gap_s if framing.with_cycle_init else 0.0
    frame_s = frame_bits / framing.bit_rate_bps
    probe_s = framing.probe_s + framing.probe_gap_s
    return head_s + packets * probe_s + frames * frame_s + (frames - packets) * framing.inter_frame_gap_s


def message_bits(framing: MicroModemFraming, payload_bits: int) -> int:
    """The bits on the water for ``payload_bits``: whole frames (a frame is sent padded),
    the n of the packet error rate."""
    frame_bits = 8 * framing.frame_bytes
    return max(1, -(-int(payload_bits) // frame_bits)) * frame_bits


# ------------------------------------------------------------------ slot offsets


def random_offsets_s(rng: np.random.Generator, shape: int | tuple[int, ...], max_offset_s: float) -> np.ndarray:
    """Transmit starts drawn uniformly in [0, max_offset_s) (an ALOHA-like slot)."""
    return rng.uniform(0.0, max_offset_s, size=shape)


def staggered_offsets_s(
    n_senders: int, packet_s: float, max_range_m: float, sound_speed_mps: float = 1400.0, guard_s: float = 0.0
) -> np.ndarray:
    """Starts k x (packet + max_range / c + guard) for k = 0..n-1: each packet has left
    every receiver within ``max_range_m`` before the next starts (a TDMA slot plan;
    1400 m/s is slower than any sea water, ``scenarios.base.SLOWEST_SOUND_SPEED_MPS``)."""
    return np.arange(n_senders) * (packet_s + max_range_m / sound_speed_mps + guard_s)


# ------------------------------------------------------------------ a channel's slot


class SlotTiming(NamedTuple):
    """A decision slot's packet timing (s): the ping's and reply's durations, the
    stagger between beacons' pings, the last ping's latest start, the reply time and
    the slot the whole exchange needs (``need_s`` <= ``ping_interval_s``)."""

    ping_s: float
    reply_s: float
    step_s: float
    last_offset_s: float
    reply_at_s: float
    need_s: float


def framing(config: Any) -> MicroModemFraming:
    """The Micro-Modem framing at the scenario's bit rate (rate 0's 32-byte frame [U]
    at other rates)."""
    return MicroModemFraming(bit_rate_bps=float(config.modem_bit_rate_bps))


def packet_durations_s(config: Any) -> tuple[float, float]:
    """(ping, reply) durations (s): Micro-Modem framing (``link_model="sonar"``) or
    bits / bit rate (``"range"``)."""
    c = config
    if c.link_model == "sonar":
        f = framing(c)
        return message_duration_s(f, c.ping_bits), message_duration_s(f, c.reply_packet_bits)
    return c.ping_bits / c.modem_bit_rate_bps, c.reply_packet_bits / c.modem_bit_rate_bps


def slot_timing(config: Any, slowest_sound_speed_mps: float) -> SlotTiming:
    """The slot's timing (``SlotTiming``) for ``config``'s packets, beacons and offsets:
    the pings staggered by D_ping + max_range_m / 1400 m/s (or drawn over that span,
    or all at 0), the reply after the last ping's flight and the turn-around, the
    slot until the reply has flown ``max_range_m``; flights at
    ``slowest_sound_speed_mps`` (``scenarios.validate.SLOWEST_SOUND_SPEED_MPS``, passed
    in: the scenarios' validation calls this)."""
    c = config
    ping_s, reply_s = packet_durations_s(c)
    flight_s = c.max_range_m / slowest_sound_speed_mps
    step_s = ping_s + flight_s
    last_s = 0.0 if c.ping_offsets == "zero" else (c.n_beacons - 1) * step_s
    reply_at_s = last_s + ping_s + flight_s + c.turnaround_s
    return SlotTiming(ping_s, reply_s, step_s, last_s, reply_at_s, reply_at_s + reply_s + flight_s)
