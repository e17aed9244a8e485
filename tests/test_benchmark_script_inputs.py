"""The benchmark scripts refuse bad input before any run, in one line with exit status 2 (an
input audit found tracebacks, hangs on huge or negative counts, NaN tables with exit 0 and
files replaced without a word): each case calls the script's ``main`` with the expensive part
replaced by a trap (``_no_run``), so a refusal that comes too late, or never, fails at once
instead of running for minutes."""

from __future__ import annotations

import copy
import json
import os
import subprocess
import sys
from importlib import import_module
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _no_run(*args, **kwargs):
    raise AssertionError("the script started its runs before refusing its input")


def _call(capsys, monkeypatch, script: str, argv: list, trap: str | None = None) -> tuple[int, str, str]:
    """(exit status, stderr, stdout) of ``benchmarks.<script>.main(argv)``; ``trap``: the
    module attribute (or ``module:attribute``) that must not be reached."""
    module = import_module(f"benchmarks.{script}")
    if trap is not None:
        where, _, name = trap.rpartition(":")
        monkeypatch.setattr(import_module(where) if where else module, name, _no_run)
    try:
        code = module.main(argv)
    except SystemExit as stop:
        code = stop.code
    out = capsys.readouterr()
    return code, out.err, out.out


def assert_refused(code, err: str, needle: str) -> None:
    """Exit 2, no traceback, and one line on stderr (no usage block: ``benchmarks._args.Parser``)."""
    assert code == 2, (code, err[-600:])
    assert "Traceback" not in err, err[-600:]
    lines = err.strip().splitlines()
    assert len(lines) == 1, err[-600:]
    assert needle in lines[0], err[-600:]


