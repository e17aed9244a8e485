"""``sousa_ping``: when to ping. Two ASVs help one survey vehicle on Sousa et al.'s
geometry (``sousa.py``), but the acoustic channel is a shared, costly resource
(``channel_mode="decide"``, ``core/channel.py``; docs/scenarios/when-to-ping.md).

Each step is a decision slot of ``ping_interval_s`` = 20 s; every beacon chooses its
motion and whether to transmit a ping this slot (``action[2] > 0``). The two ASVs
share one half-duplex channel (``link_model="sonar"``, core/link.py): a packet is a
WHOI Micro-Modem FH-FSK rate-0 packet at 80 bps (shared/reference-values.md section
3): cycle-init, probe and one 32-byte frame, 5.0 s on the water, for the 64-bit ping
and the 128-bit reply alike. The second ASV's ping starts 6.07 s after the first's
(``ping_offsets="staggered"``: one packet plus 1500 m of flight at 1400 m/s), so
pings in one slot do not collide within 1.5 km; farther, a ping is heard at the
level the sonar equation gives and survives an overlap only by capture. A ping is
lost with the probability the SNR gives (spherical spreading, Thorp absorption at
25 kHz, Wenz noise over 4 kHz); it costs 526 J (SL 185 dB at 25 % efficiency, 5 s)
and the reward's ``ping`` term (``ping_penalty``). The survey vehicle replies once
per slot in which it decoded a ping, after the last ping's flight. The slot holds
the exchange: 6.07 + 5 + 1.07 + 0.015 + 5 + 1.07 = 18.23 s (the validator refuses a
shorter one, naming this minimum); 20 s leaves a margin [U]. Micro-Modem navigation
cycles of 10-30 s are usual [U]. The earlier 5 s slot with 0.8 s pings is
``link_model="range", ping_offsets="zero", ping_interval_s=5``.
"""

from .base import register
from .sousa import SOUSA_ASV

SOUSA_PING = SOUSA_ASV.replace(
    name="sousa_ping",
    beacon_kinds=("asv", "asv"),  # two ASVs share the channel
    channel_mode="decide",  # a decision slot per step; transmit when action[2] > 0
    ping_interval_s=20.0,  # the decision slot: holds two staggered 5 s packets and a reply (18.23 s) [U]
    modem_bit_rate_bps=80.0,  # WHOI Micro-Modem FH-FSK, ref-values section 3
    ping_packet_bits=64,  # [U] one 32-byte frame: 5.0 s with cycle-init and probe
    reply_packet_bits=128,  # [U] idem
    transmit_power_w=40.0,  # [U] tens of watts (link_model="range" only)
    link_model="sonar",  # SNR, capture, Micro-Modem packets (core/link.py)
    ping_offsets="staggered",  # the second ASV's ping 6.07 s after the first's
    ping_penalty=0.05,  # [U] nats of information a ping must buy; a knob for the learner
)

register("sousa_ping", SOUSA_PING)
