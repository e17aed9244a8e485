"""When to ping: mean survey error against pings per mission, for transmit schedules at
several rates and thresholds and for trained policies, on common random numbers.

    python benchmarks/ping_tradeoff.py --episodes 50 --seed 400000 --policies runs/ping_ppo \\
        --figure docs/figures/ping_tradeoff.png --markdown results/ping_tradeoff.md --overwrite

Every schedule drives the ASVs with ``fim_a`` or ``ellipse`` (``baselines.schedule``): ``clock``
(both ASVs every slot: staggered on the sonar link, colliding with ``ping_offsets="zero"``),
``event`` at several thresholds (each ASV alone, in any slot), ``tdma`` with frames of 2 (the
default: the two ASVs take turns every slot), 4, 8 and 16 slots, and ``event_tdma`` at
several thresholds. The oracle's motion (``baselines.oracle``, given the survey filters' errors)
on ``clock`` and ``event`` is the reference: what motion alone could give at each trigger's pings.
A trained policy decides motion and transmission itself (its third action component).
Per policy: the mean over episodes of ``mean_error_m`` with a 95 % t interval, pings
per mission (both ASVs), collisions, transmit energy; and, paired over the same seeds,
each trained policy's error and pings against ``ellipse+clock`` (the best fixed schedule) and
``ellipse+tdma``.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from evaluation.paired import t_interval

try:
    from benchmarks import _args
except ImportError:  # run as a script: its own folder is on the path, not the checkout
    import _args  # type: ignore[no-redef]

if TYPE_CHECKING:
    from coopnav_env.scenarios import ScenarioConfig


def run(
    config: ScenarioConfig, spec: str, kwargs: dict, seeds: Sequence[int]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per-episode (mean error, pings, collisions, energy) of one policy on ``seeds``."""
    from coopnav_env.core import make_simulator

    B, N = len(seeds), config.n_beacons
    sim = make_simulator(config, B)
    obs = sim.reset(np.asarray(seeds, dtype=np.int64))
    if "+" in spec:
        from baselines import make_policy, tell_truth

        policies = [[make_policy(spec, config, seed=(s, j), agent=j, **kwargs) for j in range(N)] for s in seeds]

        def act(obs):
            tell_truth(policies, sim)  # the oracle's rows: told the truth before each act
            return np.stack([np.stack([policies[b][j].act(obs[b, j]) for j in range(N)]) for b in range(B)])
    else:
        import agents

        policy = agents.load(spec, scenario=config)

        def act(obs):
            return policy.act_batch(obs.reshape(B * N, -1)).reshape(B, N, -1).astype(np.float64)

    alive = np.ones(B, dtype=bool)
    err, steps = np.zeros(B), np.zeros(B)
    pings, coll, energy = np.zeros(B), np.zeros(B), np.zeros(B)
    while alive.any():
        res = sim.step(act(obs))
        obs = res.obs
        err += np.where(alive, res.info["survey_error_m"].mean(-1), 0.0)
        steps += alive
        bi = res.beacon_info
        pings += np.where(alive, bi["pings"].sum(-1), 0)
        coll += np.where(alive, bi["collisions"].sum(-1), 0)
        energy += np.where(alive, bi["energy_J"].sum(-1), 0.0)
        alive &= ~(res.terminated | res.truncated)
    return err / steps, pings, coll, energy


