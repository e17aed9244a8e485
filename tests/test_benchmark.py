"""evaluation.benchmark: the test seeds are apart from every seed training draws (and the
trainers refuse them), the paired statistics on a case with a known answer, and one
tiny run of the command."""

import json
import time

import numpy as np
import pytest
from scipy import stats

from coopnav_env import seeds
from coopnav_env.seeds import (
    MAX_SEED,
    TEST_SEED,
    TEST_SEEDS,
    TRAINING_COPY_BOUND,
    TRAINING_EPISODE_BOUND,
    TRAINING_SEED_LIMIT,
    VALIDATION_SEED,
    is_test_seed,
    max_training_seed,
    refuse_test_seeds,
)
from coopnav_env.vector import SEED_STRIDE, CoopNavVecEnv
from evaluation import benchmark
from evaluation.benchmark import BenchmarkPlan, compare_task, render_markdown, summarize_task_set
from evaluation.benchmark_stats import headroom_task, summarize_headroom
from evaluation.tasks import FLOORS, NON_GREEDY, REFERENCES, TASK_SETS

# ------------------------------------------------------------------------------------
# seed separation


def test_every_task_set_plays_test_seeds_only():
    assert TEST_SEEDS[0] == TEST_SEED == 2**62 - 2**20 and TEST_SEEDS[-1] == MAX_SEED
    for name, ts in TASK_SETS.items():
        plan = BenchmarkPlan(sets=[], challengers=[], episodes=ts.episodes, overrides={}, out="")
        assert len(plan.seeds) == ts.episodes and all(is_test_seed(s) for s in plan.seeds), name
        assert len({t.name for t in ts.tasks}) == len(ts.tasks), name
        assert ts.planners and not set(ts.planners) & set(FLOORS), name
        assert not set(ts.planners) & set(REFERENCES) and not set(ts.greedy_planners) & set(NON_GREEDY), name
        # every task set carries the oracle (the headroom's reference; the boats': baselines/boat_horizon.py)
        assert [r.partition("+")[0] for r in ts.references] == ["oracle"], name
        # no planner looking ahead (on any transmit schedule) is among the greedy ones
        assert not {p.partition("+")[0] for p in ts.greedy_planners} & set(NON_GREEDY), name
    # on the shared channel the planners and the oracle also transmit on the clock schedule (v7)
    assert {"ellipse+clock", "horizon+clock"} <= set(TASK_SETS["sousa_ping"].planners)
    assert TASK_SETS["sousa_ping"].references == ["oracle+clock"]
    assert not is_test_seed(TEST_SEED - 1) and not is_test_seed(VALIDATION_SEED) and not is_test_seed(0)


def test_training_seeds_cannot_reach_the_test_seeds_within_the_documented_bound():
    # the arithmetic of coopnav_env.seeds, at the worst accepted seed and the bounds
    assert seeds.TRAINING_SEED_STRIDE == SEED_STRIDE
    worst = max_training_seed(TRAINING_SEED_LIMIT - 1, TRAINING_COPY_BOUND, TRAINING_EPISODE_BOUND)
    assert worst < 2**61 + 2**31 + 2**41 * 1_000_003 < TEST_SEED
    assert TEST_SEED - worst > 10**17
    assert max_training_seed(10**9, 1024, 10**12) < TEST_SEED  # a realistic seed: 10**12 episodes of each copy
    # ... and that formula is what the VecEnv draws: episode k of env e is seed + e + k * SEED_STRIDE
    seed = TRAINING_SEED_LIMIT - 1
    venv = CoopNavVecEnv("gao_lawnmower", n_envs=2, seed=seed, max_cycles=2)
    venv.reset()
    drawn = {int(s) for s in venv.episode_seeds}
    for _ in range(6):  # three episodes of each env
        venv.step(np.zeros((2, 2)))
        drawn |= {int(s) for s in venv.episode_seeds}
    assert drawn == {max_training_seed(seed, e + 1, k + 1) for e in range(2) for k in range(4)}
    assert max(drawn) == seed + 1 + 3 * SEED_STRIDE and not any(is_test_seed(s) for s in drawn)


