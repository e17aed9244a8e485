"""benchmarks/horizon_vs_greedy.py on the evaluation's runner: a variant is a planner spec any
worker reads, a bad one is one line, and the table is the same on one or two workers."""

from __future__ import annotations

import pytest

from benchmarks.horizon_vs_greedy import main, variant_spec


def test_a_variant_is_a_planner_spec():
    assert variant_spec("h8:horizon:horizon=8,n_samples=128") == ("h8", "horizon:horizon=8:n_samples=128")
    assert variant_spec("hp:horizon:team=peers") == ("hp", "horizon:team=peers")
    assert variant_spec("plain:ellipse") == ("plain", "ellipse")


def test_a_bad_variant_is_one_line(capsys):
    args = ["--tasks", "gao_lawnmower", "--task", "lake", "--episodes", "1", "--challenger", "h4"]
    with pytest.raises(SystemExit) as err:
        main([*args, "--variant", "h4:horizon:bogus=4"])
    assert err.value.code == 2
    assert "--variant h4: planner 'horizon' takes no setting 'bogus'" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main([*args, "--variant", "h4:horizn:horizon=4"])
    assert "'horizn' is not a planner" in capsys.readouterr().err


def _table(text: str) -> str:
    return "\n".join(line for line in text.splitlines() if not line.startswith("CPU seconds"))


def test_the_same_table_on_one_or_two_workers(capsys):
    args = ["--tasks", "gao_lawnmower", "--task", "lake", "--episodes", "2", "--first-seed", "9000"]
    args += ["--variant", "h2:horizon:horizon=2", "--challenger", "horizon,h2", "--set", "max_cycles=12"]
    main([*args, "--workers", "2"])
    two = capsys.readouterr().out
    main(args)
    one = capsys.readouterr().out
    assert _table(one) == _table(two)
    rows = [line for line in one.splitlines() if line.startswith("| gao_lawnmower | lake |")]
    assert [r.split(" | ")[4] for r in rows] == ["horizon", "h2"]
    assert rows[0].split(" | ")[5] != rows[1].split(" | ")[5]  # the workers planned with the variant's horizon