CASES = [
    # (script, argv, what the line says, what must not run)
    ("planners_vs_floors", ["--scenarios", "gao-sea", "--episodes", "2"], "did you mean 'gao_sea'", "run_episodes"),
    (
        "planners_vs_floors",
        ["--scenarios", "gao_sea", "--episodes", "1"],
        "--episodes must be at least 2",
        "run_episodes",
    ),
    ("planners_vs_floors", ["--scenarios", "gao_sea", "--episodes", "100000000"], "MAX_EPISODES", "run_episodes"),
    ("planners_vs_floors", ["--scenarios", "gao_sea", "--seed", "-1"], "--seed", "run_episodes"),
    ("planners_vs_floors", ["--scenarios", ""], "--scenarios names nothing", "run_episodes"),
    (
        "horizon_vs_greedy",
        ["--tasks", "gao-lawnmower", "--task", "lake", "--episodes", "2"],
        "did you mean 'gao_lawnmower'",
        "run_cells",
    ),
    ("horizon_vs_greedy", ["--tasks", "gao_lawnmower", "--task", "nope"], "no task 'nope'", "run_cells"),
    ("horizon_vs_greedy", ["--tasks", "gao_lawnmower", "--task", ""], "--task names nothing", "run_cells"),
    (
        "horizon_vs_greedy",
        ["--tasks", "gao_lawnmower", "--task", "lake", "--episodes", "-3"],
        "--episodes",
        "run_cells",
    ),
    ("horizon_vs_greedy", ["--tasks", "gao_lawnmower", "--task", "lake", "--episodes", "1"], "at least 2", "run_cells"),
    (
        "horizon_vs_greedy",
        ["--tasks", "gao_lawnmower", "--task", "lake", "--first-seed", "-1"],
        "--first-seed",
        "run_cells",
    ),
    (
        "horizon_vs_greedy",
        ["--tasks", "gao_lawnmower", "--task", "lake", "--challenger", "nope"],
        "--challenger 'nope'",
        "run_cells",
    ),
    ("horizon_vs_greedy", ["--tasks", "gao_lawnmower", "--set", "max_cycles"], "KEY=VALUE", "run_cells"),
    (
        "horizon_vs_greedy",
        ["--tasks", "gao_lawnmower", "--set", "max_cycle=3"],
        "did you mean 'max_cycles'",
        "run_cells",
    ),
    ("policy_vs_planners", ["--scenario", "gao-sea"], "did you mean 'gao_sea'", "run_cells_of"),
    ("policy_vs_planners", ["--cell", "depth_m"], "--cell expects KEY=VALUE", "run_cells_of"),
    ("policy_vs_planners", ["--cell", "depth=1,5"], "did you mean 'depth_m'", "run_cells_of"),
    ("policy_vs_planners", ["--seed", "99999999999999999999999"], "--seed", "run_cells_of"),
    ("policy_vs_planners", ["--episodes", "-1"], "--episodes must be at least 2", "run_cells_of"),
    ("policy_vs_planners", ["--policies", "nope"], "--policies 'nope'", "run_cells_of"),
    ("ping_tradeoff", ["--scenario", "gao_sea"], "channel_mode='decide'", "run"),
    ("ping_tradeoff", ["--episodes", "0"], "--episodes must be at least 2", "run"),
    ("ping_tradeoff", ["--episodes", "100000000"], "MAX_EPISODES", "run"),
    ("sousa_table3", ["--ping-interval", "0"], "--ping-interval", "run_cells"),
    ("sousa_table3", ["--episodes", "2", "--duration", "nan"], "--duration", "run_cells"),
    ("sousa_table3", ["--depth", "-5"], "--depth", "run_cells"),
    ("sousa_table3", ["--seed", "-1"], "--seed", "run_cells"),
    ("link_curves", ["--episodes", "2", "--policy", "nope"], "not a planner", "episodes"),
    ("link_curves", ["--episodes", "2", "--scenario", "gao-sea"], "did you mean 'gao_sea'", "episodes"),
    ("link_curves", ["--episodes", "100000000"], "MAX_BATCH_SIZE", "episodes"),
    ("link_curves", ["--episodes", "2", "--set", "max_cycles"], "KEY=VALUE", "episodes"),
    ("planner_cost", ["--steps", "0"], "--steps must be at least 1", "time_policy"),
    ("planner_cost", ["--steps", "100000000"], "MAX_STEPS", "time_policy"),
    ("planner_cost", ["--variant", "bad"], "is not a planner", "time_policy"),
    ("planner_cost", ["--policies", "nope"], "--policies 'nope'", "time_policy"),
    ("beacon_surfacing", ["--runs", "2", "--scenario", "sousa_asv"], "no beacon AUV", "surfacing_figures"),
    ("beacon_surfacing", ["--runs", "0"], "--runs must be at least 1", "surfacing_figures"),
    ("beacon_surfacing", ["--runs", "100000000"], "MAX_BATCH_SIZE", "surfacing_figures"),
    ("beacon_surfacing", ["--planner", "nope"], "not a planner", "surfacing_figures"),
    ("beacon_surfacing", ["--seed", "-1"], "--seed", "surfacing_figures"),
    ("sim_profile", ["--batch", "2", "--steps", "1", "--seed", "-1"], "--seed", "coopnav_env.core:make_simulator"),
    ("sim_profile", ["--batch", "100000000"], "MAX_BATCH", "coopnav_env.core:make_simulator"),
    ("mls_speed", ["--seed", "-1"], "--seed", "MLSSensor"),
    ("mls_speed", ["--events", "100000000"], "MAX_EVENTS", "MLSSensor"),
    ("mls_tank", ["--snr-db", "nan"], "--snr-db", "run_sweep"),
    ("mls_tank", ["--events", "100000000"], "MAX_EVENTS", "run_sweep"),
    ("mls_analytic_vs_signal", ["--seed", "-1"], "--seed", "run_grid"),
    ("train_throughput", ["--threads", "0"], "--threads", "measure"),
    (
        "train_throughput",
        ["--only", "none", "--loop", "mappo", "--torchrl-net", "abc"],
        "--torchrl-net",
        "measure_loop",
    ),
    ("train_throughput", ["--only", "coopnav", "--n-envs", "-1"], "--n-envs", "measure"),
    ("range_model", ["--cases", "", "--runs", "2"], "--cases names nothing", "run"),
    ("lever_table", ["--tasks", "gao_lawnmower", "--policies", "", "--episodes", "2"], "names nothing", "run"),
    (
        "lever_table",
        ["--tasks", "gao_lawnmower", "--policies", "ellipse,static", "--episodes", "100000000"],
        "MAX_EPISODES",
        "run",
    ),
]


@pytest.mark.parametrize(("script", "argv", "says", "trap"), CASES, ids=[f"{c[0]} {' '.join(c[1])}" for c in CASES])
def test_bad_input_is_one_line_before_any_run(capsys, monkeypatch, script, argv, says, trap):
    code, err, _ = _call(capsys, monkeypatch, script, argv, trap)
    assert_refused(code, err, says)


def test_ping_tradeoff_refuses_a_policy_folder_without_a_model_before_the_planners(tmp_path, capsys, monkeypatch):
    """It was refused after 88 s of planner runs."""
    code, err, _ = _call(capsys, monkeypatch, "ping_tradeoff", ["--episodes", "2", "--policies", str(tmp_path)], "run")
    assert_refused(code, err, "holds no model")


