"""Figures of the acoustic link from the sonar equation (``coopnav_env.core.link``, issue 21).

    python benchmarks/link_curves.py --out docs/figures

Writes two PNGs (200 dpi):

- ``link_loss_vs_range.png``: in-band SNR and packet-success probability (one rate-0
  frame, 256 bits) against range for the Micro-Modem's 10 and 25 kHz bands under
  calm, moderate and rough noise, spherical spreading (k = 2) and SL 185 dB [U].
- ``link_timeline.png``: one slot of two beacons and two survey vehicles, with both
  beacons pinging at t = 0 (top: collisions, capture, half duplex) and staggered by
  packet + max range / c (bottom: every reception clean); transmissions and
  receptions as bars per vehicle on a time axis.
"""

from __future__ import annotations

import argparse
import io
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from coopnav_env.core import link as L

NOISE = {  # name: (shipping, wind m/s) [U]: calm, moderate, rough
    "calm (s 0.2, w 1 m/s)": L.NoiseConditions(0.2, 1.0),
    "moderate (s 0.5, w 5 m/s)": L.NoiseConditions(0.5, 5.0),
    "rough (s 0.8, w 15 m/s)": L.NoiseConditions(0.8, 15.0),
}
BANDS_KHZ = {10.0: "tab:blue", 25.0: "tab:red"}
STYLES = ["-", "--", ":"]


def _save(fig, path: Path) -> None:
    from coopnav_env.records import atomic_write_bytes

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=200)
    atomic_write_bytes(path, buf.getvalue())


def _figure(size):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=size)
    FigureCanvasAgg(fig)
    return fig


def loss_vs_range(path: Path) -> None:
    """SNR and success probability against range for the bands and noise conditions."""
    fig = _figure((8.0, 6.4))
    ax_snr, ax_p = fig.add_subplot(2, 1, 1), fig.add_subplot(2, 1, 2, sharex=None)
    r_m = np.linspace(50.0, 20000.0, 800)
    for f_khz, color in BANDS_KHZ.items():
        for (name, noise), ls in zip(NOISE.items(), STYLES):
            p = L.LinkParams(band=L.Band(f_khz, 4000.0), noise=noise)
            nl = L.band_noise_db(p.band, p.noise)
            label = f"{f_khz:g} kHz, {name}"
            ax_snr.plot(r_m / 1000.0, L.snr_db(r_m, p, noise_db=nl), ls, color=color, lw=1.4, label=label)
            ax_p.plot(
                r_m / 1000.0, L.success_probability(r_m, 256, p, noise_db=nl), ls, color=color, lw=1.4, label=label
            )
    thr = L.LinkParams().detection_threshold_db
    ax_snr.axhline(thr, color="k", lw=0.8, alpha=0.6)
    ax_snr.text(0.3, thr - 2.0, f"detection threshold {thr:g} dB [U]", ha="left", va="top", fontsize=7)
    ax_snr.set_ylabel("in-band SNR (dB)")
    ax_snr.set_ylim(-40.0, 80.0)
    ax_snr.set_title(
        "Sonar equation: SL 185 dB re 1 uPa at 1 m [U], k = 2, Thorp absorption, Wenz/Coates noise over 4 kHz",
        fontsize=9,
    )
    ax_p.set_ylabel("packet success probability")
    ax_p.set_xlabel("range (km)")
    ax_p.set_ylim(-0.02, 1.02)
    ax_p.set_title("P(detect, Rayleigh fading) x (1 - PER), one 32-byte frame at 80 bps (non-coherent FSK)", fontsize=9)
    for ax in (ax_snr, ax_p):
        ax.set_xlim(0.0, 20.0)
        ax.grid(True, lw=0.3)
    ax_snr.legend(fontsize=7, ncol=2, loc="upper right")
    fig.tight_layout()
    _save(fig, path)


def two_beacon_slot(offsets_s: Sequence[float]) -> tuple:
    """The slot of the timeline figure: beacons A, B pinging at ``offsets_s``; survey
    vehicles S, T silent. Returns (names, tx, outcome)."""
    names = ["beacon A", "beacon B", "survey S", "survey T"]
    pos = np.array([[[0.0, 0.0, 2.0], [1500.0, 500.0, 2.0], [700.0, 200.0, 30.0], [2500.0, -300.0, 30.0]]])
    framing = L.MicroModemFraming()
    dur_s = L.packet_duration_s(framing, 256)
    start = np.array([[offsets_s[0], offsets_s[1], np.nan, np.nan]])
    tx = L.SlotTransmissions(pos, np.zeros_like(pos), start, dur_s, 185.0, 256)
    return names, tx, L.slot_timeline(tx, 1500.0)


