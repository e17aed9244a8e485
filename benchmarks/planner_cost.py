"""Cost per decision: the median milliseconds of CPU per ``act`` for every planner, one core.

    python benchmarks/planner_cost.py --scenario gao_sea --steps 100
    python benchmarks/planner_cost.py --scenario sousa_asv --policies ppo --markdown results/cost.md

Every registered planner that drives the scenario's network (``baselines.list_policies``;
``--policies`` adds others: ``ppo``, a shipped policy or a train.py run directory, loaded
as evaluate.py does) drives one episode (batch of one, ``--seed``) with one instance
per beacon. The first ``--warmup`` decisions are not timed (numba compilation, caches,
a trained policy's first forward pass); then every ``act`` call of ``--steps``
decisions is timed with the thread's CPU clock (``time.thread_time_ns``: the CPU the
decision costs, not the wall time, so other processes sharing the machine do not
inflate it), the episode restarting if it ends. BLAS and OpenMP are held to one
thread and, with ``--pin`` (default), the process to one CPU. The table gives the
median and the 90th percentile in ms per act, per beacon decision.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core: before numpy is imported

import sys  # noqa: E402
import time  # noqa: E402
from collections.abc import Sequence  # noqa: E402

try:
    from benchmarks import _args
except ImportError:  # run as a script: its own folder is on the path, not the checkout
    import _args  # type: ignore[no-redef]


def time_policy(config: object, name: str, steps: int, warmup: int, seed: int) -> list:
    """CPU seconds of every timed ``act`` call of policy ``name`` on ``config``."""
    import numpy as np

    from coopnav_env.core import make_simulator
    from coopnav_env.views import action_dim
    from evaluation.episodes import make_policy

    sim = make_simulator(config, batch_size=1)  # type: ignore[arg-type]
    N = config.n_beacons  # type: ignore[attr-defined]
    obs = sim.reset([seed])
    policies = [make_policy(name, config, seed=(seed, j), agent=j) for j in range(N)]  # type: ignore[arg-type]
    actions = np.zeros((1, N, action_dim(sim)))
    out = []
    for k in range(warmup + steps):
        for j in range(N):
            t0 = time.thread_time_ns()
            actions[0, j] = policies[j].act(obs[0, j])
            if k >= warmup:
                out.append((time.thread_time_ns() - t0) * 1e-9)
        res = sim.step(actions)
        obs = res.obs
        if bool(res.terminated[0] or res.truncated[0]):
            obs = sim.reset([seed + k + 1])
            for p in policies:
                p.reset()
    return out


def main(argv: Sequence[str] | None = None) -> int:
    import numpy as np

    from baselines import list_policies

    p = _args.Parser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scenario", default="gao_sea")
    p.add_argument("--policies", default="", help="comma-separated, besides the planners (e.g. ppo)")
    p.add_argument("--steps", type=int, default=100, help="timed decisions per policy")
    p.add_argument("--warmup", type=int, default=5, help="decisions before timing starts")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="scenario parameter")
    p.add_argument("--no-pin", dest="pin", action="store_false", help="do not pin the process to one CPU")
    p.add_argument("--markdown", help="also write the table here")
    p.add_argument(
        "--variant",
        action="append",
        default=[],
        metavar="NAME:BASE:KEY=VALUE,...",
        help="also time a planner variant (benchmarks/horizon_vs_greedy.py's), e.g. hj:horizon:team=joint",
    )
    _args.add_overwrite(p, "the --markdown file")
    args = p.parse_args(argv)
    _args.outputs(p, args.overwrite, markdown=args.markdown)  # refused before any run
    _args.count(p, args.steps, "--steps", bound="MAX_STEPS")
    _args.count(p, args.warmup, "--warmup", low=0, bound="MAX_STEPS")
    _args.seeds(p, args.seed, args.warmup + args.steps + 1)  # an episode that ends restarts on the next seed
    config = _args.scenario_config(p, args.scenario, _args.overrides(p, args.set))
    extra = [q for q in args.policies.split(",") if q]
    for q in extra:  # each loads and drives the scenario: one line now, not after the planners' timing
        _args.policy(p, q, config, args.seed, "--policies")
    names = [(q, q) for q in list_policies(config.network) + extra]
    if args.variant:
        import importlib.util

        here = os.path.join(os.path.dirname(os.path.abspath(__file__)), "horizon_vs_greedy.py")
        spec = importlib.util.spec_from_file_location("horizon_vs_greedy", here)
        module = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
        spec.loader.exec_module(module)  # type: ignore[union-attr]
        for v in args.variant:
            name, planner = module.variant_spec(v)  # (NAME, the planner spec it stands for)
            _args.planner(p, planner, config, args.seed, f"--variant {v!r} (NAME:BASE:KEY=VALUE,...)")
            names.append((name, planner))
    if args.pin and hasattr(os, "sched_setaffinity"):  # once every input is checked
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    lines = [
        f"{args.scenario}{' ' + ' '.join(args.set) if args.set else ''}: CPU ms per act (one beacon's decision), "
        f"{args.steps} decisions after {args.warmup} untimed, one core.",
        "",
        "| policy | median (ms) | p90 (ms) | calls |",
        "|---|---|---|---|",
    ]
    for name, planner in names:
        sec = np.asarray(time_policy(config, planner, args.steps, args.warmup, args.seed))
        lines.append(f"| {name} | {1e3 * np.median(sec):.3f} | {1e3 * np.quantile(sec, 0.9):.3f} | {len(sec)} |")
        print(lines[-1], file=sys.stderr, flush=True)
    text = "\n".join(lines)
    print(text)
    if args.markdown:
        from coopnav_env.records import atomic_write_text

        atomic_write_text(args.markdown, text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