def main(argv: Sequence[str] | None = None) -> int:
    import coopnav_env

    p = _args.Parser(description=__doc__.split("\n\n")[0], formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--scenario", default="sousa_ping")
    p.add_argument("--episodes", type=int, default=50)
    p.add_argument("--seed", type=int, default=400_000, help="episode i uses seed SEED + i")
    p.add_argument("--policies", default="", help="comma-separated trained policies (run directories)")
    p.add_argument("--figure", help="write the error-against-pings figure here (PNG)")
    p.add_argument("--markdown", help="write the table here")
    _args.add_overwrite(p, "the --figure and --markdown files")
    args = p.parse_args(argv)
    _args.outputs(p, args.overwrite, figure=args.figure, markdown=args.markdown)  # refused before any run
    _args.count(p, args.episodes, "--episodes", low=2)
    seeds = _args.seeds(p, args.seed, args.episodes)
    config = _args.scenario_config(p, args.scenario)
    if config.channel_mode != "decide":
        deciding = [s for s in coopnav_env.list_scenarios() if coopnav_env.make_config(s).channel_mode == "decide"]
        p.error(
            f"--scenario {args.scenario}: its beacons ping on a clock (channel_mode={config.channel_mode!r}); "
            f"the transmit schedules compared here need channel_mode='decide': {', '.join(deciding)}"
        )
    for spec in [s for s in args.policies.split(",") if s]:  # each loads and drives it, before the planners run
        _args.policy(p, spec, config, seeds[0], "--policies")
    rows = []
    for motion in ("fim_a", "ellipse"):
        rows += [(f"{motion}+clock", f"{motion}+clock", {"every": 1})]
        rows += [(f"{motion}+event {t:g}", f"{motion}+event", {"threshold_nats": t}) for t in (0.3, 0.4, 0.45, 0.5)]
        rows += [(f"{motion}+tdma", f"{motion}+tdma", {})]
        rows += [(f"{motion}+tdma F={f}", f"{motion}+tdma", {"frame": f}) for f in (4, 8, 16)]
        rows += [
            (f"{motion}+event_tdma {t:g}", f"{motion}+event_tdma", {"threshold_nats": t}) for t in (0.3, 0.5, 0.8, 1.2)
        ]
    # the reference given the truth: the oracle's motion (baselines.oracle) on the clock and on the event
    # trigger, the error that motion alone could reach at each trigger's pings (not a planner anyone can run)
    rows += [("oracle+clock", "oracle+clock", {"every": 1})]
    rows += [(f"oracle+event {t:g}", "oracle+event", {"threshold_nats": t}) for t in (0.3, 0.4, 0.45, 0.475, 0.5)]
    rows += [(spec, spec, {}) for spec in args.policies.split(",") if spec]
    results = {}
    for label, spec, kw in rows:
        results[label] = run(config, spec, kw, seeds)
        e, pg, c, en = results[label]
        print(
            f"{label}: error {e.mean():.3f} m, pings {pg.mean():.1f}, collisions {c.mean():.1f}",
            file=sys.stderr,
            flush=True,
        )
    lines = [
        f"`{args.scenario}`, {args.episodes} episodes, seeds {seeds[0]}..{seeds[-1]} (common random numbers)",
        "",
        "| policy | mean error (m) [95 %] | pings per mission | collisions | energy (kJ) |",
        "|---|---|---|---|---|",
    ]
    for label, (e, pg, c, en) in results.items():
        m, lo, hi = t_interval(e)
        lines.append(
            f"| {label} | {m:.3f} [{lo:.3f}, {hi:.3f}] | {pg.mean():.1f} | {c.mean():.1f} | {en.mean() / 1e3:.2f} |"
        )
    for ref_name in ("ellipse+clock", "ellipse+tdma"):  # the best fixed schedule (every slot, staggered), and turns
        ref = results[ref_name]
        oracles = [lab for lab in results if lab.startswith("oracle+")] if ref_name == "ellipse+clock" else []
        for spec in oracles + [s for s in args.policies.split(",") if s]:
            e, pg, _, _ = results[spec]
            m, lo, hi = t_interval(e - ref[0])
            pm, plo, phi = t_interval(pg / np.maximum(ref[1], 1) - 1)
            lines += [
                "",
                f"{spec} minus {ref_name} (paired): error {m:+.3f} m [{lo:+.3f}, {hi:+.3f}], "
                f"pings {100 * pm:+.1f} % [{100 * plo:+.1f}, {100 * phi:+.1f}]",
            ]
    text = "\n".join(lines)
    print(text)
    if args.markdown:
        from coopnav_env.records import atomic_write_text

        atomic_write_text(args.markdown, text + "\n")
    if args.figure:
        import io

        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        from coopnav_env.records import atomic_write_bytes

        fig = Figure(figsize=(7.0, 4.6))
        FigureCanvasAgg(fig)
        ax = fig.add_subplot(1, 1, 1)
        groups = {
            f"{m}+{k}": (m, k) for m in ("fim_a", "ellipse", "oracle") for k in ("clock", "event", "tdma", "event_tdma")
        }
        for title, (motion, key) in groups.items():
            pts = [
                (r[1].mean(), r[0].mean())
                for lab, r in results.items()
                if lab.startswith(motion + "+") and lab.split("+")[1].split()[0] == key
            ]
            if pts:
                x, y = zip(*sorted(pts))
                if motion == "oracle":  # the reference given the truth, drawn apart from the planners
                    ax.plot(x, y, "k--" if len(pts) > 1 else "kD", lw=1.0, label=f"{title} (given the truth)")
                else:
                    ax.plot(x, y, "o-" if len(pts) > 1 else "s", label=title)
        for spec in [s for s in args.policies.split(",") if s]:
            e, pg, _, _ = results[spec]
            ax.plot([pg.mean()], [e.mean()], "*", ms=14, label=f"PPO ({spec})")
        ax.set_xlabel("pings per mission (both ASVs)")
        ax.set_ylabel("mean survey error (m)")
        ax.set_title(f"{args.scenario}: error against pings, {args.episodes} episodes", fontsize=10)
        ax.grid(True, lw=0.3)
        ax.legend(fontsize=8)
        fig.tight_layout()
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=200)
        atomic_write_bytes(args.figure, buf.getvalue())
    return 0


if __name__ == "__main__":
    sys.exit(main())
