"""One trainer per run folder: a lock on ``--out`` (and ``--resume``) for the whole run.

Two ``train.py`` processes on one folder (two new runs, or two ``--resume``) would both
write its checkpoints and interleave its ``evaluations.jsonl``. The lock is an
exclusive ``flock`` on the folder itself (no lock file: a refused run changes
nothing in the folder), held by this process until it ends or ``release_all``;
``.train.owner.json`` says who holds it (pid, host, start, command) once the
run starts writing, and is removed when it ends.

    hold(out)          # the folder exists: lock it now (ConfigError if another run holds it)
    claim(out, new)    # where a trainer creates/writes the folder: create, lock, write the owner file
    release_all()      # at the end of the command
"""

from __future__ import annotations

import json
import os
import socket
import time
from collections.abc import Callable
from pathlib import Path
from typing import ParamSpec, TypeVar

from .config import ConfigError

_P = ParamSpec("_P")
_R = TypeVar("_R")

OWNER_FILE = ".train.owner.json"
_HELD: dict = {}  # resolved folder -> (fd, owner file written)

__all__ = ["OWNER_FILE", "check_not_in_use", "claim", "hold", "release_all", "releasing"]


def _owner_text(out: Path) -> str:
    try:
        rec = json.loads((out / OWNER_FILE).read_text()[:4096])
    except (OSError, ValueError):
        return ""
    if not isinstance(rec, dict) or "pid" not in rec:
        return ""
    return f" (pid {rec.get('pid')} on {rec.get('host')}, started {rec.get('started')}: {rec.get('command')})"


def _flock(out: Path):
    """An fd of ``out`` holding an exclusive flock; ConfigError if another process holds it."""
    import fcntl

    try:
        fd = os.open(out, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    except OSError as err:
        raise ConfigError(f"cannot open run folder {out}: {err.strerror or err}") from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        raise ConfigError(
            f"{out} is in use by another train.py run{_owner_text(out)}; wait for it to end or use another --out"
        ) from None
    except OSError as err:
        os.close(fd)
        raise ConfigError(f"cannot lock run folder {out}: {err.strerror or err}") from None
    return fd


def check_not_in_use(out: str | Path) -> None:
    """ConfigError if another process holds the folder ``out`` (which may not exist)."""
    out = Path(out)
    if not out.is_dir() or str(out.resolve()) in _HELD:
        return
    fd = _flock(out)
    import fcntl

    fcntl.flock(fd, fcntl.LOCK_UN)
    os.close(fd)


def hold(out: str | Path) -> None:
    """Lock the existing folder ``out`` for this process (no file written)."""
    out = Path(out)
    key = str(out.resolve())
    if key not in _HELD:
        _HELD[key] = [_flock(out), False]


def claim(out: str | Path, new: bool, command: str | None = None) -> None:
    """Create ``out`` if needed, lock it (if not held yet) and write the owner file. A
    new run's folder must still be empty (apart from the owner file) once locked."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    hold(out)
    entry = _HELD[str(out.resolve())]
    if new and any(p.name != OWNER_FILE for p in out.iterdir()):
        raise ConfigError(f"{out} exists and is not empty (another run wrote into it); use another --out")
    if not entry[1]:
        from coopnav_env.records import atomic_write_text

        atomic_write_text(
            out / OWNER_FILE,
            json.dumps(
                {
                    "pid": os.getpid(),
                    "host": socket.gethostname(),
                    "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
                    "command": command or f"agents.training (Python API, pid {os.getpid()})",
                }
            ),
        )
        entry[1] = True


def releasing(train: Callable[_P, _R]) -> Callable[_P, _R]:
    """Decorate a trainer: the folders it locked itself (``claim`` of a new ``--out``)
    are released when it returns, those held before (``hold`` by the command line)
    stay held until ``release_all``."""
    import functools

    @functools.wraps(train)
    def wrapper(*args: _P.args, **kwargs: _P.kwargs) -> _R:
        before = set(_HELD)
        try:
            return train(*args, **kwargs)
        finally:
            _release([k for k in _HELD if k not in before])

    return wrapper


def release_all() -> None:
    """Remove the owner files this process wrote and release its locks."""
    _release(list(_HELD))


def _release(keys) -> None:
    import fcntl

    for key in keys:
        fd, wrote = _HELD[key]
        if wrote:
            try:
                os.unlink(os.path.join(key, OWNER_FILE))
            except OSError:
                pass
        try:
            fcntl.flock(fd, fcntl.LOCK_UN)
        finally:
            os.close(fd)
        del _HELD[key]