def test_refuse_test_seeds_is_one_line():
    refuse_test_seeds(TRAINING_SEED_LIMIT - 4, 4, "eval.seed")  # up to the limit - 1: fine
    for first, count in ((TRAINING_SEED_LIMIT - 3, 4), (TEST_SEED, 1), (TEST_SEED - 1, 2)):
        with pytest.raises(ValueError, match=r"^eval\.seed .*reserved seeds") as exc:
            refuse_test_seeds(first, count, "eval.seed")
        assert "\n" not in str(exc.value)


def _configs():
    from agents.training import PeriodicEvalSpec, RLlibConfig, TrainConfig
    from agents.training.config import EvalSpec

    base = dict(scenario="gao_lawnmower", timesteps=100)
    return [
        ("seed", TrainConfig(**base, seed=TEST_SEED + 5)),
        ("eval.seed", TrainConfig(**base, eval=PeriodicEvalSpec(seed=TEST_SEED - 2, episodes=4))),
        ("seed", RLlibConfig(**base, seed=TEST_SEED)),
        ("eval.seed", RLlibConfig(**base, eval=EvalSpec(seed=TEST_SEED - 10, episodes=16))),
        ("eval.seed", TrainConfig(**base, eval=PeriodicEvalSpec(seed=TRAINING_SEED_LIMIT - 1, episodes=2))),
    ]


@pytest.mark.parametrize("index", range(5))
def test_the_trainers_refuse_a_config_reaching_the_test_seeds(index):
    from agents.training import ConfigError
    from agents.training.common import prepare_job

    what, config = _configs()[index]
    with pytest.raises(ConfigError, match=f"^{what} .*reserved seeds") as exc:
        prepare_job(config)
    assert "\n" not in str(exc.value)


def test_the_trainers_accept_seeds_below_the_limit():
    from agents.training import PeriodicEvalSpec, TrainConfig
    from agents.training.common import prepare_job

    job = prepare_job(
        TrainConfig(
            scenario="gao_lawnmower",
            timesteps=100,
            seed=TRAINING_SEED_LIMIT - 1,
            eval=PeriodicEvalSpec(seed=TRAINING_SEED_LIMIT - 32, episodes=32),
        )
    )
    assert job.scenario_config.name == "gao_lawnmower"  # accepted: a job, not a ConfigError


def test_train_py_refuses_a_test_seed_with_one_line_and_exit_2(tmp_path, capsys):
    from agents.training import cli

    rc = cli.main(
        [
            "--scenario",
            "gao_lawnmower",
            "--timesteps",
            "100",
            "--seed",
            str(TEST_SEED),
            "--out",
            str(tmp_path / "run"),
            "--no-progress",
        ]
    )
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and "reserved seeds" in err
    assert not (tmp_path / "run").exists()


# ------------------------------------------------------------------------------------
# the statistics, on a toy case with a known answer