def _draw_slot(ax, names, tx, o, title):
    """One slot as lanes: per vehicle, a transmit lane and one reception lane per sender."""
    V = len(names)
    senders = [v for v in range(V) if np.isfinite(tx.tx_start_s[0, v])]
    colors = dict(zip(senders, ["tab:blue", "tab:orange", "tab:green", "tab:purple"]))
    lane, h = 0.32, 0.24
    block = (len(senders) + 1) * lane + 0.35
    ticks = []
    for w in range(V):
        top = (V - 1 - w) * block + len(senders) * lane
        ticks.append((top - 0.5 * len(senders) * lane, names[w]))
        t0 = tx.tx_start_s[0, w]
        if np.isfinite(t0):
            ax.barh(top, tx.duration_s, left=t0, height=h, color=colors[w], edgecolor="k", lw=0.6)
            ax.text(t0 + 0.1, top, "transmit", va="center", fontsize=6.5, color="w")
        for i, v in enumerate(senders):
            a = o.arrival_s[0, v, w]
            if not np.isfinite(a):
                continue
            y = top - (i + 1) * lane
            lost = o.deaf[0, v, w] or not o.captured[0, v, w]
            ax.barh(
                y,
                o.end_s[0, v, w] - a,
                left=a,
                height=h,
                color=colors[v],
                alpha=0.35 if lost else 0.9,
                hatch="xxx" if lost else None,
                edgecolor="red" if lost else "k",
                lw=1.0 if lost else 0.6,
            )
            if o.deaf[0, v, w]:
                why = "lost: deaf (transmitting)"
            elif not o.captured[0, v, w]:
                why = f"lost: collision, SIR {o.sir_db[0, v, w]:+.0f} dB"
            elif o.overlapped[0, v, w]:
                why = f"captured, SIR {o.sir_db[0, v, w]:+.0f} dB, p {o.p_success[0, v, w]:.2f}"
            else:
                why = f"clear, p {o.p_success[0, v, w]:.2f}"
            sender = names[v].split()[1]
            ax.text(
                o.end_s[0, v, w] + 0.15,
                y,
                f"from {sender} ({o.range_m[0, v, w] / 1000:.1f} km): {why}",
                va="center",
                fontsize=6.5,
                color="red" if lost else "k",
            )
    ax.set_yticks([t for t, _ in ticks])
    ax.set_yticklabels([n for _, n in ticks], fontsize=8)
    ax.set_ylim(-0.3, V * block - 0.2)
    ax.set_title(title, fontsize=9)
    ax.grid(True, axis="x", lw=0.3)


def timeline(path: Path) -> None:
    """The two-beacon slot, simultaneous and staggered."""
    framing = L.MicroModemFraming()
    dur_s = L.packet_duration_s(framing, 256)
    stagger = L.staggered_offsets_s(2, dur_s, 3000.0, 1400.0)
    fig = _figure((9.5, 8.0))
    ax1, ax2 = fig.add_subplot(2, 1, 1), fig.add_subplot(2, 1, 2)
    names, tx, o = two_beacon_slot((0.0, 0.0))
    _draw_slot(ax1, names, tx, o, f"both beacons at t = 0 ({dur_s:g} s Micro-Modem rate-0 packets, 25 kHz)")
    names, tx, o = two_beacon_slot(tuple(stagger))
    _draw_slot(ax2, names, tx, o, f"staggered: B starts at {stagger[1]:.2f} s = packet + 3 km / 1400 m/s")
    for ax in (ax1, ax2):
        ax.set_xlim(0.0, 21.0)
        ax.set_xlabel("time within the slot (s)")
    fig.text(
        0.01,
        0.005,
        "per vehicle: its transmission (top lane), then its receptions, one lane per sender, "
        "coloured by sender; hatched red: lost",
        fontsize=7,
    )
    fig.tight_layout(rect=(0, 0.02, 1, 1))
    _save(fig, path)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=Path("docs/figures"), help="directory of the PNGs")
    args = p.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    loss_vs_range(args.out / "link_loss_vs_range.png")
    timeline(args.out / "link_timeline.png")
    print(f"wrote {args.out / 'link_loss_vs_range.png'} and {args.out / 'link_timeline.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
