"""The acoustic link from the sonar equation (issue 21), used by the simulator's channel.

What a packet from vehicle v is worth at vehicle w, from physics instead of the
quadratic-in-range loss of ``acoustics.packet_loss_probability`` and the hard
``max_range_m`` interference cut of the channel's ``link_model="range"``:

1. **Transmission loss** (Urick's spreading plus Thorp's absorption, as written in
   Stojanovic 2007, path loss): TL(r, f) = k 10 log10(r / 1 m) + a(f) r / 1000,
   with a(f) in dB/km from Thorp's formula (f in kHz) and k = 2 (spherical) or 1.5
   ("practical"). ``thorp_absorption_db_per_km``, ``transmission_loss_db``.
2. **Ambient noise** (the empirical Wenz/Coates model of Stojanovic 2007: turbulence, shipping s in [0, 1],
   wind w in m/s, thermal), a power
   spectral density in dB re 1 uPa^2/Hz; over a band B either integrated or
   NL(fc) + 10 log10(B). ``noise_psd_db``, ``band_noise_db``.
3. **Sonar equation** (passive form for a one-way link, Urick 1983):
   RL = SL - TL + DI at the receiver, SNR = RL - NL_band. ``received_level_db``,
   ``snr_db``.
4. **Packet success** = P(detect) x (1 - PER): detection of the probe under Rayleigh
   fading (``detection_probability``) and the packet error rate of n bits under
   non-coherent FSK, BER = 0.5 exp(-Eb/N0 / 2) (Proakis, Digital Communications,
   binary orthogonal FSK with non-coherent detection), Eb/N0 = SNR B / R.
5. **Collisions by capture** (``slot_timeline``): a reception survives overlapping
   receptions when its signal-to-interference ratio, its RL over the power sum of
   the overlapping receptions' RL, reaches ``capture_threshold_db`` (10 dB [U]);
   a receiver transmitting during any part of a reception loses it (half duplex).
6. **Packet timing** from the WHOI Micro-Modem framing (``MicroModemFraming``,
   ``packet_duration_s``) and **energy** from the source level
   (``acoustic_power_w``, ``electrical_power_w``, ``transmit_energy_j``).

Sources (cited again where each constant is defined):

- M. Stojanovic, "On the relationship between capacity and distance in an
  underwater acoustic communication channel", ACM SIGMOBILE MC2R 11(4), 2007
  (WUWNet'06): path loss A(l, f) = l^k a(f)^l, Thorp's a(f), the four noise terms.
- W. H. Thorp, "Analytic description of the low-frequency attenuation coefficient",
  JASA 42:270, 1967 (the formula as quoted by Stojanovic 2007).
- R. J. Urick, Principles of Underwater Sound, 3rd ed., 1983: the sonar equation;
  SL = 170.8 + 10 log10(P_acoustic / 1 W) + DI dB re 1 uPa at 1 m.
- L. Freitag et al., "The WHOI Micro-Modem: an acoustic communications and
  navigation system for multiple platforms", OCEANS 2005: FH-FSK and PSK, four
  bands from 3 to 30 kHz.
- acomms.whoi.edu/micro-modem: 80-5400 bps; FSK bandwidth 4 kHz, PSK 5 kHz; the
  packet table's "signal length = probe + null + packet" (rate 6: 3.25 s against a
  2.95 s packet, so probe + null = 0.30 s, derived).
- goby-acomms Micro-Modem driver (GobySoft/goby, ``goby::acomms::MMDriver``):
  ``PACKET_FRAME_COUNT = {1, 3, 3, 2, 2, 8}``, ``PACKET_SIZE = {32, 64, 64, 256,
  256, 256}`` bytes for rates 0-5: rate 0 (FH-FSK, 80 bps) is one 32-byte frame.
- S. Singh et al., "Underwater acoustic navigation with the WHOI Micro-Modem",
  OCEANS 2006, and issue 21's text: a data packet follows a cycle-init packet (the
  paper not re-read here).

[U] marks a value that is a guess (the project's convention). Units are in every
name: _db (dB), _hz/_khz, _m, _s, _w, _j, _mps.

Wired: ``core/channel.py`` (``channel_mode="decide"``) resolves every slot with
``slot_timeline``; its ``link_model="sonar"`` (the default) takes the success
probability from here, ``"range"`` keeps the earlier range-only loss with the same
timeline (``hearing_range_m`` finite, capture off).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange, vectorize
from numpy.typing import ArrayLike

from .acoustics import travel_time

# the packets on the water (framing, offsets in a slot) live in link_framing, re-exported here
from .jit import parallel_twin

# the modem's electrical side (PowerModel, energy per packet) lives in link_energy, re-exported here
from .link_energy import (  # noqa: F401
    DEFAULT_POWER,
    SL_ONE_WATT_DB,
    PowerModel,
    acoustic_power_w,
    electrical_power_w,
    receive_energy_j,
    source_level_from_power_db,
    transmit_energy_j,
)
from .link_framing import (  # noqa: F401
    DEFAULT_FRAMING,
    MicroModemFraming,
    frames_needed,
    message_bits,
    message_duration_s,
    packet_duration_s,
    random_offsets_s,
    staggered_offsets_s,
)

# --------------------------------------------------------------------------- records


class Band(NamedTuple):
    """A modem band: centre frequency (kHz) and bandwidth (Hz).

    The default is the Micro-Modem's 25 kHz band (Freitag et al. 2005: four bands
    between 3 and 30 kHz; the centre of the highest, 25 kHz, is [U] as a figure) with
    the FH-FSK bandwidth of 4 kHz (acomms.whoi.edu: "FSK BW = 4kHz", PSK 5 kHz).
    """

    center_khz: float = 25.0
    bandwidth_hz: float = 4000.0


class NoiseConditions(NamedTuple):
    """Ambient noise drivers of the Wenz/Coates model (Stojanovic 2007).

    ``shipping`` in [0, 1] (0.5: moderate [U]); ``wind_mps`` the wind speed at the
    surface (5 m/s, about sea state 2-3 [U]).
    """

    shipping: float = 0.5
    wind_mps: float = 5.0


class LinkParams(NamedTuple):
    """The link budget that turns a range into a success probability.

    - ``source_level_db``: SL, dB re 1 uPa at 1 m. 185 [U]: Micro-Modem transducers
      are said to reach 185-190 dB (issue 21's brief); no source found here.
    - ``spreading_k``: 2 spherical (default, conservative), 1.5 "practical"
      (Stojanovic 2007).
    - ``receive_directivity_index_db``: DI of the *receiving* transducer against isotropic
      noise (SNR = SL - TL - (NL - DI)), 0 for the omnidirectional transducers of small
      vehicles. The transmitter's directivity is inside SL already (``link_energy``'s
      ``transmit_directivity_index_db``, a different quantity).
    - ``detection_threshold_db``: the in-band SNR the probe detector needs, 3 dB [U].
    - ``detection_model``: "rayleigh" (default) or "logistic"; see
      ``detection_probability``.
    - ``logistic_width_db``: the logistic's scale, 2 dB [U].
    - ``capture_threshold_db``: the SIR a reception needs to survive an overlapping
      one, 10 dB [U].
    - ``bit_rate_bps``: the data rate in the packet error rate, 80 bps (Micro-Modem
      rate 0, acomms.whoi.edu).
    - ``hearing_range_m``: inf (the sonar link: every sender interferes everywhere,
      its level falling with TL). Finite only for the channel's ``link_model="range"``
      (the earlier model): a sender farther than this (straight line at its start) is
      neither heard nor heard interfering.
    """

    band: Band = Band()
    noise: NoiseConditions = NoiseConditions()
    source_level_db: float = 185.0
    spreading_k: float = 2.0
    receive_directivity_index_db: float = 0.0
    detection_threshold_db: float = 3.0
    detection_model: str = "rayleigh"
    logistic_width_db: float = 2.0
    capture_threshold_db: float = 10.0
    bit_rate_bps: float = 80.0
    hearing_range_m: float = math.inf


class SlotTransmissions(NamedTuple):
    """The packets of one slot, over a batch of B environments and V vehicles.

    - ``pos_m`` (B, V, 3) positions at the slot's t = 0; ``vel_mps`` (B, V, 3) constant
      velocities (a sender sends from where it is at its start time; the receiver
      moves while the sound travels, ``acoustics.travel_time``).
    - ``tx_start_s`` (B, V): each vehicle's transmit start within the slot (NaN:
      silent). Offsets, drawn or chosen, not all at t = 0.
    - ``duration_s`` (B, V): how long each packet occupies the water
      (``packet_duration_s``).
    - ``source_level_db`` (B, V): SL of each sender, dB re 1 uPa at 1 m.
    - ``payload_bits`` (B, V): bits whose errors lose the packet (the PER's n).
    """

    pos_m: np.ndarray
    vel_mps: np.ndarray
    tx_start_s: np.ndarray
    duration_s: np.ndarray
    source_level_db: np.ndarray
    payload_bits: np.ndarray


class SlotOutcome(NamedTuple):
    """Every reception of a slot, (B, V, V) indexed [b, sender, receiver].

    - ``arrival_s``, ``end_s``: the reception's interval at the receiver (NaN: the
      sender was silent, or sender == receiver).
    - ``range_m``: the acoustic path length c x time of flight.
    - ``received_level_db``: RL = SL - TL + DI.
    - ``snr_db``: RL - band noise.
    - ``sir_db``: RL over the power sum of the receptions overlapping it at that
      receiver (+inf: nothing overlaps).
    - ``overlapped``: another reception overlaps it (intervals that only touch do not).
    - ``captured``: it survives its overlaps (none, or SIR >= capture threshold).
    - ``deaf``: the receiver transmits during some part of it (half duplex).
    - ``p_success``: P(detect) x (1 - PER) at the SINR, 1 / (1 / SNR + 1 / SIR) (the SNR
      where nothing overlaps); 0 where deaf or not captured.
    """

    arrival_s: np.ndarray
    end_s: np.ndarray
    range_m: np.ndarray
    received_level_db: np.ndarray
    snr_db: np.ndarray
    sir_db: np.ndarray
    overlapped: np.ndarray
    captured: np.ndarray
    deaf: np.ndarray
    p_success: np.ndarray


# The defaults as module-level singletons (records are immutable; used as argument defaults).
DEFAULT_BAND = Band()
DEFAULT_NOISE = NoiseConditions()
DEFAULT_LINK = LinkParams()


class _KernelScalars(NamedTuple):
    """The scalars the slot kernel needs, all float (numba takes a NamedTuple)."""

    center_khz: float
    bandwidth_hz: float
    spreading_k: float
    receive_directivity_index_db: float
    detection_threshold_db: float
    logistic_width_db: float  # <= 0: Rayleigh model
    capture_threshold_db: float
    bit_rate_bps: float
    hearing_range_m: float


# --------------------------------------------------------------- propagation and noise


@vectorize(["float64(float64)"], cache=True)
def thorp_absorption_db_per_km(f_khz: float) -> float:
    """Thorp's absorption a(f), dB/km, f in kHz (Thorp 1967, as in Stojanovic 2007):
    10 log a(f) = 0.11 f^2/(1 + f^2) + 44 f^2/(4100 + f^2) + 2.75e-4 f^2 + 0.003.
    Valid above a few hundred Hz. A ufunc.

    >>> round(float(thorp_absorption_db_per_km(25.0)), 3)
    6.105
    """
    f2 = f_khz * f_khz
    return 0.11 * f2 / (1.0 + f2) + 44.0 * f2 / (4100.0 + f2) + 2.75e-4 * f2 + 0.003


@vectorize(["float64(float64, float64, float64)"], cache=True)
def transmission_loss_db(range_m: float, f_khz: float, spreading_k: float) -> float:
    """TL = k 10 log10(r / 1 m) + a(f) r / 1000, dB (Stojanovic 2007, path loss
    A(l, f) = l^k a(f)^l in dB with l in m re 1 m). Ranges below 1 m count as 1 m
    (the source level's reference distance). A ufunc."""
    r = max(range_m, 1.0)
    return spreading_k * 10.0 * math.log10(r) + thorp_absorption_db_per_km(f_khz) * r / 1000.0


MIN_BAND_EDGE_HZ = 1.0  # the lowest frequency of Wenz (1962)'s curves, which noise_psd_db's terms fit


def band_problem(center_khz: float, bandwidth_hz: float) -> str | None:
    """Why a band cannot be used by the noise model (its turbulence term diverges at 0 Hz),
    or None: it must be positive and start at or above ``MIN_BAND_EDGE_HZ``. The message
    names the widest band around that centre. ``band_noise_db`` and the scenarios'
    validation read it."""
    low_hz = 1000.0 * center_khz - 0.5 * bandwidth_hz
    if bandwidth_hz > 0.0 and low_hz >= MIN_BAND_EDGE_HZ:
        return None
    widest = 2.0 * (1000.0 * center_khz - MIN_BAND_EDGE_HZ)
    return (
        f"a band of {bandwidth_hz:g} Hz around {center_khz:g} kHz reaches {low_hz:g} Hz: it must be positive and "
        f"start at or above {MIN_BAND_EDGE_HZ:g} Hz; the widest band there is {widest:g} Hz (or raise the centre)"
    )


@vectorize(["float64(float64, float64, float64)"], cache=True)
def noise_psd_db(f_khz: float, shipping: float, wind_mps: float) -> float:
    """Ambient noise power spectral density, dB re 1 uPa^2/Hz, f in kHz: the power sum
    of Stojanovic 2007's empirical terms (after Coates, "Underwater Acoustic
    Systems", 1990, fitting Wenz 1962's curves):

    - turbulence  10 log Nt  = 17 - 30 log f
    - shipping    10 log Ns  = 40 + 20 (s - 0.5) + 26 log f - 60 log(f + 0.03)
    - wind        10 log Nw  = 50 + 7.5 w^0.5 + 20 log f - 40 log(f + 0.4)
    - thermal     10 log Nth = -15 + 20 log f
    """
    lf = math.log10(f_khz)
    nt = 17.0 - 30.0 * lf
    ns = 40.0 + 20.0 * (shipping - 0.5) + 26.0 * lf - 60.0 * math.log10(f_khz + 0.03)
    nw = 50.0 + 7.5 * math.sqrt(wind_mps) + 20.0 * lf - 40.0 * math.log10(f_khz + 0.4)
    nth = -15.0 + 20.0 * lf
    return 10.0 * math.log10(10.0 ** (nt / 10.0) + 10.0 ** (ns / 10.0) + 10.0 ** (nw / 10.0) + 10.0 ** (nth / 10.0))


def band_noise_db(
    band: Band = DEFAULT_BAND, noise: NoiseConditions = DEFAULT_NOISE, integrate: bool = True, points: int = 201
) -> float:
    """Noise power in the band, dB re 1 uPa^2: the PSD integrated over
    [fc - B/2, fc + B/2] (trapezoid on ``points`` frequencies, linear power) or, with
    ``integrate=False``, NL(fc) + 10 log10(B) (flat over the band)."""
    problem = band_problem(band.center_khz, band.bandwidth_hz)
    if problem is not None:
        raise ValueError(problem)
    if not integrate:
        return float(noise_psd_db(band.center_khz, noise.shipping, noise.wind_mps) + 10.0 * np.log10(band.bandwidth_hz))
    half_khz = 0.5 * band.bandwidth_hz / 1000.0
    f_khz = np.linspace(band.center_khz - half_khz, band.center_khz + half_khz, points)
    psd = 10.0 ** (noise_psd_db(f_khz, noise.shipping, noise.wind_mps) / 10.0)  # uPa^2/Hz
    df_hz = (f_khz[1] - f_khz[0]) * 1000.0
    return float(10.0 * np.log10(np.sum(0.5 * (psd[1:] + psd[:-1])) * df_hz))


# ------------------------------------------------------------------- sonar equation


@vectorize(["float64(float64, float64, float64, float64, float64)"], cache=True)
def received_level_db(
    source_level_db: float, range_m: float, f_khz: float, spreading_k: float, receive_directivity_index_db: float
) -> float:
    """RL = SL - TL(r, f) + DI, dB re 1 uPa (Urick 1983), DI the receiver's (so that RL - NL
    is SL - TL - (NL - DI), the receiving array's gain against isotropic noise). A ufunc."""
    return source_level_db - transmission_loss_db(range_m, f_khz, spreading_k) + receive_directivity_index_db


def snr_db(
    range_m: ArrayLike,
    params: LinkParams = DEFAULT_LINK,
    source_level_db: ArrayLike | None = None,
    noise_db: ArrayLike | None = None,
) -> np.ndarray:
    """In-band SNR = SL - TL + DI - NL_band (dB) at ``range_m`` (array or scalar).
    ``source_level_db`` defaults to the link's; ``noise_db`` to ``band_noise_db``."""
    sl = params.source_level_db if source_level_db is None else source_level_db
    nl = band_noise_db(params.band, params.noise) if noise_db is None else noise_db
    return (
        received_level_db(
            sl,
            np.asarray(range_m, float),
            params.band.center_khz,
            params.spreading_k,
            params.receive_directivity_index_db,
        )
        - nl
    )


@vectorize(["float64(float64, float64, float64)"], cache=True)
def detection_probability(snr_db: float, threshold_db: float, logistic_width_db: float) -> float:
    """P(the probe is detected) at mean in-band SNR ``snr_db`` against ``threshold_db``.

    ``logistic_width_db`` <= 0 (the default of ``LinkParams`` maps to it): the
    probability that a Rayleigh-faded SNR exceeds the threshold,
    P = exp(-thr_lin / snr_lin): the instantaneous SNR of a Rayleigh-fading channel is
    exponentially distributed about its mean (Proakis, Digital Communications, fading channels).
    Chosen because it has no free width (a logistic's width is a guess), it follows
    from the physics of shallow-water multipath without a dominant path, and it is
    pessimistic: P = 0.90 needs 10 dB of margin. A Rician model (a direct path plus
    scattering) would sit between it and a hard threshold.
    ``logistic_width_db`` > 0: 1 / (1 + exp(-(snr - thr) / width)), a smooth step in
    dB [U].
    """
    if logistic_width_db > 0.0:
        return 1.0 / (1.0 + math.exp(-(snr_db - threshold_db) / logistic_width_db))
    return math.exp(-(10.0 ** ((threshold_db - snr_db) / 10.0)))


@vectorize(["float64(float64, float64, float64)"], cache=True)
def bit_error_rate(snr_db: float, bandwidth_hz: float, bit_rate_bps: float) -> float:
    """Non-coherent binary FSK in white noise: BER = 0.5 exp(-Eb/N0 / 2) (Proakis,
    Digital Communications, binary orthogonal signals, non-coherent detection), with
    Eb/N0 = SNR x B / R (the in-band SNR spread over the bit rate). Uncoded, so
    pessimistic for the Micro-Modem's coded FH-FSK [U]."""
    ebn0 = 10.0 ** (snr_db / 10.0) * bandwidth_hz / bit_rate_bps
    return 0.5 * math.exp(-0.5 * ebn0)


@vectorize(["float64(float64, float64, float64, float64)"], cache=True)
def packet_error_rate(snr_db: float, bandwidth_hz: float, bit_rate_bps: float, n_bits: float) -> float:
    """PER of an n-bit frame with independent bit errors: 1 - (1 - BER)^n."""
    ber = bit_error_rate(snr_db, bandwidth_hz, bit_rate_bps)
    return -math.expm1(n_bits * math.log1p(-ber))


@njit(cache=True)
def _success_probability(snr, n_bits, s):
    """P(detect) x (1 - PER) with the kernel's scalars ``s``."""
    pd = detection_probability(snr, s.detection_threshold_db, s.logistic_width_db)
    return pd * (1.0 - packet_error_rate(snr, s.bandwidth_hz, s.bit_rate_bps, n_bits))


def _scalars(params: LinkParams) -> _KernelScalars:
    if params.detection_model not in ("rayleigh", "logistic"):
        raise ValueError(f"detection_model must be 'rayleigh' or 'logistic', not {params.detection_model!r}")
    width = params.logistic_width_db if params.detection_model == "logistic" else 0.0
    return _KernelScalars(
        float(params.band.center_khz),
        float(params.band.bandwidth_hz),
        float(params.spreading_k),
        float(params.receive_directivity_index_db),
        float(params.detection_threshold_db),
        float(width),
        float(params.capture_threshold_db),
        float(params.bit_rate_bps),
        float(params.hearing_range_m),
    )


def success_probability(
    range_m: ArrayLike, n_bits: ArrayLike, params: LinkParams = DEFAULT_LINK, noise_db: ArrayLike | None = None
) -> np.ndarray:
    """P(a packet of ``n_bits`` is decoded at ``range_m``) on a free channel:
    P(detect | SNR) x (1 - PER(SNR, n)). Arrays broadcast (``noise_db`` too)."""
    s = _scalars(params)
    snr = snr_db(range_m, params, noise_db=noise_db)
    pd = detection_probability(snr, s.detection_threshold_db, s.logistic_width_db)
    return pd * (1.0 - packet_error_rate(snr, s.bandwidth_hz, s.bit_rate_bps, np.asarray(n_bits, float)))


# --------------------------------------------------------------------- capture (SIR)


def sir_db(signal_rl_db: ArrayLike, interferer_rl_db: ArrayLike) -> np.ndarray:
    """SIR of one reception over simultaneous ones: its RL minus 10 log10 of the sum of
    the interferers' linear powers (dB). ``interferer_rl_db`` (..., K); +inf for K = 0
    or all -inf."""
    i = np.asarray(interferer_rl_db, float)
    total = np.sum(10.0 ** (i / 10.0), axis=-1)
    with np.errstate(divide="ignore"):
        return np.asarray(signal_rl_db, float) - 10.0 * np.log10(total)


def captured(
    signal_rl_db: ArrayLike, interferer_rl_db: ArrayLike, capture_threshold_db: ArrayLike = 10.0
) -> np.ndarray:
    """Whether a reception survives overlapping ones: SIR >= threshold (10 dB [U])."""
    return sir_db(signal_rl_db, interferer_rl_db) >= capture_threshold_db


# ------------------------------------------------------------------ slot timeline


def _slot_kernel(pos, vel, start, dur, sl, bits, c, noise_db, s, out):
    """One slot's receptions at every receiver, into ``out`` (``SlotOutcome``'s arrays,
    filled with their empty values); see ``slot_timeline``. c (B, V, V), noise_db (B,)."""
    arrival, end, rng, rl, snr, sir, overlapped, capt, deaf, p = out
    B, V = pos.shape[0], pos.shape[1]
    for b in prange(B):
        src = np.empty(3)
        rcv = np.empty(3)
        # 1. propagation: arrival interval, path length, received level
        for v in range(V):
            t0 = start[b, v]
            if not np.isfinite(t0):
                continue
            for w in range(V):
                if w == v:
                    continue
                for k in range(3):
                    src[k] = pos[b, v, k] + vel[b, v, k] * t0
                    rcv[k] = pos[b, w, k] + vel[b, w, k] * t0
                d = np.sqrt((rcv[0] - src[0]) ** 2 + (rcv[1] - src[1]) ** 2 + (rcv[2] - src[2]) ** 2)
                if d > s.hearing_range_m:  # link_model="range" only (inf for the sonar link)
                    continue
                tau = travel_time(src, rcv, vel[b, w], c[b, v, w])
                arrival[b, v, w] = t0 + tau
                end[b, v, w] = t0 + tau + dur[b, v]
                rng[b, v, w] = c[b, v, w] * tau
                rl[b, v, w] = received_level_db(
                    sl[b, v], rng[b, v, w], s.center_khz, s.spreading_k, s.receive_directivity_index_db
                )
                snr[b, v, w] = rl[b, v, w] - noise_db[b]
        # 2. interference, capture, half duplex, success probability
        for w in range(V):
            for v in range(V):
                a = arrival[b, v, w]
                if not np.isfinite(a):
                    continue
                e = end[b, v, w]
                t_own = start[b, w]
                if np.isfinite(t_own) and t_own < e and a < t_own + dur[b, w]:
                    deaf[b, v, w] = True
                interference = 0.0  # linear, uPa^2
                for u in range(V):
                    a2 = arrival[b, u, w]
                    if u != v and np.isfinite(a2) and a2 < e and a < end[b, u, w]:
                        overlapped[b, v, w] = True
                        interference += 10.0 ** (rl[b, u, w] / 10.0)
                if overlapped[b, v, w]:
                    sir[b, v, w] = rl[b, v, w] - 10.0 * np.log10(interference)
                capt[b, v, w] = sir[b, v, w] >= s.capture_threshold_db
                if capt[b, v, w] and not deaf[b, v, w]:
                    # a captured packet is decoded against noise and what it captured:
                    # SINR = 1 / (1 / SNR + 1 / SIR), linear (= SNR with nothing overlapping)
                    sinr = snr[b, v, w]
                    if overlapped[b, v, w]:
                        sinr = -10.0 * np.log10(10.0 ** (-snr[b, v, w] / 10.0) + 10.0 ** (-sir[b, v, w] / 10.0))
                    p[b, v, w] = _success_probability(sinr, bits[b, v], s)


slot_kernel = njit(cache=True)(_slot_kernel)
slot_kernel_parallel = parallel_twin(_slot_kernel)


def slot_timeline(
    tx: SlotTransmissions,
    sound_speed_mps: ArrayLike,
    params: LinkParams = DEFAULT_LINK,
    noise_db: ArrayLike | None = None,
    parallel: bool = False,
) -> SlotOutcome:
    """Resolve one slot of packets at every receiver with the sonar equation.

    For each sender v with a finite ``tx_start_s`` and each other vehicle w: the
    time of flight from v's position at its start to w moving at constant velocity
    (``acoustics.travel_time``), the reception interval [arrival, arrival + duration),
    the path length, RL = SL - TL + DI and SNR = RL - band noise. Then at each
    receiver: the receptions overlapping each one (touching intervals do not), its
    SIR over their power sum, capture (SIR >= ``capture_threshold_db``), half duplex
    (w transmits during any part of it) and the success probability P(detect) x
    (1 - PER) at the SINR (what a captured packet overlapped is noise to it) for the
    captured, non-deaf ones (0 otherwise).

    ``sound_speed_mps`` broadcasts to (B, V, V) [sender, receiver]: a scalar, a (B,)
    per-environment value as ``[:, None, None]``, or per pair (the channel's
    Mackenzie speed at the pair's mean depth). ``noise_db``, a scalar or (B,) (domain
    randomization of the sea state), overrides ``band_noise_db(params.band,
    params.noise)``.

    Every sender interferes at every receiver however far (its RL falls with TL), so
    there is no hard interference range. Simplifications: any overlap counts in full
    (no partial-overlap weighting), and capture does not depend on which packet the
    receiver locked onto first [U].

    ``core/channel.py`` builds the transmissions from the simulator's state (beacons
    then survey vehicles, pings at their offsets, replies at the reply time), delivers
    ``captured & ~deaf`` receptions with ``u >= 1 - p_success`` on the modem's and
    messages' own uniforms (``draw_delivered``) and counts ``overlapped & ~captured``
    as collisions. ``parallel``: the threaded kernel (large batches).
    """
    pos = np.ascontiguousarray(tx.pos_m, float)
    B, V = pos.shape[:2]

    def bv(x: ArrayLike) -> np.ndarray:
        return np.ascontiguousarray(np.broadcast_to(np.asarray(x, float), (B, V)))

    vel = np.ascontiguousarray(np.broadcast_to(np.asarray(tx.vel_mps, float), (B, V, 3)))
    c = np.asarray(sound_speed_mps, float)
    if c.ndim == 1:
        c = c[:, None, None]
    c = np.ascontiguousarray(np.broadcast_to(c, (B, V, V)))
    nl = band_noise_db(params.band, params.noise) if noise_db is None else noise_db
    nl = np.ascontiguousarray(np.broadcast_to(np.asarray(nl, float), (B,)))
    shape = (B, V, V)
    empty = [np.full(shape, x) for x in (np.nan, np.nan, np.nan, -np.inf, -np.inf, np.inf)]
    out = SlotOutcome._make([*empty, *(np.zeros(shape, dtype=np.bool_) for _ in range(3)), np.zeros(shape)])
    kernel = slot_kernel_parallel if parallel else slot_kernel
    kernel(
        pos,
        vel,
        bv(tx.tx_start_s),
        bv(tx.duration_s),
        bv(tx.source_level_db),
        bv(tx.payload_bits),
        c,
        nl,
        _scalars(params),
        out,
    )
    return out


def draw_delivered(outcome: SlotOutcome, u: ArrayLike) -> np.ndarray:
    """(B, V, V) delivered: ``u < p_success`` with uniforms ``u`` (same shape), so a
    caller keeps its common random numbers. Deaf or uncaptured receptions have
    p_success = 0 and are never delivered."""
    return np.asarray(u) < outcome.p_success