def test_policy_vs_planners_refuses_a_cache_that_is_not_json(tmp_path, capsys, monkeypatch):
    cache = tmp_path / "cache.json"
    cache.write_text("")
    code, err, _ = _call(capsys, monkeypatch, "policy_vs_planners", ["--cache", str(cache)], "run_cells_of")
    assert_refused(code, err, "--cache")


def test_train_throughput_asks_for_supersuit_before_the_run(capsys, monkeypatch):
    """A default run measured coopnav for 14 s, then failed on the missing import."""
    import importlib.util

    if importlib.util.find_spec("supersuit") is not None:
        pytest.skip("supersuit is installed: nothing to refuse")
    code, err, _ = _call(capsys, monkeypatch, "train_throughput", ["--rollouts", "1", "--n-envs", "2"], "measure")
    assert_refused(code, err, "supersuit")


def test_rllib_vs_sb3_refuses_a_net_that_is_not_numbers(capsys):
    from benchmarks import rllib_vs_sb3

    with pytest.raises(SystemExit) as stop:
        rllib_vs_sb3.parse_args(["--net", "abc"])
    assert_refused(stop.value.code, capsys.readouterr().err, "--net")


def test_entity_update_says_a_team_that_is_not_yaml_in_one_line(capsys, monkeypatch):
    code, err, _ = _call(capsys, monkeypatch, "entity_update", ["--team", "{"], "observations")
    assert_refused(code, err, "--team is not YAML")


def test_time_to_beat_refuses_an_out_that_is_a_file(tmp_path, capsys, monkeypatch):
    afile = tmp_path / "afile"
    afile.write_text("")
    code, err, _ = _call(capsys, monkeypatch, "time_to_beat", ["--out", str(afile)], "train_until_beaten")
    assert_refused(code, err, "not a folder")


# ------------------------------------------------------------------------------------
# results read back: NaN, text, unpaired counts and empty selections are refused


def _benchmark_result() -> dict:
    policy = {"mean_error_m": 3.0, "episode_mean_error_m": [2.0, 4.0]}
    planner = {"mean_error_m": 3.5, "episode_mean_error_m": [3.0, 4.0]}
    policy["paired"] = {"mean_m": -0.5, "ci95_m": [-7.0, 6.0], "verdict": "tie"}
    task = {"best_planner": "ellipse", "policies": {"ppo": policy, "ellipse": planner}}
    ts = {
        "challengers": ["ppo"],
        "planners": ["ellipse"],
        "greedy_planners": ["ellipse"],
        "summary": {"ppo": {"win": 0, "tie": 1, "loss": 0, "n/a": 0}},
        "tasks": {"lake": task},
    }
    return {"task_sets": {"gao_lawnmower": ts}}


def _broken(kind: str):
    result = _benchmark_result()
    ppo = result["task_sets"]["gao_lawnmower"]["tasks"]["lake"]["policies"]["ppo"]
    if kind == "list":
        return []
    if kind == "nan":
        ppo["episode_mean_error_m"] = [float("nan"), 3.0]
    elif kind == "text":
        ppo["episode_mean_error_m"] = ["x", 3.0]
    elif kind == "null":
        ppo["mean_error_m"] = None
    elif kind == "one_against_two":
        ppo["episode_mean_error_m"] = [3.0]
    return result


@pytest.mark.parametrize("kind", ["list", "nan", "text", "null", "one_against_two"])
def test_benchmark_summary_refuses_a_result_it_cannot_summarize(tmp_path, capsys, monkeypatch, kind):
    """They were tracebacks, a +nan interval, and a 1-against-2 episode difference numpy
    broadcast into a valid-looking interval."""
    path = tmp_path / "results.json"
    path.write_text(json.dumps(_benchmark_result()))  # the sound result reads
    code, err, out = _call(capsys, monkeypatch, "benchmark_summary", [str(path)])
    assert code in (0, None) and "`gao_lawnmower`" in out, err
    path.write_text(json.dumps(_broken(kind)))  # NaN is written as JSON's NaN token, which Python reads
    code, err, out = _call(capsys, monkeypatch, "benchmark_summary", [str(path)])
    assert_refused(code, err, "not a benchmark results.json")
    assert "nan" not in out


