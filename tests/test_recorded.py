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


SIMD_SCENARIOS = ("gao_lawnmower", "gao_sea", "matos_moving_lbl", "swarm_mls")
SIMD_CHECK = """
import importlib.util, json
import numpy as np
spec = importlib.util.spec_from_file_location("test_recorded", {here!r})
here = importlib.util.module_from_spec(spec)
spec.loader.exec_module(here)
close_enough = here.close_enough
rec = here._recorder()
ref = np.load(rec.PATH)
n = differ = beyond = 0
for s in {scenarios!r}:
    for batch, seeds in rec.RUNS:
        for k, v in rec.record(s, batch, seeds).items():
            key = f"{{s}}/default/B{{batch}}/{{k}}"
            n += 1
            differ += not np.array_equal(ref[key], v)
            beyond += not close_enough(ref[key], v, rec.RTOL)
print(json.dumps({{"arrays": n, "differ": differ, "beyond": beyond}}))
"""


def test_another_simd_path_stays_within_the_tolerance():
    """numpy's vectorized loops switched to the baseline SIMD path (every dispatched
    target this CPU has disabled, as on an older CPU): the recorded episodes still replay
    within the stated tolerance (on this machine, some arrays then differ in their last
    bits: the reason bit for bit is promised on one machine only)."""
    import json
    import subprocess
    import sys

    from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__

    targets = [t for t in __cpu_dispatch__ if __cpu_features__.get(t)]
    if not targets:
        pytest.skip("this CPU runs numpy's baseline SIMD path only: no other path to compare")
    code = SIMD_CHECK.format(here=str(Path(__file__).resolve()), scenarios=SIMD_SCENARIOS)
    env = dict(os.environ, NPY_DISABLE_CPU_FEATURES=" ".join(targets))
    out = subprocess.run(
        [sys.executable, "-c", code],
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
        cwd=Path(__file__).resolve().parent.parent,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    counts = json.loads(out.stdout.strip().splitlines()[-1])
    assert counts["arrays"] > 100 and counts["beyond"] == 0, counts