def test_paired_difference_and_interval_on_a_known_case():
    rng = np.random.default_rng(0)
    a = rng.uniform(2.0, 8.0, 5)  # large episode-to-episode spread: common random numbers remove it
    eps = np.array([0.1, -0.1, 0.2, -0.2, 0.0])
    episodes = {
        "fim_a": a,
        "circle": a + 1.0,  # a worse planner
        "static": a - 2.0,  # a floor, better than every planner: never the best planner
        "ppo": a - 0.5 + eps,  # the challenger: 0.5 m better, exactly, plus noise we know
        "tie": a + np.array([0.3, -0.3, 0.1, -0.1, 0.0]),
        "worse": a + 0.5 + eps,
        "other_team": None,
    }
    task = compare_task(
        episodes,
        planners=["fim_a", "circle"],
        ranges_fused={"ppo": [10, 11, 12, 13, 14]},
        skipped={"other_team": "observations of size 21"},
    )
    assert task["best_planner"] == "fim_a"
    d = task["policies"]["ppo"]["paired"]
    h = stats.t.ppf(0.975, 4) * eps.std(ddof=1) / np.sqrt(5)  # = 2.776 * 0.1581 / 2.236 = 0.196
    assert d["vs"] == "fim_a" and d["mean_m"] == pytest.approx(-0.5, abs=1e-12)
    assert d["ci95_m"] == pytest.approx([-0.5 - h, -0.5 + h], abs=1e-12)
    assert h == pytest.approx(0.1963, abs=1e-4) and d["verdict"] == "win"
    assert task["policies"]["ppo"]["mean_error_m"] == pytest.approx(a.mean() - 0.5)
    assert task["policies"]["ppo"]["ranges_fused"] == 12.0
    lo, hi = task["policies"]["ppo"]["ci95_error_m"]  # the unpaired interval is far wider than the paired one
    assert hi - lo > 10 * 2 * h
    assert task["policies"]["tie"]["paired"]["verdict"] == "tie"
    assert task["policies"]["worse"]["paired"]["verdict"] == "loss"
    assert task["policies"]["worse"]["paired"]["mean_m"] == pytest.approx(0.5)
    assert task["policies"]["fim_a"]["paired"]["verdict"] == "best"
    assert task["policies"]["static"]["paired"]["verdict"] == "win"  # a floor may beat the planners: reported
    assert task["policies"]["other_team"] == {"skipped": "observations of size 21"}
    assert task["wins"] == ["static", "ppo"]

    summary = summarize_task_set({"t1": task, "t2": task}, ["fim_a", "ppo", "tie", "worse", "other_team"])
    assert summary["ppo"] == {"win": 2, "tie": 0, "loss": 0, "best": 0, "n/a": 0, "tasks_won": ["t1", "t2"]}
    assert summary["fim_a"]["best"] == 2 and summary["worse"]["loss"] == 2 and summary["other_team"]["n/a"] == 2


def _task_with(means: dict, oracle_noise: float = 0.0) -> dict:
    """A task whose policies' per-episode errors are ``means`` plus a shared episode offset."""
    offset = np.array([0.4, -0.4, 0.2, -0.2])
    errors = {p: m + offset for p, m in means.items()}
    if "oracle" in errors:
        errors["oracle"] = errors["oracle"] + oracle_noise * np.array([1.0, -1.0, 1.0, -1.0])
    return compare_task(errors, [p for p in means if p not in ("oracle", "ppo")])


def test_the_headroom_fraction_on_a_hand_computed_case():
    # best greedy 10 m, oracle 6 m: a headroom of 4 m; horizon at 8 m closes (10 - 8) / 4 = 50 %
    task = _task_with({"fim_a": 10.0, "circle": 11.0, "horizon": 8.0, "oracle": 6.0, "ppo": 5.0}, oracle_noise=0.5)
    assert task["best_planner"] == "horizon"  # the win verdict stays against the best planner, horizon included
    assert task["policies"]["ppo"]["paired"]["vs"] == "horizon"
    h = headroom_task(task, ["fim_a", "circle"], ["horizon", "ppo"])
    assert h["best_greedy"] == "fim_a" and h["best_greedy_m"] == pytest.approx(10.0)
    assert h["oracle_m"] == pytest.approx(6.0) and h["headroom_m"] == pytest.approx(4.0)
    assert h["closed"]["horizon"] == pytest.approx(0.5)
    assert h["closed"]["ppo"] == pytest.approx(1.25)  # lower than the oracle: above 100 %
    # the paired headroom interval: differences 4 -+ 0.5, t(0.975, 3) * 0.5774 / 2 = 0.919
    half = stats.t.ppf(0.975, 3) * np.std([0.5, -0.5, 0.5, -0.5], ddof=1) / 2
    assert h["headroom_ci95_m"] == pytest.approx([4.0 - half, 4.0 + half]) and half == pytest.approx(0.9187, abs=1e-4)
    assert "na" not in h


