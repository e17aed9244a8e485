"""Figures of the acoustic link from the sonar equation (``coopnav_env.core.link``, issue 21).

    python benchmarks/link_curves.py --out docs/figures --overwrite
    python benchmarks/link_curves.py --episodes 20 --policy fim_a+tdma [--set NAME=VALUE ...]

Writes two PNGs (200 dpi):

- ``link_loss_vs_range.png``: in-band SNR and packet-success probability (one rate-0
  frame, 256 bits) against range for the Micro-Modem's 10 and 25 kHz bands under
  calm, moderate and rough noise, spherical spreading (k = 2) and SL 185 dB [U].
- ``link_timeline.png``: one slot of two beacons and two survey vehicles, with both
  beacons pinging at t = 0 (top: collisions, capture, half duplex) and staggered by
  packet + max range / c (bottom: every reception clean); transmissions and
  receptions as bars per vehicle on a time axis.

``--episodes N``: instead of the figures, N episodes of ``--scenario`` (``sousa_ping``)
driven by ``--policy`` (a ``baselines`` planner+schedule), printing per episode and on
average the ping loss fraction (pings sent to a survey vehicle and not decoded there:
collisions, half duplex and the link's random loss), the collisions, the SNR losses
(``packets_lost``) and the energy per ping. Uses only the simulator's public infos, so
it also measures a checkout without the sonar link (``PYTHONPATH=<checkout>``).
"""

from __future__ import annotations

import io
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from coopnav_env.core import link as L

try:
    from benchmarks import _args
except ImportError:  # run as a script: its own folder is on the path, not the checkout
    import _args  # type: ignore[no-redef]

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
    r_mc_m, frac, p_wired = wired_delivery_vs_range()
    ax_p.plot(r_mc_m / 1000.0, frac, "o", color="k", ms=4, label="simulator's channel, 25 kHz moderate (MC)")
    ax_p.plot(r_mc_m / 1000.0, p_wired, "x", color="k", ms=5, label="simulator's channel, its P")
    ax_p.legend(fontsize=7, loc="upper right")
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


def _channel_sim(batch: int, **overrides):
    """A ``sousa_ping`` simulator (the wired sonar link) reset, and its vehicles at rest."""
    import coopnav_env
    from coopnav_env.core import make_simulator

    sim = make_simulator(coopnav_env.make_config("sousa_ping", **overrides), batch)
    sim.reset(np.arange(batch) + 900)
    st = sim.state
    st.b_vel[:] = 0.0
    st.s_vel_true[:] = 0.0
    return sim


def wired_delivery_vs_range(batch: int = 2000) -> tuple:
    """Through the simulator's channel (``sousa_ping``, 25 kHz, moderate noise): one ASV
    pinging alone at each range from the survey vehicle (both at 5 m), ``batch``
    environments each: the fraction decoded and the channel's P."""
    sim = _channel_sim(batch)
    ranges_m = np.array([1000.0, 2000.0, 3000.0, 4000.0, 5000.0, 6000.0, 7000.0, 8000.0])
    frac, p = np.zeros(len(ranges_m)), np.zeros(len(ranges_m))
    tx = np.zeros((batch, 2), dtype=bool)
    tx[:, 0] = True
    st = sim.state
    for i, r in enumerate(ranges_m):
        st.b_pos[:] = 5.0
        st.b_pos[:, 0, :2] = (r, 0.0)
        st.b_pos[:, 1, :2] = (1e5, 0.0)
        st.s_pos[:] = 5.0
        st.s_pos[..., :2] = 0.0
        ok, slot = sim.channel.pings(tx, sim._draws.draw(st.keys, st.cycle + i))
        frac[i], p[i] = ok[:, 0, 0].mean(), slot.outcome.p_success[0, 0, 2]
    return ranges_m, frac, p


def channel_slot(offsets: str) -> tuple:
    """The timeline figure's slot through the simulator's channel (``sousa_ping`` with a
    second survey vehicle, ``ping_offsets=offsets``): beacons A, B ping; a survey vehicle
    that decoded a ping replies at the reply time. Returns (names, tx, outcome, sim)."""
    sim = _channel_sim(1, n_survey=2, ping_offsets=offsets)
    st = sim.state
    st.b_pos[0] = [[0.0, 0.0, 2.0], [1500.0, 500.0, 2.0]]
    st.s_pos[0] = [[700.0, 200.0, 30.0], [2500.0, -300.0, 30.0]]
    draws = sim._draws.draw(st.keys, st.cycle)
    beacon_tx = np.ones((1, 2), dtype=bool)
    ok, slot = sim.channel.pings(beacon_tx, draws)
    replied = (ok & slot.ended[:, :2, 2:]).any(1)  # a ping decoded by the reply time
    _, _, o = sim.channel.replies(beacon_tx, replied, draws)
    ch = sim.channel
    start = np.concatenate([ch.offsets_s(draws), np.where(replied, ch.reply_at_s, np.nan)], 1)
    tx = L.SlotTransmissions(st.b_pos, st.b_vel, start, ch.tx_dur[None], ch.link.source_level_db, ch.tx_bits[None])
    return ["beacon A", "beacon B", "survey S", "survey T"], tx, o, sim


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
    colors = {v: ["tab:blue", "tab:orange", "tab:green", "tab:purple"][v] for v in senders}
    lane, h = 0.32, 0.24
    block = (len(senders) + 1) * lane + 0.35
    ticks = []
    for w in range(V):
        top = (V - 1 - w) * block + len(senders) * lane
        ticks.append((top - 0.5 * len(senders) * lane, names[w]))
        t0 = tx.tx_start_s[0, w]
        if np.isfinite(t0):
            ax.barh(top, tx.duration_s[0, w], left=t0, height=h, color=colors[w], edgecolor="k", lw=0.6)
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
    """One slot of the simulator's channel (``sousa_ping`` + a second survey vehicle):
    every ping at t = 0 (top) and at the default staggered offsets (bottom), replies included."""
    fig = _figure((9.5, 8.6))
    axes = fig.add_subplot(2, 1, 1), fig.add_subplot(2, 1, 2)
    for ax, offsets in zip(axes, ("zero", "staggered")):
        names, tx, o, sim = channel_slot(offsets)
        t = sim.channel.timing
        title = (
            f'ping_offsets="{offsets}": pings at {", ".join(f"{x:.2f}" for x in tx.tx_start_s[0, :2])} s, '
            f"replies at {t.reply_at_s:.2f} s ({t.ping_s:g} s Micro-Modem rate-0 packets, 25 kHz, "
            f"slot {sim.config.ping_interval_s:g} s)"
        )
        _draw_slot(ax, names, tx, o, title)
        ax.set_xlim(0.0, sim.config.ping_interval_s + 6.0)
        ax.axvline(sim.config.ping_interval_s, color="k", lw=0.8, ls="--")
        ax.set_xlabel("time within the slot (s); dashed: the slot's end")
    fig.text(
        0.01,
        0.005,
        "per vehicle: its transmission (top lane), then its receptions, one lane per sender, "
        "coloured by sender; hatched red: lost. A survey vehicle replies only if it decoded a ping by the reply time.",
        fontsize=7,
    )
    fig.tight_layout(rect=(0, 0.02, 1, 1))
    _save(fig, path)


