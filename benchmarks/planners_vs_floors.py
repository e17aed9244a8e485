"""Do the planners still beat the floors? Every planner of every scenario against the
`static` and `random` beacons, paired over common random numbers.

    python benchmarks/planners_vs_floors.py --episodes 50 --seed 300000 --markdown results/floors.md

For each scenario, every planner that can drive its network (``baselines.list_policies``)
and the two floors run on the same seeds (episode ``i`` of every policy uses seed
``--seed + i``); the table gives each planner's mean error and its paired difference
to each floor (planner minus floor, mean of the per-episode differences with a 95 % t
interval). A planner beats a floor when the whole interval is below zero.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

import numpy as np

from evaluation.episodes import run_episodes
from evaluation.paired import t_interval

try:
    from benchmarks import _args
except ImportError:  # run as a script: its own folder is on the path, not the checkout
    import _args  # type: ignore[no-redef]

FLOORS = ("static", "random")


def main(argv: Sequence[str] | None = None) -> int:
    import coopnav_env
    from baselines import list_policies

    p = _args.Parser(description=__doc__.split("\n\n")[0], formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--scenarios", default=",".join(coopnav_env.list_scenarios()), help="comma-separated")
    p.add_argument("--episodes", type=int, default=50, help="episodes per policy and scenario")
    p.add_argument("--seed", type=int, default=300_000, help="episode i uses seed SEED + i")
    p.add_argument("--markdown", help="also write the table here")
    _args.add_overwrite(p, "the --markdown file")
    args = p.parse_args(argv)
    _args.outputs(p, args.overwrite, markdown=args.markdown)  # refused before any run
    _args.count(p, args.episodes, "--episodes", low=2)
    seeds = _args.seeds(p, args.seed, args.episodes)
    configs = {
        name: _args.scenario_config(p, name, option="--scenarios")
        for name in _args.names(p, args.scenarios, "--scenarios")
    }
    lines = [
        f"{args.episodes} episodes per policy, seeds {seeds[0]}..{seeds[-1]}; planner minus floor, "
        "mean survey_error_m (m), paired 95 % t interval; ✓ when the interval is below zero.",
        "",
        "| scenario | planner | mean (m) | minus static | minus random |",
        "|---|---|---|---|---|",
    ]
    all_beat = True
    for scenario, config in configs.items():
        planners = [q for q in list_policies(config.network) if q not in FLOORS]
        scores = {
            q: np.array([r["mean_error_m"] for r in run_episodes(config, q, seeds)[0]]) for q in planners + list(FLOORS)
        }
        for q in planners:
            cells = []
            for floor in FLOORS:
                m, lo, hi = t_interval(np.asarray(scores[q]) - np.asarray(scores[floor]))
                beat = hi < 0
                all_beat &= beat
                cells.append(f"{m:+.2f} [{lo:+.2f}, {hi:+.2f}]{' ✓' if beat else ''}")
            lines.append(f"| {scenario} | {q} | {np.mean(scores[q]):.2f} | " + " | ".join(cells) + " |")
        lines.append(
            f"| {scenario} | (floors) | static {np.mean(scores['static']):.2f}, random "
            f"{np.mean(scores['random']):.2f} | | |"
        )
        print("\n".join(lines[-len(planners) - 1 :]), file=sys.stderr, flush=True)
    text = "\n".join(lines)
    print(text)
    if args.markdown:
        from coopnav_env.records import atomic_write_text

        atomic_write_text(args.markdown, text + "\n")
    print("every planner beats both floors" if all_beat else "NOT every planner beats both floors", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
