#!/usr/bin/env python
"""Evaluate policies on a coopnav scenario: the command-line front end of the
``evaluation`` package (the same as the installed ``coopnav-evaluate``).

    python evaluate.py --scenario sousa_asv --policies fim_a,fim_b,ellipse,circle,static \\
        --episodes 50 --seed 0 --out results/sousa
    python evaluate.py --help

The outputs, the options and the Python API (``evaluation.EvalConfig``,
``evaluation.run_evaluation``) are documented in ``evaluation/__init__.py``.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

from evaluation.cli import main as _main

# names other modules imported from this script before the package existed; new code
# imports them from evaluation.* directly
from evaluation.config import UsageError, split_top_level  # noqa: F401
from evaluation.episodes import run_episodes  # noqa: F401


def main(argv: Sequence[str] | None = None) -> int:
    """``python evaluate.py ARGS``; returns the exit status (2: bad input)."""
    return _main(argv, prog="evaluate.py")


if __name__ == "__main__":
    sys.exit(main())
