"""One line for the failures of the machine rather than of the input: a full disk, a
read-only folder, no memory left. Every file is written atomically
(``coopnav_env.records.atomic_write_bytes``), so such a failure leaves the earlier
content in place and no half-written file; the command says what happened in one
line and exits with status 2."""

from __future__ import annotations

import errno

__all__ = ["MACHINE_FAILURES", "one_line"]

#: What a command catches as the machine's failure (one line, exit status 2) rather than a bug:
#: a full disk, a read-only folder, a lost worker (OSError), no memory left, a size that
#: overflows an allocation. One home, so every command line catches the same set.
MACHINE_FAILURES: tuple[type[BaseException], ...] = (OSError, MemoryError, OverflowError)

_WHAT: dict[int | None, str] = {
    errno.ENOSPC: "the disk is full",
    errno.EROFS: "the folder is on a read-only file system",
    errno.EDQUOT: "the disk quota is exceeded",
    errno.EACCES: "permission denied",
    errno.EPERM: "permission denied",
}


def one_line(err: BaseException) -> str:
    """``err`` (an OSError, MemoryError, OverflowError, ...) as one line."""
    if isinstance(err, MemoryError):
        return "out of memory (MemoryError): nothing more was written; use smaller settings"
    if isinstance(err, OSError) and err.errno is None and err.strerror is None and str(err):
        return " ".join(str(err).split())  # raised by this project with its own sentence (a lost worker)
    if isinstance(err, OSError):
        what = _WHAT.get(err.errno, err.strerror or type(err).__name__)
        where = f" writing {err.filename}" if err.filename else ""
        return f"{what}{where} ({err.strerror or err}): the files written before are intact, none is half-written"
    text = " ".join(str(err).split())
    return f"{type(err).__name__}: {text}" if text else type(err).__name__