@pytest.mark.parametrize("kind", ["nan", "text"])
def test_resummarize_refuses_a_result_it_cannot_summarize(tmp_path, capsys, monkeypatch, kind):
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "results.json").write_text(json.dumps(_broken(kind)))
    out = tmp_path / "new"
    code, err, _ = _call(capsys, monkeypatch, "resummarize", [str(tmp_path / "run"), "--out", str(out)])
    assert_refused(code, err, "not a benchmark result")
    assert not out.exists()


def test_resummarize_refuses_a_folder_holding_an_evaluation(tmp_path, capsys, monkeypatch):
    """The benchmark refuses such a folder; resummarize.py wrote into it (an input audit)."""
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "results.json").write_text(json.dumps(_benchmark_result()))
    evaluation = tmp_path / "ev"
    evaluation.mkdir()
    (evaluation / "episodes.csv").write_text("policy,seed,mean_error_m\n")
    code, err, _ = _call(capsys, monkeypatch, "resummarize", [str(tmp_path / "run"), "--out", str(evaluation)])
    assert_refused(code, err, "holds an evaluate.py result")
    assert sorted(os.listdir(evaluation)) == ["episodes.csv"]


def test_resummarize_refuses_an_out_that_is_a_file(tmp_path, capsys, monkeypatch):
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "results.json").write_text(json.dumps(_benchmark_result()))
    (tmp_path / "afile").write_text("")
    code, err, _ = _call(capsys, monkeypatch, "resummarize", [str(tmp_path / "run"), "--out", str(tmp_path / "afile")])
    assert_refused(code, err, "is a file")


def _lever_result() -> dict:
    return {
        "task_set": "gao_lawnmower",
        "tasks": ["lake"],
        "policies": [
            {"label": "ellipse", "spec": "ellipse", "planner": True, "fingerprint": None},
            {"label": "static", "spec": "static", "planner": True, "fingerprint": None},
        ],
        "seeds": [700000, 700001],
        "episodes": 2,
        "errors": {"ellipse": {"lake": [1.0, 2.0]}, "static": {"lake": [3.0, 5.0]}},
    }


@pytest.mark.parametrize(
    ("errors", "says"),
    [([float("nan"), 2.0], "not finite numbers"), (["x", 2.0], "not finite numbers"), ([1.0], "interval needs two")],
)
def test_lever_table_paired_refuses_what_is_not_paired_numbers(tmp_path, capsys, monkeypatch, errors, says):
    """NaN printed '+nan [+nan, +nan]', text was a numpy traceback, one episode against two
    was 'over 1 seeds'."""
    result = copy.deepcopy(_lever_result())
    result["errors"]["ellipse"]["lake"] = errors
    path = tmp_path / "lv.json"
    path.write_text(json.dumps(result))
    code, err, _ = _call(capsys, monkeypatch, "lever_table", ["paired", str(path), "ellipse", "static"])
    assert_refused(code, err, says)


def test_lever_table_summarize_refuses_a_policy_no_file_holds(tmp_path, capsys, monkeypatch):
    path = tmp_path / "lv.json"
    path.write_text(json.dumps(_lever_result()))
    code, err, _ = _call(capsys, monkeypatch, "lever_table", ["summarize", "--policy", "nope", str(path)])
    assert_refused(code, err, "no policy 'nope'")


def test_beacon_covariance_says_n_a_not_nan(capsys, monkeypatch):
    """gao_lawnmower's beacon surfaces every cycle: no cycle is left to judge its walk by."""
    code, err, out = _call(capsys, monkeypatch, "beacon_covariance", ["--runs", "2", "--cases", "0"])
    assert code == 0, err[-600:]
    assert "nan" not in out and "n/a" in out, out


# ------------------------------------------------------------------------------------
# the output folder and files


def test_times_lists_and_refuses_without_making_its_folder(tmp_path, capsys, monkeypatch):
    out = tmp_path / "times"
    code, err, listing = _call(capsys, monkeypatch, "times", ["--list", "--out", str(out)], "measure")
    assert code in (0, None) and "ci:" in listing, err
    code, err, _ = _call(capsys, monkeypatch, "times", ["--only", "nope", "--out", str(out)], "measure")
    assert_refused(code, err, "unknown item 'nope'")
    code, err, _ = _call(capsys, monkeypatch, "times", ["--only", "", "--out", str(out)], "measure")
    assert_refused(code, err, "--only names nothing")
    assert not out.exists()


def _marl_run(folder: Path, rows: int = 6) -> Path:
    folder.mkdir()
    lines = [json.dumps({"steps": 1000 * (i + 1), "survey_error_m": 10.0 - i}) for i in range(rows)]
    (folder / "log.jsonl").write_text("\n".join(lines) + "\n")
    return folder