@pytest.mark.parametrize("oracle_m", [10.0, 10.5])
def test_no_headroom_when_the_oracle_is_no_better_than_the_best_greedy_planner(oracle_m):
    task = _task_with({"fim_a": 10.0, "horizon": 9.0, "oracle": oracle_m})
    h = headroom_task(task, ["fim_a"], ["horizon"])  # g - o = 0 or -0.5: n/a, not a division by zero
    assert h["closed"] == {"horizon": None} and h["headroom_m"] == pytest.approx(10.0 - oracle_m)
    assert h["na"] == "oracle no better than the best greedy planner (fim_a)"


def test_a_headroom_the_paired_interval_does_not_resolve_is_not_measured():
    """g - o > 0 but its interval holds 0 (the oracle's episodes scatter): n/a, so that no fraction
    of noise is reported (matos_moving_lbl, v6: 0.003 m headrooms gave 464 % and -14144 %)."""
    task = _task_with({"fim_a": 10.0, "horizon": 9.9, "oracle": 9.95}, oracle_noise=0.5)
    h = headroom_task(task, ["fim_a"], ["horizon"])
    assert h["headroom_m"] == pytest.approx(0.05) and h["headroom_ci95_m"][0] < 0 < h["headroom_ci95_m"][1]
    assert h["closed"] == {"horizon": None} and "not resolved" in h["na"]


def test_resummarize_recomputes_the_headrooms_from_the_episodes_and_the_script_writes_them(tmp_path):
    import json
    import subprocess
    import sys

    from evaluation.benchmark import resummarize

    resolved = _task_with({"fim_a": 10.0, "horizon": 8.0, "oracle": 6.0})
    noisy = _task_with({"fim_a": 10.0, "horizon": 9.9, "oracle": 9.95}, oracle_noise=0.5)
    stale = {"tasks": 9, "closed": {"horizon": 99.0}}  # what an earlier rule wrote
    ts = {
        "planners": ["fim_a", "horizon"],
        "greedy_planners": ["fim_a"],
        "references": ["oracle"],
        "challengers": [],
        "tasks": {"a": dict(resolved, headroom=stale), "b": dict(noisy, headroom=stale)},
        "headroom": stale,
    }
    results = json.loads(json.dumps({"benchmark_version": 5, "task_sets": {"s": ts}}, default=float))
    out = resummarize(results)
    h = out["task_sets"]["s"]["headroom"]
    assert h["tasks"] == 1 and h["tasks_without"] == ["b"] and h["closed"]["horizon"] == pytest.approx(0.5)
    assert out["task_sets"]["s"]["tasks"]["b"]["headroom"]["closed"] == {"horizon": None}
    assert results["task_sets"]["s"]["headroom"] == stale  # the input is left as it was
    script = [sys.executable, "benchmarks/resummarize.py"]
    bad = subprocess.run(
        script + [str(tmp_path / "none"), "--out", str(tmp_path / "o")], capture_output=True, text=True
    )
    assert bad.returncode == 2 and "not a benchmark result" in bad.stderr and "Traceback" not in bad.stderr


