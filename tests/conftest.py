"""Tests run quiet: no progress bars or stage lines (``coopnav_env.progress``) unless a
test asks for them (tests/test_progress.py sets COOPNAV_PROGRESS itself), so the
one-line error messages the tests check stay one line."""

import pytest


@pytest.fixture(autouse=True)
def _quiet_progress(monkeypatch):
    monkeypatch.setenv("COOPNAV_PROGRESS", "off")
