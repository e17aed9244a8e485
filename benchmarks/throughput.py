"""Environment throughput of coopnav, against PettingZoo's reference MPE.

    python benchmarks/throughput.py                 # readable table, 3 s per measurement
    python benchmarks/throughput.py --seconds 10 --json

Measures environment steps per second of

(a) the PettingZoo parallel env ``coopnav_env.parallel_env(scenario)`` (a batch of
    one): every step samples ``env.action_space(a).sample()`` for every live agent
    and the env is reset when ``env.agents`` is empty;
(b) the batched core ``Simulator`` at batch sizes 1, 64 and 1024: env-steps/s =
    batch * batch-steps/s; actions uniform in [-1, 1] from a seeded numpy
    Generator; rows that terminate or truncate are reset alone with
    ``sim.reset(new_seeds, mask)``;
(c) PettingZoo's MPE ``simple_spread_v3`` (package ``mpe2``, N=3, continuous
    actions), measured exactly as (a).

Resets are inside the timed loop (they are part of running episodes) but only
``step`` calls count as steps. Every environment runs a short untimed warm-up,
then its ``--seconds`` are split into ``--rounds`` chunks taken round-robin over
the environments, so that load from other processes hits them alike; the rate
reported is the best chunk (the least disturbed, as ``timeit`` does) and the
median is reported beside it. The aims stated by the project:

* core at batch 1024 >= 100x the PettingZoo env;
* the PettingZoo env >= MPE simple_spread_v3 (3 agents).

Numbers depend on the machine; run on an idle one (compare best and median: a
large gap means other processes were competing for the CPU). This is a script, not a test: nothing here is
timed under pytest.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from collections.abc import Callable, Sequence

try:
    from benchmarks import _args
except ImportError:  # run as a script: its own folder is on the path, not the checkout
    import _args  # type: ignore[no-redef]

BATCH_SIZES = (1, 64, 1024)
AIM_CORE_OVER_PZ = 100.0
AIM_PZ_OVER_MPE = 1.0


def _positive_seconds(text):
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not (value > 0.0 and value < float("inf")):
        raise argparse.ArgumentTypeError(f"must be a positive finite number of seconds, got {text!r}")
    return value


def _positive_int(text):
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be an integer >= 1, got {text!r}")
    return value


class _Bench:
    """A named stepper: ``step()`` advances the environment(s) once and returns
    how many env-steps that was; ``close()`` releases it."""

    def __init__(self, name, step, close=lambda: None):
        self.name, self.step, self.close = name, step, close
        self.rates = []

    def warm_up(self, seconds):
        end = time.perf_counter() + seconds
        n = 0
        while n < 3 or time.perf_counter() < end:
            self.step()
            n += 1

    def timed(self, seconds):
        """Step for ``seconds``; record and return env-steps per second."""
        step = self.step
        count = 0
        t0 = time.perf_counter()
        deadline = t0 + seconds
        while True:
            count += step()
            now = time.perf_counter()
            if now >= deadline:
                break
        rate = count / (now - t0)
        self.rates.append(rate)
        return rate


def _pettingzoo_stepper(env, seed=0):
    """One env step with sampled actions for every live agent, resetting when the
    episode is over (the reset is timed; it is not counted as a step)."""
    env.reset(seed=seed)
    for i, a in enumerate(env.possible_agents):
        env.action_space(a).seed(seed + i)

    def step():
        if not env.agents:
            env.reset()
        env.step({a: env.action_space(a).sample() for a in env.agents})
        return 1

    return step


def pettingzoo_bench(scenario: str) -> _Bench:
    import coopnav_env

    env = coopnav_env.parallel_env(scenario)
    return _Bench("pettingzoo", _pettingzoo_stepper(env), env.close)


def mpe_bench() -> _Bench:
    from mpe2 import simple_spread_v3

    env = simple_spread_v3.parallel_env(N=3, continuous_actions=True)
    return _Bench("mpe", _pettingzoo_stepper(env), env.close)


def core_bench(scenario: str, batch_size: int, seed: int = 0) -> _Bench:
    import numpy as np

    from coopnav_env import make_config
    from coopnav_env.core import make_simulator

    sim = make_simulator(make_config(scenario), batch_size)
    B, N = sim.batch_size, sim.N
    gen = np.random.default_rng(seed)
    sim.reset(np.arange(B))
    next_seed = [B]

    def step():
        res = sim.step(gen.uniform(-1.0, 1.0, size=(B, N, 2)))
        done = res.terminated | res.truncated
        if done.any():
            k = int(done.sum())
            sim.reset(np.arange(next_seed[0], next_seed[0] + k), done)
            next_seed[0] += k
        return B

    return _Bench(f"core_{B}", step)


def machine_info() -> dict:
    import numpy as np

    info = {
        "python": platform.python_version(),
        "implementation": platform.python_implementation(),
        "platform": platform.platform(),
        "machine": platform.machine(),
        "processor": platform.processor() or None,
        "cpu_count": os.cpu_count(),
        "numpy": np.__version__,
    }
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    info["cpu_model"] = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    if hasattr(os, "sched_getaffinity"):
        info["cpus_available"] = len(os.sched_getaffinity(0))
    threads = {
        k: os.environ[k] for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS") if k in os.environ
    }
    if threads:
        info["thread_env"] = threads
    from importlib import metadata

    for dist in ("scipy", "numba", "pettingzoo", "mpe2", "coopnav"):
        try:
            info[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            info[dist] = None
    if "numba" in sys.modules:  # the core's compiled kernels may run on numba's threads
        info["numba_threads"] = sys.modules["numba"].get_num_threads()
    return info


def _ratio(a, b):
    return a / b if b > 0 else float("inf")


def run(scenario: str, seconds: float, rounds: int = 5, progress: Callable[[str], None] | None = None) -> dict:
    """Measure every environment; ``seconds`` per measurement, split into
    ``rounds`` chunks taken round-robin over the environments (so that a burst of
    load from elsewhere hits them alike). Each rate reported is the best chunk
    (the least disturbed, as timeit does); the medians are reported too."""
    import statistics

    say = progress or (lambda msg: None)
    warmup = min(0.5, max(0.1, 0.1 * seconds))
    benches = [pettingzoo_bench(scenario)] + [core_bench(scenario, B) for B in BATCH_SIZES] + [mpe_bench()]
    try:
        for b in benches:
            b.warm_up(warmup)
        chunk = seconds / rounds
        for r in range(rounds):
            say(f"round {r + 1}/{rounds} ({chunk:.2g} s per environment) ...")
            for b in benches:
                b.timed(chunk)
    finally:
        for b in benches:
            b.close()
    best = {b.name: max(b.rates) for b in benches}
    median = {b.name: statistics.median(b.rates) for b in benches}
    pz, mpe = best["pettingzoo"], best["mpe"]
    core = {str(B): best[f"core_{B}"] for B in BATCH_SIZES}
    core_ratio = _ratio(core[str(BATCH_SIZES[-1])], pz)
    pz_ratio = _ratio(pz, mpe)
    return {
        "scenario": scenario,
        "seconds_per_measurement": seconds,
        "rounds": rounds,
        "pettingzoo_steps_per_s": pz,
        "core_steps_per_s": core,
        "mpe_simple_spread_steps_per_s": mpe,
        "core1024_over_pettingzoo": core_ratio,
        "pettingzoo_over_mpe": pz_ratio,
        "aims": {
            "core1024_over_pettingzoo_at_least": AIM_CORE_OVER_PZ,
            "core1024_over_pettingzoo_met": core_ratio >= AIM_CORE_OVER_PZ,
            "pettingzoo_over_mpe_at_least": AIM_PZ_OVER_MPE,
            "pettingzoo_over_mpe_met": pz_ratio >= AIM_PZ_OVER_MPE,
        },
        "median_steps_per_s": {
            "pettingzoo": median["pettingzoo"],
            "core": {str(B): median[f"core_{B}"] for B in BATCH_SIZES},
            "mpe_simple_spread": median["mpe"],
        },
        "machine": machine_info(),
    }


def format_table(r: dict) -> str:
    m, med = r["machine"], r["median_steps_per_s"]
    rows = [(f"PettingZoo parallel_env({r['scenario']!r}), batch 1", r["pettingzoo_steps_per_s"], med["pettingzoo"])]
    rows += [(f"core Simulator, batch {b}", v, med["core"][b]) for b, v in r["core_steps_per_s"].items()]
    rows.append(
        ("MPE simple_spread_v3 (N=3, continuous)", r["mpe_simple_spread_steps_per_s"], med["mpe_simple_spread"])
    )
    width = max(len(row[0]) for row in rows)
    lines = [
        f"coopnav throughput: {r['seconds_per_measurement']:g} s per measurement, "
        f"in {r['rounds']} round-robin rounds (best round; median beside it)",
        f"machine: {m.get('cpu_model') or m.get('processor') or m['machine']}, "
        f"{m.get('cpus_available', m['cpu_count'])} CPUs, Python {m['python']}, numpy {m['numpy']}",
        "",
        f"{'measurement':<{width}}  {'env-steps/s':>12}  {'(median)':>12}",
        f"{'-' * width}  {'-' * 12}  {'-' * 12}",
    ]
    lines += [f"{name:<{width}}  {best:>12,.0f}  {median:>12,.0f}" for name, best, median in rows]
    a = r["aims"]

    def verdict(ok):
        return "MET" if ok else "NOT MET"

    lines += [
        "",
        "aims:",
        f"  core at batch 1024 >= {a['core1024_over_pettingzoo_at_least']:g}x the PettingZoo env: "
        f"{r['core1024_over_pettingzoo']:.1f}x  -> {verdict(a['core1024_over_pettingzoo_met'])}",
        f"  PettingZoo env >= MPE simple_spread_v3 (3 agents): "
        f"{r['pettingzoo_over_mpe']:.2f}x  -> {verdict(a['pettingzoo_over_mpe_met'])}",
    ]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = _args.Parser(
        description="Environment steps per second of the coopnav PettingZoo env, the batched core "
        "(batch 1, 64, 1024) and PettingZoo's MPE simple_spread_v3."
    )
    parser.add_argument(
        "--seconds", type=_positive_seconds, default=3.0, help="timed seconds per measurement (default: 3)"
    )
    parser.add_argument(
        "--scenario",
        default="gao_lawnmower",
        help="coopnav scenario for the PettingZoo env and the core (default: gao_lawnmower)",
    )
    parser.add_argument(
        "--rounds",
        type=_positive_int,
        default=5,
        help="split each measurement into this many round-robin chunks; the best is reported (default: 5)",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    args = parser.parse_args(argv)

    import coopnav_env

    names = coopnav_env.list_scenarios()
    if args.scenario not in names:
        parser.error(f"unknown scenario {args.scenario!r}; valid: {', '.join(names)}")

    progress = None if args.json else (lambda msg: print(msg, file=sys.stderr, flush=True))
    result = run(args.scenario, args.seconds, args.rounds, progress)
    print(json.dumps(result, indent=2) if args.json else format_table(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
