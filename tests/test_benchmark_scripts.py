"""Every script in benchmarks/ is a command a page of the docs names: each answers ``--help``
(exit 0, a usage line) and refuses bad input in one line with exit status 2, as the
project's other commands do (``compare_sousa_tables.py --help`` once read a folder named
"--help" and ended in a traceback)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
# the commands: not __init__.py, nor a module the scripts import (_args.py)
SCRIPTS = sorted(p for p in (ROOT / "benchmarks").glob("*.py") if not p.name.startswith("_"))


def _run(script: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(script), *args], capture_output=True, text=True, timeout=120, cwd=ROOT)


@pytest.mark.parametrize("script", SCRIPTS, ids=[p.stem for p in SCRIPTS])
def test_every_benchmark_script_answers_help(script):
    r = _run(script, "--help")
    assert r.returncode == 0 and r.stdout.lstrip().startswith("usage:"), (r.returncode, r.stderr[-400:])


def test_compare_sousa_tables_refuses_what_is_not_a_sweep(tmp_path):
    r = _run(ROOT / "benchmarks" / "compare_sousa_tables.py", str(tmp_path))
    assert r.returncode == 2 and r.stderr.strip().count("\n") == 0 and "no summary.json" in r.stderr, r.stderr
    (tmp_path / "summary.json").write_text('{"policies": []}')
    (tmp_path / "episodes.csv").write_text("cell,policy,seed,mean_error_m\n")
    r = _run(ROOT / "benchmarks" / "compare_sousa_tables.py", str(tmp_path))
    assert r.returncode == 2 and "not a --sweep result" in r.stderr and "Traceback" not in r.stderr, r.stderr


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (("--set", "beacon_covariance=full"), "what this script compares"),
        (("--set", "foo=1"), "unknown scenario parameter"),
        (("--cases", "4"), "no beacon AUV"),
        (("--runs", "0"), "--runs must be"),
    ],
)
def test_beacon_covariance_refuses_bad_input_in_one_line(args, says):
    """benchmarks/beacon_covariance.py: what it cannot compare is one line and exit 2 (the
    compared switch itself, a parameter the scenario does not have, a case without a beacon
    AUV), never a traceback nor a silently replaced --set."""
    r = _run(ROOT / "benchmarks" / "beacon_covariance.py", *args)
    assert r.returncode == 2 and says in r.stderr and r.stderr.strip().count("\n") == 0, r.stderr[-400:]
