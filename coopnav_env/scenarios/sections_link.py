"""The acoustic link's sections: the modem's packets and power, the MLS array's
receiver (with ``acoustic_sensor="mls"``) and the shared channel's price and schedule
(with ``channel_mode="decide"``). ``sections.py`` holds the others; ``config.py``
assembles them."""

from __future__ import annotations

from .params import Section, param, section


@section
class Modem(Section):
    """The acoustic modem's packets and power (the channel's timing, and the energy a ping costs)."""

    modem_bit_rate_bps: float = param(
        80.0,
        unit="bit/s",
        low=0,
        high=1000000.0,
        open_low=True,
        source="reference-values.md §3",
        doc="WHOI Micro-Modem FH-FSK, the slowest of its 80-5400 bps, ref-values section 3",
    )
    ping_packet_bits: int = param(
        64,
        unit="bit",
        low=1,
        high=1000000,
        source="assumption [U]",
        doc="a beacon's ping: id, send time, own position and variance [U]",
    )
    reply_packet_bits: int = param(
        128,
        unit="bit",
        low=1,
        high=1000000,
        source="assumption [U]",
        doc="a survey vehicle's reply: estimate, covariance, waypoint index, range age [U]",
    )
    transmit_power_w: float = param(
        40.0,
        unit="W",
        low=0.0,
        high=10000.0,
        source="assumption [U]",
        doc="electrical power while a modem transmits [U: tens of watts]",
    )


@section
class MLSSensor(Section):
    """Kottege & Zimmer's MLS array (``acoustic_sensor="mls"``)."""

    mls_snr_db_at_1m: float = param(
        30.0,
        unit="dB",
        low=-50.0,
        high=150.0,
        source="assumption [U]",
        doc="in-band SNR per sample at 1 m [U]; falls 20 log10(r)",
    )
    mls_max_range_m: float = param(
        60.0,
        unit="m",
        low=1.0,
        high=10000.0,
        source="assumption [U]",
        doc="receive window; farther senders are not heard [U]",
    )


@section
class Channel(Section):
    """The acoustic channel as a shared, costly resource (``channel_mode="decide"``)."""

    ping_penalty: float = param(
        0.0, low=0.0, high=1000000.0, doc='reward weight of the "ping" term (per ping a beacon transmits)'
    )
    tdma_frame_slots: int = param(
        0,
        unit="slots",
        low=0,
        high=1024,
        doc="> 0: beacon j may transmit only in slots k with k mod this == j mod this (0: any slot)",
    )
