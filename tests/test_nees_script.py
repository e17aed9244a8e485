"""benchmarks/nees_per_cycle.py --beacon: another policy drives the beacons (the filter's
consistency depends on where the beacon goes), with a one-line refusal of a bad name."""

import numpy as np
import pytest

from benchmarks import nees_per_cycle


def test_beacon_drives_instead_of_the_case_planner(capsys):
    # the same planner through either path: the same filter, the same NEES (ellipse is deterministic)
    a = nees_per_cycle.nees_of_case("gao_sea", "ellipse", {"max_cycles": 12}, 3, 700000)
    b = nees_per_cycle.nees_of_case("gao_sea", "ellipse", {"max_cycles": 12}, 3, 700000, beacon="ellipse")
    assert a["run_cycles"] == b["run_cycles"] == 36 and np.isclose(a["mean"], b["mean"], rtol=1e-12)
    # another beacon, another filter history
    c = nees_per_cycle.nees_of_case("gao_sea", "ellipse", {"max_cycles": 12}, 3, 700000, beacon="static")
    assert c["mean"] != a["mean"]
    assert nees_per_cycle.main(["--runs", "2", "--cases", "1", "--beacon", "static", "--set", "max_cycles=5"]) == 0
    out = capsys.readouterr().out
    assert "| gao_sea | static | 10 |" in out


def test_a_bad_beacon_is_one_line_and_exit_2(capsys):
    assert nees_per_cycle.main(["--runs", "2", "--cases", "1", "--beacon", "elipse"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--beacon 'elipse'" in err[0] and "Traceback" not in err[0]
    assert "did you mean 'ellipse'?" in err[0]


def test_by_distance_splits_the_run_cycles():
    """Hand-made run-cycles: NEES 1 at 10 m, 20 at 30 m (above the 99.9 % point), 2 and 4
    at 60 m, none beyond 100 m."""
    nees = np.array([1.0, 20.0, 2.0, 4.0])
    dist = np.array([10.0, 30.0, 60.0, 99.9])
    bands = nees_per_cycle.by_distance(nees, dist)
    assert [b["band_m"] for b in bands] == [(0.0, 20.0), (20.0, 50.0), (50.0, 100.0), (100.0, np.inf)]
    assert [b["share"] for b in bands] == [0.25, 0.25, 0.5, 0.0]
    assert [b["mean"] for b in bands] == [1.0, 20.0, 3.0, None]
    assert bands[1]["above_x"] == pytest.approx(1000.0) and bands[0]["above_x"] == 0.0 and bands[3]["above_x"] is None
