"""``sousa_ping``: when to ping. Two ASVs help one survey vehicle on Sousa et al.'s
geometry (``sousa.py``), but the acoustic channel is a shared, costly resource
(``channel_mode="decide"``, ``core/channel.py``; docs/scenarios/when-to-ping.md).

Each step is a decision slot of ``ping_interval_s`` = 5 s (Sousa's ping interval
here); every beacon chooses its motion and whether to transmit a ping this slot
(``action[2] > 0``). The two ASVs share one half-duplex channel: if both ping in
the same slot their pings overlap at the survey vehicle and both are lost; a ping
costs transmit energy (``transmit_power_w`` x its duration) and the reward's
``ping`` term (``ping_penalty``). The survey vehicle replies once per slot in
which it decoded a ping. The modem is the WHOI Micro-Modem at its slowest FH-FSK
rate, 80 bps (shared/reference-values.md section 3): a 64-bit ping lasts 0.8 s,
a 128-bit reply 1.6 s [U: packet sizes].
"""

from .base import register
from .sousa import SOUSA_ASV

SOUSA_PING = SOUSA_ASV.replace(
    name="sousa_ping",
    beacon_kinds=("asv", "asv"),  # two ASVs share the channel
    channel_mode="decide",  # a decision slot per step; transmit when action[2] > 0
    ping_interval_s=5.0,  # the decision slot: Sousa's ping interval [U] (sousa.py)
    modem_bit_rate_bps=80.0,  # WHOI Micro-Modem FH-FSK, ref-values section 3
    ping_packet_bits=64,  # [U] 0.8 s at 80 bps
    reply_packet_bits=128,  # [U] 1.6 s at 80 bps
    transmit_power_w=40.0,  # [U] tens of watts
    ping_penalty=0.05,  # [U] nats of information a ping must buy; a knob for the learner
)

register("sousa_ping", SOUSA_PING)