def test_marl_curves_refuses_a_log_it_cannot_draw(tmp_path, capsys, monkeypatch):
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "log.jsonl").write_text("[1]\n")
    code, err, _ = _call(capsys, monkeypatch, "marl_curves", [f"a={bad}", "--out", str(tmp_path / "a.png")])
    assert_refused(code, err, "not a batched PPO log")
    short = _marl_run(tmp_path / "short", rows=2)
    code, err, _ = _call(capsys, monkeypatch, "marl_curves", [f"a={short}", "--out", str(tmp_path / "b.png")])
    assert_refused(code, err, "fewer than --smooth 5")
    code, err, _ = _call(capsys, monkeypatch, "marl_curves", [f"a={short}", "--out", str(tmp_path)])
    assert_refused(code, err, "is a folder")
    assert not (tmp_path / "a.png").exists() and not (tmp_path / "b.png").exists()


# (script, the flag of a single-file output, the rest of a command that would otherwise run, the trap)
SINGLE_FILES = [
    ("nees_per_cycle", "--markdown", ["--runs", "2", "--cases", "0"], "nees_of_case"),
    ("beacon_covariance", "--markdown", ["--runs", "2"], "covariance_figures"),
    ("planners_vs_floors", "--markdown", ["--scenarios", "gao_sea", "--episodes", "2"], "run_episodes"),
    ("horizon_vs_greedy", "--markdown", ["--tasks", "gao_lawnmower", "--task", "lake", "--episodes", "2"], "run_cells"),
    ("horizon_vs_greedy", "--json", ["--tasks", "gao_lawnmower", "--task", "lake", "--episodes", "2"], "run_cells"),
    ("policy_vs_planners", "--out", ["--episodes", "2"], "run_cells_of"),
    ("policy_vs_planners", "--markdown", ["--episodes", "2"], "run_cells_of"),
    ("ping_tradeoff", "--figure", ["--episodes", "2"], "run"),
    ("ping_tradeoff", "--markdown", ["--episodes", "2"], "run"),
    ("sousa_table3", "--markdown", ["--episodes", "2"], "run_cells"),
    ("planner_cost", "--markdown", ["--steps", "2"], "time_policy"),
    ("lever_table", "--out", ["--tasks", "gao_lawnmower", "--policies", "ellipse", "--episodes", "2"], "run"),
    ("lever_table", "--markdown", ["--tasks", "gao_lawnmower", "--policies", "ellipse", "--episodes", "2"], "run"),
]


@pytest.mark.parametrize(("script", "flag", "argv", "trap"), SINGLE_FILES, ids=[f"{s[0]} {s[1]}" for s in SINGLE_FILES])
def test_an_existing_file_is_not_replaced_without_overwrite(tmp_path, capsys, monkeypatch, script, flag, argv, trap):
    """Each replaced an existing table, JSON or figure without a word (lever_table.py lost
    another run's policies that way)."""
    keep = tmp_path / "keep.out"
    keep.write_text("precious\n")
    code, err, _ = _call(capsys, monkeypatch, script, [*argv, flag, str(keep)], trap)
    assert_refused(code, err, "exists; pass --overwrite to replace it")
    assert keep.read_text() == "precious\n"


def test_link_curves_does_not_replace_its_figures_without_overwrite(tmp_path, capsys, monkeypatch):
    (tmp_path / "link_timeline.png").write_bytes(b"precious")
    code, err, _ = _call(capsys, monkeypatch, "link_curves", ["--out", str(tmp_path)], "loss_vs_range")
    assert_refused(code, err, "exists; pass --overwrite")
    assert (tmp_path / "link_timeline.png").read_bytes() == b"precious"


def test_marl_curves_and_benchmark_summary_replace_a_file_with_overwrite(tmp_path, capsys, monkeypatch):
    run = _marl_run(tmp_path / "run")
    png = tmp_path / "curve.png"
    png.write_bytes(b"old")
    code, err, _ = _call(capsys, monkeypatch, "marl_curves", [f"a={run}", "--out", str(png)])
    assert_refused(code, err, "exists; pass --overwrite")
    assert png.read_bytes() == b"old"
    code, err, _ = _call(capsys, monkeypatch, "marl_curves", [f"a={run}", "--out", str(png), "--overwrite"])
    assert code in (0, None) and png.read_bytes().startswith(b"\x89PNG"), err
    results, table = tmp_path / "results.json", tmp_path / "summary.md"
    results.write_text(json.dumps(_benchmark_result()))
    table.write_text("old\n")
    code, err, _ = _call(capsys, monkeypatch, "benchmark_summary", [str(results), "--markdown", str(table)])
    assert_refused(code, err, "--markdown")
    assert table.read_text() == "old\n"
    code, err, _ = _call(
        capsys, monkeypatch, "benchmark_summary", [str(results), "--markdown", str(table), "--overwrite"]
    )
    assert code in (0, None) and "`gao_lawnmower`" in table.read_text(), err


