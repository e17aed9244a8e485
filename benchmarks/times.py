"""How long a newcomer's commands take on this machine: the times table of the README and
docs/getting-started.md#how-long.

    python benchmarks/times.py --list
    python benchmarks/times.py --only quickstart,first_training --out results/times
    python benchmarks/times.py                       # every item (hours: the CI run, time to beat, 8 task sets)
    python benchmarks/times.py --only benchmark:gao_team --workers 2   # the benchmark items with --workers 2

Each item is the command the documentation gives, run as a subprocess from this
checkout (``ci`` from a fresh ``git clone`` of it, as CI does), timed by the wall clock.
The 1-minute load average before and after is recorded beside each time: the table's
numbers are for two *idle* cores, and a loaded machine shows up there (say so when you
copy a number). Appends one JSON object per item to ``OUT/times.jsonl`` and prints a
Markdown table of what it measured. Each item's output goes to ``OUT/<item>.log``; a
benchmark task set writes a line there per task and policy (``tail -f`` it to follow a
run of an hour).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

try:
    from benchmarks import _args
except ImportError:  # run as a script: its own folder is on the path, not the checkout
    import _args  # type: ignore[no-redef]

ROOT = Path(__file__).resolve().parent.parent
PY = sys.executable


def _items(out: Path, workers: int = 1) -> dict:
    """name -> (what, command, working directory or None for a fresh clone); ``workers`` > 1
    adds ``--workers`` to the benchmark's items."""
    from evaluation.tasks import TASK_SETS

    items = {
        "ci": ("`bash .ci/run` on a fresh clone (install, the tests, the docs build)", ["bash", ".ci/run"], None),
        "quickstart": (
            "the quick start's evaluation (10 episodes x 4 policies on gao_sea)",
            [
                PY,
                "evaluate.py",
                "--scenario",
                "gao_sea",
                "--policies",
                "ppo,ellipse,fim_a,static",
                "--episodes",
                "10",
                "--seed",
                "0",
                "--out",
                str(out / "demo"),
                "--overwrite",
            ],
            ROOT,
        ),
        "first_training": (
            "a first training: `train.py --scenario sousa_asv --timesteps 2000000` (sousa_asv.yml)",
            [
                PY,
                "train.py",
                "--scenario",
                "sousa_asv",
                "--timesteps",
                "2000000",
                "--seed",
                "0",
                "--out",
                str(out / "first_training"),
                "--no-progress",
            ],
            ROOT,
        ),
        "time_to_beat": (
            "`benchmarks/time_to_beat.py` (3 seeds, sousa_fast.yml)",
            [PY, "benchmarks/time_to_beat.py", "--out", str(out / "time_to_beat"), "--overwrite"],
            ROOT,
        ),
    }
    items["benchmark_task"] = (
        "`coopnav-benchmark --task lake --policies ppo` (one task of gao_lawnmower, 50 episodes)",
        [
            PY,
            "-m",
            "evaluation.benchmark",
            "--task",
            "lake",
            "--policies",
            "ppo",
            "--out",
            str(out / "benchmark_task"),
            "--overwrite",
        ],
        ROOT,
    )
    extra = ["--workers", str(workers)] if workers > 1 else []
    note = f", --workers {workers}" if workers > 1 else ""
    for name, ts in TASK_SETS.items():
        items[f"benchmark:{name}"] = (
            f"`coopnav-benchmark --tasks {name} --policies ppo` "
            f"({len(ts.tasks)} tasks, {ts.episodes} episodes each{note})",
            [
                PY,
                "-m",
                "evaluation.benchmark",
                "--tasks",
                name,
                "--policies",
                "ppo",
                "--out",
                str(out / f"benchmark_{name}"),
                "--overwrite",
                *extra,
            ],
            ROOT,
        )
    return items


def _clean_output(path: Path):
    import shutil

    if path.is_dir():
        shutil.rmtree(path)


def measure(name: str, what: str, cmd: list, cwd: str | Path | None, out: Path) -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT)] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p])
    tmp = None
    if cwd is None:  # a fresh clone of this checkout's HEAD, as CI sees it
        tmp = tempfile.mkdtemp(prefix="coopnav-clone-")
        subprocess.run(["git", "clone", "-q", str(ROOT), tmp], check=True)
        cwd = tmp
        env.pop("PYTHONPATH")
    if name == "first_training":
        _clean_output(out / "first_training")
    load_before = os.getloadavg()[0]
    started = time.perf_counter()
    with open(out / f"{name.replace(':', '_')}.log", "w") as log:
        rc = subprocess.run(cmd, cwd=cwd, env=env, stdout=log, stderr=subprocess.STDOUT).returncode
    seconds = time.perf_counter() - started
    return {
        "item": name,
        "what": what,
        "command": shlex.join(cmd),
        "exit_status": rc,
        "seconds": round(seconds, 1),
        "load_average_1min_before": round(load_before, 2),
        "load_average_1min_after": round(os.getloadavg()[0], 2),
        "cores": os.cpu_count(),
        "machine": platform.processor() or platform.machine(),
        "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
    }


def main(argv: list[str] | None = None) -> int:
    p = _args.Parser(
        prog="times.py", description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--only", default=None, help="comma-separated items (default: all; --list shows them)")
    p.add_argument(
        "--out", type=Path, default=ROOT / "results" / "times", help="output directory (default: %(default)s)"
    )
    p.add_argument("--list", action="store_true", help="list the items and exit")
    p.add_argument(
        "--workers", type=int, default=1, help="the task sets' items with --workers N (default 1: without it)"
    )
    args = p.parse_args(argv)
    from evaluation.parallel import check_workers

    try:
        args.workers = check_workers(args.workers)
    except ValueError as err:
        p.error(str(err))
    from coopnav_env.progress import format_seconds, say

    items = _items(args.out.resolve(), args.workers)
    if args.list:  # nothing written: the folder is made only for a measurement
        for name, (what, cmd, _) in items.items():
            print(f"{name}: {what}\n    {shlex.join(cmd)}")
        return 0
    names = list(items) if args.only is None else [n.strip() for n in args.only.split(",") if n.strip()]
    if not names:
        p.error(f"--only names nothing (got {args.only!r}): give at least one item (--list shows them)")
    unknown = [n for n in names if n not in items]
    if unknown:
        from coopnav_env.names import did_you_mean

        p.error(f"unknown item {unknown[0]!r}{did_you_mean(unknown[0], items)} valid: {', '.join(items)}")
    from coopnav_env.records import check_writable

    try:
        check_writable(args.out)
    except OSError as err:
        p.error(f"--out: {err}")
    args.out.mkdir(parents=True, exist_ok=True)
    rows = []
    for k, name in enumerate(names):
        what, cmd, cwd = items[name]
        say(f"[{k}/{len(names)} items] {name}: {what} (log: {args.out}/{name.replace(':', '_')}.log)")
        row = measure(name, what, cmd, cwd, args.out.resolve())
        rows.append(row)
        with open(args.out / "times.jsonl", "a") as f:
            f.write(json.dumps(row) + "\n")
        say(
            f"[{k + 1}/{len(names)} items] {name}: {format_seconds(row['seconds'])} (exit {row['exit_status']}, "
            f"load {row['load_average_1min_before']} -> {row['load_average_1min_after']})"
        )
    print("\n| item | time | load average (1 min) before -> after | measured |\n|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['what']} | {format_seconds(r['seconds'])} | {r['load_average_1min_before']} -> "
            f"{r['load_average_1min_after']} | {r['date']} |"
        )
    return 0 if all(r["exit_status"] == 0 for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