def test_no_headroom_without_an_oracle_and_the_pooled_fraction():
    no_oracle = headroom_task(_task_with({"fim_a": 10.0, "horizon": 9.0}), ["fim_a"], ["horizon"])
    assert no_oracle["closed"] == {"horizon": None} and no_oracle["na"] == "no oracle ran on this task"
    skipped = compare_task({"fim_a": [1.0, 2.0], "ppo": None}, ["fim_a"], skipped={"ppo": "team size"})
    skipped["policies"]["oracle"] = {"mean_error_m": 0.5, "episode_mean_error_m": [0.4, 0.6]}
    h = headroom_task(skipped, ["fim_a"], ["ppo"])
    assert h["headroom_m"] == pytest.approx(1.0) and h["closed"] == {"ppo": None}  # ppo n/a there
    # pooled over tasks with a headroom: (10 - 8) + (5 - 5) over 4 + 1 = 40 %, the task without one left out
    tasks = {
        "a": headroom_task(_task_with({"fim_a": 10.0, "horizon": 8.0, "oracle": 6.0}), ["fim_a"], ["horizon"]),
        "b": headroom_task(_task_with({"fim_a": 5.0, "horizon": 5.0, "oracle": 4.0}), ["fim_a"], ["horizon"]),
        "c": headroom_task(_task_with({"fim_a": 5.0, "horizon": 4.0, "oracle": 5.0}), ["fim_a"], ["horizon"]),
    }
    pooled = summarize_headroom(tasks, ["horizon"])
    assert pooled["tasks"] == 2 and pooled["tasks_without"] == ["c"]
    assert pooled["closed"]["horizon"] == pytest.approx(0.4) and pooled["headroom_m"] == pytest.approx(2.5)
    assert summarize_headroom({"c": tasks["c"]}, ["horizon"])["closed"] == {"horizon": None}


def test_the_best_planner_is_the_lowest_mean_among_planners_only():
    task = compare_task({"fim_a": [3.0, 3.0], "fim_b": [2.0, 2.5], "random": [1.0, 1.0]}, ["fim_a", "fim_b"])
    assert task["best_planner"] == "fim_b"
    with pytest.raises(ValueError, match="different numbers of episodes"):
        compare_task({"fim_a": [1.0, 2.0], "ppo": [1.0]}, ["fim_a"])


# ------------------------------------------------------------------------------------
# the command


