"""benchmarks/lever_table.py: the paired arithmetic of its table on numbers known by
construction, and its one-line refusals."""

import numpy as np
import pytest

from benchmarks import lever_table


def _result():
    rng = np.random.default_rng(0)
    seeds = 10
    a = {t: (4.0 + rng.normal(0, 0.5, seeds)).tolist() for t in ("x", "y")}
    b = {"x": (np.asarray(a["x"]) + 1.0).tolist(), "y": (np.asarray(a["y"]) - 2.0).tolist()}  # best on y only
    learned = {t: (np.minimum(np.asarray(a[t]), np.asarray(b[t])) - 0.5).tolist() for t in ("x", "y")}
    other = {t: (np.asarray(learned[t]) + 0.25).tolist() for t in ("x", "y")}
    return {
        "task_set": "demo",
        "tasks": ["x", "y"],
        "policies": [
            {"label": "a", "spec": "a", "planner": True},
            {"label": "b", "spec": "b", "planner": True},
            {"label": "mappo", "spec": "runs/m", "planner": False},
            {"label": "ippo", "spec": "runs/i", "planner": False},
        ],
        "seeds": [700000, 700009],
        "episodes": seeds,
        "errors": {"a": a, "b": b, "mappo": learned, "ippo": other},
    }


def test_the_table_pairs_each_task_with_its_best_planner():
    """The learned policy is 0.5 m below the better planner of each task (a on x, b on y) on
    every seed: paired -0.500 with a zero-width interval, two wins; ippo is 0.25 above it."""
    table = lever_table.markdown(_result())
    row = next(line for line in table.splitlines() if line.startswith("| `mappo`"))
    assert "-0.500 [-0.500, -0.500]" in row and "| 2 / 0 / 0 |" in row and row.endswith("| 0 |  |")
    ippo = next(line for line in table.splitlines() if line.startswith("| `ippo`"))
    assert "-0.250 [-0.250, -0.250]" in ippo and "+0.250 [+0.250, +0.250] loss" in ippo
    assert "x `a`, y `b`" in table


def test_paired_is_a_minus_b_over_the_tasks_both_drove(capsys, tmp_path):
    """mappo is 0.25 m below ippo on every seed of both tasks; with ippo n/a on y, x alone."""
    result = _result()
    assert (
        lever_table.paired(result, "mappo", "ippo") == "mappo - ippo: -0.250 [-0.250, -0.250] m over 10 seeds, 2 tasks"
    )
    result["errors"]["ippo"]["x"][0] += 1.0  # one seed 1 m worse on x, the only task left: +1.0 / 10 seeds
    result["na"] = {"ippo": {"y": "n/a"}}
    line = lever_table.paired(result, "ippo", "mappo")
    assert line.startswith("ippo - mappo: +0.350 [") and line.endswith("over 10 seeds, 1 tasks")
    with pytest.raises(ValueError, match="no policy 'ppo'"):
        lever_table.paired(result, "ppo", "mappo")
    path = tmp_path / "r.json"
    path.write_text(__import__("json").dumps(result))
    assert lever_table.main(["paired", str(path), "mappo", "nope"]) == 2
    assert capsys.readouterr().err.startswith("error: no policy 'nope'")
    assert lever_table.main(["paired", str(tmp_path / "missing.json"), "mappo", "ippo"]) == 2
    assert capsys.readouterr().err.strip().endswith("missing.json: no such file")
    assert lever_table.main(["summarize", str(tmp_path / "missing.json")]) == 2
    assert "no such file" in capsys.readouterr().err


def test_a_lost_episode_is_ten_times_the_best_planner_of_its_seed():
    result = _result()
    errs = result["errors"]
    errs["mappo"]["y"][3] = 10.0 * min(errs["a"]["y"][3], errs["b"]["y"][3]) + 0.01
    errs["mappo"]["x"][4] = 9.9 * min(errs["a"]["x"][4], errs["b"]["x"][4])
    assert lever_table.lost_episodes(errs, "mappo", ["a", "b"], ["x", "y"]) == 1
    row = next(line for line in lever_table.markdown(result).splitlines() if line.startswith("| `mappo`"))
    rel = {t: np.mean(errs["mappo"][t]) / np.mean(errs["a" if t == "x" else "b"][t]) - 1 for t in ("x", "y")}
    worst = max(rel, key=rel.get)
    assert "| 1 |" in row and f"| {worst} {100 * rel[worst]:+.1f} % |" in row and rel[worst] > 0


