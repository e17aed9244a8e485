"""Learning curves of BenchMARL runs (``python -m agents.training.marl``) and batched PPO runs
(``python -m agents.training.batched_ppo``) side by side.

    python benchmarks/marl_curves.py mappo=runs/gao_team_mappo ippo=runs/gao_team_ippo \\
        --out docs/figures/levers_gao_team.png --overwrite

Reads each run's BenchMARL CSV log (``<run>/benchmarl/*/scalars/<metric>.csv``: one row per
collected batch) and plots it against the env-steps collected (BenchMARL's
``counters_total_frames``), smoothed over ``--smooth`` batches. The default metric is the training
batch's mean true survey error (``collection_info_survey_error_m``: every step of every
environment in the batch, exploration noise included; a learning curve, not a score). A batched
PPO run's ``log.jsonl`` gives the same quantity per iteration as ``survey_error_m`` (the mean
error of the episodes that ended in the iteration, exploration included); it is read for the
default metric.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

try:
    from benchmarks import _args
except ImportError:  # run as a script: its own folder is on the path, not the checkout
    import _args  # type: ignore[no-redef]


def curve(run: Path, metric: str) -> tuple:
    """(env-steps, values) of ``metric`` in the run folder ``run`` (the env-steps from
    BenchMARL's own frame counter, logged beside it)."""
    if (run / "log.jsonl").is_file() and not (run / "benchmarl").is_dir():  # agents.training.batched_ppo
        import json

        key = "survey_error_m" if metric == "collection_info_survey_error_m" else metric
        rows = [json.loads(line) for line in (run / "log.jsonl").read_text().splitlines() if line.strip()]
        if not all(isinstance(r, dict) for r in rows):
            raise ValueError(f"{run}/log.jsonl is not a batched PPO log (a line is not a JSON object)")
        rows = [r for r in rows if r.get(key) is not None and r.get("steps") is not None]
        if not rows:
            raise ValueError(f"{run}/log.jsonl has no {key!r}")
        return np.array([r["steps"] for r in rows], dtype=float), np.array([r[key] for r in rows], dtype=float)
    logs = sorted((run / "benchmarl").glob("*/scalars"))
    if not logs or not (logs[0] / f"{metric}.csv").is_file():
        raise ValueError(f"{run} has no BenchMARL log of {metric!r} (benchmarl/*/scalars/{metric}.csv)")
    data = np.loadtxt(logs[0] / f"{metric}.csv", delimiter=",", ndmin=2)
    frames = dict(np.loadtxt(logs[0] / "counters_total_frames.csv", delimiter=",", ndmin=2).tolist())
    keep = [i for i, step in enumerate(data[:, 0]) if step in frames]
    return np.array([frames[data[i, 0]] for i in keep]), data[keep, 1]


def main(argv: Sequence[str] | None = None) -> int:
    p = _args.Parser(description=__doc__.split("\n\n")[0])
    p.add_argument("runs", nargs="+", help="label=run_folder")
    p.add_argument("--metric", default="collection_info_survey_error_m")
    p.add_argument("--smooth", type=int, default=5, help="moving average over this many batches")
    p.add_argument("--title", default="")
    p.add_argument("--out", required=True, help="PNG to write")
    _args.add_overwrite(p, "the --out PNG")
    args = p.parse_args(argv)
    _args.outputs(p, args.overwrite, out=args.out)  # refused before any log is read
    _args.count(p, args.smooth, "--smooth", bound="MAX_STEPS")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from coopnav_env.records import atomic_write_bytes

    fig, ax = plt.subplots(figsize=(7, 4))
    try:
        for item in args.runs:
            label, _, path = item.rpartition("=")
            x, y = curve(Path(path), args.metric)
            k = args.smooth
            if len(y) < k:
                raise ValueError(
                    f"{path} has {len(y)} rows of {args.metric}, fewer than --smooth {k}: give a smaller --smooth"
                )
            ys = np.convolve(y, np.ones(k) / k, mode="valid")
            ax.plot(x[k - 1 :], ys, label=label or Path(path).name)
    except (OSError, ValueError) as err:
        p.error(_args.first_line(err))
    ax.set_xlabel("env-steps collected")
    ax.set_ylabel("batch mean survey error (m)" if args.metric == "collection_info_survey_error_m" else args.metric)
    ax.set_title(args.title)
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    atomic_write_bytes(args.out, buf.getvalue())
    print(args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