def test_a_tiny_run_of_the_command(tmp_path, capsys, monkeypatch):
    out = tmp_path / "bench"
    # the versions are the code's at the start: a commit made during the run is not recorded
    head = {"git_commit": "at-start"}
    monkeypatch.setattr(benchmark, "version_record", lambda: dict(head))
    run = benchmark.run_benchmark

    def run_then_commit(*args, **kwargs):
        raw = run(*args, **kwargs)
        head["git_commit"] = "committed-during-the-run"
        return raw

    monkeypatch.setattr(benchmark, "run_benchmark", run_then_commit)
    t0 = time.perf_counter()
    rc = benchmark.main(
        ["--tasks", "gao_lawnmower", "--episodes", "2", "--set", "max_cycles=3", "--out", str(out), "--no-progress"]
    )
    assert rc == 0, capsys.readouterr().err
    assert time.perf_counter() - t0 < 30
    results = json.loads((out / "results.json").read_text())
    assert results["official"] is False and len(results["not_official_because"]) == 2
    assert results["versions"] == {"git_commit": "at-start"}
    assert results["seeds"]["first"] == TEST_SEED and results["episodes"] == 2
    s = results["task_sets"]["gao_lawnmower"]
    assert s["columns"] == ["circle", "ellipse", "fim_a", "fim_b", "horizon", "oracle", "static", "random"]
    assert s["references"] == ["oracle"] and "horizon" not in s["greedy_planners"]
    assert list(s["tasks"]) == [t.name for t in TASK_SETS["gao_lawnmower"].tasks]
    for task in s["tasks"].values():
        assert task["best_planner"] in s["planners"]
        h = task["headroom"]
        assert h["best_greedy"] in s["greedy_planners"] and list(h["closed"]) == ["horizon"]
        assert h["headroom_m"] == pytest.approx(h["best_greedy_m"] - task["policies"]["oracle"]["mean_error_m"])
        if h["headroom_ci95_m"][0] > 0:  # measured only where its paired interval lies above 0
            g, c = h["best_greedy_m"], task["policies"]["horizon"]["mean_error_m"]
            assert h["closed"]["horizon"] == pytest.approx((g - c) / h["headroom_m"])
        else:
            assert h["closed"]["horizon"] is None and ("no better" in h["na"] or "not resolved" in h["na"])
        for p in s["columns"]:
            st = task["policies"][p]
            assert len(st["episode_mean_error_m"]) == 2 and st["ranges_fused"] >= 0
            assert st["paired"]["verdict"] in ("best", "win", "tie", "loss")
            lo, hi = st["ci95_error_m"]
            assert lo <= st["mean_error_m"] <= hi
            assert st["ms_per_act"] > 0  # the cost per decision, measured around the act calls (not timed here)
    assert set(s["ms_per_act"]) == set(s["columns"]) and all(v > 0 for v in s["ms_per_act"].values())
    assert s["headroom"]["tasks"] + len(s["headroom"]["tasks_without"]) == len(s["tasks"])
    md = (out / "results.md").read_text()
    assert "Not a benchmark result" in md and "## gao_lawnmower" in md and "### Wins over 6 tasks" in md
    assert "### Headroom: best greedy planner minus the oracle" in md and "| closed by horizon |" in md
    assert "| tasks won | ms per act |" in md
    assert md == render_markdown(results)
    assert not list(out.glob(".*.tmp*"))
    # the same --out again: refused (one line, exit 2), the result kept
    before = (out / "results.json").read_bytes()
    capsys.readouterr()
    assert benchmark.main(["--tasks", "gao_lawnmower", "--episodes", "2", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--overwrite" in err
    assert (out / "results.json").read_bytes() == before


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--tasks", "nope"], "unknown task set 'nope'"),
        (["--tasks", "gao_sea", "--policies", "fim_x"], "policy 'fim_x' can drive no task"),
        (["--tasks", "gao_sea", "--episodes", "1"], "--episodes must be in [2,"),
        (["--tasks", "gao_sea", "--set", "bogus=1"], "unknown scenario parameter"),
        (["--policies", "ppo"], "--tasks is required"),
        (["--tasks", "gao_sea", "--bogus"], "unrecognized arguments"),
        (["--task", ""], "--task names no task"),  # it ran every task of every set (an input audit)
        (["--task", ","], "--task names no task"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, argv, message):
    out = tmp_path / "bench"
    assert benchmark.main(argv + ["--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err, err
    assert not out.exists()


def test_ppo_without_a_shipped_policy_is_one_line(tmp_path, capsys, monkeypatch):
    """Every scenario ships one; with none (an empty policy directory) 'ppo' is bad input."""
    import agents

    monkeypatch.setattr(agents, "POLICY_DIR", tmp_path / "none")
    out = tmp_path / "bench"
    assert benchmark.main(["--tasks", "matos_moving_lbl", "--policies", "ppo", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "has no shipped policy" in err, err
    assert not out.exists()


def test_the_markdown_of_a_run_with_a_skipped_policy():
    task = compare_task({"fim_a": [1.0, 1.2], "ppo": None}, ["fim_a"], skipped={"ppo": "cannot drive"})
    results = {
        "benchmark_version": 1,
        "official": True,
        "not_official_because": [],
        "command": "x",
        "episodes": 2,
        "seeds": {"first": TEST_SEED},
        "versions": {"git_commit": "abc"},
        "task_sets": {
            "s": {
                "scenario": "gao_sea",
                "about": "a",
                "planners": ["fim_a"],
                "floors": [],
                "challengers": ["ppo"],
                "columns": ["fim_a", "ppo"],
                "trained_policies": {},
                "tasks": {"t": task},
                "summary": summarize_task_set({"t": task}, ["fim_a", "ppo"]),
            }
        },
    }
    md = render_markdown(results)
    assert "Not a benchmark result" not in md and "| t | fim_a | best | n/a | - |" in md
    assert "`ppo`: cannot drive" in md
    assert len(TEST_SEEDS) == seeds.TEST_SEED_COUNT


def test_the_docs_list_every_task():
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "docs" / "benchmark.md").read_text()
    for name, ts in TASK_SETS.items():
        assert f"`{name}`" in text and f"`{ts.scenario}`" in text, name
        for task in ts.tasks if name != "sousa_grid" else (ts.tasks[0], ts.tasks[-1]):
            assert f"`{task.name}`" in text, (name, task.name)
