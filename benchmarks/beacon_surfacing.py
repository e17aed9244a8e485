"""What the beacon AUV's surfacing costs: GPS fixes per hour, time away from the survey
(ascending, at the surface, descending) and its effect on the survey's error.

    python benchmarks/beacon_surfacing.py --runs 20 --scenario gao_sea

``--runs`` episodes run as one batch (seeds ``--seed`` + i) with ``--planner`` driving
every beacon. Reported per beacon AUV, over the run-hours simulated: GPS fixes per hour
(``SimState.b_surfacings``), the fraction of time away (``beacon_away_s`` in the beacon
infos; 0 where surfacing is instant), the fraction of cycles the beacon pinged from
below the ranging depth; and the survey's mean and worst horizontal error and the ranges
fused per cycle.
"""

from __future__ import annotations

import sys

import numpy as np

try:
    from benchmarks import _args
except ImportError:  # run as a script: its own folder is on the path, not the checkout
    import _args  # type: ignore[no-redef]


def surfacing_figures(scenario: str, planner: str, overrides: dict, runs: int, seed: int) -> dict:
    """Run the case and summarize the beacon AUVs' surfacing."""
    from baselines.rollout import planned_steps

    fixes = away = seconds = fused = cycles = 0.0
    err_sum = worst = 0.0
    n_survey = 1
    for cfg, sim, res, live in planned_steps(scenario, planner, overrides, runs, seed):
        auv = np.array([k == "beacon_auv" for k in cfg.beacon_kinds])
        n_survey = cfg.n_survey
        fixes += float(sim.state.b_surfacings[live][:, auv].sum())
        if "beacon_away_s" in res.beacon_info:
            away += float(np.asarray(res.beacon_info["beacon_away_s"])[live][:, auv].sum())
        seconds += cfg.ping_interval_s * int(live.sum()) * int(auv.sum())
        fused += float(np.asarray(res.info["ranges_fused"])[live].sum())
        err = np.asarray(res.info["survey_error_m"])[live]
        err_sum += float(err.sum())
        worst = max(worst, float(err.max(initial=0.0)))
        cycles += int(live.sum())
    hours = seconds / 3600.0
    return {
        "fixes_per_hour": fixes / max(hours, 1e-12),
        "time_away": away / max(seconds, 1e-12),
        "survey_error_mean_m": err_sum / max(cycles * n_survey, 1),
        "survey_error_worst_m": worst,
        "ranges_fused_per_cycle": fused / max(cycles, 1),
    }


def main(argv: list[str] | None = None) -> int:
    ap = _args.Parser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenario", default="gao_sea")
    ap.add_argument("--planner", default="ellipse")
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE", help="a scenario override")
    args = ap.parse_args(argv)
    _args.count(ap, args.runs, "--runs", bound="MAX_BATCH_SIZE")  # the runs are one batch
    _args.seeds(ap, args.seed, args.runs)
    overrides = _args.overrides(ap, args.set)
    config = _args.scenario_config(ap, args.scenario, overrides)
    if "beacon_auv" not in config.beacon_kinds:  # as beacon_covariance.py: nothing surfaces
        import coopnav_env

        with_auv = [s for s in coopnav_env.list_scenarios() if "beacon_auv" in coopnav_env.make_config(s).beacon_kinds]
        ap.error(
            f"--scenario {args.scenario} has no beacon AUV (beacons: {', '.join(config.beacon_kinds)}): nothing "
            f"surfaces; scenarios with one: {', '.join(with_auv)}"
        )
    _args.planner(ap, args.planner, config, args.seed, "--planner")  # the runs are driven by baselines' planners
    f = surfacing_figures(args.scenario, args.planner, overrides, args.runs, args.seed)
    print(f"{args.scenario} ({args.planner}, {args.runs} runs, seed {args.seed}, set {overrides or '-'})")
    for k, v in f.items():
        print(f"  {k}: {v:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
