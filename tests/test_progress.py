"""Every long command shows progress (issue 24): in a pseudo-terminal a bar that ends at
its total (never past it), without one a line per stage ending in "[total/total ...]
done"; the first sign of life comes within 5 s of the start (5 s on an idle machine:
the bound grows with the load average, since imports alone take longer on busy
cores). Tiny runs: a few episodes, a thousand steps."""

from __future__ import annotations

import fcntl
import os
import pty
import re
import select
import struct
import subprocess
import sys
import termios
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TINY_TRAIN = """\
n_envs: 4
ppo: {n_steps: 64, batch_size: 128, n_epochs: 1, policy_kwargs: {net_arch: [16, 16]}}
env: {overrides: {max_cycles: 10, mission_duration_s: 200.0}}
eval: {every_steps: 512, episodes: 2, seed: 1000000, baselines: [fim_a]}
checkpoint_every_steps: 256
"""


def _env() -> dict:
    env = dict(os.environ)
    env.pop("COOPNAV_PROGRESS", None)  # tests/conftest.py turns progress off for the other tests
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT)] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p])
    env["PYTHONUNBUFFERED"] = "1"
    return env


def _first_output_limit() -> float:
    """5 s, stretched by the load average beyond the cores (a shared, busy machine)."""
    load = os.getloadavg()[0] / (os.cpu_count() or 1)
    return 5.0 * max(1.0, load)


def _run(args, tty: bool, cols: int = 100, timeout: float = 600.0):
    """Run ``python ARGS`` in a pseudo-terminal (``tty``) or with a pipe; returns (exit
    status, output text, seconds from start to the first output)."""
    cmd = [sys.executable, *args]
    started = time.perf_counter()
    first = None
    chunks = []
    if tty:
        master, slave = pty.openpty()
        fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 30, cols, 0, 0))
        proc = subprocess.Popen(cmd, stdin=slave, stdout=slave, stderr=slave, env=_env(), cwd=ROOT, close_fds=True)
        os.close(slave)
        fd = master
    else:
        proc = subprocess.Popen(
            cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env=_env(), cwd=ROOT
        )
        fd = proc.stdout.fileno()
    try:
        while True:
            if time.perf_counter() - started > timeout:
                proc.kill()
                raise AssertionError(f"{args} ran over {timeout} s")
            ready, _, _ = select.select([fd], [], [], 0.2)
            if ready:
                try:
                    data = os.read(fd, 65536)
                except OSError:  # the pty closes when the child exits
                    data = b""
                if not data:
                    if proc.poll() is not None:
                        break
                    continue
                if first is None and data.strip():
                    first = time.perf_counter() - started
                chunks.append(data)
            elif proc.poll() is not None and not tty:
                continue
    finally:
        proc.wait()
        if tty:
            os.close(master)
    return proc.returncode, b"".join(chunks).decode("utf-8", "replace"), first


COUNT = re.compile(r"(\d+(?:\.\d+)?)/(\d+(?:\.\d+)?) ")


def _check_bar(text: str):
    """A tqdm bar that reaches its total and never passes it."""
    assert "|" in text and "%" in text, text[-2000:]
    pairs = [(float(n), float(t)) for n, t in COUNT.findall(text)]
    assert pairs, text[-2000:]
    assert all(n <= t for n, t in pairs), [p for p in pairs if p[0] > p[1]]
    assert any(n == t for n, t in pairs), pairs[-5:]


def _check_lines(text: str):
    """Stage lines (no carriage-return bar), the last counted one at its total."""
    assert "\r" not in text and "%|" not in text, text[-2000:]
    done = re.findall(r"^\[(\d+)/(\d+) [^\]]*\] done$", text, flags=re.M)
    assert done and all(n == t for n, t in done), text[-2000:]
    pairs = [(float(n), float(t)) for n, t in re.findall(r"^\[(\d+(?:\.\d+)?)/(\d+) ", text, flags=re.M)]
    assert all(n <= t for n, t in pairs), pairs


def _check(rc, text, first, tty):
    assert rc == 0, text[-3000:]
    assert first is not None and first < _first_output_limit(), (first, text[:500])
    (_check_bar if tty else _check_lines)(text)


@pytest.mark.parametrize("tty", [True, False], ids=["terminal", "pipe"])
def test_evaluate_shows_progress(tmp_path, tty):
    rc, text, first = _run(
        [
            "evaluate.py",
            "--scenario",
            "gao_lawnmower",
            "--policies",
            "fim_a,static",
            "--episodes",
            "2",
            "--set",
            "max_cycles=20",
            "--no-figures",
            "--out",
            str(tmp_path / "ev"),
        ],
        tty,
    )
    _check(rc, text, first, tty)
    assert "fim_a" in text and "static" in text


