"""Keep numba's on-disk kernel cache consistent with the core's source.

numba (``cache=True``) invalidates a cached kernel when *its own* file changes, not
when a compiled function it calls from another module does: after editing, say,
``navigation.reinit_on_range``, the fusion kernels in ``measurements/`` would keep
running the old version from the cache. This stamps the cache with a hash of every
source file of ``coopnav_env.core`` and clears the core's cached kernels when the
hash changes. It runs once per process when ``coopnav_env.core`` is imported (a few
milliseconds); a fresh checkout has no cache and nothing to clear.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

CORE = Path(__file__).resolve().parent
STAMP = CORE / "__pycache__" / "numba-source.sha256"


def source_hash() -> str:
    h = hashlib.sha256()
    for path in sorted(CORE.rglob("*.py")):
        h.update(str(path.relative_to(CORE)).encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def clear_stale_kernels() -> bool:
    """Delete the core's cached numba kernels if the core's source changed since they
    were compiled; returns whether anything was cleared. Never raises (a read-only
    install simply keeps its cache)."""
    try:
        digest = source_hash()
        if STAMP.is_file() and STAMP.read_text().strip() == digest:
            return False
        cleared = False
        for pattern in ("*.nbi", "*.nbc"):
            for f in CORE.rglob(pattern):
                f.unlink(missing_ok=True)
                cleared = True
        STAMP.parent.mkdir(exist_ok=True)
        tmp = STAMP.with_name(f".{STAMP.name}.{os.getpid()}")
        tmp.write_text(digest + "\n")
        os.replace(tmp, STAMP)
        return cleared
    except OSError:
        return False
