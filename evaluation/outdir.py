"""The output directory of an evaluation: one run owns it at a time, an earlier result is
neither replaced nor mixed with another run's by accident, and ``--resume`` keeps only
episodes that are complete and exact.

* ``OutputLock``: a lock on ``out`` (``filelock``, the file ``.evaluate.lock``) held for
  the whole run, with ``.evaluate.owner.json`` saying who holds it (pid, host, start,
  command); a second writer is refused with a one-line ``UsageError`` naming the first.
* ``check_existing``: ``out`` holding an earlier result needs ``resume`` (same
  scenario, ``--set``, ``--sweep`` and ``--seed``, checked against its run.json) or
  ``overwrite`` (``clear`` removes the earlier files).
* what ``resume`` keeps of the CSV files: ``evaluation.resume.kept_rows``.

The CSV floats are written exactly (``repr``: they read back to the same float), so the
statistics of a resumed run are those of an uninterrupted one; run.json's
``format_version`` says so (files without it were rounded to 6 digits: their episodes
are run again).
"""

from __future__ import annotations

import os
import socket
import time
from typing import Any

from coopnav_env.records import atomic_write_text, read_json, strict_json

from .errors import UsageError
from .limits import MAX_EPISODES

FORMAT_VERSION = 3  # 3: + pings, collisions, energy_J; 2: CSV floats written with repr (exact); 1 (absent): rounded
RESULT_FILES = ("run.json", "episodes.csv", "steps.csv", "checksums.json", "summary.json", "summary.md")
BENCHMARK_RESULT_FILES = ("results.json", "results.md")  # a benchmark's (evaluation.benchmark_report)
SUMMARY_FILES = ("summary.json", "summary.md")
FIGURE_FILES = ("paths.png", "error_vs_time.png", "ellipse_axes.png", "frame_errors.png", "sweep.png")
LOCK_FILE = ".evaluate.lock"
OWNER_FILE = ".evaluate.owner.json"
_DATA_FILES = ("run.json", "episodes.csv", "steps.csv", "summary.json")  # any of them: out holds a result


# ------------------------------------------------------------------------------------
# what out holds


def has_results(out: str) -> bool:
    """Whether ``out`` holds (part of) an evaluation's result."""
    return any(os.path.exists(os.path.join(out, name)) for name in _DATA_FILES)


def other_result(out: str) -> str | None:
    """What else ``out`` holds that an evaluation must not write beside (or, with
    ``--overwrite``, half replace): a benchmark's result, or a ``train.py`` run. None:
    nothing of the kind."""
    held = [f for f in BENCHMARK_RESULT_FILES if os.path.exists(os.path.join(out, f))]
    if held:
        return f"a benchmark result ({', '.join(held)})"
    if is_training_run(out):
        return "a train.py run (config.yml); evaluate its policy with --policies " + out
    return None


def is_training_run(out: str) -> bool:
    """Whether ``out`` holds a ``train.py`` run: its config.yml beside a model, its
    checkpoints or its trainer's lock record."""
    return os.path.exists(os.path.join(out, "config.yml")) and any(
        os.path.exists(os.path.join(out, f)) for f in ("model.safetensors", "checkpoints", ".train.owner.json")
    )


def snapshot(out: str) -> tuple:
    """What ``out`` holds, to notice a change between the checks and the lock: which
    result files exist, and run.json's bytes."""
    exists = tuple(os.path.exists(os.path.join(out, name)) for name in _DATA_FILES)
    try:
        with open(os.path.join(out, "run.json"), "rb") as f:
            run = f.read()
    except OSError:
        run = None
    return exists, run


def _is_record(rec) -> str | None:
    """What is wrong with a run.json record (None: nothing)."""
    if not isinstance(rec, dict):
        return "not a JSON object"
    checks = {
        "scenario": lambda v: isinstance(v, str),
        "overrides": lambda v: isinstance(v, dict),
        "sweep": lambda v: isinstance(v, dict),
        "seed": lambda v: isinstance(v, int) and not isinstance(v, bool) and v >= 0,
        "episodes": lambda v: isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= MAX_EPISODES,
        "policies": lambda v: (
            isinstance(v, list) and v and all(isinstance(p, str) for p in v) and len(set(v)) == len(v)
        ),
    }
    for key, ok in checks.items():
        if key not in rec or not ok(rec[key]):
            return f"no valid {key!r}"
    return None


def read_previous(out: str) -> dict | None:
    """run.json of the earlier run in ``out`` (None: ``out`` holds no result). A result
    without a readable run.json cannot be checked against the arguments: UsageError."""
    path = os.path.join(out, "run.json")
    if not os.path.exists(path):
        if has_results(out):
            raise UsageError(
                f"cannot resume: {out!r} holds evaluation files but no run.json to check them against; "
                "use --overwrite to replace them, or another --out"
            )
        return None
    try:
        rec = read_json(path)
        problem = _is_record(rec)
    except (OSError, ValueError) as err:
        problem = f"not JSON: {str(err).splitlines()[0] if str(err) else type(err).__name__}"
    if problem is not None:
        raise UsageError(
            f"cannot resume: {path} is unreadable ({problem}); use --overwrite to replace the result, or another --out"
        )
    return rec


def describe(out: str) -> str:
    """A few words on the result in ``out``, for messages."""
    finished = os.path.exists(os.path.join(out, "summary.json"))
    what = "a finished evaluation" if finished else "an unfinished evaluation"
    try:
        rec = read_json(os.path.join(out, "run.json"))
    except (OSError, ValueError):
        rec = None
    if _is_record(rec) is None:
        what += f" ({rec['scenario']}, {rec['episodes']} episode(s) of {', '.join(rec['policies'])})"
    return what


