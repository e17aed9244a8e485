"""Episode cells side by side: ``run_cells`` plays cells (a scenario config, a policy, the
episodes' seeds) in this process or in worker processes, and gives each cell's result in
the cells' order.

    from coopnav_env import make_config
    from evaluation.parallel import Cell, run_cells
    cells = [Cell(make_config("gao_lawnmower", max_cycles=20), p, (0, 1, 2)) for p in ("fim_a", "ellipse")]
    for cell, result in zip(cells, run_cells(cells, workers=2)):
        print(cell.policy, [r["mean_error_m"] for r in result.episodes])

The one place where the evaluation, the benchmark and ``benchmarks/lever_table.py`` run
cells (``--workers`` of each). A cell is one ``evaluation.episodes.run_episodes`` call, so
its numbers do not depend on where it ran: the simulator's random numbers are counter-based
per episode, a policy instance acts for one beacon of one episode, and every kernel works on
each row of the batch on its own (``tests/test_parallel.py`` checks two workers against one,
to the bit). What runs where:

* ``workers=1``: every cell in this process, one after the other (what the commands did
  before ``--workers``);
* ``workers=N > 1``: N processes started fresh (``spawn``: nothing of this process's torch
  or numba threads is copied), each with one numba and one torch thread, so N workers use N
  cores. A worker imports what the cells need itself: a scenario, sensor, reward term or
  policy registered only in ``__main__`` of a script is not there (register it in a module
  that is imported). The pickle-based policy files this process trusted
  (``agents.trust_pickle``) are trusted there too. As with any ``spawn`` start, a script
  that calls this with workers must keep its top level under ``if __name__ == "__main__":``
  (the workers import the script's module).

Progress (``progress``: a ``coopnav_env.progress.Progress``) moves with every step of every
running cell, as in one process; each cell's ``label`` becomes the bar's stage when it starts.
Ctrl-C (or any error) stops the workers at once and raises in this process; cells not yet
given back are lost, as an interrupted single process loses its running batch. A worker that
dies (the kernel's out-of-memory killer, a ``kill -9``) raises ``WorkerLost`` here.
"""

from __future__ import annotations

import dataclasses
import os
import queue
from collections.abc import Iterator, Sequence
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from coopnav_env.progress import Progress
    from coopnav_env.scenarios import ScenarioConfig

__all__ = ["Cell", "CellResult", "WorkerLost", "add_workers_argument", "check_workers", "default_workers", "run_cells"]

MAX_WORKERS = 64


class WorkerLost(OSError):
    """A worker process ended without giving its cell back (killed, or out of memory): an
    ``OSError``, so the commands report it in one line as they do a full disk."""


@dataclasses.dataclass(frozen=True)
class Cell:
    """One ``run_episodes`` call: ``policy`` (a planner or trained policy name, as
    ``evaluation.episodes.make_policy`` takes) on ``config`` for the episodes ``seeds``.
    ``label``: the progress stage while it runs; ``steps``: keep the step rows
    (``steps.csv``); ``act_seconds``: keep the CPU seconds of every act call."""

    config: ScenarioConfig
    policy: str
    seeds: tuple
    label: str = ""
    steps: bool = True
    act_seconds: bool = False


@dataclasses.dataclass
class CellResult:
    """What ``run_episodes`` gave for a cell: episode rows, step rows (empty unless the
    cell keeps them), the act calls' CPU seconds (empty unless it keeps them) and the
    cell's wall-clock seconds where it ran."""

    episodes: list
    steps: list
    act_seconds: list
    wall_s: float = 0.0


def default_workers() -> int:
    """The cores this process may use (``os.sched_getaffinity``, else ``os.cpu_count``)."""
    try:
        return max(len(os.sched_getaffinity(0)), 1)
    except AttributeError:  # not on Linux
        return max(os.cpu_count() or 1, 1)


def check_workers(workers: Any) -> int:
    """``workers`` (an int, or its text) as an int in [1, MAX_WORKERS], ``0`` meaning
    ``default_workers()``; ValueError naming what was wrong and the valid range."""
    valid = f"an integer in [0, {MAX_WORKERS}] (0: every core, {default_workers()} here)"
    if isinstance(workers, bool):
        raise ValueError(f"--workers must be {valid}, got {workers!r}")
    if not isinstance(workers, int):
        try:
            workers = int(str(workers).strip())
        except ValueError:
            raise ValueError(f"--workers must be {valid}, got {workers!r}") from None
    if workers == 0:
        return default_workers()
    if not 1 <= workers <= MAX_WORKERS:
        raise ValueError(f"--workers must be {valid}, got {workers}")
    return workers


