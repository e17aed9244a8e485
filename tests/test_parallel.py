"""Cells side by side (``evaluation.parallel``): the same numbers as one process, to the bit,
in the cells' order; errors and early stops end the workers; bad counts are one line."""

from __future__ import annotations

import json
import multiprocessing
import time

import pytest

from coopnav_env import make_config
from evaluation.parallel import Cell, check_workers, default_workers, run_cells


def _cells():
    config = make_config("gao_lawnmower", max_cycles=8)
    # a slow planner first, so that with two workers the later cells finish before it
    return [Cell(config, p, (3, 4, 5), label=p) for p in ("horizon", "fim_a", "static", "ellipse")]


def test_two_workers_give_one_process_numbers_in_order():
    cells = _cells()
    one = list(run_cells(cells, workers=1))
    two = list(run_cells(cells, workers=2))
    assert len(two) == len(cells)
    for a, b in zip(one, two):
        assert a.episodes == b.episodes  # every column of every episode, floats to the bit
        assert a.steps == b.steps
    # the cells differ from each other (the order is checked, not four equal answers)
    assert len({json.dumps(r.episodes) for r in one}) == len(cells)


@pytest.mark.parametrize("scenario", ["gao_lawnmower", "matos_moving_lbl"])
def test_a_cell_without_step_rows_has_the_same_episodes(scenario, monkeypatch):
    """``Cell(steps=False)`` (the benchmark's cells) builds no step rows and computes nothing only
    they read (the ellipse's axes); its episodes are the same to the bit as a cell that keeps
    them (8 step rows an episode here; the moving network's rows carry the frame's error too)."""
    from coopnav_env.core import information

    config = make_config(scenario, max_cycles=8)
    policy = "fim_a" if scenario == "gao_lawnmower" else "static"
    (kept,) = run_cells([Cell(config, policy, (3, 4))], workers=1)
    assert len(kept.steps) == 2 * 8 and {"ellipse_major_m", "reward"} <= set(kept.steps[0])
    assert ("error_x_m" in kept.steps[0]) == (scenario == "matos_moving_lbl")

    def no_ellipse(*args, **kwargs):
        raise AssertionError("the ellipse is computed for step rows that are not kept")

    monkeypatch.setattr(information, "error_ellipse", no_ellipse)
    (dropped,) = run_cells([Cell(config, policy, (3, 4), steps=False)], workers=1)
    assert dropped.steps == []
    assert dropped.episodes == kept.episodes


class _Bar:
    def __init__(self):
        self.n, self.stages = 0.0, []

    def update(self, n):
        self.n += n

    def stage(self, text):
        self.stages.append(text)


def test_progress_adds_up_over_workers():
    cells = _cells()
    bar = _Bar()
    list(run_cells(cells, workers=2, progress=bar))
    assert bar.n == pytest.approx(sum(len(c.seeds) for c in cells))
    assert sorted(bar.stages) == sorted(c.label for c in cells)


def test_a_worker_error_reaches_the_caller():
    config = make_config("gao_lawnmower", max_cycles=4)
    cells = [Cell(config, "fim_a", (1,)), Cell(config, "no_such_policy", (1,))]
    with pytest.raises(Exception, match="no_such_policy"):
        list(run_cells(cells, workers=2))
    time.sleep(0.5)
    assert not [p for p in multiprocessing.active_children() if p.is_alive()]


def test_stopping_early_ends_the_workers():
    short = make_config("gao_lawnmower", max_cycles=4)
    long = make_config("gao_lawnmower")  # 150 cycles: 16 episodes of horizon take about 7 s
    cells = [Cell(short, "fim_a", (1,))] + [Cell(long, "horizon", tuple(range(16)))] * 6
    gen = run_cells(cells, workers=2)
    first = next(gen)
    assert len(first.episodes) == 1
    time.sleep(1.0)  # the second worker is inside a long cell now
    gen.close()  # what Ctrl-C in the consumer does
    deadline = time.monotonic() + 2  # a worker left running would take seconds more
    while [p for p in multiprocessing.active_children() if p.is_alive()] and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not [p for p in multiprocessing.active_children() if p.is_alive()]


