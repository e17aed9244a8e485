"""The acoustic link from the sonar equation (``core.link``, issue 21) against values
computed by hand in the comments."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from coopnav_env.core import link as L

C = 1500.0  # sound speed of the hand-computed timelines, m/s


# ----------------------------------------------------------------------- absorption


@pytest.mark.parametrize(
    "f_khz, expected",
    [
        # 0.11 f^2/(1+f^2) + 44 f^2/(4100+f^2) + 2.75e-4 f^2 + 0.003
        # 1 kHz:  0.055      + 44/4101 = 0.0107291   + 0.000275 + 0.003 = 0.0690041
        (1.0, 0.0690041),
        # 10 kHz: 11/101 = 0.1089109 + 4400/4200 = 1.0476190 + 0.0275 + 0.003 = 1.1870299
        (10.0, 1.1870299),
        # 25 kHz: 68.75/626 = 0.1098243 + 27500/4725 = 5.8201058 + 0.171875 + 0.003 = 6.1048051
        (25.0, 6.1048051),
    ],
)
def test_thorp_absorption_by_hand(f_khz, expected):
    assert L.thorp_absorption_db_per_km(f_khz) == pytest.approx(expected, abs=1e-6)


def test_transmission_loss_at_1_and_5_km_by_hand():
    # 1 km, 25 kHz, k = 2: 20 log10(1000) = 60 + 6.1048051 x 1 = 66.1048051
    assert L.transmission_loss_db(1000.0, 25.0, 2.0) == pytest.approx(66.1048051, abs=1e-6)
    # 5 km: 20 log10(5000) = 73.9794001 + 6.1048051 x 5 = 30.5240255 -> 104.5034256
    assert L.transmission_loss_db(5000.0, 25.0, 2.0) == pytest.approx(104.5034256, abs=1e-6)
    # practical spreading, 5 km: 15 log10(5000) = 55.4845501 + 30.5240255 = 86.0085756
    assert L.transmission_loss_db(5000.0, 25.0, 1.5) == pytest.approx(86.0085756, abs=1e-6)
    # below the 1 m reference distance: no gain
    assert L.transmission_loss_db(0.1, 25.0, 2.0) == pytest.approx(6.1048051e-3)


# ---------------------------------------------------------------------------- noise


def test_noise_psd_at_25_khz_moderate_shipping_5_mps_wind_by_hand():
    # log10(25) = 1.3979400
    # turbulence 17 - 30 x 1.39794 = -24.938
    # shipping   40 + 0 + 26 x 1.39794 - 60 log10(25.03) = 40 + 36.3464 - 83.9077 = -7.561
    # wind       50 + 7.5 sqrt(5) + 20 x 1.39794 - 40 log10(25.4)
    #            = 50 + 16.7705 + 27.9588 - 56.1934 = 38.536
    # thermal    -15 + 27.9588 = 12.959
    # power sum: 10^3.8536 + 10^1.2959 + 10^-0.7561 + 10^-2.4938 = 7139.6 + 19.76 + 0.175 + 0.003
    #            = 7159.5 -> 38.549 dB re 1 uPa^2/Hz (wind dominates)
    assert L.noise_psd_db(25.0, 0.5, 5.0) == pytest.approx(38.549, abs=0.005)


def test_noise_psd_at_100_hz_where_shipping_dominates_by_hand():
    # f = 0.1 kHz, log10 f = -1, no wind; heavy shipping s = 1:
    # turbulence 17 + 30 = 47
    # shipping   40 + 20 x 0.5 - 26 - 60 log10(0.13) = 24 + 53.1634 = 77.1634
    # wind       50 + 0 - 20 - 40 log10(0.5) = 30 + 12.0412 = 42.0412
    # thermal    -15 - 20 = -35
    # power sum: 10^7.71634 + 10^4.7 + 10^4.20412 = 5.2030e7 + 5.01e4 + 1.60e4 -> 77.169 dB
    # no shipping (s = 0): 57.1634 beside the same turbulence and wind -> 57.683 dB
    # (at 25 kHz, above, wind hides the shipping term: 20 dB of it moved nothing there)
    assert L.noise_psd_db(0.1, 1.0, 0.0) == pytest.approx(77.169, abs=0.005)
    assert L.noise_psd_db(0.1, 0.0, 0.0) == pytest.approx(57.683, abs=0.005)


def test_band_noise_flat_and_integrated_agree():
    band, noise = L.Band(25.0, 4000.0), L.NoiseConditions(0.5, 5.0)
    # NL(fc) + 10 log10(4000) = 38.549 + 36.021 = 74.570
    assert L.band_noise_db(band, noise, integrate=False) == pytest.approx(74.570, abs=0.005)
    # the PSD falls ~6 dB/octave around 25 kHz: integrating barely differs from flat
    assert L.band_noise_db(band, noise) == pytest.approx(74.570, abs=0.1)
    # more wind, more noise; more shipping barely matters at 25 kHz
    assert L.band_noise_db(band, L.NoiseConditions(0.5, 15.0)) > L.band_noise_db(band, noise) + 3.0


def test_a_band_reaching_0_hz_is_refused_not_silent():
    """The turbulence term diverges at 0 Hz: a 4 kHz band around 2 kHz gave +inf noise
    (around 1 kHz NaN), so every packet was lost without a word. Refused, in the link and
    in a scenario, with the widest band that fits."""
    from coopnav_env.scenarios import make_config

    with pytest.raises(ValueError, match="reaches 0 Hz"):
        L.band_noise_db(L.Band(2.0, 4000.0))
    with pytest.raises(ValueError, match="reaches -1000 Hz"):
        L.band_noise_db(L.Band(1.0, 4000.0), integrate=False)
    assert np.isfinite(L.band_noise_db(L.Band(2.0, 3998.0)))
    with pytest.raises(ValueError, match="the widest band there is 3998 Hz"):
        make_config("sousa_ping", band_center_khz=2.0)
    make_config("sousa_ping", band_center_khz=2.0, band_width_hz=3998.0)


# ------------------------------------------------------------------------------ SNR


def test_snr_by_hand():
    # SL 185, 1 km at 25 kHz: TL 66.1048; band noise (flat) 74.5687
    # SNR = 185 - 66.1048 - 74.5687 = 44.3265 dB
    p = L.LinkParams()
    nl = L.band_noise_db(p.band, p.noise, integrate=False)
    assert L.snr_db(1000.0, p, noise_db=nl) == pytest.approx(44.3265, abs=1e-3)
    # a 3 dB directivity index adds 3 dB
    assert L.snr_db(1000.0, p._replace(receive_directivity_index_db=3.0), noise_db=nl) == pytest.approx(
        47.3265, abs=1e-3
    )


def test_detection_models_at_the_threshold():
    # Rayleigh: P(snr_inst > thr) = exp(-thr/mean); at mean == thr, exp(-1)
    assert L.detection_probability(3.0, 3.0, 0.0) == pytest.approx(math.exp(-1.0))
    # 10 dB of margin: exp(-0.1) = 0.904837
    assert L.detection_probability(13.0, 3.0, 0.0) == pytest.approx(0.904837, abs=1e-6)
    # logistic: one half at the threshold
    assert L.detection_probability(3.0, 3.0, 2.0) == pytest.approx(0.5)


def test_bit_and_packet_error_rates_by_hand():
    # SNR 0 dB over 4 kHz at 80 bps: Eb/N0 = 50; BER = 0.5 exp(-25) = 6.9440e-12
    assert L.bit_error_rate(0.0, 4000.0, 80.0) == pytest.approx(0.5 * math.exp(-25.0), rel=1e-9)
    # SNR -10 dB: Eb/N0 = 5; BER = 0.5 exp(-2.5) = 0.0410425; PER(256) = 1 - (1 - BER)^256 ~ 1
    ber = 0.5 * math.exp(-2.5)
    assert L.packet_error_rate(-10.0, 4000.0, 80.0, 256.0) == pytest.approx(1.0 - (1.0 - ber) ** 256, rel=1e-9)


def test_success_falls_with_range_and_faster_at_a_higher_band():
    r = np.linspace(100.0, 20000.0, 400)
    p25 = L.success_probability(r, 256, L.LinkParams(band=L.Band(25.0, 4000.0)))
    p10 = L.success_probability(r, 256, L.LinkParams(band=L.Band(10.0, 4000.0)))
    assert np.all(np.diff(p25) <= 0.0) and np.all(np.diff(p10) <= 0.0)
    assert p25[0] > 0.999 and p25[-1] < 1e-6
    far = r > 4000.0
    assert np.all(p25[far] < p10[far])  # absorption: 6.1 dB/km at 25 kHz, 1.2 at 10
    # 5 km at 25 kHz: SNR = 185 - 104.50 - 74.59 = 5.90 dB (integrated band noise), 2.9 dB
    # over the threshold: P(detect) = exp(-10^(-0.29)) = exp(-0.5129) = 0.599; PER ~ 0
    at5 = L.success_probability(5000.0, 256, L.LinkParams(band=L.Band(25.0, 4000.0)))
    assert at5 == pytest.approx(0.599, abs=0.002)


# --------------------------------------------------------------------------- timing


def test_packet_duration_of_the_default_rate_0_packet_by_hand():
    # cycle-init 1.0 + gap 0.5 + probe 0.2 + null 0.1 + one frame 8 x 32 / 80 = 3.2 -> 5.0 s
    f = L.MicroModemFraming()
    assert L.packet_duration_s(f, 256) == pytest.approx(5.0)
    assert L.packet_duration_s(f, 1) == pytest.approx(5.0)  # a frame is sent whole
    # without the cycle-init: 0.2 + 0.1 + 3.2 = 3.5 s
    assert L.packet_duration_s(f._replace(with_cycle_init=False), 100) == pytest.approx(3.5)
    with pytest.raises(ValueError):
        L.packet_duration_s(f, 257)  # rate 0 carries one 32-byte frame


def test_packet_duration_of_several_frames_by_hand():
    # 3 frames of 64 bytes at 500 bps (rate 2's frame count and size, goby), 0.1 s
    # between frames: 1000 bits -> 2 frames of 512 bits, 1.024 s each;
    # 1.0 + 0.5 + 0.2 + 0.1 + 2 x 1.024 + 0.1 = 3.948 s
    f = L.MicroModemFraming(bit_rate_bps=500.0, frame_bytes=64, max_frames=3, inter_frame_gap_s=0.1)
    assert L.frames_needed(f, 1000) == 2
    assert L.packet_duration_s(f, 1000) == pytest.approx(3.948)


# --------------------------------------------------------------------------- energy


def test_energy_from_source_level_by_hand():
    # SL 185, DI 0: P_acoustic = 10^((185 - 170.8)/10) = 10^1.42 = 26.3027 W
    # electrical at 25 % efficiency: 105.2107 W; over 5 s: 526.0536 J
    assert L.acoustic_power_w(185.0, 0.0) == pytest.approx(26.3027, abs=1e-4)
    assert L.electrical_power_w(185.0) == pytest.approx(105.2107, abs=1e-4)
    assert L.transmit_energy_j(185.0, 5.0) == pytest.approx(526.0536, abs=1e-3)
    # 3 dB more source level doubles the power; a 3 dB DI gives it for free
    assert L.acoustic_power_w(188.0, 3.0) == pytest.approx(26.3027, abs=1e-4)
    # the inverse: the scenario's 40 W electrical [U] at 25 %: 10 W acoustic, 170.8 + 10 = 180.8 dB
    assert L.source_level_from_power_db(40.0) == pytest.approx(180.8)
    assert L.source_level_from_power_db(L.electrical_power_w(185.0)) == pytest.approx(185.0)
    # receiving 5 s at 0.3 W [U]: 1.5 J
    assert L.receive_energy_j(5.0) == pytest.approx(1.5)


# ----------------------------------------------------------------- slot timelines


def slot(xs_m, starts_s, duration_s=5.0, sl_db=185.0, bits=256):
    """One environment, vehicles on the x axis at ``xs_m``, at rest."""
    V = len(xs_m)
    pos = np.zeros((1, V, 3))
    pos[0, :, 0] = xs_m
    tx = L.SlotTransmissions(pos, np.zeros((1, V, 3)), np.asarray([starts_s], float), duration_s, sl_db, bits)
    return L.slot_timeline(tx, C)


NAN = np.nan


def test_capture_a_near_ping_survives_a_far_one():
    # receiver 0 at the origin; sender 1 at 100 m, sender 2 at 1000 m, both at t = 0 for
    # 5 s: they overlap at 0 ([0.0667, 5.0667) and [0.6667, 5.6667)).
    # SIR of 1 = TL(1000) - TL(100) = 20 log10(10) + 6.1048 x 0.9 = 20 + 5.4943 = 25.4943 dB
    o = slot([0.0, 100.0, 1000.0], [NAN, 0.0, 0.0])
    assert o.arrival_s[0, 1, 0] == pytest.approx(100.0 / C)
    assert o.arrival_s[0, 2, 0] == pytest.approx(1000.0 / C)
    assert o.overlapped[0, 1, 0] and o.overlapped[0, 2, 0]
    assert o.sir_db[0, 1, 0] == pytest.approx(25.4943, abs=1e-3)
    assert o.sir_db[0, 2, 0] == pytest.approx(-25.4943, abs=1e-3)
    assert o.captured[0, 1, 0] and not o.captured[0, 2, 0]
    assert o.p_success[0, 1, 0] > 0.99 and o.p_success[0, 2, 0] == 0.0
    # at 1 kHz absorption is negligible and the SIR is the spreading's 20 dB:
    # 20 + 0.0690041 x 0.9 = 20.0621 dB
    pos = np.array([[[0.0, 0, 0], [100.0, 0, 0], [1000.0, 0, 0]]])
    tx = L.SlotTransmissions(pos, np.zeros_like(pos), np.array([[NAN, 0.0, 0.0]]), 5.0, 185.0, 256)
    o = L.slot_timeline(tx, C, L.LinkParams(band=L.Band(1.0, 400.0)))
    assert o.sir_db[0, 1, 0] == pytest.approx(20.0621, abs=1e-3) and o.captured[0, 1, 0]


def test_a_captured_packet_is_decoded_at_its_sinr_not_its_snr():
    # receiver at the origin, senders at 1 km and 2 km, both at t = 0: the near one is
    # captured with SIR = TL(2000) - TL(1000) = 20 log10 2 + 6.1048 x 1.0 = 12.125 dB, and
    # decoded against noise and the far packet together: SINR = 1 / (1/SNR + 1/SIR), linear.
    # SNR 44.3 dB, so SINR = 12.12 dB; Rayleigh P = exp(-10^0.3 / 10^1.212) = exp(-1.995 / 16.29) = 0.885 (the
    # 3 dB threshold); at 4 kHz / 80 bps Eb/N0 is 815, no bit errors: P = 0.885, where
    # the SNR alone gives 0.9999 (what the kernel gave before it counted the interference)
    o = slot([0.0, 1000.0, 2000.0], [NAN, 0.0, 0.0])
    assert o.captured[0, 1, 0] and not o.captured[0, 2, 0]
    assert o.sir_db[0, 1, 0] == pytest.approx(12.125, abs=1e-3)
    snr, sir = o.snr_db[0, 1, 0], o.sir_db[0, 1, 0]
    sinr_lin = 1.0 / (10.0 ** (-snr / 10.0) + 10.0 ** (-sir / 10.0))
    assert 10.0 * np.log10(sinr_lin) == pytest.approx(12.12, abs=0.01)
    assert o.p_success[0, 1, 0] == pytest.approx(np.exp(-(10.0**0.3) / sinr_lin), rel=1e-6)
    assert o.p_success[0, 1, 0] == pytest.approx(0.885, abs=1e-3)
    alone = slot([0.0, 1000.0, 2000.0], [NAN, 0.0, NAN])  # the far sender silent: the SNR's
    assert alone.p_success[0, 1, 0] > 0.9999


def test_interference_is_the_power_sum_of_every_overlapping_ping():
    # as the capture case above with a second interferer, 1000 m on the other side: the
    # two far pings arrive together and add, SIR = 25.4943 - 10 log10 2 = 22.4840 dB (the
    # louder of them alone would leave 25.49)
    o = slot([0.0, 100.0, 1000.0, -1000.0], [NAN, 0.0, 0.0, 0.0])
    assert o.sir_db[0, 1, 0] == pytest.approx(22.4840, abs=1e-3)
    assert o.captured[0, 1, 0]


def test_two_equal_overlapping_pings_are_both_lost():
    # senders at -500 m and +500 m: equal RL at the origin, SIR 0 dB < 10 dB
    o = slot([0.0, -500.0, 500.0], [NAN, 0.0, 0.0])
    assert o.sir_db[0, 1, 0] == pytest.approx(0.0, abs=1e-9)
    assert o.sir_db[0, 2, 0] == pytest.approx(0.0, abs=1e-9)
    assert not o.captured[0, 1, 0] and not o.captured[0, 2, 0]
    assert o.p_success[0, 1, 0] == 0.0 and o.p_success[0, 2, 0] == 0.0


def test_near_far_a_near_interferer_drowns_a_good_far_link():
    # alone, the 2 km link at 25 kHz has SNR ~ 185 - 78.2 - 74.6 = 32 dB: decoded
    alone = slot([0.0, 2000.0, 200.0], [NAN, 0.0, NAN])
    assert alone.p_success[0, 1, 0] > 0.99 and not alone.overlapped[0, 1, 0]
    # a sender at 200 m overlapping it: SIR = -(20 + 6.1048 x 1.8) = -30.99 dB: lost,
    # and the near one is captured at the same receiver
    both = slot([0.0, 2000.0, 200.0], [NAN, 0.0, 0.0])
    assert both.sir_db[0, 1, 0] == pytest.approx(-(20.0 + 6.1048051 * 1.8), abs=1e-3)
    assert not both.captured[0, 1, 0] and both.p_success[0, 1, 0] == 0.0
    assert both.captured[0, 2, 0] and both.p_success[0, 2, 0] > 0.99


def test_half_duplex_a_transmitting_receiver_is_deaf():
    # 1 sends at 0 from 1500 m: arrives at 0 over [1, 6). 0 transmits over [3, 8): deaf.
    o = slot([0.0, 1500.0], [3.0, 0.0])
    assert o.arrival_s[0, 1, 0] == pytest.approx(1.0)
    assert o.deaf[0, 1, 0] and o.p_success[0, 1, 0] == 0.0
    assert not o.overlapped[0, 1, 0]  # deafness is not a collision
    # 0 transmits over [6, 11): starts as the reception ends; touching is no overlap
    o = slot([0.0, 1500.0], [6.0, 0.0])
    assert not o.deaf[0, 1, 0] and o.p_success[0, 1, 0] > 0.99
    # and 0's own packet reaches 1 at 7 s, after 1 has finished sending at 5 s
    assert not o.deaf[0, 0, 1] and o.p_success[0, 0, 1] > 0.99


def test_two_offset_pings_do_not_collide():
    # receiver at the origin; sender 1 at 1000 m, sender 2 at 3000 m; 5 s packets.
    # At the same start they overlap: 1 over [0.667, 5.667), 2 over [2, 7).
    same = slot([0.0, 1000.0, 3000.0], [NAN, 0.0, 0.0])
    assert same.overlapped[0, 1, 0] and same.overlapped[0, 2, 0]
    # staggered by packet + max range / c = 5 + 3000/1500 = 7 s: 2 arrives over [9, 14),
    # after 1 has ended at 5.667 (an offset above packet + flight difference, 5 - 1.333 = 3.667 s)
    offsets = L.staggered_offsets_s(2, 5.0, 3000.0, C)
    assert offsets == pytest.approx([0.0, 7.0])
    o = slot([0.0, 1000.0, 3000.0], [NAN, *offsets])
    assert o.arrival_s[0, 2, 0] == pytest.approx(9.0)
    assert not o.overlapped[0, 1, 0] and not o.overlapped[0, 2, 0]
    assert o.captured[0, 1, 0] and o.captured[0, 2, 0]
    assert np.isinf(o.sir_db[0, 1, 0]) and np.isinf(o.sir_db[0, 2, 0])
    # 3 km at 25 kHz: SNR = 185 - (69.54 + 18.31) - 74.6 ~ 22.5 dB: exp(-10^-1.95) ~ 0.989
    assert o.p_success[0, 2, 0] > 0.98
    # the senders hear each other too: 1 hears 2's packet over [8.333, 13.333), after its own
    assert not o.deaf[0, 2, 1] and o.p_success[0, 2, 1] > 0.98


def test_silent_senders_and_self_receptions_are_empty():
    o = slot([0.0, 1000.0], [NAN, NAN])
    assert np.all(np.isnan(o.arrival_s)) and np.all(o.p_success == 0.0)
    o = slot([0.0, 1000.0], [NAN, 0.0])
    assert np.isnan(o.arrival_s[0, 1, 1]) and o.p_success[0, 1, 1] == 0.0


def test_moving_receiver_and_batch_axis():
    # env 0: receiver closes at 2 m/s from 1500 m: tau = 1500 / (1500 + 2) = 0.998668 s
    # env 1: at rest: 1 s
    pos = np.zeros((2, 2, 3))
    pos[:, 1, 0] = 1500.0
    vel = np.zeros((2, 2, 3))
    vel[0, 0, 0] = 2.0
    tx = L.SlotTransmissions(pos, vel, np.array([[NAN, 0.0], [NAN, 0.0]]), 5.0, 185.0, 256)
    o = L.slot_timeline(tx, np.array([C, C]))
    assert o.arrival_s[0, 1, 0] == pytest.approx(1500.0 / 1502.0, rel=1e-9)
    assert o.arrival_s[1, 1, 0] == pytest.approx(1.0)
    assert o.range_m[0, 1, 0] == pytest.approx(C * 1500.0 / 1502.0, rel=1e-9)


def test_noise_per_environment():
    # the same 3 km link in two environments, band noise 74.6 and 104.6 dB: SNR 22.5 and
    # -7.5 dB (TL 87.85): P = exp(-10^-1.95) = 0.989 and exp(-10^1.05) ~ 1e-5
    pos = np.zeros((2, 2, 3))
    pos[:, 1, 0] = 3000.0
    tx = L.SlotTransmissions(pos, np.zeros_like(pos), np.array([[NAN, 0.0], [NAN, 0.0]]), 5.0, 185.0, 256)
    o = L.slot_timeline(tx, C, noise_db=np.array([74.6, 104.6]))
    assert o.snr_db[0, 1, 0] - o.snr_db[1, 1, 0] == pytest.approx(30.0)
    assert o.p_success[0, 1, 0] > 0.98
    assert o.p_success[1, 1, 0] < 0.001


def test_draw_delivered_uses_the_callers_uniforms():
    o = slot([0.0, 5000.0], [NAN, 0.0])
    p = o.p_success[0, 1, 0]
    assert 0.2 < p < 0.9  # 5 km at 25 kHz
    u = np.full_like(o.p_success, p - 1e-9)
    assert L.draw_delivered(o, u)[0, 1, 0]
    u[...] = p + 1e-9
    assert not L.draw_delivered(o, u)[0, 1, 0]


def test_unknown_detection_model_is_refused():
    with pytest.raises(ValueError):
        L.success_probability(1000.0, 256, L.LinkParams(detection_model="gaussian"))


# ----------------------------------------------------------------------- properties


@settings(max_examples=200, deadline=None)
@given(r1=st.floats(1.0, 5e4), dr=st.floats(1e-3, 5e4), f=st.floats(0.5, 60.0), k=st.floats(1.0, 2.0))
def test_transmission_loss_increases_with_range(r1, dr, f, k):
    assert L.transmission_loss_db(r1 + dr, f, k) > L.transmission_loss_db(r1, f, k)


@settings(max_examples=200, deadline=None)
@given(a=st.floats(60.0, 200.0), b=st.floats(60.0, 200.0))
def test_sir_of_two_overlapping_receptions_is_antisymmetric(a, b):
    assert L.sir_db(a, [b]) == pytest.approx(-L.sir_db(b, [a]), abs=1e-9)
    assert L.captured(a, [b], 10.0) + L.captured(b, [a], 10.0) <= 1  # at most one survives


@settings(max_examples=30, deadline=None)
@given(x1=st.floats(50.0, 8000.0), x2=st.floats(50.0, 8000.0), side=st.sampled_from([-1.0, 1.0]))
def test_slot_sir_is_antisymmetric_and_symmetric_geometry_gives_zero(x1, x2, side):
    o = slot([0.0, x1, side * x2], [NAN, 0.0, 0.0], duration_s=20.0)  # long packets: always overlap
    assert o.sir_db[0, 1, 0] == pytest.approx(-o.sir_db[0, 2, 0], abs=1e-6)
    mirror = slot([0.0, x1, -x1], [NAN, 0.0, 0.0], duration_s=20.0)
    assert mirror.sir_db[0, 1, 0] == pytest.approx(0.0, abs=1e-6)