def test_records_check_output_file_refuses_an_existing_file_unless_overwrite(tmp_path):
    from coopnav_env.records import check_output_args, check_output_file

    table = tmp_path / "t.md"
    check_output_file(table)  # not there yet: fine
    table.write_text("x")
    with pytest.raises(OSError, match="exists; pass --overwrite to replace it"):
        check_output_file(table)
    check_output_file(table, overwrite=True)
    said: list = []
    check_output_args(said.append, markdown=str(table))
    assert said == [f"--markdown: {table} exists; pass --overwrite to replace it"]
    said.clear()
    check_output_args(said.append, overwrite=True, markdown=str(table))
    assert said == []


SCRIPTS = sorted(p.stem for p in (ROOT / "benchmarks").glob("*.py") if not p.name.startswith("_"))


@pytest.mark.parametrize("script", SCRIPTS)
def test_a_mistyped_option_is_one_line_naming_the_one_meant(capsys, monkeypatch, script):
    """Every script's parser is ``benchmarks._args.Parser``: argparse's usage block is not
    printed above an error (it was, in 26 of them), and where the error is the mistyped
    option (a script with required arguments names those first) it names the one meant."""
    import argparse

    module = import_module(f"benchmarks.{script}")
    parsers: list = []
    real = argparse.ArgumentParser.parse_known_args

    def spy(self, *args, **kwargs):
        parsers.append(self)
        return real(self, *args, **kwargs)

    monkeypatch.setattr(argparse.ArgumentParser, "parse_known_args", spy)

    def refusal(argv: list[str]) -> tuple[int, str]:
        try:
            code = module.main(argv)
        except SystemExit as stop:
            code = stop.code
        return code, capsys.readouterr().err

    code, err = refusal(["--zz-no-such-option"])
    assert_refused(code, err, ": error: ")
    parser = parsers[0]
    assert type(parser).__name__ == "Parser" and err.startswith(f"{parser.prog}: error: "), (parser, err)
    # --help's description is a whole sentence, not the docstring's first line (12 stopped mid-phrase)
    assert parser.description.rstrip().endswith((".", ":")), parser.description
    if "unrecognized arguments" in err:
        meant = next(o for o in parser._option_string_actions if o.startswith("--") and o != "--help")
        code, err = refusal([meant + "x"])
        assert_refused(code, err, f"unrecognized arguments: {meant}x; did you mean {meant}?")


def test_a_script_run_directly_finds_its_shared_checks(tmp_path):
    """Run as a command from another folder (as the docs give them), a script finds the
    shared checks (benchmarks/_args.py) and refuses in one line; beacon_surfacing.py printed
    zeros for a scenario without a beacon AUV, with exit 0."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    r = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "beacon_surfacing.py"), "--runs", "2", "--scenario", "sousa_asv"],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path,
        env=env,
    )
    assert_refused(r.returncode, r.stderr, "no beacon AUV")


def test_the_nees_and_profile_scripts_read_set_as_evaluate_does():
    """nees_per_cycle (and beacon_covariance through it) and sim_profile had parsers of their
    own, which took a key given twice as its last value and a misspelt key as a new one."""
    from benchmarks.nees_per_cycle import parse_sets

    assert parse_sets(["beacon_error_fusion=white", "depth_m=5"]) == {"beacon_error_fusion": "white", "depth_m": 5.0}
    with pytest.raises(ValueError, match="--set beacon_error_fusion given twice"):
        parse_sets(["beacon_error_fusion=white", "beacon_error_fusion=schmidt"])
    with pytest.raises(ValueError, match="did you mean 'beacon_error_fusion'"):
        parse_sets(["beacon_eror_fusion=white"])
    r = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "sim_profile.py"), "--set", "depth_m=5", "--set", "depth_m=6"],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=ROOT,
    )
    assert r.returncode == 2 and "--set depth_m given twice" in r.stderr, r.stderr[-400:]