def test_bad_input_is_one_line(capsys):
    assert lever_table.main(["--tasks", "gao_tem", "--policies", "ellipse"]) == 2
    assert "did you mean 'gao_team'" in capsys.readouterr().err
    assert lever_table.main(["--tasks", "gao_team", "--policies", "ellipse", "--seed", str(2**62 - 10)]) == 2
    assert "reserved" in capsys.readouterr().err
    assert lever_table.main(["--tasks", "gao_team", "--policies", "a=ellipse,a=circle"]) == 2
    assert "labels must differ" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        lever_table.main(["--tasks", "gao_team"])


def test_a_reuse_file_that_is_no_result_is_one_line(tmp_path, capsys):
    """--reuse of a file that is not JSON, or JSON that is not a result: one line and exit 2
    before the runs (the first was an UnsafeDataError traceback; an input audit)."""
    bad, other = tmp_path / "bad.json", tmp_path / "other.json"
    bad.write_text("not json")
    other.write_text("[1, 2]")
    for path, what in ((bad, "not JSON"), (other, "not a lever_table.py --out result")):
        args = ["--tasks", "gao_lawnmower", "--policies", "ellipse", "--episodes", "2", "--reuse", str(path)]
        assert lever_table.main(args) == 2
        err = capsys.readouterr().err
        assert what in err and len(err.strip().splitlines()) == 1, err


def test_reuse_takes_the_policies_of_an_earlier_run_and_refuses_other_seeds():
    """Policies of --reuse (same task set and seeds) are not run again; other seeds: refused."""
    from evaluation.tasks import get_task_set

    tasks = [t.name for t in get_task_set("gao_team").tasks]
    earlier = {
        "task_set": "gao_team",
        "seeds": [700000, 700001],
        "policies": [{"label": "e", "spec": "ellipse", "planner": True}],
        "errors": {"e": {t: [1.0, 2.0] for t in tasks}},
        "seconds": {"e": 5.0},
    }
    out = lever_table.run("gao_team", [("e", "ellipse")], 2, 700000, progress=None, reuse=earlier)
    assert out["errors"]["e"] == earlier["errors"]["e"] and out["seconds"]["e"] == 5.0
    with pytest.raises(ValueError, match="not this run's"):
        lever_table.run("gao_team", [("e", "ellipse")], 2, 700001, progress=None, reuse=earlier)


def test_reuse_runs_a_trained_policy_again_when_its_files_changed(monkeypatch):
    """``ppo`` names other weights once a policy is re-shipped: --reuse compares the files'
    fingerprint with the earlier run's, not the spec alone, and runs a changed policy again."""
    from evaluation.tasks import get_task_set

    tasks = [t.name for t in get_task_set("gao_team").tasks]
    earlier = {
        "task_set": "gao_team",
        "seeds": [700000, 700001],
        "policies": [{"label": "p", "spec": "ppo", "planner": False, "fingerprint": "the-old-weights"}],
        "errors": {"p": {t: [1.0, 2.0] for t in tasks}},
    }
    assert lever_table.fingerprint("ppo", "gao_team") == lever_table.fingerprint("ppo", "gao_team") != "the-old-weights"
    assert lever_table.fingerprint("ellipse", "gao_team") is None
    said: list = []
    na = {"p": dict.fromkeys(tasks[1:], "skipped here")}  # one task only: the test stays short
    out = lever_table.run("gao_team", [("p", "ppo")], 2, 700000, progress=said.append, reuse=earlier, na=na)
    assert any("its files differ from --reuse's, run again" in line for line in said)
    assert out["errors"]["p"][tasks[0]] != [1.0, 2.0]
    assert out["policies"][0]["fingerprint"] == lever_table.fingerprint("ppo", "gao_team")


