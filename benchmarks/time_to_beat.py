"""Time from scratch to beat ``fim_a`` on the Sousa grid, on this machine's CPU cores.

    python benchmarks/time_to_beat.py                       # 3 seeds, configs/ppo/sousa_fast.yml
    python benchmarks/time_to_beat.py --config configs/ppo/sousa_asv.yml --budget-s 900

For each seed, trains PPO on ``sousa_asv`` from scratch with ``train.py`` (the config's
hyperparameters and domain randomization; ``--threads`` torch threads) and validates it
every ``--eval-every`` steps on the trainer's validation seeds: every cell of Sousa et
al.'s Tables I-II (the benchmark's ``sousa_grid`` tasks), ``eval.episodes`` episodes
each, against ``fim_a`` on the same episodes. The run stops (SIGINT: the trainer's
clean stop) at the first validation whose mean error is below ``fim_a``'s, or at
``--budget-s`` seconds of training.

The time to beat is the trainer's ``train_s`` at that validation: the wall clock since
learning started, without the validations themselves (they measure, they do not
train); the record keeps ``wall_s`` (validations included) and the start-up (imports,
compiling the simulator, scoring ``fim_a`` once) beside it. The median over the seeds
is the figure of merit; a seed that never beats ``fim_a`` within the budget counts as
the budget (so the median is an upper bound then, and the output says so).

Each seed's run directory is kept (``OUT/runs/seed_N``): its best model is the one that
beat ``fim_a``, so the benchmark can score it on the test seeds (``python -m
evaluation.benchmark --tasks sousa_grid --policies OUT/runs/seed_0``).

Writes, atomically, ``OUT/time_to_beat.json`` (every validation of every seed, the
times, the machine, the command) and ``OUT/time_to_beat.png`` (validation error
against training time per seed, ``fim_a``'s line, the median time), and prints a
summary. The machine should be otherwise idle: another process on the same cores
slows training and shows in the time (the JSON records the load average).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import signal
import statistics
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

try:
    from benchmarks import _args
except ImportError:  # run as a script: its own folder is on the path, not the checkout
    import _args  # type: ignore[no-redef]

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_CONFIG = ROOT / "configs" / "ppo" / "sousa_fast.yml"


def train_until_beaten(
    config: Path,
    seed: int,
    out: Path,
    eval_every: int,
    budget_s: float,
    threads: int,
    timesteps: int,
    baseline: str = "fim_a",
    margin: float = 0.0,
    eval_episodes: int | None = None,
    bar: Any = None,
) -> dict:
    """Train one seed until its validation is below ``(1 - margin)`` times ``baseline``'s,
    or ``budget_s`` of training; returns its validations and times. ``bar``: a
    ``coopnav_env.progress.Progress`` in seconds of training, moved to each validation's
    ``train_s`` (and told each validation)."""
    cmd = [
        sys.executable,
        str(ROOT / "train.py"),
        "--scenario",
        "sousa_asv",
        "--config",
        str(config),
        "--seed",
        str(seed),
        "--timesteps",
        str(timesteps),
        "--out",
        str(out),
        "--threads",
        str(threads),
        "--no-progress",
        "--set",
        f"eval.every_steps={eval_every}",
        "--set",
        f"eval.baselines=[{baseline}]",
        "--set",
        f"checkpoint_every_steps={10 * timesteps}",
    ]
    if eval_episodes is not None:
        cmd += ["--set", f"eval.episodes={eval_episodes}"]
    started = time.perf_counter()
    log = open(out.parent / f"seed_{seed}.log", "w")  # noqa: SIM115 (closed in the finally below) the trainer's output
    proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, cwd=ROOT)
    records, beaten, told = [], None, 0
    path = out / "evaluations.jsonl"
    try:  # from here on, whatever fails, the trainer is not left running (an orphan trained for an hour)
        base = bar.n if bar is not None else 0.0
        if bar is not None:
            bar.stage(f"seed {seed}: starting train.py (log: {log.name})")
        while proc.poll() is None:
            time.sleep(0.5)
            if path.is_file():
                records = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
            if bar is not None and len(records) > told:
                for r in records[told:]:
                    bar.write(
                        f"seed {seed}: validation at {r['num_timesteps']:,} steps, {r['train_s']:.0f} s of "
                        f"training: {r['survey_error_m']:.3f} m ({baseline} "
                        f"{r[f'{baseline}_survey_error_m']:.3f} m)"
                    )
                told = len(records)
                bar.set(base + min(records[-1].get("train_s", 0.0), budget_s))
                bar.stage(f"seed {seed}: training")
            for r in records:
                if r["survey_error_m"] < (1.0 - margin) * r[f"{baseline}_survey_error_m"]:
                    beaten = r
                    break
            if beaten or (records and records[-1].get("train_s", 0.0) >= budget_s):
                proc.send_signal(signal.SIGINT)  # the trainer's clean stop
                proc.wait(timeout=120)
                break
    finally:
        if proc.poll() is None:
            proc.kill()
        log.close()
    if proc.returncode not in (0, 130, -signal.SIGINT):
        tail = (out.parent / f"seed_{seed}.log").read_text().strip().splitlines()[-1:]
        raise SystemExit(f"time_to_beat.py: training seed {seed} failed: {' '.join(tail)}")
    if path.is_file():
        records = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
    return {
        "seed": seed,
        "beaten": beaten is not None,
        "time_to_beat_s": beaten["train_s"] if beaten else None,
        "wall_s_with_validation": beaten["wall_s"] if beaten else None,
        "steps_to_beat": beaten["num_timesteps"] if beaten else None,
        "process_s": round(time.perf_counter() - started, 1),
        "baseline_survey_error_m": records[0][f"{baseline}_survey_error_m"] if records else None,
        "validations": [{k: r[k] for k in ("num_timesteps", "train_s", "wall_s", "survey_error_m")} for r in records],
    }


def figure(result: dict, path: Path) -> None:
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from coopnav_env.records import atomic_write_bytes

    fig, ax = plt.subplots(figsize=(7, 4.2))
    for run in result["runs"]:
        t = [v["train_s"] for v in run["validations"]]
        e = [v["survey_error_m"] for v in run["validations"]]
        (line,) = ax.plot(t, e, marker="o", ms=3, label=f"seed {run['seed']}")
        if run["beaten"]:
            ax.plot(
                [run["time_to_beat_s"]], [e[t.index(run["time_to_beat_s"])]], marker="*", ms=14, color=line.get_color()
            )
    base = result["runs"][0]["baseline_survey_error_m"]
    ax.axhline(base, color="k", ls="--", lw=1, label=f"{result['baseline']} ({base:.3f} m)")
    if result.get("margin"):
        ax.axhline(
            (1 - result["margin"]) * base,
            color="k",
            ls=":",
            lw=1,
            label=f"{result['margin']:.0%} below {result['baseline']}: the beat",
        )
    med = result["median_time_to_beat_s"]
    ax.axvline(med, color="grey", ls=":", lw=1.5, label=f"median time to beat: {med:.0f} s")
    ax.set_xlabel("training time (s, validations excluded)")
    ax.set_ylabel("validation mean error (m), 16 cells")
    ax.set_title(
        f"PPO from scratch on sousa_asv: time to beat {result['baseline']} "
        f"({result['cores']} CPU cores, {Path(result['config']).name})",
        fontsize=9,
    )
    ax.set_ylim(top=min(ax.get_ylim()[1], 3 * base))
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    buf = io.BytesIO()
    fig.tight_layout()
    fig.savefig(buf, format="png", dpi=200)
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())


def main(argv: Sequence[str] | None = None) -> int:
    p = _args.Parser(
        prog="time_to_beat.py",
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--config", type=Path, default=DEFAULT_CONFIG, help="train.py config (default: %(default)s)")
    p.add_argument("--seeds", default="0,1,2", help="training seeds, comma-separated (default: %(default)s)")
    p.add_argument("--eval-every", type=int, default=65536, help="steps between validations (default: %(default)s)")
    p.add_argument(
        "--budget-s",
        type=float,
        default=600.0,
        help="training seconds per seed before giving up (default: %(default)s)",
    )
    p.add_argument(
        "--margin",
        type=float,
        default=0.0,
        help="beat = validation below (1 - margin) x fim_a's (default: %(default)s)",
    )
    p.add_argument(
        "--eval-episodes",
        type=int,
        default=None,
        help="validation episodes per cell (default: the config's eval.episodes)",
    )
    p.add_argument("--threads", type=int, default=2, help="torch threads (default: %(default)s, the two cores)")
    p.add_argument(
        "--out",
        type=Path,
        default=ROOT / "results" / "time_to_beat",
        help="output directory; runs/seed_N holds each run, its best model the one that beat fim_a "
        "(default: %(default)s)",
    )
    p.add_argument("--overwrite", action="store_true", help="replace a result already in --out")
    args = p.parse_args(argv)
    from agents.training.bounds import MAX_RUN_SEED

    try:
        seeds = [int(s) for s in args.seeds.split(",")]
    except ValueError:
        p.error(f"--seeds: integers separated by commas, got {args.seeds!r}")
    if not all(0 <= s <= MAX_RUN_SEED for s in seeds):  # train.py's range, checked before any run
        p.error(f"--seeds: each in [0, {MAX_RUN_SEED}], got {args.seeds!r}")
    if not args.config.is_file():
        p.error(f"--config: no file {args.config}")
    args.config = args.config.resolve()  # train.py runs from the checkout, not from here
    args.out = args.out.resolve()  # likewise: a relative --out put the runs in the checkout
    if args.eval_every < 1 or not 0 < args.budget_s < float("inf") or args.threads < 1:
        p.error("--eval-every, --budget-s and --threads must be positive (and --budget-s finite)")
    if not 0.0 <= args.margin < 1.0:
        p.error(f"--margin must be in [0, 1), got {args.margin}")
    if args.eval_episodes is not None and args.eval_episodes < 1:
        p.error(f"--eval-episodes must be at least 1, got {args.eval_episodes}")
    from coopnav_env.records import atomic_write_text, version_record

    if (args.out / "time_to_beat.json").exists() and not args.overwrite:
        p.error(f"--out: {args.out} holds a result; --overwrite replaces it")
    from coopnav_env.records import check_writable

    try:  # a file, or a folder that cannot be written: one line before any training
        check_writable(args.out)
    except OSError as err:
        p.error(f"--out: {err}")
    args.out.mkdir(parents=True, exist_ok=True)
    from coopnav_env.progress import Progress

    runs = []
    # in seconds of training: a seed that beats fim_a early counts its whole budget (the estimate is an upper bound)
    bar = Progress(len(seeds) * args.budget_s, unit="s of training", desc="time to beat", every_s=60.0)
    bar.write(
        f"time_to_beat.py: {len(seeds)} seed(s), up to {args.budget_s:.0f} s of training each; the trainers' "
        f"output goes to {args.out}/runs/seed_N.log"
    )
    for k, seed in enumerate(seeds):
        run_dir = args.out / "runs" / f"seed_{seed}"
        if run_dir.exists():
            shutil.rmtree(run_dir)
        run_dir.parent.mkdir(parents=True, exist_ok=True)
        load_before = os.getloadavg()[0]
        run = train_until_beaten(
            args.config,
            seed,
            run_dir,
            args.eval_every,
            args.budget_s,
            args.threads,
            timesteps=50_000_000,
            margin=args.margin,
            eval_episodes=args.eval_episodes,
            bar=bar,
        )
        bar.set((k + 1) * args.budget_s)
        run["load_average_1min_before"] = round(load_before, 2)
        run["run_dir"] = str(run_dir)
        runs.append(run)
        said = (
            f"after {run['time_to_beat_s']:.0f} s of training ({run['steps_to_beat']} steps)"
            if run["beaten"]
            else f"not within {args.budget_s:.0f} s"
        )
        bar.write(f"seed {seed}: beats fim_a {said}", stream=sys.stdout)
    bar.close()
    median = statistics.median(r["time_to_beat_s"] if r["beaten"] else args.budget_s for r in runs)
    result = {
        "command": " ".join(["python", "benchmarks/time_to_beat.py", *(argv or sys.argv[1:])]),
        "config": str(args.config.relative_to(ROOT) if args.config.resolve().is_relative_to(ROOT) else args.config),
        "baseline": "fim_a",
        "margin": args.margin,
        "cores": os.cpu_count(),
        "threads": args.threads,
        "machine": platform.processor() or platform.machine(),
        "median_time_to_beat_s": median,
        "median_is_upper_bound": not all(r["beaten"] for r in runs),
        "budget_s": args.budget_s,
        "runs": runs,
        "versions": version_record(),
    }
    atomic_write_text(args.out / "time_to_beat.json", json.dumps(result, indent=1, allow_nan=False) + "\n")
    figure(result, args.out / "time_to_beat.png")
    bound = " (an upper bound: a seed did not beat it)" if result["median_is_upper_bound"] else ""
    print(
        f"median time to beat fim_a over seeds {args.seeds}: {median:.0f} s{bound}; "
        f"wrote {args.out}/time_to_beat.json, time_to_beat.png"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
