"""How fast the batched simulator steps, and the share of its fusion kernel.

    python benchmarks/sim_profile.py                         # sousa_asv, 4,096 environments
    python benchmarks/sim_profile.py --scenario gao_sea --batch 1024 --steps 60
    python benchmarks/sim_profile.py --set range_outlier_model=gate

Steps ``make_simulator(make_config(scenario, **overrides), batch)`` with uniform random
actions in [-1, 1] (a seeded numpy Generator), resetting finished rows with new seeds,
after a few untimed warm-up steps (numba's compilation included there). The sensor's
fusion kernel (``sim.sensor.kernel``: the modem's or the MLS array's) is wrapped by a
timer, so the report gives env-steps/s of the whole simulator, the kernel's share of
that time and its time per environment and ping (one ping: one beacon to one survey
vehicle). One thread; run it on an idle machine. ``docs/performance.md#refcounts``
reads its figures. This is a script, not a test: nothing here is timed under pytest.
"""

from __future__ import annotations

import sys
import time

try:
    from benchmarks import _args
except ImportError:  # run as a script: its own folder is on the path, not the checkout
    import _args  # type: ignore[no-redef]


def main(argv: list[str] | None = None) -> int:
    p = _args.Parser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scenario", default="sousa_asv")
    p.add_argument("--batch", type=int, default=4096, help="environments stepped at once")
    p.add_argument("--steps", type=int, default=40, help="timed steps of the whole batch")
    p.add_argument("--warmup", type=int, default=5, help="untimed steps first")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="a scenario parameter")
    a = p.parse_args(argv)
    MAX_BATCH, MAX_STEPS = _args.MAX_BATCH, _args.MAX_STEPS
    if not (1 <= a.batch <= MAX_BATCH and 1 <= a.steps <= MAX_STEPS and 0 <= a.warmup <= MAX_STEPS):
        print(
            f"sim_profile: --batch must be in [1, {MAX_BATCH}] (benchmarks._args.MAX_BATCH), "
            f"--steps in [1, {MAX_STEPS}] "
            f"and --warmup in [0, {MAX_STEPS}] (benchmarks._args.MAX_STEPS); got {a.batch}, {a.steps}, {a.warmup}",
            file=sys.stderr,
        )
        return 2
    from coopnav_env.seeds import check_seed

    try:
        check_seed(a.seed, "--seed")
    except ValueError as e:
        print(f"sim_profile: {e}", file=sys.stderr)
        return 2

    import numpy as np

    from coopnav_env import make_config
    from coopnav_env.core import make_simulator

    try:
        overrides = _args.scenario_overrides(a.set)
        sim = make_simulator(make_config(a.scenario, **overrides), a.batch)
    except (KeyError, ValueError, TypeError) as e:
        print(f"sim_profile: {e}", file=sys.stderr)
        return 2
    sensor = getattr(sim, "sensor", None)
    spent = [0.0]
    if sensor is not None and hasattr(sensor, "kernel"):
        kernel = sensor.kernel

        def timed(*args):
            t0 = time.perf_counter()
            kernel(*args)
            spent[0] += time.perf_counter() - t0

        sensor.kernel = timed
    B = sim.batch_size
    gen = np.random.default_rng(a.seed)
    sim.reset(np.arange(B))
    next_seed = B

    def step() -> None:
        nonlocal next_seed
        res = sim.step(gen.uniform(-1.0, 1.0, size=(B, sim.N, 2)))
        done = res.terminated | res.truncated
        if done.any():
            k = int(done.sum())
            sim.reset(np.arange(next_seed, next_seed + k), done)
            next_seed += k

    for _ in range(a.warmup):
        step()
    spent[0] = 0.0
    t0 = time.perf_counter()
    for _ in range(a.steps):
        step()
    wall = time.perf_counter() - t0
    rate = a.steps * B / wall
    line = f"{a.scenario}, {B} environments, {a.steps} steps: {rate:,.0f} env-steps/s"
    if sensor is not None and hasattr(sensor, "kernel"):
        pings = a.steps * B * sim.N * sim.S
        line += (
            f"; fusion kernel {100 * spent[0] / wall:.0f} % of the time,"
            f" {spent[0] / a.steps * 1e3:.1f} ms per step, {spent[0] / pings * 1e6:.2f} us per environment and ping"
        )
    print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
