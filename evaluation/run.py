"""Running a whole evaluation: check the inputs (``config.prepare``), run the missing
episodes in batches (with a progress bar on a terminal), write episodes.csv and
steps.csv after every batch (``config.workers`` batches side by side:
``evaluation.parallel``), then run.json, summary.json, summary.md and the figures.

    from evaluation import EvalConfig, run_evaluation
    summary = run_evaluation(EvalConfig(scenario="gao_lawnmower", policies=("fim_a", "static"),
                                        episodes=2, out="results/x"))

Nothing is written before every input is checked; bad input raises ``UsageError``.
One run at a time holds the output directory (``outdir.OutputLock``); ``--resume``
keeps only complete episodes (``resume.kept_rows``) and the rows are kept in the
grid's order with exact floats, so a resumed run's summary.json is byte-identical to
an uninterrupted run's.
"""

from __future__ import annotations

import math
import os
import sys
from collections.abc import Sequence
from typing import Any, NamedTuple

from coopnav_env.records import atomic_write_text, strict_json, version_record

from .config import EvalConfig, cell_id, prepare
from .parallel import Cell, run_cells
from .report import EPISODE_COLUMNS, STEP_COLUMNS, csv_text, markdown
from .resume import kept_rows
from .stats import summarize


class EvalResult(NamedTuple):
    """What ``evaluate`` returns: summary.json's content, summary.md's text, the output
    directory and the names of the files written there."""

    summary: dict
    markdown: str
    out: str
    files: list


class EvaluationError(RuntimeError):
    """The evaluation ran but its result cannot be summarized (a non-finite value in an
    episode, named); on the command line one line and exit status 1."""


class EvaluationInterrupted(KeyboardInterrupt):
    """Ctrl-C (or SIGTERM on the command line) during an evaluation: ``saved`` of
    ``total`` episodes are on disk in ``out``; ``--resume`` runs the rest."""

    def __init__(self, out: str, saved: int, total: int) -> None:
        super().__init__(f"interrupted: {saved} of {total} episodes saved in {out!r}")
        self.out, self.saved, self.total = out, saved, total


def _progress_bar(config: EvalConfig, total: int):
    """A bar on a terminal, one line per batch elsewhere (``coopnav_env.progress``); None
    with nothing to run or ``progress=False``."""
    from coopnav_env.progress import Progress

    if not total or config.progress is False:
        return None
    return Progress(total, unit="episode", desc="evaluating", mode="bar" if config.progress else None)


def _row_order(plan):
    """Sort keys of episode and step rows: the grid's order (cell, policy, episode, step),
    whatever order they were run in, so a resumed run's files and sums are an
    uninterrupted run's."""
    cells = {cell_id(c): i for i, c in enumerate(plan.cells)}
    policies = {p: i for i, p in enumerate(plan.policies)}

    def episode_key(r):
        return cells[r["cell"]], policies[r["policy"]], int(r["episode"])

    def step_key(r):
        return cells[r["cell"]], policies[r["policy"]], int(r["episode"]), int(r["step"])

    return episode_key, step_key


def _check_finite(ep_rows, step_rows):
    """EvaluationError naming the first episode with a NaN or infinite value."""
    from .resume import STEP_FLOATS

    checks: list[tuple[dict, Sequence[str], str]] = [(r, EPISODE_COLUMNS[4:], "episodes.csv") for r in ep_rows]
    checks += [(r, STEP_FLOATS + ("error_x_m", "error_y_m"), "steps.csv") for r in step_rows]
    for r, columns, where in checks:
        for k in columns:
            v = r.get(k, "")
            if v == "" or v is None:
                continue
            if not math.isfinite(float(v)):
                step = f" step {r['step']}" if "step" in r else ""
                cell = f" in cell {r['cell']}" if r["cell"] else ""
                raise EvaluationError(
                    f"episode {r['episode']} (seed {r['seed']}) of policy {r['policy']!r}{cell}"
                    f"{step}: {k} is {float(v)} in {where}; summary.json not written"
                )


def evaluate(config: EvalConfig, command: str | None = None) -> EvalResult:
    """Run the evaluation ``config`` describes and write its files (see ``evaluation``).
    Holds a lock on ``config.out`` while it runs (``command``: how the run was started,
    shown to a second writer). Raises UsageError (bad input, nothing written),
    EvaluationError (a non-finite result) or EvaluationInterrupted (Ctrl-C: what was
    finished stays on disk)."""
    import baselines  # noqa: F401 - imported before the timer: a mistyped name fails fast and stays one line
    from coopnav_env.progress import announce_after

    from . import outdir

    with announce_after(
        "checking the scenario and the policies (the first run also compiles the simulator, about a minute)"
    ):
        plan = prepare(config)
    out = config.out
    with outdir.OutputLock(out, command):
        if outdir.snapshot(out) != plan.out_state:  # changed since the checks: check again, under the lock
            plan = prepare(config)
        saved = [0]
        try:
            return _run_locked(plan, saved)
        except KeyboardInterrupt as err:
            total = len(plan.cells) * len(plan.policies) * plan.episodes
            raise EvaluationInterrupted(out, saved[0], total) from err


