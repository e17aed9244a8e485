"""A Ray Tune grid of RLlib runs (``agents.training.rllib``'s part 3): ``--tune KEY=V1,V2``
parsed and checked, every combination trained as one trial, each trial's checkpoint
evaluated on the fixed seeds, and ``summary.csv`` / ``summary.md`` written atomically."""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

from coopnav_env.records import atomic_write_text

from .common import Job
from .config import ConfigError, RLlibConfig, parse_value
from .rllib_algo import env_config, training_keywords
from .rllib_checkpoints import evaluate_checkpoint, metrics

SUMMARY_COLUMNS = [
    "trial",
    "env_steps",
    "iterations",
    "episode_return_mean",
    "train_survey_error_m",
    "eval_survey_error_m",
    "checkpoint",
]


def parse_tune(items: list) -> dict:
    """``["lr=1e-4,3e-4", "seed=0,1,2"]`` -> ``{"lr": [1e-4, 3e-4], "seed": [0, 1, 2]}``
    (values: numbers, or YAML such as ``[64,64],[128,128]``); checked by ``check_tune``."""
    grid = {}
    for item in items:
        if "=" not in item:
            raise ConfigError(f"--tune expects KEY=V1,V2,..., got {item!r}")
        key, values = (s.strip() for s in item.split("=", 1))
        if key in grid:
            raise ConfigError(f"--tune {key} given twice")
        grid[key] = split_values(key, values)
    return grid


def split_values(key: str, text: str) -> list:
    """'1e-4,3e-4' -> [0.0001, 0.0003]; '[64,64],[128,128]' -> two lists (a YAML flow
    sequence, its strings then read as numbers where they are)."""
    import yaml

    try:
        items = yaml.safe_load(f"[{text}]")
    except yaml.YAMLError:
        raise ConfigError(f"--tune {key}: cannot read {text!r} as values") from None
    if not text.strip() or text.strip().startswith(",") or text.strip().endswith(",") or ",," in text.replace(" ", ""):
        raise ConfigError(f"--tune {key}: empty value in {text!r}")
    return [parse_value(v) if isinstance(v, str) else v for v in items]


def check_tune(grid: dict) -> dict:
    """A grid's keys (seed or PPOConfig.training keywords) and values (none empty or
    repeated; integer seeds), or a ``ConfigError``."""
    if not grid:
        return {}
    valid = training_keywords()
    for key, values in grid.items():
        if key != "seed" and key not in valid:
            raise ConfigError(
                f"--tune {key}: not seed or a PPOConfig.training keyword (lr, gamma, lambda_, "
                "entropy_coeff, clip_param, num_epochs, minibatch_size, ...)"
            )
        if not values or any(v is None or v == "" for v in values):
            raise ConfigError(f"--tune {key}: empty value in {values!r}")
        if len(set(map(repr, values))) != len(values):
            raise ConfigError(f"--tune {key} repeats a value")
        if key == "seed" and not all(isinstance(v, int) and not isinstance(v, bool) for v in values):
            raise ConfigError(f"--tune seed takes integers, got {values!r}")
    return {k: list(v) for k, v in grid.items()}


def run_tune(algo_config: Any, grid: dict, out: Path, config: RLlibConfig, job: Job) -> int:
    from ray import tune

    param_space = algo_config.to_dict()
    for key, values in grid.items():
        name = "lambda" if key == "lambda_" else key
        param_space[name] = tune.grid_search(values)
    if "seed" in grid:  # every trial's environments from its own seed
        base_env_config = env_config(config, config.seed)
        # Tune calls it with the trial's spec (an object with .config), though sample_from's stub says dict
        param_space["env_config"] = tune.sample_from(
            lambda spec: {**base_env_config, "seed": int(spec.config["seed"])}  # type: ignore[attr-defined]
        )
    tuner = tune.Tuner(
        algo_config.algo_class,
        param_space=param_space,  # the class: the name "PPO" makes Tune import every algorithm
        tune_config=tune.TuneConfig(
            max_concurrent_trials=config.ray.max_concurrent_trials,
            reuse_actors=False,
            trial_name_creator=_trial_name,
            trial_dirname_creator=_trial_name,
        ),
        run_config=tune.RunConfig(
            name="tune",
            storage_path=str(out.resolve()),
            verbose=0,
            stop={"num_env_steps_sampled_lifetime": config.timesteps},
            checkpoint_config=tune.CheckpointConfig(checkpoint_at_end=True, num_to_keep=1),
        ),
    )
    t0 = time.perf_counter()
    results = tuner.fit()
    print(f"tune: {len(results)} trial(s) in {time.perf_counter() - t0:.0f} s", flush=True)
    rows = []
    for r in sorted((results[i] for i in range(len(results))), key=lambda r: r.path):  # a ResultGrid indexes
        trial_cfg = r.config or {}
        row: dict[str, Any] = {"trial": Path(r.path).name}
        for key in grid:
            row[key] = trial_cfg.get("lambda" if key == "lambda_" else key)
        if r.error is not None:
            row.update(
                {
                    "env_steps": None,
                    "iterations": None,
                    "episode_return_mean": None,
                    "train_survey_error_m": None,
                    "eval_survey_error_m": None,
                    "checkpoint": f"error: {' '.join(str(r.error).split())[:120]}",
                }
            )
            rows.append(row)
            continue
        m = metrics(r.metrics or {})
        ckpt = Path(r.checkpoint.path) if r.checkpoint is not None else None
        if ckpt is not None:  # the trial's own checkpoint: its safe export, what agents.load reads
            from agents.rllib_policy import export

            export(ckpt)
        evaluation = evaluate_checkpoint(ckpt, config, job) if ckpt else None
        row.update(
            {
                "env_steps": m["env_steps"],
                "iterations": m["iteration"],
                "episode_return_mean": m["episode_return_mean"],
                "train_survey_error_m": m["survey_error_m"],
                "eval_survey_error_m": evaluation["survey_error_m"] if evaluation else None,
                "checkpoint": str(ckpt.relative_to(out.resolve())) if ckpt else None,
            }
        )
        rows.append(row)
    columns = ["trial", *grid, *SUMMARY_COLUMNS[1:]]
    write_summary(out, columns, rows)
    print((out / "summary.md").read_text())
    failed = [r for r in rows if str(r.get("checkpoint") or "").startswith("error")]
    if failed:
        print(f"{len(failed)} trial(s) failed; see {out / 'tune'}", file=sys.stderr)
        return 1
    return 0


def _trial_name(trial) -> str:
    """``trial_<index>_<grid values>`` from Tune's experiment tag, without commas (the
    evaluation's ``--policies`` separator) or '=': ``trial_1_lr-0.0003_seed-0``."""
    tag = str(trial.experiment_tag).replace(",", "_").replace("=", "-").replace("/", "_").replace(" ", "")
    return f"trial_{tag}"[:120]


def write_summary(out: Path, columns: list, rows: list) -> None:
    """summary.csv and summary.md (the same table), each written atomically."""
    import csv
    import io

    def cell(v):
        if isinstance(v, float):
            return f"{v:.6g}"
        return "" if v is None else str(v)

    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(columns)
    for r in rows:
        w.writerow([cell(r.get(c)) for c in columns])
    atomic_write_text(out / "summary.csv", buf.getvalue())
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(cell(r.get(c)) for c in columns) + " |" for r in rows]
    atomic_write_text(out / "summary.md", "\n".join(lines) + "\n")
