"""The evaluation (evaluation/ and its front ends evaluate.py / coopnav-evaluate) on tiny
runs: files, columns, common random numbers, resume, sweeps, the library API against the
command line, and bad input (one line, exit status 2, before any work)."""

import csv
import json
import os
import subprocess
import sys

import pytest

from evaluation import cli as evaluate

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

TINY = ["--scenario", "gao_lawnmower", "--set", "max_cycles=3"]


def rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    out = str(tmp_path_factory.mktemp("eval") / "run")
    code = evaluate.main(TINY + ["--policies", "static,fim_a,random", "--episodes", "2", "--seed", "5", "--out", out])
    assert code == 0
    return out


def test_outputs_and_columns(tiny_run):
    for name in (
        "summary.json",
        "summary.md",
        "episodes.csv",
        "steps.csv",
        "run.json",
        "paths.png",
        "error_vs_time.png",
        "ellipse_axes.png",
    ):
        assert os.path.getsize(os.path.join(tiny_run, name)) > 0, name
    assert not [f for f in os.listdir(tiny_run) if f.endswith(".tmp")]
    with open(os.path.join(tiny_run, "summary.json")) as f:
        summary = json.load(f)
    assert summary["scenario"] == "gao_lawnmower" and summary["episodes"] == 2
    assert set(summary["policies"]) == {"static", "fim_a", "random"}
    keys = {
        "mean_error_m",
        "median_error_m",
        "p95_error_m",
        "std_error_m",
        "ci95_error_m",
        "final_error_m",
        "mean_return",
        "ranges_fused",
        "outliers_rejected",
        "beacon_distance_m",
    }
    for stats in summary["policies"].values():
        assert keys <= set(stats)
        lo, hi = stats["ci95_error_m"]
        assert lo <= stats["mean_error_m"] <= hi
    eps = rows(os.path.join(tiny_run, "episodes.csv"))
    assert len(eps) == 3 * 2
    assert {
        "policy",
        "episode",
        "seed",
        "mean_error_m",
        "final_error_m",
        "return",
        "ranges_fused",
        "outliers_rejected",
        "beacon_distance_m",
    } <= set(eps[0])
    assert sorted({r["seed"] for r in eps}) == ["5", "6"]
    steps = rows(os.path.join(tiny_run, "steps.csv"))
    assert len(steps) == 3 * 2 * 3
    md = open(os.path.join(tiny_run, "summary.md")).read()
    assert "| fim_a |" in md and "95% CI" in md


def test_common_random_numbers(tiny_run):
    """Every policy sees the same episode: the first step's dead-reckoning error (which no
    beacon can change) is identical across policies."""
    steps = rows(os.path.join(tiny_run, "steps.csv"))
    first = {}
    for r in steps:
        if r["step"] == "1":
            first.setdefault(r["seed"], set()).add(r["dr_error_m"])
    assert all(len(v) == 1 for v in first.values())


def test_resume_skips_done_episodes(tmp_path, capsys):
    out = str(tmp_path / "r")
    assert evaluate.main(TINY + ["--policies", "static,ellipse", "--episodes", "2", "--out", out, "--no-figures"]) == 0
    before = rows(os.path.join(out, "episodes.csv"))
    # an interrupted run: the last episode of one policy is missing from the files
    with open(os.path.join(out, "episodes.csv")) as f:
        lines = f.readlines()
    with open(os.path.join(out, "episodes.csv"), "w") as f:
        f.writelines(lines[:-1])
    assert (
        evaluate.main(
            TINY + ["--policies", "static,ellipse", "--episodes", "3", "--out", out, "--no-figures", "--resume"]
        )
        == 0
    )
    after = rows(os.path.join(out, "episodes.csv"))
    assert len(after) == 2 * 3
    keep = {(r["policy"], r["seed"]): r for r in after}
    for r in before:  # re-run episodes reproduce, kept ones are untouched
        assert keep[(r["policy"], r["seed"])]["mean_error_m"] == r["mean_error_m"]
    steps = rows(os.path.join(out, "steps.csv"))
    assert len(steps) == 2 * 3 * 3
    # resuming into a run of another scenario is refused
    code = evaluate.main(
        ["--scenario", "sousa_asv", "--policies", "static", "--episodes", "1", "--out", out, "--resume"]
    )
    assert code == 2
    # a folder that does not exist is said so (a mistyped one is seen at once); the run starts afresh,
    # since the resume command a killed run prints must work before its folder exists
    code = evaluate.main(TINY + ["--policies", "static", "--out", str(tmp_path / "r_typo"), "--resume", "--no-figures"])
    assert code == 0 and "does not exist: nothing to keep" in capsys.readouterr().err