def _run_locked(plan, saved: list) -> EvalResult:
    from . import outdir

    config, out = plan.config, plan.config.out
    if config.overwrite:
        outdir.clear(out)
    ep_path, st_path = os.path.join(out, "episodes.csv"), os.path.join(out, "steps.csv")
    ep_rows, step_rows, notes = kept_rows(out, plan) if config.resume else ([], [], [])
    for note in notes:
        print(f"resuming: {note}", file=sys.stderr)
    saved[0] = len(ep_rows)
    previous = plan.previous or {}
    run_record = dict(
        plan.run_info, trained_policies=plan.trained, format_version=outdir.FORMAT_VERSION, versions=version_record()
    )
    earlier = [
        v
        for v in previous.get("earlier_versions", []) + [previous.get("versions")]
        if isinstance(v, dict) and v != run_record["versions"]
    ]
    if earlier:
        run_record["earlier_versions"] = earlier  # what produced the episodes kept by resume
    done = {(r["cell"], r["policy"], str(r["seed"])) for r in ep_rows}
    ep_columns = EPISODE_COLUMNS[:1] + list(plan.sweep) + EPISODE_COLUMNS[1:]
    todo = []
    for cell in plan.cells:
        cid = cell_id(cell)
        for p in plan.policies:
            missing = [(i, s) for i, s in enumerate(plan.seeds) if (cid, p, str(s)) not in done]
            for k in range(0, len(missing), config.batch_size):
                todo.append((cell, p, missing[k : k + config.batch_size]))
    total = sum(len(m) for _, _, m in todo)
    skipped = len(plan.cells) * len(plan.policies) * plan.episodes - total
    if config.resume and plan.previous is not None:
        old_p, old_e = previous["policies"], previous["episodes"]
        if old_p != plan.policies or old_e != plan.episodes:
            print(
                f"resuming: {out!r} held {old_e} episode(s) of {', '.join(old_p)}; the run now covers "
                f"{plan.episodes} of {', '.join(plan.policies)}",
                file=sys.stderr,
            )
        print(f"resuming: {skipped} episode(s) already done, {total} to run", file=sys.stderr)
    episode_key, step_key = _row_order(plan)
    from . import checksums

    digests = {}

    def write_rows():
        ep_rows.sort(key=episode_key)
        step_rows.sort(key=step_key)
        by_episode: dict = {}
        for r in step_rows:
            by_episode.setdefault(checksums.key(r), []).append(r)
        for r in ep_rows:  # each episode's checksum, computed once
            k = checksums.key(r)
            if k not in digests:
                digests[k] = checksums.digest(r, by_episode.get(k, []), ep_columns)
        # steps first, then the checksums: an episode's row is written only once both are on disk
        atomic_write_text(st_path, csv_text(STEP_COLUMNS, step_rows))
        checksums.write(out, {checksums.key(r): digests[checksums.key(r)] for r in ep_rows})
        atomic_write_text(ep_path, csv_text(ep_columns, ep_rows))
        saved[0] = len(ep_rows)

    if todo:
        outdir.remove_summaries(out)  # summaries exist only while they match the CSV files
    atomic_write_text(os.path.join(out, "run.json"), strict_json(run_record))
    bar = _progress_bar(config, total)
    try:
        jobs = [
            Cell(
                plan.configs[cell_id(cell)],
                p,
                tuple(s for _, s in chunk),
                label=f"{p} {cell_id(cell)}".strip() + f" ({len(chunk)} episodes)",
            )
            for cell, p, chunk in todo
        ]
        for (cell, p, chunk), result in zip(todo, run_cells(jobs, config.workers, bar)):
            cid = cell_id(cell)
            eps, sts = result.episodes, result.steps
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
    if not todo:  # rewrite in the current layout anyway
        write_rows()
    _check_finite(ep_rows, step_rows)
    summary = summarize(plan, ep_rows, step_rows)
    try:
        summary_text = strict_json(summary)
    except ValueError as err:
        raise EvaluationError(f"summary.json not written: {err}") from None
    atomic_write_text(os.path.join(out, "summary.json"), summary_text)
    md = markdown(summary, plan)
    atomic_write_text(os.path.join(out, "summary.md"), md + "\n")
    files = ["run.json", "summary.json", "summary.md", "episodes.csv", "steps.csv"]
    if config.figures:
        from .figures import draw_all

        if bar is not None:
            bar.write("drawing the figures")

        files += draw_all(out, plan, step_rows, summary)
    return EvalResult(summary, md, out, files)


def run_evaluation(config: EvalConfig | None = None, **fields: Any) -> dict:
    """Run an evaluation and return its summary (summary.json's content).
    ``run_evaluation(EvalConfig(...))``, or the fields directly:
    ``run_evaluation(scenario="sousa_asv", policies="fim_a,static", episodes=5)``."""
    if config is None:
        config = EvalConfig(**fields)
    elif fields:
        config = config.replace(**fields)
    return evaluate(config).summary