def _text(key, value) -> str:
    if key in ("overrides", "sweep"):
        if not value:
            return "none"
        return " ".join(f"{k}={','.join(map(str, v)) if key == 'sweep' else v}" for k, v in value.items())
    return str(value)


def check_existing(config: Any, run_info: dict, previous: dict | None, trained: dict) -> None:
    """Refuse (UsageError) to write into ``config.out`` over an earlier result without
    ``resume`` or ``overwrite``, or to resume a run of other arguments. ``config``: the
    ``EvalConfig`` (typed Any: importing evaluation.config here, even for the type
    checker, would be an import cycle, which tests/test_contract refuses)."""
    out = config.out
    if config.overwrite or not has_results(out):
        return
    if not config.resume:
        raise UsageError(
            f"{out!r} already holds {describe(out)}; use --resume to keep its episodes and run the "
            "missing ones, --overwrite to replace it, or another --out"
        )
    assert previous is not None  # read_previous: None only when out holds no result
    for key, option in (("scenario", "--scenario"), ("seed", "--seed"), ("overrides", "--set"), ("sweep", "--sweep")):
        old, new = previous[key], run_info[key]  # _is_record: run.json has every key
        same = list(old.items()) == list(new.items()) if key == "sweep" else old == new
        if not same:
            raise UsageError(
                f"cannot resume: {out!r} holds a run with {option} {_text(key, old)}, not "
                f"{_text(key, new)} (--resume keeps --scenario, --seed, --set and --sweep; use "
                "--overwrite or another --out)"
            )
    earlier = previous.get("trained_policies") or {}
    for name, now in trained.items():
        then = earlier.get(name) if isinstance(earlier, dict) else None
        if isinstance(then, dict) and then.get("model") != now["model"]:
            raise UsageError(
                f"cannot resume: policy {name!r} was {then.get('model')} in {out!r}, now resolves to "
                f"{now['model']}; use --overwrite or another --out"
            )


def clear(out: str) -> list:
    """Remove an earlier result from ``out`` (``--overwrite``): its data files, summaries,
    figures and temporary files left by a killed run. Returns the names removed."""
    removed = []
    ours = RESULT_FILES + FIGURE_FILES
    for name in os.listdir(out):
        stale_tmp = name.endswith(".tmp") and any(name.startswith("." + f + ".") for f in ours)
        if name in ours or stale_tmp:
            os.unlink(os.path.join(out, name))
            removed.append(name)
    return removed


def remove_summaries(out: str) -> None:
    """Remove summary.json and summary.md: present only while they match the CSV files."""
    for name in SUMMARY_FILES:
        try:
            os.unlink(os.path.join(out, name))
        except FileNotFoundError:
            pass


# ------------------------------------------------------------------------------------
# the lock


def check_not_in_use(out: str) -> None:
    """UsageError if another run holds ``out`` (checked before anything else about it;
    the lock is taken, for the run, by ``OutputLock``)."""
    from filelock import FileLock, Timeout

    if not os.path.exists(os.path.join(out, LOCK_FILE)):
        return
    lock = FileLock(os.path.join(out, LOCK_FILE))
    try:
        lock.acquire(timeout=0)
    except Timeout:
        raise UsageError(
            f"{out!r} is in use by another evaluation ({OutputLock(out).owner_text()}); wait for it "
            "to end or use another --out"
        ) from None
    except OSError:
        return  # not lockable: OutputLock says why
    lock.release()


class OutputLock:
    """Hold ``out`` for one run: ``with OutputLock(out, command): ...``. Creates ``out``;
    a second holder gets a UsageError naming the first (from its owner file)."""

    def __init__(self, out: str, command: str | None = None) -> None:
        self.out, self.command = out, command
        self.lock: Any = None

    def owner_text(self) -> str:
        try:
            rec = read_json(os.path.join(self.out, OWNER_FILE)) or {}
        except (OSError, ValueError):
            rec = {}
        if not isinstance(rec, dict) or "pid" not in rec:
            return "owner unknown"
        text = f"pid {rec.get('pid')} on {rec.get('host')}, started {rec.get('started')}"
        if rec.get("command"):
            text += f": {rec['command']}"
        return text

    def __enter__(self):
        from filelock import FileLock, Timeout

        try:
            os.makedirs(self.out, exist_ok=True)
        except OSError as err:
            raise UsageError(f"cannot create output directory {self.out!r}: {err.strerror}") from None
        lock = FileLock(os.path.join(self.out, LOCK_FILE))
        try:
            lock.acquire(timeout=0)
        except Timeout:
            raise UsageError(
                f"{self.out!r} is in use by another evaluation ({self.owner_text()}); wait for it "
                "to end or use another --out"
            ) from None
        except OSError as err:
            raise UsageError(f"cannot lock output directory {self.out!r}: {err.strerror or err}") from None
        self.lock = lock
        try:
            atomic_write_text(
                os.path.join(self.out, OWNER_FILE),
                strict_json(
                    {
                        "pid": os.getpid(),
                        "host": socket.gethostname(),
                        "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
                        "command": self.command or f"evaluation.evaluate (Python API, pid {os.getpid()})",
                    }
                ),
            )
        except BaseException:
            lock.release()
            raise
        return self

    def __exit__(self, *exc):
        try:
            os.unlink(os.path.join(self.out, OWNER_FILE))
        except OSError:
            pass
        self.lock.release()
        return False
