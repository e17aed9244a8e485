"""Optional extras in the tests: skipped where the extra is not installed, a failure under CI.

.ci/run installs every extra the tests use (``[test,rllib,marl,docs]``) and sets ``CI``, so there
a missing module is a broken install, not a reason to skip. (A helper module, not conftest.py:
import it as ``from optional import require``.)
"""

from __future__ import annotations

import importlib
import os
from types import ModuleType

import pytest

# top-level module -> the pyproject extra that installs it
EXTRAS = {"ray": "rllib", "torchrl": "marl", "tensordict": "marl", "benchmarl": "marl"}


def under_ci() -> bool:
    """CI is set to anything but an explicit no (CI=false, CI=0 or empty: a local run)."""
    return os.environ.get("CI", "").strip().lower() not in ("", "0", "false", "no")


def require(module: str) -> ModuleType:
    """Import module (e.g. "ray.rllib"); if it is missing, skip the test, or fail it under CI."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        extra = EXTRAS.get(module.split(".")[0])
        hint = f' (pip install -e ".[{extra}]")' if extra else ""
        if under_ci():
            pytest.fail(f"{module} is not importable under CI, which installs it{hint}: {exc}", pytrace=False)
        pytest.skip(f"{module} is not installed{hint}: {exc}")
