"""Compile the simulator's kernels ahead, split over several processes.

The simulator's numba kernels are compiled on first use and cached on disk beside their
source (``cache=True``); every later process loads them. On a fresh install the first
command therefore pays for the compilation, about three minutes on one core of this
project's machines: ``gao_lawnmower`` about 110 s (the survey/beacon network's kernels,
which every scenario but the moving network's shares), ``matos_moving_lbl`` about 60 s
(the moving network's own), the rest a few seconds (measured 2026-12-07 with an empty
``NUMBA_CACHE_DIR``). Two processes that start cold compile the same kernels twice; this
command compiles each network's kernels in a process of their own, at the same time::

    coopnav-warmup                          # every scenario, on min(2, CPUs) processes
    coopnav-warmup --jobs 1 --scenarios gao_sea,sousa_ping

Each process builds the PettingZoo env of its scenarios and steps it three cycles with
actions drawn from the action space (so that a sender's transmit path runs too). CI runs it
before pytest-xdist's two workers (``.ci/run``), which then load the kernels those cycles
reach instead of each compiling them. The planners' and the evaluation's own kernels are
left to first use. Exit status 0; 2 with one line for a bad option; 1 if a process failed;
130 on Ctrl-C.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from collections.abc import Sequence

from coopnav_env.names import OneLineParser

STEPS = 3  # cycles stepped per scenario: enough to run every kernel of a cycle once


def compile_scenarios(names: Sequence[str]) -> list[tuple[str, float]]:
    """Build each scenario's env, reset it and step it ``STEPS`` cycles; (name, seconds) each."""
    import coopnav_env

    times = []
    for name in names:
        t0 = time.perf_counter()
        env = coopnav_env.parallel_env(name)
        env.reset(seed=0)
        for j, agent in enumerate(env.agents):
            env.action_space(agent).seed(j)  # the same draws every time
        for _ in range(STEPS):
            env.step({agent: env.action_space(agent).sample() for agent in env.agents})
        env.close()
        times.append((name, time.perf_counter() - t0))
    return times


def split(names: Sequence[str], jobs: int) -> list[list[str]]:
    """``names`` in at most ``jobs`` parts that share no network (``ScenarioConfig.network``):
    the scenarios of one network compile the same kernels, so they stay in one process; the
    networks go to the parts in turn, the most scenarios first."""
    import coopnav_env

    by_network: dict[str, list[str]] = {}
    for name in names:
        by_network.setdefault(coopnav_env.make_config(name).network, []).append(name)
    groups = sorted(by_network.values(), key=len, reverse=True)
    parts: list[list[str]] = [[] for _ in range(max(1, min(jobs, len(groups))))]
    for k, group in enumerate(groups):
        parts[k % len(parts)].extend(group)
    return parts


def _count(n: int, one: str, many: str | None = None) -> str:
    return f"{n} {one if n == 1 else many or one + 's'}"


def _parser() -> argparse.ArgumentParser:
    p = OneLineParser(
        prog="coopnav-warmup",
        description="Compile the simulator's numba kernels ahead (they are cached on disk), one network per process.",
    )
    p.add_argument("--scenarios", metavar="A,B", help="scenarios to compile (default: every one)")
    p.add_argument("--jobs", type=int, default=None, help="processes (default: min(2, CPUs))")
    p.add_argument("--in-process", action="store_true", help=argparse.SUPPRESS)  # a worker: compile here
    return p


def main(argv: Sequence[str] | None = None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    import coopnav_env
    from coopnav_env.names import did_you_mean

    valid = coopnav_env.list_scenarios()
    names = [n for n in (args.scenarios or "").split(",") if n] or list(valid)
    for name in names:
        if name not in valid:
            parser.error(f"--scenarios: unknown scenario {name!r}{did_you_mean(name, valid)} valid: {', '.join(valid)}")
    jobs = min(2, os.cpu_count() or 1) if args.jobs is None else args.jobs
    if jobs < 1:
        parser.error(f"--jobs must be at least 1, got {jobs}")
    if args.in_process:
        for name, seconds in compile_scenarios(names):
            print(f"  {name}: {seconds:.1f} s", flush=True)
        return 0
    procs: list[subprocess.Popen] = []
    try:  # from here Ctrl-C is one line, and the workers stop too (what they cached stays cached)
        t0 = time.perf_counter()
        parts = split(names, jobs)
        print(
            f"coopnav-warmup: compiling the kernels of {_count(len(names), 'scenario')} "
            f"in {_count(len(parts), 'process', 'processes')}",
            flush=True,
        )
        for part in parts:  # each in a session of its own: a terminal's Ctrl-C reaches this process alone
            cmd = [sys.executable, "-m", "coopnav_env.warmup", "--in-process", "--scenarios", ",".join(part)]
            procs.append(subprocess.Popen(cmd, start_new_session=True))
        failed = [",".join(part) for part, proc in zip(parts, procs) if proc.wait() != 0]
    except KeyboardInterrupt:
        for proc in procs:
            proc.terminate()
        print("coopnav-warmup: stopped", file=sys.stderr)
        return 130
    if failed:
        print(f"coopnav-warmup: the process for {'; '.join(failed)} failed (its error is above)", file=sys.stderr)
        return 1
    print(f"coopnav-warmup: done in {time.perf_counter() - t0:.0f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