def episodes(scenario: str, policy: str, n: int, seed: int, overrides: dict) -> dict:
    """Per-episode ping loss fraction, collisions, SNR losses and energy per ping (n,)."""
    import coopnav_env
    from baselines import make_policy
    from coopnav_env.core import make_simulator

    config = coopnav_env.make_config(scenario, **overrides)
    seeds = np.arange(seed, seed + n)
    B, N = n, config.n_beacons
    sim = make_simulator(config, B)
    obs = sim.reset(seeds)
    pols = [[make_policy(policy, config, seed=(int(s), j), agent=j) for j in range(N)] for s in seeds]
    alive = np.ones(B, dtype=bool)
    tot = {k: np.zeros(B) for k in ("sent", "decoded", "collisions", "snr_lost", "energy_J", "cycles")}
    while alive.any():
        res = sim.step(np.stack([np.stack([pols[b][j].act(obs[b, j]) for j in range(N)]) for b in range(B)]))
        obs, bi, info = res.obs, res.beacon_info, res.info
        step = {
            "sent": bi["pings"].sum(-1) * config.n_survey,
            "decoded": (info["ranges_fused"] + info["outliers_rejected"]).sum(-1),
            "collisions": bi["collisions"].sum(-1),
            "snr_lost": info["packets_lost"].sum(-1),
            "energy_J": bi["energy_J"].sum(-1),
            "cycles": np.ones(B),
        }
        for k, v in step.items():
            tot[k] += np.where(alive, v, 0.0)
        alive &= ~(res.terminated | res.truncated)
    sent = np.maximum(tot["sent"], 1.0)
    return {
        "loss": 1.0 - tot["decoded"] / sent,
        "collision_frac": tot["collisions"] / sent,
        "snr_frac": tot["snr_lost"] / sent,
        "energy_per_ping_J": tot["energy_J"] / np.maximum(tot["sent"] / config.n_survey, 1.0),
        "pings": tot["sent"] / config.n_survey,
        "cycles": tot["cycles"],
        "slot_s": np.full(B, config.ping_interval_s),
    }


def _print_episodes(out: dict) -> None:
    for k, v in out.items():
        print(f"{k}: mean {v.mean():.4f}, std {v.std(ddof=1):.4f}, min {v.min():.4f}, max {v.max():.4f}")


FIGURES = ("link_loss_vs_range.png", "link_timeline.png")  # what --out receives


def main(argv: list[str] | None = None) -> int:
    p = _args.Parser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, default=Path("docs/figures"), help="directory of the PNGs")
    p.add_argument("--episodes", type=int, default=0, help="> 0: measure episodes instead of drawing figures")
    p.add_argument("--scenario", default="sousa_ping")
    p.add_argument("--policy", default="fim_a+tdma")
    p.add_argument("--seed", type=int, default=500000, help="first episode seed")
    p.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE", help="scenario overrides")
    _args.add_overwrite(p, "the two PNGs in --out")
    args = p.parse_args(argv)
    _args.count(p, args.episodes, "--episodes", low=0, bound="MAX_BATCH_SIZE")
    if args.episodes > 0:
        _args.count(p, args.episodes, "--episodes", low=2)  # a standard deviation needs two
        _args.seeds(p, args.seed, args.episodes)
        extra = _args.overrides(p, args.set)
        config = _args.scenario_config(p, args.scenario, extra)
        _args.planner(p, args.policy, config, args.seed, "--policy")  # the episodes are driven by make_policy
        _print_episodes(episodes(args.scenario, args.policy, args.episodes, args.seed, extra))
        return 0
    for name in FIGURES:  # refused before anything is drawn
        _args.outputs(p, args.overwrite, out=args.out / name)
    args.out.mkdir(parents=True, exist_ok=True)
    loss_vs_range(args.out / FIGURES[0])
    timeline(args.out / FIGURES[1])
    print(f"wrote {args.out / 'link_loss_vs_range.png'} and {args.out / 'link_timeline.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
