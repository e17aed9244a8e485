"""What the planners' range model changes: ``range_model="constant"`` (one R at every
distance, the default) against ``"filter"`` (the survey filter's R(d), with the sound
speed's scale error that grows with the distance), paired on the same episodes.

    python benchmarks/range_model.py --cases gao_sea,gao_sea:temperature_uncertainty_c=2 \\
        --planners ellipse --runs 40 --seed 950000

Each case is a scenario with optional ``:key=value`` overrides (``+`` between several).
Prints per case and planner the mean horizontal error (the benchmark's score: the
error averaged over the episode's steps, then over episodes) with each model, the paired
difference filter - constant with its 95 % interval (t), and the mean distance from the
beacon(s) to the survey vehicle(s). Docs: docs/baselines/horizon.md#range-variance.
"""

from __future__ import annotations

import sys

import numpy as np

try:
    from benchmarks import _args
except ImportError:  # run as a script: its own folder is on the path, not the checkout
    import _args  # type: ignore[no-redef]


def parse_case(text: str) -> tuple[str, dict]:
    """``scenario[:key=value[+key=value...]]`` -> (scenario, overrides), each value typed as
    its scenario parameter (``evaluation.config.coerce_value``, as ``--set`` does)."""
    from evaluation.config import coerce_value, parse_assignment

    name, _, rest = text.partition(":")
    overrides: dict = {}
    for item in filter(None, rest.split("+")):
        key, value = parse_assignment(item, f"case {text!r}")
        overrides[key] = coerce_value(key, value)
    return name, overrides


def run(scenario: str, overrides: dict, planner: str, model: str, runs: int, seed: int) -> tuple[np.ndarray, float]:
    """Per-episode mean horizontal error (runs,) and the mean beacon-survey distance (m)."""
    from baselines.rollout import planned_steps

    err_sum = np.zeros(runs)
    steps = np.zeros(runs)
    dist: list[float] = []
    for _cfg, sim, res, live in planned_steps(scenario, planner, overrides, runs, seed, {"range_model": model}):
        e = np.asarray(res.info["survey_error_m"]).mean(-1)  # (runs,): the horizontal error, over survey vehicles
        err_sum += np.where(live, e, 0.0)
        steps += live
        st = sim.state
        d = np.linalg.norm(st.b_pos[:, :, None, :2] - st.s_pos[:, None, :, :2], axis=-1).mean((1, 2))
        dist.extend(d[live].tolist())
    return err_sum / np.maximum(steps, 1), float(np.mean(dist))


def main(argv: list[str] | None = None) -> int:
    from evaluation.paired import t_interval

    ap = _args.Parser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", default="gao_sea,gao_sea:temperature_uncertainty_c=2")
    ap.add_argument("--planners", default="ellipse")
    ap.add_argument("--runs", type=int, default=40)
    ap.add_argument("--seed", type=int, default=950000)
    args = ap.parse_args(argv)
    try:
        cases = [parse_case(c) for c in args.cases.split(",") if c]
    except ValueError as exc:
        print(f"range_model.py: {exc}", file=sys.stderr)
        return 2
    if not cases or not [q for q in args.planners.split(",") if q]:  # an empty table is no answer
        what = "--cases" if not cases else "--planners"
        print(
            f"range_model.py: {what} names nothing (got {getattr(args, what[2:])!r}): give at least one",
            file=sys.stderr,
        )
        return 2
    from evaluation.limits import MAX_BATCH_SIZE

    if not 2 <= args.runs <= MAX_BATCH_SIZE:  # the runs are one batch
        print(
            f"range_model.py: --runs must be in [2, {MAX_BATCH_SIZE}] (a paired interval needs two; "
            f"evaluation.limits.MAX_BATCH_SIZE), got {args.runs}",
            file=sys.stderr,
        )
        return 2
    import inspect

    import coopnav_env
    from baselines.base import list_policies, policy_class

    for scenario, overrides in cases:
        try:
            config = coopnav_env.make_config(scenario, **overrides)
        except (ValueError, TypeError) as exc:
            print(f"range_model.py: {exc}", file=sys.stderr)
            return 2
        if config.channel_mode == "decide":
            print(
                f"range_model.py: {scenario} decides when to ping (a schedule's third action); not here",
                file=sys.stderr,
            )
            return 2
        for planner in args.planners.split(","):
            if planner not in list_policies(config=config):
                valid = ", ".join(list_policies(config=config))
                print(f"range_model.py: unknown planner {planner!r} for {scenario}; valid: {valid}", file=sys.stderr)
                return 2
            cls = policy_class(planner, config.network)
            if "range_model" not in inspect.signature(cls).parameters:
                print(
                    f"range_model.py: planner {planner!r} weighs no range; try ellipse, horizon or oracle",
                    file=sys.stderr,
                )
                return 2
    print(f"runs {args.runs}, seeds {args.seed}..{args.seed + args.runs - 1}")
    print("| case | planner | constant (m) | filter (m) | filter - constant [95 %] | distance constant / filter (m) |")
    print("|---|---|---|---|---|---|")
    for scenario, overrides in cases:
        for planner in args.planners.split(","):
            try:
                a, da = run(scenario, overrides, planner, "constant", args.runs, args.seed)
                b, db = run(scenario, overrides, planner, "filter", args.runs, args.seed)
            except ValueError as exc:
                print(f"range_model.py: {exc}", file=sys.stderr)
                return 2
            mean, low, high = t_interval(b - a)
            label = scenario + "".join(f" {k}={v}" for k, v in overrides.items())
            print(
                f"| {label} | {planner} | {a.mean():.3f} | {b.mean():.3f} | {mean:+.3f} "
                f"[{low:+.3f}, {high:+.3f}] | {da:.0f} / {db:.0f} |",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