def test_the_summary_applies_the_shift_criteria():
    """ippo is 0.25 m below the best planner everywhere (yes); mappo with one episode at 10x
    the best planner is lost there (no)."""
    result = _result()
    assert "| yes |" in lever_table.summary([result], "ippo")
    result["errors"]["mappo"]["y"][3] = 100.0
    row = lever_table.summary([result], "mappo").splitlines()[-1]
    assert row.startswith("| `demo` | 10 |") and row.endswith("| 1 | **no** |")


def test_pings_per_episode_are_tabled_when_every_policy_has_them():
    result = _result()
    result["pings"] = {"a": {"x": [10, 12], "y": [14, 16]}, "mappo": {"x": [5, 5], "y": [7, 7]}}
    assert "Pings per episode" not in lever_table.markdown(result)  # b and ippo were not recorded
    result["pings"].update(b={"x": [1, 1], "y": [1, 1]}, ippo={"x": [2, 2], "y": [4, 4]})
    assert "| 13.0 | 1.0 | 6.0 | 3.0 |" in lever_table.markdown(result)


def test_a_planner_with_a_schedule_plays_through_the_benchmark_loop():
    """``ellipse+clock`` on sousa_ping's shared channel: both ASVs ping every slot (8 in 4
    slots), where the plain name's default TDMA alternates (4)."""
    from coopnav_env import make_config
    from evaluation.episodes import run_episodes

    config = make_config("sousa_ping", max_cycles=4)
    clock, _ = run_episodes(config, "ellipse+clock", [700000])
    tdma, _ = run_episodes(config, "ellipse", [700000])
    assert clock[0]["pings"] == 8 and tdma[0]["pings"] == 4


def test_a_task_a_policy_cannot_drive_is_na_and_left_out_of_its_pooled_row(monkeypatch):
    """A flat policy on a team task: ``find_na`` names the task (not an error), the table
    shows n/a there, and the policy's row pools only the tasks it drove (x: -0.5 m, a win).
    A policy that drives no task of the set is refused."""
    import evaluation.episodes

    def check(spec, config, seed):
        if spec == "runs/m" and config.n_survey == 2:
            raise ValueError(f"policy {spec!r} was trained on 1 survey vehicle")
        if spec == "runs/none":
            raise ValueError("observation size 12, not 40")

    monkeypatch.setattr(evaluation.episodes, "check_policy", check)
    na = lever_table.find_na("gao_lawnmower", [("e", "ellipse"), ("mappo", "runs/m")], 700000)
    assert na == {"mappo": {"two_surveys": "policy 'runs/m' was trained on 1 survey vehicle"}}
    with pytest.raises(ValueError, match="cannot drive any task of gao_lawnmower: observation size 12"):
        lever_table.find_na("gao_lawnmower", [("x", "runs/none")], 700000)

    result = _result()
    del result["errors"]["mappo"]["y"]
    result["na"] = {"mappo": {"y": "trained on 1 survey vehicle"}}
    table = lever_table.markdown(result)
    assert "| y | " in table and "| n/a |" in next(line for line in table.splitlines() if line.startswith("| y |"))
    row = next(line for line in table.splitlines() if line.startswith("| `mappo`"))
    assert "-0.500 [-0.500, -0.500]" in row and "| 1 / 0 / 0 (1 n/a) |" in row
    ippo = next(line for line in table.splitlines() if line.startswith("| `ippo`"))
    assert "+0.250 [+0.250, +0.250] loss" in ippo  # paired with mappo on x only
    assert "n/a: `mappo` on y: trained on 1 survey vehicle" in table


def test_two_workers_give_the_same_errors_per_task_and_label():
    """``--workers 2`` plays the (task, policy) cells in two processes: each label's errors
    land under the right task, the same as one process's (the tasks differ, so a cell filed
    under another task would show)."""
    one = lever_table.run("gao_lawnmower", [("a", "fim_a"), ("s", "static")], 2, 700000, progress=None)
    two = lever_table.run("gao_lawnmower", [("a", "fim_a"), ("s", "static")], 2, 700000, progress=None, workers=2)
    assert one["errors"] == two["errors"] and one["pings"] == two["pings"]
    assert len({tuple(v) for v in one["errors"]["a"].values()}) == len(one["tasks"])
