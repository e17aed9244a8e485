"""Files a run leaves behind: atomic writes, JSON/YAML reads, strict JSON, version records.

One home for what the trainers and the evaluation both write. Every output file is
written to a temporary file in the same directory, flushed to disk and renamed into
place (``os.replace``), so an interrupted run never leaves a half-written file and a
reader never sees one.

    from coopnav_env.records import atomic_write_text, version_record
    atomic_write_text("runs/x/run.json", strict_json({"versions": version_record()}))
"""

from __future__ import annotations

import json
import math
import os
import platform
import subprocess
import tempfile
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

# the checkout this package was imported from (where `git rev-parse` is asked)
PROJECT_ROOT = Path(__file__).resolve().parent.parent


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` atomically: a temporary file beside it (same
    filesystem; its folder made if missing), fsync, then ``os.replace``. The file gets the
    umask's permissions (mkstemp's 0600 would otherwise leak through). On any error, including Ctrl-C,
    the temporary file is removed and ``path`` keeps its old content."""
    path = os.fspath(path)
    directory = os.path.dirname(os.path.abspath(path))
    os.makedirs(directory, exist_ok=True)  # a table asked for in a folder not made yet
    fd, tmp = tempfile.mkstemp(dir=directory, prefix="." + os.path.basename(path) + ".", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def check_writable(out: str | os.PathLike[str]) -> None:
    """An ``OSError`` (one line) if nothing can be written at ``out``, a folder to be created
    or filled: a temporary file is made and removed in ``out`` or its nearest existing parent.
    Commands call it before building anything, so a folder they cannot write is refused at
    once, not after minutes of compiling or training."""
    target = os.path.abspath(os.fspath(out))
    probe = target
    while not os.path.exists(probe):
        parent = os.path.dirname(probe)
        if parent == probe:  # a root that does not exist (a missing drive or share)
            raise OSError(f"{os.fspath(out)}: {probe} does not exist")
        probe = parent
    if not os.path.isdir(probe):
        where = "is a file" if probe == target else f"lies under a file ({probe})"
        raise OSError(f"{os.fspath(out)} {where}, not a folder")
    try:
        fd, tmp = tempfile.mkstemp(dir=probe, prefix=".coopnav-write-check.", suffix=".tmp")
    except OSError as err:
        raise OSError(f"cannot write in {probe} ({err.strerror or err}), where {os.fspath(out)} would go") from None
    os.close(fd)
    os.unlink(tmp)


def check_output_file(path: str | os.PathLike[str], overwrite: bool = False) -> None:
    """An ``OSError`` (one line) if the file ``path`` cannot be written: it is a folder, it
    exists and ``overwrite`` is false (a table or figure is not replaced silently: the
    scripts' ``--overwrite``), or nothing can be written where it would go (``check_writable``
    of its folder). Scripts call it before their runs, so a table's path is refused at once,
    not after the runs."""
    target = os.path.abspath(os.fspath(path))
    if os.path.isdir(target):
        raise OSError(f"{os.fspath(path)} is a folder, not a file")
    if os.path.lexists(target) and not overwrite:
        raise OSError(f"{os.fspath(path)} exists; pass --overwrite to replace it")
    check_writable(os.path.dirname(target))


def check_output_args(
    error: Callable[[str], Any], overwrite: bool = False, **files: str | os.PathLike[str] | None
) -> None:
    """``check_output_file`` of each given file flag (``markdown=args.markdown``; None: not
    given), reporting the first that cannot be written through ``error`` (argparse's
    ``parser.error``: one line, exit 2) as ``--markdown: ...``; an existing file is refused
    unless ``overwrite`` (the script's ``--overwrite``). The measurement scripts call it right
    after parsing, before any run."""
    for name, path in files.items():
        if path is not None:
            try:
                check_output_file(path, overwrite=overwrite)
            except OSError as err:
                error(f"--{name.replace('_', '-')}: {err}")


def atomic_write_text(path: str | os.PathLike[str], text: str) -> None:
    """``atomic_write_bytes`` of ``text`` encoded as UTF-8."""
    atomic_write_bytes(path, text.encode("utf-8"))


def atomic_append_line(path: str | os.PathLike[str], line: str) -> None:
    """Append ``line`` (and a newline) to a text file atomically: the old content plus
    the line is written beside it and renamed into place (``atomic_write_bytes``), so
    a full disk or a kill leaves the file as it was, never a line cut short."""
    try:
        with open(path, "rb") as f:
            old = f.read()
    except FileNotFoundError:
        old = b""
    if old and not old.endswith(b"\n"):
        old += b"\n"
    atomic_write_bytes(path, old + line.rstrip("\n").encode("utf-8") + b"\n")


def read_json(path: str | os.PathLike[str]) -> Any:
    """The parsed content of a JSON file, or None if the file does not exist. Bounded
    in size and depth (``coopnav_env.safe_load``: a ``ValueError`` of one line else)."""
    from .safe_load import read_json as _read_json

    return _read_json(path)


def read_yaml(path: str | os.PathLike[str]) -> Any:
    """The parsed content of a YAML file (safe loader; no aliases, bounded size and
    depth: ``coopnav_env.safe_load``), or None if it does not exist."""
    from .safe_load import read_yaml as _read_yaml

    return _read_yaml(path)


def plain(obj: Any) -> Any:
    """Tuples -> lists and numpy scalars -> Python numbers, recursively (for
    ``yaml.safe_dump`` and ``json.dumps``)."""
    if isinstance(obj, dict):
        return {k: plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [plain(v) for v in obj]
    if hasattr(obj, "item") and callable(obj.item) and getattr(obj, "shape", None) == ():
        return obj.item()
    return obj


def _first_non_finite(obj, where="") -> str | None:
    if isinstance(obj, float) and not math.isfinite(obj):
        return where or "the value"
    if isinstance(obj, dict):
        for k, v in obj.items():
            found = _first_non_finite(v, f"{where}.{k}" if where else str(k))
            if found:
                return found
    if isinstance(obj, (list, tuple)):
        for i, v in enumerate(obj):
            found = _first_non_finite(v, f"{where}[{i}]")
            if found:
                return found
    return None


def strict_json(obj: Any, indent: int | None = 2) -> str:
    """``obj`` as standard JSON text (with a final newline). NaN and infinities are not
    JSON: they raise ``ValueError`` naming where they are (e.g. ``policies.fim_a.mean_error_m``)."""
    obj = plain(obj)
    bad = _first_non_finite(obj)
    if bad is not None:
        raise ValueError(f"not finite, cannot be written as JSON: {bad}")
    return json.dumps(obj, indent=indent, allow_nan=False) + "\n"


def _git(*args) -> str:
    try:
        return subprocess.run(
            ["git", *args], cwd=PROJECT_ROOT, capture_output=True, text=True, timeout=10
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""


def version_record(
    packages: Iterable[str] = (
        "numpy",
        "scipy",
        "numba",
        "gymnasium",
        "pettingzoo",
        "torch",
        "stable_baselines3",
        "filterpy",
    ),
) -> dict:
    """What produced a result: Python, the given packages' versions (those that are
    installed; imported lazily, only their metadata is read), coopnav's version, and
    the git commit of the checkout (``git_dirty``: tracked files were modified)."""
    from importlib import metadata

    out: dict[str, Any] = {"python": platform.python_version()}
    names = {"stable_baselines3": "stable-baselines3"}
    for name in ("coopnav",) + tuple(packages):
        try:
            out[name] = metadata.version(names.get(name, name))
        except metadata.PackageNotFoundError:
            continue
    commit = _git("rev-parse", "HEAD") or None
    out["git_commit"] = commit
    out["git_dirty"] = bool(_git("status", "--porcelain", "--untracked-files=no")) if commit else None
    return out
