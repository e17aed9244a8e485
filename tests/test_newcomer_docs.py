"""One story (issue 24): the commands in docs/getting-started.md and the README parse with
the command lines they name and name real scenarios, policies and task sets; the two
pages state the same CI install, test count, times and figures; help texts name the
command as invoked; mistyped names get a 'did you mean'; the figures a newcomer is
promised exist."""

from __future__ import annotations

import json
import re
import shlex
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = {"README.md": ROOT / "README.md", "getting-started": ROOT / "docs" / "getting-started.md"}


def _commands(text: str) -> list:
    """Every command of the page's ```bash blocks and `inline` code that runs one of the
    project's command lines, split into words (``&&`` chains split, comments dropped)."""
    blocks = re.findall(r"```bash\n(.*?)```", text, flags=re.S)
    found = []
    for block in blocks:
        for line in block.replace("\\\n", " ").splitlines():
            for part in line.split("&&"):
                part = part.split("  #")[0].strip()
                words = shlex.split(part, comments=True) if part else []
                if words:
                    found.append(words)
    return found


def _parse(words: list):
    """(front end, parsed args) for a command of the project, else None."""
    from agents.training.cli import build_parser as train_parser
    from evaluation.benchmark import build_parser as bench_parser
    from evaluation.cli import build_parser as eval_parser

    if words[:2] == ["python", "evaluate.py"] or words[:1] == ["coopnav-evaluate"]:
        rest = words[2:] if words[0] == "python" else words[1:]
        return "evaluate", eval_parser("evaluate.py").parse_args(rest)
    if words[:2] == ["python", "train.py"] or words[:1] == ["coopnav-train"]:
        rest = words[2:] if words[0] == "python" else words[1:]
        return "train", train_parser("train.py").parse_args(rest)
    if words[:3] == ["python", "-m", "evaluation.benchmark"] or words[:1] == ["coopnav-benchmark"]:
        rest = words[3:] if words[0] == "python" else words[1:]
        return "benchmark", bench_parser("coopnav-benchmark").parse_args(rest)
    return None


def _check_policies(names: str, valid: set):
    for p in names.split(","):
        assert p in valid or p.startswith(("runs/", "results/")), p


@pytest.mark.parametrize("page", list(PAGES))
def test_the_pages_commands_parse_and_name_real_things(page):
    import agents
    import baselines
    import coopnav_env
    from evaluation.tasks import TASK_SETS

    scenarios = set(coopnav_env.list_scenarios())
    policies = set(baselines.list_policies()) | {"ppo"} | set(agents.list_policies())
    parsed = [p for p in map(_parse, _commands(PAGES[page].read_text())) if p is not None]
    assert {kind for kind, _ in parsed} >= ({"evaluate", "train"} if page == "getting-started" else {"evaluate"}), (
        parsed
    )
    for kind, args in parsed:
        if getattr(args, "scenario", None) is not None:
            assert args.scenario in scenarios, args.scenario
        if getattr(args, "policies", None):
            _check_policies(args.policies, policies)
        if kind == "benchmark" and args.tasks:
            assert set(args.tasks.split(",")) <= set(TASK_SETS) | {"all"}, args.tasks


def _flat(text: str) -> str:
    return " ".join(text.split())


def test_ci_install_and_test_count_are_one_story():
    ci = (ROOT / ".ci" / "run").read_text()
    extras = re.search(r'pip install -q -e "(\.\[[^\]]+\])"', ci).group(1)
    assert "mkdocs build" in ci
    counts = set()
    for name, path in PAGES.items():
        text = _flat(path.read_text())
        assert f'pip install -e "{extras}"' in text, (name, extras)
        assert "mkdocs build --strict" in text, name
        m = re.search(r"about (\d+) tests in about (\d+) minutes", text)
        assert m, name
        counts.add(m.groups())
    assert len(counts) == 1, counts  # "about": the count is not checked against the suite, only kept the same


def test_the_readmes_planner_table_is_the_results_pages():
    """The README's headline planner rows are docs/results.md#planners' (the results page is
    re-run when the physics changes; the README's copy went stale once, a round behind)."""

    def rows(text: str) -> dict:
        table = {}
        for line in text.splitlines():
            m = re.match(r"\| (fim_a|ellipse|static|dead reckoning) \| ([^|]+) \| ([^|]+) \|$", line.strip())
            if m:
                table.setdefault(m.group(1), (m.group(2).strip(), m.group(3).strip()))
        return table

    readme = rows((ROOT / "README.md").read_text().split("## Headline results", 1)[1])
    results = rows((ROOT / "docs" / "results.md").read_text().split("{#planners}", 1)[1])
    assert set(readme) == {"fim_a", "ellipse", "static", "dead reckoning"}, readme
    assert all(readme[k] == results[k] for k in readme), (readme, results)


