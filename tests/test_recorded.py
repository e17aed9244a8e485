"""Every scenario's recorded episodes replay: the guard for refactors of the core.

``tests/data/record_all_scenarios.py`` recorded short episodes of every registered
scenario (defaults and a variant that reaches the branches the defaults leave off).
On the machine that recorded them the replay is equal bit for bit; set
``COOPNAV_BITWISE=1`` to demand that (a refactor must pass it there). Across machines
numpy and numba pick SIMD code by CPU (AVX2 and AVX-512 ``sin``/``cos``/``exp`` differ by
an ulp or two), so by default each array must agree within ``RTOL`` of its largest
magnitude (measured: at most 2e-13 between two
machines' recordings; docs/reliability.md#reproducibility).
"""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).resolve().parent / "data"


def _recorder():
    spec = importlib.util.spec_from_file_location("record_all_scenarios", DATA / "record_all_scenarios.py")
    rec = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(rec)
    return rec


def close_enough(ref: np.ndarray, new: np.ndarray, rtol: float) -> bool:
    """Equal shapes and dtypes; booleans and integers equal; floats within ``rtol`` of
    the reference array's largest finite magnitude, NaN where the reference has NaN."""
    if ref.shape != new.shape or ref.dtype != new.dtype:
        return False
    if ref.dtype.kind not in "fc":
        return bool(np.array_equal(ref, new))
    nan = np.isnan(ref)
    if not np.array_equal(nan, np.isnan(new)):
        return False
    finite = ref[~nan]
    scale = float(np.max(np.abs(finite))) if finite.size else 0.0
    return bool(np.all(np.abs(ref[~nan] - new[~nan]) <= rtol * max(scale, 1e-300)))


def test_close_enough_is_strict_where_it_must_be():
    a = np.array([1.0, 2.0, np.nan])
    assert close_enough(a, a.copy(), 0.0)
    assert close_enough(a, a + np.array([1e-12, 0, 0]), 1e-9)
    assert not close_enough(a, a + np.array([1e-6, 0, 0]), 1e-9)
    assert not close_enough(a, np.array([1.0, 2.0, 3.0]), 1e-9)  # NaN where the reference has none
    assert not close_enough(np.array([1, 2]), np.array([1, 3]), 1.0)  # integers exactly
    assert not close_enough(a, a.astype(np.float32), 1e-9)  # dtype


@pytest.fixture(scope="module")
def replay():
    rec = _recorder()
    return rec, np.load(rec.PATH), rec.record_all()


def test_every_scenario_is_recorded(replay):
    rec, ref, _ = replay
    recorded = {k.split("/")[0] for k in ref.files}
    assert recorded == set(rec.scenarios()), "re-record: python tests/data/record_all_scenarios.py"


def test_recorded_episodes_replay(replay):
    rec, ref, new = replay
    assert set(new) == set(ref.files)
    rtol = 0.0 if os.environ.get("COOPNAV_BITWISE") == "1" else rec.RTOL
    bad = [k for k in ref.files if not close_enough(ref[k], new[k], rtol)]
    assert not bad, f"{len(bad)} arrays differ beyond rtol={rtol:g}: {bad[:10]}"