def test_sweep_writes_the_table_layout(tmp_path):
    out = str(tmp_path / "s")
    code = evaluate.main(
        [
            "--scenario",
            "sousa_asv",
            "--set",
            "max_cycles=2",
            "--policies",
            "fim_a,static",
            "--episodes",
            "1",
            "--sweep",
            "depth_m=1,50",
            "--sweep",
            "survey_path=stationary,circle",
            "--out",
            out,
        ]
    )
    assert code == 0
    summary = json.load(open(os.path.join(out, "summary.json")))
    assert len(summary["cells"]) == 4
    assert summary["cells"][0]["params"] == {"depth_m": 1.0, "survey_path": "stationary"}
    md = open(os.path.join(out, "summary.md")).read()
    assert "## fim_a: mean error (m) / variance (m^2)" in md
    assert "| depth_m | stationary | circle |" in md
    eps = rows(os.path.join(out, "episodes.csv"))
    assert len(eps) == 4 * 2 and {"depth_m", "survey_path"} <= set(eps[0])
    assert os.path.getsize(os.path.join(out, "sweep.png")) > 0


@pytest.mark.parametrize(
    "argv,needle",
    [
        (["--policies", "static,nope"], "unknown policy 'nope'"),
        (["--policies", "ellipse:rang_model=filter"], "did you mean 'range_model'?"),
        (["--policies", "ellipse:range_model=d2"], "range_model must be one of"),
        (["--policies", "fim_a:range_model=filter"], "takes no setting 'range_model'; it takes none"),
        (["--scenario", "atlantis"], "unknown scenario 'atlantis'"),
        (["--sweep", "depth=1,5"], "depth"),
        (["--sweep", "survey_path=stationary,zigzag"], "zigzag"),
        (["--sweep", "depth_m=1,deep"], "deep"),
        (["--set", "max_cycles=2.5"], "max_cycles"),
        (["--set", "depth_m=-3"], "depth_m"),
        (["--set", "max_cycles=5", "--set", "max_cycles=10"], "--set max_cycles given twice"),  # which one?
        (["--episodes", "0"], "--episodes"),
        (["--bogus"], "unrecognized"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, argv, needle):
    out = tmp_path / "never"
    code = evaluate.main(["--out", str(out)] + argv)
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and needle in err, err
    assert not out.exists()  # no work done


def test_output_path_that_is_a_file(tmp_path):
    f = tmp_path / "file.txt"
    f.write_text("x")
    proc = subprocess.run(
        [sys.executable, os.path.join(ROOT, "evaluate.py"), "--out", str(f), "--episodes", "1"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2
    assert len(proc.stderr.strip().splitlines()) == 1 and "is a file" in proc.stderr
    assert proc.stdout == ""
    assert f.read_text() == "x"


def test_a_trained_run_directory_evaluates_beside_the_planners(tmp_path):
    """--policies RUN_DIR,static: a policy written by train.py runs through agents/."""
    import yaml

    from agents.training import cli as train

    hp = {
        "n_envs": 2,
        "ppo": {"n_steps": 32, "batch_size": 64, "n_epochs": 1, "policy_kwargs": {"net_arch": [8]}},
        "env": {"overrides": {"max_cycles": 4}},
        "eval": {"every_steps": 10**9, "episodes": 1, "seed": 7, "baselines": []},
        "checkpoint_every_steps": 10**9,
    }
    cfg = tmp_path / "hp.yml"
    cfg.write_text(yaml.safe_dump(hp))
    run = tmp_path / "ppo_run"
    assert (
        train.main(
            [
                "--scenario",
                "gao_lawnmower",
                "--timesteps",
                "64",
                "--seed",
                "1",
                "--out",
                str(run),
                "--config",
                str(cfg),
                "--no-progress",
            ]
        )
        == 0
    )
    out = tmp_path / "eval"
    code = evaluate.main(
        TINY + ["--policies", f"{run},static", "--episodes", "2", "--seed", "3", "--out", str(out), "--no-figures"]
    )
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["policies"]) == {str(run), "static"}
    assert summary["policies"][str(run)]["mean_error_m"] > 0


def test_library_api_gives_what_the_command_line_gives(tmp_path):
    """run_evaluation(EvalConfig(...)) and main([...]) with the same arguments: the same
    summary; run.json records the versions, summary.md defines its columns."""
    from evaluation import EvalConfig, run_evaluation

    cli_out, api_out = tmp_path / "cli", tmp_path / "api"
    assert (
        evaluate.main(
            [
                "--scenario",
                "gao_lawnmower",
                "--policies",
                "fim_a,static",
                "--episodes",
                "2",
                "--set",
                "max_cycles=4",
                "--out",
                str(cli_out),
                "--no-figures",
            ]
        )
        == 0
    )
    summary = run_evaluation(
        EvalConfig(
            scenario="gao_lawnmower",
            policies=("fim_a", "static"),
            episodes=2,
            overrides={"max_cycles": 4},
            out=str(api_out),
            figures=False,
        )
    )
    assert summary == json.loads((cli_out / "summary.json").read_text())
    assert summary == json.loads((api_out / "summary.json").read_text())
    assert (api_out / "steps.csv").read_text() == (cli_out / "steps.csv").read_text()
    run = json.loads((api_out / "run.json").read_text())
    assert "git_commit" in run["versions"] and run["versions"]["numpy"]
    assert run["policies"] == ["fim_a", "static"] and run["trained_policies"] == {}
    md = (api_out / "summary.md").read_text()
    assert "## Columns" in md and "**mean (m)** (`mean_error_m`, m)" in md and "unitless" in md


def test_eval_config_refuses_unknown_fields_naming_the_closest():
    from evaluation import EvalConfig, UsageError

    with pytest.raises(TypeError, match="did you mean 'episodes'"):
        EvalConfig(episods=3)
    with pytest.raises(TypeError, match="did you mean 'overrides'"):
        EvalConfig().replace(overides={})
    with pytest.raises(UsageError, match="--batch-size must be >= 1"):
        EvalConfig(batch_size=0)
    assert EvalConfig(policies="fim_a, static").policies == ("fim_a", "static")


def test_ppo_resolution_is_recorded(tmp_path):
    """ "ppo" on gao_lawnmower is the shipped ppo_gao_lawnmower: run.json's trained_policies and
    summary.md say so; prepare checks that it drives the scenario and writes nothing."""
    from evaluation import EvalConfig, prepare
    from evaluation.report import trained_lines

    plan = prepare(EvalConfig(policies="ppo,static", out=str(tmp_path / "x")))
    r = plan.trained["ppo"]
    assert r["shipped"] == "ppo_gao_lawnmower" and r["model"].startswith("agents/policies/ppo_gao_lawnmower/")
    assert "shipped policy `ppo_gao_lawnmower`" in trained_lines(plan.trained)[0]
    assert not (tmp_path / "x").exists()


def test_column_docs_cover_every_column(tiny_run):
    from evaluation.report import EPISODE_COLUMN_DOCS, STEP_COLUMN_DOCS, SUMMARY_COLUMN_DOCS

    for name, docs in (("episodes.csv", EPISODE_COLUMN_DOCS), ("steps.csv", STEP_COLUMN_DOCS)):
        with open(os.path.join(tiny_run, name), newline="") as f:
            assert next(csv.reader(f)) == list(docs)
        assert all(len(v) == 2 and v[1] for v in docs.values())
    with open(os.path.join(tiny_run, "summary.json")) as f:
        stats = next(iter(json.load(f)["policies"].values()))
    assert set(stats) <= set(SUMMARY_COLUMN_DOCS)  # and the moving network's frame errors


def test_a_planner_with_settings_is_a_column_of_its_own(tmp_path):
    """``--policies ellipse,ellipse:range_model=filter``: the same planner with one setting
    changed, each its own column, on the same episodes (common random numbers)."""
    out = str(tmp_path / "run")
    policies = "ellipse,ellipse:range_model=filter"
    code = evaluate.main(["--scenario", "gao_lawnmower", "--policies", policies, "--episodes", "2", "--out", out])
    assert code == 0
    eps = rows(os.path.join(out, "episodes.csv"))
    assert {e["policy"] for e in eps} == {"ellipse", "ellipse:range_model=filter"}
    assert len(eps) == 4
