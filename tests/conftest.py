"""Tests run quiet: no progress bars or stage lines (``coopnav_env.progress``) unless a
test asks for them (tests/test_progress.py sets COOPNAV_PROGRESS itself), so the
one-line error messages the tests check stay one line.

Ray reads its settings when it is first imported, and torchrl imports it (tests/test_benchmarl.py
ran before tests/test_rllib.py and left Ray without token authentication, so every RLlib test
failed to start its cluster): the loopback settings of test_rllib.py and test_safe_formats.py are
set here, before any test module is imported."""

import os

import pytest
from ray_loopback import LOOPBACK_ENV

for _k, _v in LOOPBACK_ENV.items():
    os.environ.setdefault(_k, _v)


@pytest.fixture(autouse=True)
def _quiet_progress(monkeypatch):
    monkeypatch.setenv("COOPNAV_PROGRESS", "off")
