"""Keep every read of a run folder inside that folder.

A run folder someone sends you can hold symbolic links: ``checkpoints -> /``,
``best_model.safetensors -> /home/you/other_run/model.safetensors``,
``policy_export -> ../elsewhere``, or a file inside ``checkpoints/`` pointing at
``/etc/passwd``. Following them would load (or, in ``agents.convert``, copy into the
output) files from outside the folder the user named. So:

* ``check_tree(root)`` walks ``root`` without following links and refuses any
  symbolic link whose target (resolved) leaves ``root`` (links that stay inside are
  fine); it also bounds the walk (``MAX_ENTRIES``);
* ``inside(root, path)`` resolves ``path`` (relative to ``root`` unless absolute) and
  refuses it if it leaves ``root``.

Both raise ``agents.PolicyFormatError`` (a ``ValueError``) with one line naming the path.
"""

from __future__ import annotations

import os
from pathlib import Path

from .formats import PolicyFormatError

MAX_ENTRIES = 100_000  # files and folders a run folder may hold (a long run's tb/ holds a few hundred)

__all__ = ["MAX_ENTRIES", "check_tree", "inside"]


def _within(base: Path, target: Path) -> bool:
    return target == base or base in target.parents


def inside(root: str | os.PathLike[str], path: str | os.PathLike[str], what: str = "file") -> Path:
    """``path`` resolved; a ``PolicyFormatError`` if it (or a link on its way) leaves ``root``."""
    base = Path(root).resolve()
    p = Path(path)
    target = (Path(root) / p if not p.is_absolute() else p).resolve()
    if not _within(base, target):
        link = " (a symbolic link)" if _any_link(Path(root), p) else ""
        raise PolicyFormatError(
            f"{what} {str(path)!r}{link} leads outside the run folder {root} (to {target}): refused"
        )
    return target


def _any_link(root: Path, p: Path) -> bool:
    q = root / p if not p.is_absolute() else p
    for part in [q, *q.parents]:
        try:
            if part.is_symlink():
                return True
        except OSError:
            return False
        if part == root:
            break
    return False


def check_tree(root: str | os.PathLike[str], what: str = "run folder") -> Path:
    """``root`` resolved, after refusing every symbolic link under it that leads outside
    it (a ``PolicyFormatError`` naming the first); ``root`` itself may be a link."""
    root = Path(root)
    base = root.resolve()
    if not base.is_dir():
        return base
    seen = 0
    for dirpath, dirnames, filenames in os.walk(base, followlinks=False):
        seen += len(dirnames) + len(filenames)
        if seen > MAX_ENTRIES:
            raise PolicyFormatError(f"{root} holds more than {MAX_ENTRIES} files and folders: refused as a {what}")
        for name in dirnames + filenames:
            entry = Path(dirpath) / name
            if entry.is_symlink():
                try:
                    target = entry.resolve(strict=False)
                except (OSError, RuntimeError):  # a loop of links
                    raise PolicyFormatError(f"{entry} is a symbolic link that cannot be resolved: refused") from None
                if not _within(base, target):
                    shown = root / entry.relative_to(base)
                    raise PolicyFormatError(
                        f"{shown} is a symbolic link to {target}, outside the {what} {root}: "
                        "refused (copy the file in instead)"
                    )
    return base
