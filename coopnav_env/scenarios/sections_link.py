"""The acoustic link's sections: the modem's packets and power, the MLS array's
receiver (with ``acoustic_sensor="mls"``) and the shared channel's price and schedule
(with ``channel_mode="decide"``). ``sections.py`` and ``sections_beacons.py`` hold others; ``config.py``
assembles them."""

from __future__ import annotations

from .params import Section, param, section

LINK_MODELS = ("sonar", "range")
PING_OFFSETS = ("staggered", "random", "zero")


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
    link_model: str = param(
        "sonar",
        choices=LINK_MODELS,
        doc='"sonar": Micro-Modem packets, loss from the sonar equation\'s SNR, capture by SIR, no hard '
        'interference range (core/link.py); "range": the earlier bits / bit rate packets, loss quadratic in '
        "range (packet_loss_near/far), nothing heard beyond max_range_m, any overlap a collision",
    )
    ping_offsets: str = param(
        "staggered",
        choices=PING_OFFSETS,
        doc='where beacon j\'s ping starts in the slot: "staggered" j (ping + max_range_m / 1400 m/s), one '
        'packet clear of the previous at every receiver in range; "random" uniform over the same span, drawn '
        'each slot; "zero" every ping at t = 0 (the earlier channel)',
    )
    source_level_db: float = param(
        185.0,
        unit="dB re 1 uPa at 1 m",
        low=100.0,
        high=240.0,
        source="assumption [U]",
        doc="SL of every modem (link_model='sonar') [U: Micro-Modem transducers 185-190 dB, issue 21]",
    )
    transmit_efficiency: float = param(
        0.25,
        low=0.0,
        high=1.0,
        open_low=True,
        source="assumption [U]",
        doc="acoustic over electrical power while transmitting: a ping costs 10^((SL - 170.8) / 10) W / this "
        "x its duration (link_model='sonar'; Urick 1983)",
    )
    band_center_khz: float = param(
        25.0,
        unit="kHz",
        low=1.0,
        high=100.0,
        source="Freitag et al. 2005; centre [U]",
        doc="the modem's band centre: Thorp absorption and the noise band (link_model='sonar')",
    )
    band_width_hz: float = param(
        4000.0,
        unit="Hz",
        low=100.0,
        high=50000.0,
        source="acomms.whoi.edu (FSK)",
        doc="the modem's bandwidth: the noise band and Eb/N0 (link_model='sonar')",
    )
    noise_shipping: float = param(
        0.5,
        low=0.0,
        high=1.0,
        source="assumption [U]",
        doc="shipping activity of the Wenz/Coates noise model, 0-1 (Stojanovic 2007; link_model='sonar')",
    )
    noise_wind_mps: float = param(
        5.0,
        unit="m/s",
        low=0.0,
        high=40.0,
        source="assumption [U]",
        doc="surface wind of the Wenz/Coates noise model (about sea state 2-3; link_model='sonar')",
    )
    detection_threshold_db: float = param(
        3.0,
        unit="dB",
        low=-20.0,
        high=40.0,
        source="assumption [U]",
        doc="in-band SNR the probe detector needs; Rayleigh fading: P(detect) = exp(-thr / SNR), linear",
    )
    capture_threshold_db: float = param(
        10.0,
        unit="dB",
        low=0.0,
        high=60.0,
        source="assumption [U]",
        doc="SIR over overlapping receptions at which a packet survives them (capture; link_model='sonar')",
    )
