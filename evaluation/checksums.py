"""Checksums of the episodes an evaluation keeps, so ``--resume`` never builds a
summary on rows that changed after they were written.

``checksums.json`` (written atomically beside episodes.csv, after steps.csv and
before episodes.csv, at every batch) maps each episode ("cell|policy|seed") to the
SHA-256 of its episodes.csv row and its steps.csv rows, as CSV text. On resume, an
episode whose rows are well formed but do not match its checksum (a flipped digit,
an edited value) is refused: a ``UsageError`` of one line naming it, exit status 2,
nothing changed. An episode with no checksum (checksums.json missing, or written
by an older version) is run again, said on stderr: nothing unverified is kept.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Mapping, Sequence
from typing import Any

from coopnav_env.records import atomic_write_text, strict_json

from .errors import UsageError

FILE = "checksums.json"
FORMAT = "coopnav-episode-sha256"
MAX_BYTES = 2 << 30  # about 100 bytes per episode: evaluation.limits.MAX_TOTAL_EPISODES fit

__all__ = ["FILE", "digest", "key", "read", "verify", "write"]


def key(r: Mapping[str, Any]) -> str:
    return f"{r['cell']}|{r['policy']}|{r['seed']}"


def digest(ep_row: dict, step_rows: list, ep_columns: Sequence[str]) -> str:
    """SHA-256 of one episode's rows as the CSV files hold them."""
    from .report import STEP_COLUMNS, csv_text

    h = hashlib.sha256()
    h.update(csv_text(ep_columns, [ep_row]).split("\n", 1)[1].encode("utf-8"))
    h.update(csv_text(STEP_COLUMNS, step_rows).split("\n", 1)[1].encode("utf-8"))
    return h.hexdigest()


def write(out: str, digests: dict) -> None:
    atomic_write_text(os.path.join(out, FILE), strict_json({"format": FORMAT, "episodes": digests}))


def read(out: str) -> dict | None:
    """{episode key: sha256} of ``out`` (None: no usable checksums.json)."""
    from coopnav_env.safe_load import read_json

    try:
        rec = read_json(os.path.join(out, FILE), max_bytes=MAX_BYTES)
    except ValueError:
        return None
    if not isinstance(rec, dict) or rec.get("format") != FORMAT or not isinstance(rec.get("episodes"), dict):
        return None
    return {str(k): v for k, v in rec["episodes"].items() if isinstance(v, str)}


def verify(out: str, kept: list, ep_columns: Sequence[str]) -> tuple:
    """``kept``: [(episode row, its step rows)] that passed the format checks. Returns
    (the verified ones, notes); a ``UsageError`` if one does not match its checksum."""
    recorded = read(out)
    if not kept:
        return [], []
    if recorded is None:
        return [], [
            (
                f"{FILE} is missing or unreadable in {out!r}: the {len(kept)} episode(s) there cannot be "
                "verified and are run again"
            )
        ]
    good, unknown = [], 0
    for ep, steps in kept:
        want = recorded.get(key(ep))
        if want is None:
            unknown += 1
            continue
        if digest(ep, steps, ep_columns) != want:
            cell = f" in cell {ep['cell']}" if ep["cell"] else ""
            raise UsageError(
                f"cannot resume: episode {ep['episode']} (seed {ep['seed']}) of policy {ep['policy']!r}"
                f"{cell} in {out!r} does not match its checksum in {FILE} (episodes.csv or steps.csv "
                "changed after it was written); use --overwrite to run it again, or another --out"
            )
        good.append((ep, steps))
    notes = [f"{unknown} episode(s) have no checksum in {FILE}: they are run again"] if unknown else []
    return good, notes