def add_workers_argument(parser: Any, what: str) -> None:
    """The commands' one ``--workers N`` option (text, checked later by ``check_workers``):
    ``what`` names what the workers run side by side."""
    parser.add_argument(
        "--workers",
        default="1",
        metavar="N",
        help=f"processes running {what} side by side (default 1; 0: every core); the results are the same for any N",
    )


def _play(cell: Cell, progress: Any = None) -> CellResult:
    import time

    from .episodes import run_episodes

    t0 = time.perf_counter()
    seconds: list | None = [] if cell.act_seconds else None
    episodes, steps = run_episodes(
        cell.config, cell.policy, list(cell.seeds), progress=progress, act_seconds=seconds, keep_steps=cell.steps
    )
    return CellResult(episodes, steps, seconds or [], time.perf_counter() - t0)


# ------------------------------------------------------------------------------------
# the workers

_QUEUE: Any = None  # the worker's progress queue (set by _init_worker)


def _init_worker(messages: Any, trusted: Sequence[str]) -> None:
    """A worker's start: one thread each for numba and torch (before either is imported),
    Ctrl-C left to the parent, the parent's trusted pickle files trusted."""
    import signal

    global _QUEUE
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    for var in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = "1"
    _QUEUE = messages
    if trusted:
        from agents.formats import trust_pickle

        trust_pickle(*trusted)


def _work(index: int, cell: Cell) -> CellResult:
    if _QUEUE is not None:
        _QUEUE.put(("stage", index, cell.label))

    def progress(n: float) -> None:
        _QUEUE.put(("update", index, n))

    return _play(cell, progress if _QUEUE is not None else None)


def _trusted_files() -> list:
    import sys

    formats = sys.modules.get("agents.formats")  # trusted files exist only once agents was used
    return sorted(getattr(formats, "_TRUSTED", ())) if formats is not None else []


def run_cells(cells: Sequence[Cell], workers: int = 1, progress: Progress | None = None) -> Iterator[CellResult]:
    """Play ``cells`` on ``workers`` processes (1: in this process) and yield each cell's
    ``CellResult`` in the order of ``cells`` (a later cell that finishes first waits).
    ``progress``: updated with every step of every running cell (the episodes' worth of
    work, as ``run_episodes`` reports it), its stage set to a cell's label as it starts."""
    cells = list(cells)
    workers = min(check_workers(workers), max(len(cells), 1))
    if workers == 1:
        for cell in cells:
            if progress is not None and cell.label:
                progress.stage(cell.label)
            yield _play(cell, None if progress is None else progress.update)
        return
    yield from _run_pool(cells, workers, progress)


def _run_pool(cells: list, workers: int, progress: Progress | None) -> Iterator[CellResult]:
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor
    from concurrent.futures.process import BrokenProcessPool

    ctx = multiprocessing.get_context("spawn")
    messages = ctx.Queue()
    pool = ProcessPoolExecutor(workers, mp_context=ctx, initializer=_init_worker, initargs=(messages, _trusted_files()))
    finished = False
    try:
        futures = [pool.submit(_work, i, cell) for i, cell in enumerate(cells)]
        for future in futures:
            while not future.done():
                _drain(messages, progress, timeout=0.2)
            _drain(messages, progress, timeout=0.0)
            try:
                result = future.result()
            except BrokenProcessPool as err:
                raise WorkerLost(
                    "a --workers process ended abruptly (killed, or out of memory?) before giving its "
                    "cell back: run again, with fewer workers if memory is short"
                ) from err
            yield result
        finished = True
        pool.shutdown(wait=True)  # the workers exit, flushing what their queue still held
        _drain(messages, progress, timeout=0.0)  # the last cells' last steps: the bar ends at its total
    finally:
        if not finished:  # an error, Ctrl-C or a consumer that stopped early: stop every worker now
            processes = list((getattr(pool, "_processes", None) or {}).values())
            pool.shutdown(wait=False, cancel_futures=True)
            for process in processes:
                process.terminate()
        messages.close()


def _drain(messages: Any, progress: Progress | None, timeout: float) -> None:
    """Hand the workers' progress messages to ``progress`` (waiting up to ``timeout`` s
    for the first)."""
    try:
        kind, _, value = messages.get(timeout=timeout) if timeout > 0 else messages.get_nowait()
    except queue.Empty:
        return
    while True:
        if progress is not None:
            if kind == "update":
                progress.update(value)
            elif value:
                progress.stage(value)
        try:
            kind, _, value = messages.get_nowait()
        except queue.Empty:
            return
