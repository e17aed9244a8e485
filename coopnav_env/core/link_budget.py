"""The link budget of a scenario: its ``link.LinkParams`` and what one ping is worth.

Read from the scenario's fields once here, for the channel (``core/channel.py``, which
resolves every slot with it) and for the planners' delivery model
(``measurements.arrival_probability``), so that both see one link. No import of the
scenarios package (the measurements package, which the scenarios import, reads it).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .link import Band, LinkParams, NoiseConditions, band_noise_db, success_probability
from .link_framing import framing, message_bits


def on_sonar_link(config: Any) -> bool:
    """Whether ``config``'s pings cross the shared channel's sonar link
    (``channel_mode="decide"``, ``link_model="sonar"``): there the link decides every
    loss, and the modem's range-loss curve is off."""
    return config.channel_mode == "decide" and config.link_model == "sonar"


def link_params(config: Any) -> LinkParams:
    """The link budget of ``config``: its band, noise, thresholds and bit rate; the
    range link hears nothing beyond ``max_range_m`` and has no capture."""
    c = config
    p = LinkParams(
        band=Band(float(c.band_center_khz), float(c.band_width_hz)),
        noise=NoiseConditions(float(c.noise_shipping), float(c.noise_wind_mps)),
        source_level_db=float(c.source_level_db),
        detection_threshold_db=float(c.detection_threshold_db),
        capture_threshold_db=float(c.capture_threshold_db),
        bit_rate_bps=float(c.modem_bit_rate_bps),
    )
    if c.link_model == "range":
        p = p._replace(capture_threshold_db=math.inf, hearing_range_m=float(c.max_range_m))
    return p


def ping_success_probability(config: Any, distance_m: ArrayLike) -> np.ndarray:
    """P(a ping over ``distance_m`` is decoded) on the sonar link of ``config`` alone in
    its slot (no interference): P(detect | SNR) x (1 - PER) of the ping's frames, SNR =
    SL - TL(distance) - NL over the band (``link.success_probability``). What the
    channel draws each ping against (``Channel._decode``); the planners' delivery model
    on this link (``measurements.arrival_probability``)."""
    c = config
    link = link_params(c)
    bits = message_bits(framing(c), c.ping_bits)
    return success_probability(np.asarray(distance_m, float), bits, link, noise_db=band_noise_db(link.band, link.noise))