def test_the_times_table_is_one_story_and_names_its_command():
    guide = (ROOT / "docs" / "getting-started.md").read_text()
    readme = _flat((ROOT / "README.md").read_text())
    table = guide[guide.index("## How long things take") : guide.index("## A first environment loop")]
    assert "python benchmarks/times.py" in table and "python benchmarks/times.py" in readme
    assert (ROOT / "benchmarks" / "times.py").is_file()
    for figure in (
        "3.5 min",
        "under 3 min",
        "11 min 34 s",
        "about 25 min",
        "9 min 44 s",
        "23 s",
        "8 min 41 s",
        "16 min 28 s",
        "27 min 18 s",
        "30 min 31 s",
    ):
        assert figure in table and figure in readme, figure
    items = _times_items()
    for item in ("ci", "quickstart", "first_training", "time_to_beat", "benchmark:sousa_ping"):
        assert item in items, item
    # a task set's log shows a line per task and policy: an hour-long run can be followed
    assert all("--no-progress" not in cmd for name, (_, cmd, _) in items.items() if name.startswith("benchmark"))


def _times_items() -> dict:
    import importlib.util

    spec = importlib.util.spec_from_file_location("times", ROOT / "benchmarks" / "times.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module._items(Path("/nonexistent"))


def test_the_promised_figures_are_in_the_docs():
    for page, figure in (
        ("getting-started.md", "figures/learning_curve.png"),
        ("benchmark.md", "figures/benchmark_gao_lawnmower.png"),
    ):
        assert figure in (ROOT / "docs" / page).read_text(), (page, figure)
        assert (ROOT / "docs" / figure).is_file(), figure


def test_help_texts_name_the_command_as_invoked():
    from agents.training.cli import build_parser

    text = build_parser("coopnav-train").format_help()
    assert "coopnav-train --scenario sousa_asv" in text and "  train.py --" not in text
    assert "--plot RUN" in text
    assert "python -m agents.convert" not in text


def test_train_out_on_a_folder_that_is_not_a_run_does_not_suggest_resume(tmp_path):
    from agents.training.common import new_run_dir
    from agents.training.config import ConfigError

    (tmp_path / "summary.json").write_text("{}")
    with pytest.raises(ConfigError) as err:
        new_run_dir(tmp_path)
    assert "--resume" not in str(err.value) and "not a train.py run" in str(err.value)


@pytest.mark.parametrize(
    "argv, hint",
    [
        (["--scenario", "sousa_asx", "--policies", "fim_a"], "did you mean 'sousa_asv'?"),
        (["--scenario", "sousa_asv", "--policies", "fim_c"], "did you mean 'fim_"),
    ],
)
def test_evaluate_suggests_the_closest_name(tmp_path, capsys, argv, hint):
    from evaluation.cli import main

    assert main(argv + ["--out", str(tmp_path / "x")], prog="evaluate.py") == 2
    err = capsys.readouterr().err
    assert hint in err and len(err.strip().splitlines()) == 1, err


@pytest.mark.parametrize(
    "argv, hint",
    [
        (["--tasks", "sousa_grd"], "did you mean 'sousa_grid'?"),
        (["--tasks", "gao_sea", "--task", "calmm"], "did you mean 'calm'?"),
    ],
)
def test_benchmark_suggests_the_closest_name(tmp_path, capsys, argv, hint):
    from evaluation.benchmark import main

    assert main(argv + ["--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert hint in err and len(err.strip().splitlines()) == 1, err


def test_training_and_planners_suggest_the_closest_name(tmp_path, capsys):
    import baselines
    import coopnav_env
    from agents.training import cli

    assert cli.main(["--scenario", "gao_se", "--timesteps", "10", "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert "did you mean 'gao_sea'?" in err and len(err.strip().splitlines()) == 1, err
    with pytest.raises(ValueError, match="did you mean 'ellipse'"):
        baselines.make_policy("elipse", coopnav_env.make_config("gao_lawnmower"))


def test_plot_redraws_a_learning_curve(tmp_path, capsys):
    from agents.training import cli

    run = tmp_path / "run"
    run.mkdir()
    (run / "config.yml").write_text("args: {scenario: sousa_asv, timesteps: 2048, seed: 0}\n")
    rows = [
        {
            "num_timesteps": 1024 * k,
            "train_s": 3.0 * k,
            "wall_s": 4.0 * k,
            "survey_error_m": 2.0 / k,
            "fim_a_survey_error_m": 1.2,
        }
        for k in (1, 2)
    ]
    rows.append({"num_timesteps": 3072, "train_s": 9.0, "survey_error_m": 400.0})  # a blow-up, clipped
    (run / "evaluations.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    (run / "baseline_eval.json").write_text(json.dumps({"fim_a": {"survey_error_m": 1.2, "per_cell": {}}}))
    (run / "best.json").write_text(json.dumps(rows[1]))
    assert cli.main(["--plot", str(run)]) == 0
    png = run / "learning_curve.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "config.yml").write_text("args: {scenario: sousa_asv}\n")
    assert cli.main(["--plot", str(empty)]) == 2
    assert "no validation yet" in capsys.readouterr().err


def test_plot_draws_a_run_whose_files_were_edited_by_hand(tmp_path):
    """A line of evaluations.jsonl with a non-number, a planner score that is not a number, a
    best.json that is not an object: drawn from what is usable, where they were tracebacks
    (statistics.median of a string, a list's .get; an input audit, 2026-12-07)."""
    from agents.training import cli

    run = tmp_path / "run"
    run.mkdir()
    (run / "config.yml").write_text("args: {scenario: sousa_asv, timesteps: 2048, seed: 0}\n")
    rows = [
        {"num_timesteps": 1024, "train_s": "3", "survey_error_m": 2.0},
        {"num_timesteps": 2048, "train_s": 6.0, "survey_error_m": "x"},  # skipped
        {"num_timesteps": 3072, "train_s": 9.0, "survey_error_m": 1.5},
    ]
    (run / "evaluations.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    (run / "baseline_eval.json").write_text(json.dumps({"fim_a": {"survey_error_m": "x"}, "ellipse": 3}))
    (run / "best.json").write_text("[1, 2]")
    assert cli.main(["--plot", str(run)]) == 0
    assert (run / "learning_curve.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_paths_figure_grid_leaves_at_most_one_slot_and_uses_it_for_the_legend():
    from evaluation.figures import panel_grid

    assert panel_grid(1) == (1, 1) and panel_grid(3) == (1, 3)
    assert panel_grid(4) == (2, 2) and panel_grid(6) == (2, 3)
    for n in range(1, 13):
        rows, cols = panel_grid(n)
        assert rows * cols >= n and rows * cols - n <= 1 and cols <= 3, n


def test_benchmark_figure_from_results(tmp_path):
    from evaluation.benchmark import compare_task
    from evaluation.figures import draw_benchmark

    errors = {"fim_a": [1.0, 1.2, 1.1], "ellipse": [1.3, 1.2, 1.4], "static": [9.0, 8.0, 10.0], "mine": [0.9, 1.0, 1.0]}
    task = {"overrides": {}, "about": "", **compare_task(errors, ["fim_a", "ellipse"])}
    results = {
        "episodes": 3,
        "official": False,
        "task_sets": {
            "toy": {
                "scenario": "gao_sea",
                "columns": list(errors),
                "planners": ["fim_a", "ellipse"],
                "floors": ["static"],
                "challengers": ["mine"],
                "tasks": {"a": task, "b": task},
            }
        },
    }
    assert draw_benchmark(str(tmp_path), results) == ["benchmark_toy.png"]
    assert (tmp_path / "benchmark_toy.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_more_threads_than_cpus_is_refused_naming_the_count(capsys, tmp_path):
    """--threads 100000 aborted the process in torch's OpenMP (exit 134, an input audit): now
    one line naming the machine's CPU count, the closest valid value."""
    import os

    from agents.training import cli

    cpus = os.cpu_count() or 1
    args = ["--scenario", "sousa_asv", "--timesteps", "10", "--out", str(tmp_path / "r"), "--threads", "100000"]
    assert cli.main(args) == 2
    assert f"at most {cpus}" in capsys.readouterr().err
    assert cli.threads_arg(str(cpus)) == cpus


@pytest.mark.parametrize(
    ("args", "what"),
    [(["--seeds", "-1"], "--seeds: each in"), (["--budget-s", "nan"], "--budget-s finite")],
)
def test_time_to_beat_refuses_bad_input_before_training(tmp_path, capsys, args, what):
    """A negative seed reached train.py and failed there after the run had begun; a NaN budget
    was a ZeroDivisionError traceback (an input audit): now one line, exit 2, nothing run."""
    from benchmarks import time_to_beat

    with pytest.raises(SystemExit) as exit_info:
        time_to_beat.main([*args, "--out", str(tmp_path / "ttb")])
    assert exit_info.value.code == 2 and what in capsys.readouterr().err
    assert not (tmp_path / "ttb").exists()