@pytest.mark.parametrize(("value", "expected"), [(1, 1), ("2", 2), (" 3 ", 3), (0, None)])
def test_worker_counts(value, expected):
    assert check_workers(value) == (default_workers() if expected is None else expected)


@pytest.mark.parametrize("value", [-1, 65, "two", 1.5, True, None])
def test_bad_worker_counts_name_the_valid_range(value):
    with pytest.raises(ValueError, match=r"--workers must be an integer in \[0, 64\]"):
        check_workers(value)


def test_benchmark_and_evaluate_refuse_a_bad_count(tmp_path, capsys):
    from evaluation.benchmark import main as bench_main
    from evaluation.cli import main as eval_main

    code = bench_main(["--tasks", "gao_lawnmower", "--workers", "many", "--out", str(tmp_path / "b")])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and "--workers" in err, err
    code = eval_main(["--scenario", "gao_lawnmower", "--workers", "-2", "--out", str(tmp_path / "e")])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and "--workers" in err, err
    assert not (tmp_path / "b").exists() and not (tmp_path / "e").exists()


def test_the_benchmark_with_two_workers_writes_the_same_errors(tmp_path):
    import dataclasses

    from evaluation.benchmark import plan_benchmark, run_benchmark

    def raw(workers, out):
        plan = plan_benchmark("gao_lawnmower", None, episodes=2, out=str(out), only_tasks="lake,spiral")
        for sp in plan.sets:  # every task's episodes cut to 6 cycles: a quick run of the same code
            sp.configs = {k: dataclasses.replace(c, max_cycles=6) for k, c in sp.configs.items()}
        r = run_benchmark(plan, progress=False, workers=workers)
        for per_task in r.values():
            for cells in per_task.values():
                for v in cells.values():
                    if v is not None:
                        v.pop("ms_per_act")  # a timing: the one field that differs
        return r

    one = raw(1, tmp_path / "one")
    two = raw(2, tmp_path / "two")
    assert one == two
    assert list(one["gao_lawnmower"]) == ["lake", "spiral"]


def test_evaluate_with_two_workers_writes_the_same_files(tmp_path):
    from evaluation import EvalConfig, evaluate

    def files(workers):
        out = tmp_path / f"w{workers}"
        config = EvalConfig(
            scenario="gao_lawnmower",
            policies=("fim_a", "static", "ellipse"),
            episodes=3,
            batch_size=2,  # two batches per policy: six cells
            overrides={"max_cycles": 6},
            out=str(out),
            workers=workers,
            figures=False,
            progress=False,
        )
        evaluate(config)
        return {name: (out / name).read_bytes() for name in ("episodes.csv", "steps.csv", "summary.json")}

    one, two = files(1), files(2)
    assert one == two
    assert one["episodes.csv"].count(b"\n") == 1 + 3 * 3


def test_a_killed_worker_is_one_oserror():
    """The out-of-memory killer's SIGKILL on a worker: WorkerLost (an OSError, which the
    commands print as one line), and the other worker stopped too."""
    import os
    import signal

    from evaluation.parallel import WorkerLost

    short = make_config("gao_lawnmower", max_cycles=4)
    long = make_config("gao_lawnmower")
    cells = [Cell(short, "fim_a", (1,))] + [Cell(long, "horizon", tuple(range(16)))] * 4
    gen = run_cells(cells, workers=2)
    next(gen)
    time.sleep(1.0)
    victims = [p for p in multiprocessing.active_children() if p.is_alive()]
    assert len(victims) == 2
    os.kill(victims[0].pid, signal.SIGKILL)
    with pytest.raises(WorkerLost, match="ended abruptly") as info:
        next(gen)
    assert isinstance(info.value, OSError)
    deadline = time.monotonic() + 2
    while [p for p in multiprocessing.active_children() if p.is_alive()] and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not [p for p in multiprocessing.active_children() if p.is_alive()]
