"""Running a whole evaluation: check the inputs (``config.prepare``), run the missing
episodes in batches (with a progress bar on a terminal), write episodes.csv and
steps.csv after every batch, then run.json, summary.json, summary.md and the figures.

    from evaluation import EvalConfig, run_evaluation
    summary = run_evaluation(EvalConfig(scenario="gao_lawnmower", policies=("fim_a", "static"),
                                        episodes=2, out="results/x"))

Nothing is written before every input is checked; bad input raises ``UsageError``.
"""

from __future__ import annotations

import os
import sys
from typing import NamedTuple

from coopnav_env.records import atomic_write_text, strict_json, version_record

from .config import EvalConfig, UsageError, cell_id, prepare
from .episodes import run_episodes
from .report import EPISODE_COLUMNS, STEP_COLUMNS, csv_text, markdown, read_csv
from .stats import summarize


class EvalResult(NamedTuple):
    """What ``evaluate`` returns: summary.json's content, summary.md's text, the output
    directory and the names of the files written there."""

    summary: dict
    markdown: str
    out: str
    files: list


def _kept_rows(out: str):
    """The episode and step rows of an earlier run in ``out`` that are complete in both files."""
    ep_rows, step_rows = read_csv(os.path.join(out, "episodes.csv")), read_csv(os.path.join(out, "steps.csv"))
    have_steps = {(r["cell"], r["policy"], r["seed"]) for r in step_rows}
    ep_rows = [r for r in ep_rows if (r["cell"], r["policy"], r["seed"]) in have_steps]
    have_eps = {(r["cell"], r["policy"], r["seed"]) for r in ep_rows}
    step_rows = [r for r in step_rows if (r["cell"], r["policy"], r["seed"]) in have_eps]
    return ep_rows, step_rows


def _progress_bar(config: EvalConfig, total: int):
    show = sys.stderr.isatty() if config.progress is None else config.progress
    if not (total and show):
        return None
    from tqdm import tqdm

    return tqdm(total=total, unit="episode", file=sys.stderr, dynamic_ncols=True)


def evaluate(config: EvalConfig) -> EvalResult:
    """Run the evaluation ``config`` describes and write its files (see ``evaluation``)."""
    plan = prepare(config)
    out = config.out
    try:
        os.makedirs(out, exist_ok=True)
    except OSError as err:
        raise UsageError(f"cannot create output directory {out!r}: {err.strerror}") from None
    ep_path, st_path = os.path.join(out, "episodes.csv"), os.path.join(out, "steps.csv")
    ep_rows, step_rows = _kept_rows(out) if config.resume else ([], [])
    run_record = dict(plan.run_info, trained_policies=plan.trained, versions=version_record())
    atomic_write_text(os.path.join(out, "run.json"), strict_json(run_record))
    done = {(r["cell"], r["policy"], str(r["seed"])) for r in ep_rows}
    ep_columns = EPISODE_COLUMNS[:1] + list(plan.sweep) + EPISODE_COLUMNS[1:]
    seeds_all = [config.seed + i for i in range(config.episodes)]
    todo = []
    for cell in plan.cells:
        cid = cell_id(cell)
        for p in plan.policies:
            missing = [(i, s) for i, s in enumerate(seeds_all) if (cid, p, str(s)) not in done]
            for k in range(0, len(missing), config.batch_size):
                todo.append((cell, p, missing[k:k + config.batch_size]))
    total = sum(len(m) for _, _, m in todo)
    skipped = len(plan.cells) * len(plan.policies) * config.episodes - total
    if skipped and config.resume:
        print(f"resuming: {skipped} episode(s) already done, {total} to run", file=sys.stderr)

    def write_rows():
        atomic_write_text(st_path, csv_text(STEP_COLUMNS, step_rows))
        atomic_write_text(ep_path, csv_text(ep_columns, ep_rows))

    bar = _progress_bar(config, total)
    try:
        for cell, p, chunk in todo:
            cid = cell_id(cell)
            if bar is not None:
                bar.set_description(f"{p} {cid}".strip()[:40])
            eps, sts = run_episodes(plan.configs[cid], p, [s for _, s in chunk],
                                    progress=bar.update if bar is not None else None)
            index = {s: i for i, s in chunk}
            for r in eps:
                r.update({"cell": cid, "policy": p, "episode": index[r["seed"]], **cell})
            for r in sts:
                r.update({"cell": cid, "policy": p, "episode": index[r["seed"]]})
            ep_rows.extend(eps)
            step_rows.extend(sts)
            write_rows()
    finally:
        if bar is not None:
            bar.close()
    if not todo:  # rewrite in the current column layout anyway
        write_rows()
    summary = summarize(plan, ep_rows, step_rows)
    atomic_write_text(os.path.join(out, "summary.json"), strict_json(summary))
    md = markdown(summary, plan)
    atomic_write_text(os.path.join(out, "summary.md"), md + "\n")
    files = ["run.json", "summary.json", "summary.md", "episodes.csv", "steps.csv"]
    if config.figures:
        from .figures import draw_all

        files += draw_all(out, plan, step_rows, summary)
    return EvalResult(summary, md, out, files)


def run_evaluation(config: EvalConfig | None = None, **fields) -> dict:
    """Run an evaluation and return its summary (summary.json's content).
    ``run_evaluation(EvalConfig(...))``, or the fields directly:
    ``run_evaluation(scenario="sousa_asv", policies="fim_a,static", episodes=5)``."""
    if config is None:
        config = EvalConfig(**fields)
    elif fields:
        config = config.replace(**fields)
    return evaluate(config).summary