def test_evaluate_on_a_terminal_of_zero_columns_prints_lines(tmp_path):
    rc, text, _first = _run(
        [
            "evaluate.py",
            "--scenario",
            "gao_lawnmower",
            "--policies",
            "fim_a",
            "--episodes",
            "2",
            "--set",
            "max_cycles=20",
            "--no-figures",
            "--out",
            str(tmp_path / "ev"),
        ],
        True,
        cols=0,
    )
    assert rc == 0, text[-3000:]
    text = text.replace("\r\n", "\n")
    assert re.search(r"^\[2/2 episode, [^\]]*\] done$", text, flags=re.M), text[-2000:]


@pytest.mark.parametrize("tty", [True, False], ids=["terminal", "pipe"])
def test_benchmark_shows_progress_and_draws_its_figure(tmp_path, tty):
    out = tmp_path / "bench"
    rc, text, first = _run(
        [
            "-m",
            "evaluation.benchmark",
            "--task",
            "lake",
            "--episodes",
            "2",
            "--set",
            "max_cycles=20",
            "--out",
            str(out),
        ],
        tty,
    )
    _check(rc, text, first, tty)
    if not tty:
        assert "gao_lawnmower/lake fim_a" in text  # a line per task and policy
    png = out / "benchmark_gao_lawnmower.png"
    assert png.is_file() and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "not a benchmark result" in (out / "results.md").read_text().lower()  # --task: a part of it


@pytest.mark.parametrize("tty", [True, pytest.param(False, marks=pytest.mark.slow)], ids=["terminal", "pipe"])
def test_train_shows_stages_and_a_bar_that_ends_at_its_total(tmp_path, tty):
    cfg = tmp_path / "tiny.yml"
    cfg.write_text(TINY_TRAIN)
    out = tmp_path / "run"
    rc, text, first = _run(
        ["train.py", "--scenario", "sousa_asv", "--timesteps", "1000", "--config", str(cfg), "--out", str(out)], tty
    )
    _check(rc, text, first, tty)
    for said in ("loading torch", "building 4 environments", "scoring the planners fim_a", "training: 1,024 steps"):
        assert said in text, said
    assert "1024/1024" in text and "1000/1000" not in text  # the steps SB3 really runs: 4 whole rollouts
    assert (out / "learning_curve.png").is_file()


@pytest.mark.slow
@pytest.mark.parametrize("tty", [True, False], ids=["terminal", "pipe"])
def test_time_to_beat_shows_progress(tmp_path, tty):
    cfg = tmp_path / "tiny.yml"
    cfg.write_text(TINY_TRAIN)
    rc, text, first = _run(
        [
            "benchmarks/time_to_beat.py",
            "--config",
            str(cfg),
            "--seeds",
            "0",
            "--budget-s",
            "3",
            "--eval-every",
            "512",
            "--eval-episodes",
            "1",
            "--threads",
            "1",
            "--out",
            str(tmp_path / "ttb"),
        ],
        tty,
    )
    _check(rc, text, first, tty)
    assert "seed 0: validation at" in text


@pytest.mark.parametrize("tty", [True, False], ids=["terminal", "pipe"])
def test_nees_per_cycle_shows_progress(tty):
    rc, text, first = _run(["benchmarks/nees_per_cycle.py", "--runs", "2", "--cases", "0,1"], tty)
    _check(rc, text, first, tty)
    assert "| gao_lawnmower | ellipse |" in text and "| gao_sea | ellipse |" in text


@pytest.mark.parametrize("tty", [True, False], ids=["terminal", "pipe"])
def test_horizon_vs_greedy_shows_progress(tty):
    rc, text, first = _run(
        ["benchmarks/horizon_vs_greedy.py", "--tasks", "gao_lawnmower", "--task", "lake", "--episodes", "2"], tty
    )
    _check(rc, text, first, tty)
    assert "| gao_lawnmower | lake |" in text


def test_a_bar_cut_short_by_an_exception_says_stopped_not_done(capsys, monkeypatch):
    """In line mode the last line says what happened: a ``with`` block that raised (Ctrl-C)
    before the total ends "stopped" (it said "done" after 19 of 120 episodes); one that
    finished its work, or left with its total reached, ends "done"."""
    from coopnav_env.progress import Progress

    monkeypatch.setenv("COOPNAV_PROGRESS", "lines")
    try:
        with Progress(120, unit="episode", desc="t", mode="lines") as bar:
            bar.update(19)
            raise KeyboardInterrupt
    except KeyboardInterrupt:
        pass
    with Progress(3, unit="episode", desc="t", mode="lines") as bar:
        bar.update(3)
    err = capsys.readouterr().err
    assert re.search(r"^\[19/120 episode, [^\]]*\] stopped$", err, flags=re.M), err
    assert re.search(r"^\[3/3 episode, [^\]]*\] done$", err, flags=re.M), err
