"""benchmarks/benchmark_summary.py: its rows on a results.json whose numbers are known by
construction, against the best planner and against the best greedy planner."""

import json

import numpy as np
import pytest

from benchmarks import benchmark_summary


def _entry(errors):
    return {"mean_error_m": float(np.mean(errors)), "episode_mean_error_m": list(map(float, errors))}


def _results(greedy=("circle", "ellipse")):
    rng = np.random.default_rng(1)
    base = 4.0 + rng.normal(0.0, 0.3, 12)
    tasks = {}
    # x: ellipse is the best greedy planner (circle +1), horizon 0.5 below it, ppo 1.0 below it;
    # y: circle the best greedy (ellipse +0.2), horizon 0.2 below it, ppo 0.1 above horizon
    for name, circle, ellipse, horizon, ppo in (
        ("x", base + 1.0, base, base - 0.5, base - 1.0),
        ("y", base, base + 0.2, base - 0.2, base - 0.1),
    ):
        best = "horizon"
        tasks[name] = {
            "best_planner": best,
            "policies": {
                "circle": _entry(circle),
                "ellipse": _entry(ellipse),
                "horizon": _entry(horizon),
                "ppo": _entry(ppo),
            },
        }
    ts = {
        "challengers": ["ppo"],
        "tasks": tasks,
        "summary": {"ppo": {"win": 1, "tie": 0, "loss": 1, "n/a": 0}},
    }
    if greedy is not None:
        ts["greedy_planners"] = list(greedy)
    return {"task_sets": {"demo": ts}, "official": True}, base


def test_rows_against_the_best_planner_and_the_best_greedy_planner():
    results, base = _results()
    (row,) = benchmark_summary.rows(results)
    name, challenger, n, na, mean, best, rel, pm, (lo, hi), w, t, l, official, greedy = row
    b = float(np.mean(base))
    assert (name, challenger, n, na, w, t, l, official) == ("demo", "ppo", 2, 0, 1, 0, 1, True)
    # ppo's mean over the tasks: (b - 1.0 + b - 0.1) / 2; the best planner's (horizon): (b - 0.5 + b - 0.2) / 2
    assert mean == pytest.approx(b - 0.55) and best == pytest.approx(b - 0.35)
    assert rel == pytest.approx((b - 0.55) / (b - 0.35) - 1.0)
    # the per-seed differences are constants (-0.5 on x, +0.1 on y): pooled -0.2, a zero-width interval
    assert pm == pytest.approx(-0.2) and lo == pytest.approx(-0.2) and hi == pytest.approx(-0.2)
    g_mean, g_rel, g_pm, (g_lo, g_hi) = greedy
    # the best greedy planner: ellipse on x (b), circle on y (b): ppo is 1.0 and 0.1 below them
    assert g_mean == pytest.approx(b) and g_rel == pytest.approx((b - 0.55) / b - 1.0)
    assert g_pm == pytest.approx(-0.55) and g_lo == pytest.approx(-0.55) and g_hi == pytest.approx(-0.55)
    table = benchmark_summary.markdown([row])
    assert f"| {b:.3f} | {g_rel * 100:+.1f} % | -0.550 [-0.550, -0.550] |" in table


def test_results_without_the_greedy_planners_leave_those_columns_na(tmp_path, capsys):
    results, _ = _results(greedy=None)
    (row,) = benchmark_summary.rows(results)
    assert row[-1] is None
    path = tmp_path / "results.json"
    path.write_text(json.dumps(results))
    assert benchmark_summary.main([str(path)]) == 0
    assert "| n/a | n/a | n/a |" in capsys.readouterr().out


def test_a_file_that_is_not_a_results_json_is_one_line(tmp_path, capsys):
    path = tmp_path / "results.json"
    path.write_text(json.dumps({"task_sets": {"demo": {}}}))
    with pytest.raises(SystemExit) as exit_info:
        benchmark_summary.main([str(path)])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert "not a benchmark results.json" in err[-1]
