"""What ``--resume`` keeps of an earlier run's episodes.csv and steps.csv
(``kept_rows``): an episode is kept when its episodes.csv row is well formed and
steps.csv holds exactly its ``steps`` rows (steps 1..n, well formed, finite); anything
else (a truncated or garbled file, a row cut short, a duplicate) is run again, and
said on stderr by the caller. Files written before the CSV floats were exact
(``outdir.FORMAT_VERSION``) are not kept at all: nothing is recomputed from rounded
text.
"""

from __future__ import annotations

import csv
import io
import math
import os
import re
from typing import TYPE_CHECKING

from .config import cell_id
from .outdir import FORMAT_VERSION, has_results
from .report import EPISODE_COLUMNS, STEP_COLUMNS, _fmt

if TYPE_CHECKING:
    from .config import Plan

_INT = re.compile(r"-?[0-9]+\Z")
EPISODE_INTS = (
    "steps",
    "ranges_fused",
    "outliers_rejected",
    "packets_lost",
    "safety_violations",
    "geofence_violations",
    "pings",
    "collisions",
)
STEP_FLOATS = (
    "t_s",
    "survey_error_m",
    "dr_error_m",
    "ellipse_major_m",
    "ellipse_minor_m",
    "reward",
    "beacon_distance_m",
)


class _Unreadable(Exception):
    pass


def _read_csv(path: str, columns: list):
    """(rows as lists of text, whether the last row ended with a newline); None if the
    file does not exist; _Unreadable if it is not CSV text with the header ``columns``."""
    try:
        with open(path, "rb") as f:
            data = f.read()
    except FileNotFoundError:
        return None
    try:
        text = data.decode("utf-8")
        if "\0" in text:
            raise _Unreadable("it holds NUL bytes")
        rows = list(csv.reader(io.StringIO(text, newline="")))
    except (UnicodeDecodeError, csv.Error) as err:
        raise _Unreadable(str(err).splitlines()[0] if str(err) else type(err).__name__) from None
    if not rows or rows[0] != list(columns):
        raise _Unreadable("its header is not this run's columns")
    return rows[1:], text.endswith("\n")


def _int(text):
    if not isinstance(text, str) or not _INT.match(text):
        raise ValueError(text)
    return int(text)


def _finite(text):
    v = float(text)
    if not math.isfinite(v):
        raise ValueError(text)
    return v


def _cell_text(value) -> str:
    return str(_fmt(value))


def kept_rows(out: str, plan: Plan) -> tuple:
    """(episode rows, step rows, notes) that ``resume`` keeps from ``out``: the episodes
    of ``plan`` whose episodes.csv row is well formed and whose steps.csv rows (steps 1..n,
    n its ``steps``) are all there and well formed; rows are dicts of the files' text.
    ``notes``: one line per reason episodes are run again."""
    notes: list[str] = []
    if plan.previous is None:
        return [], [], notes
    if plan.previous.get("format_version") != FORMAT_VERSION:
        if has_results(out):
            notes.append(
                f"the episodes in {out!r} were written with rounded numbers (an older evaluation); they are run again"
            )
        return [], [], notes
    ep_columns = EPISODE_COLUMNS[:1] + list(plan.sweep) + EPISODE_COLUMNS[1:]
    cells = {cell_id(c): c for c in plan.cells}
    policies = set(plan.policies)
    first, n_eps = plan.config.seed, plan.episodes
    frame = {cid: cfg.network == "moving_lbl" for cid, cfg in plan.configs.items()}

    def identity(r):  # (cell, policy, seed text) of a well-formed row, else ValueError
        if r["cell"] not in cells or r["policy"] not in policies:
            raise ValueError("cell/policy")
        seed, episode = _int(r["seed"]), _int(r["episode"])
        if not (first <= seed < first + n_eps) or episode != seed - first:
            raise ValueError("seed")
        return r["cell"], r["policy"], r["seed"]

    bad_files = []
    try:
        ep_read = _read_csv(os.path.join(out, "episodes.csv"), ep_columns)
    except _Unreadable as err:
        ep_read = None
        bad_files.append(f"episodes.csv is unreadable ({err})")
    try:
        st_read = _read_csv(os.path.join(out, "steps.csv"), STEP_COLUMNS)
    except _Unreadable as err:
        st_read = None
        bad_files.append(f"steps.csv is unreadable ({err})")

    episodes: dict = {}
    bad_eps, seen = 0, set()
    if ep_read is not None:
        rows, complete = ep_read
        for i, fields in enumerate(rows):
            try:
                if len(fields) != len(ep_columns) or (i == len(rows) - 1 and not complete):
                    raise ValueError("fields")
                r = dict(zip(ep_columns, fields))
                key = identity(r)
                cell = cells[r["cell"]]
                if any(r[k] != _cell_text(v) for k, v in cell.items()):
                    raise ValueError("cell values")
                if _int(r["steps"]) < 1:
                    raise ValueError("steps")
                for k in EPISODE_COLUMNS[4:]:
                    (_int if k in EPISODE_INTS else _finite)(r[k])
            except (ValueError, KeyError):
                bad_eps += 1
                continue
            if key in seen:  # twice: neither is trusted
                episodes.pop(key, None)
                bad_eps += 1
                continue
            seen.add(key)
            episodes[key] = r

    groups: dict = {}
    bad_groups = set()
    if st_read is not None:
        rows, complete = st_read
        for i, fields in enumerate(rows):
            key = None
            try:
                if len(fields) != len(STEP_COLUMNS):
                    raise ValueError("fields")
                r = dict(zip(STEP_COLUMNS, fields))
                key = identity(r)
                if i == len(rows) - 1 and not complete:
                    raise ValueError("cut")
                _int(r["step"])
                for k in STEP_FLOATS:
                    _finite(r[k])
                for k in ("error_x_m", "error_y_m"):
                    if frame[r["cell"]]:
                        _finite(r[k])
                    elif r[k] != "":
                        raise ValueError(k)
            except (ValueError, KeyError):
                if key is not None:
                    bad_groups.add(key)
                continue
            groups.setdefault(key, []).append(r)

    kept = []
    short = unreadable_steps = 0
    for key, r in episodes.items():
        g = groups.get(key, [])
        if key in bad_groups:
            unreadable_steps += 1
            continue
        if [x["step"] for x in g] != [str(k) for k in range(1, int(r["steps"]) + 1)]:
            short += 1
            continue
        kept.append((r, g))
    from . import checksums

    kept, checksum_notes = checksums.verify(out, kept, ep_columns)  # a changed row: UsageError
    ep_rows = [r for r, _ in kept]
    step_rows = [x for _, g in kept for x in g]
    notes += [f"{text}: its episodes are run again" for text in bad_files]
    if bad_eps:
        notes.append(f"{bad_eps} row(s) of episodes.csv are malformed: those episodes are run again")
    if unreadable_steps:
        notes.append(f"{unreadable_steps} episode(s) have malformed rows in steps.csv: they are run again")
    if short:
        notes.append(f"{short} episode(s) do not have all their steps in steps.csv (truncated?): they are run again")
    return ep_rows, step_rows, notes + checksum_notes
