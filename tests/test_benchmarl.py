"""coopnav as a BenchMARL task family (agents/training/benchmarl_task.py) and the training
entry ``python -m agents.training.marl``: the task configs are the benchmark's task sets,
the specs BenchMARL reads, and a tiny MAPPO experiment end to end."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from optional import require

require("benchmarl")
import torch  # noqa: E402
from safetensors.torch import load_file  # noqa: E402

from agents.training import marl  # noqa: E402
from agents.training.benchmarl_task import (  # noqa: E402
    CONFIG_DIR,
    REWARD_SCALE,
    CoopNavTask,
    default_reward_terms,
    get_task,
    register,
    scenario_config,
    task_yaml,
)
from evaluation.tasks import TASK_SETS  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
TINY = ["--frames", "512", "--n-envs", "16", "--set", "evaluation=false", "--override", "max_cycles=20"]


def test_task_configs_are_the_benchmark_task_sets():
    """One member per task set, and each YAML is generated from its task set (regenerate
    with write_task_configs, see its docstring, when a task set changes)."""
    assert [m.name.lower() for m in CoopNavTask] == list(TASK_SETS)
    for name, task_set in TASK_SETS.items():
        path = CONFIG_DIR / "task" / "coopnav" / f"{name}.yaml"
        assert path.read_text() == task_yaml(task_set), f"{path} differs from evaluation/tasks.py's {name}"
        member = CoopNavTask[name.upper()].get_from_yaml()
        for t in task_set.tasks:  # every task's scenario is the benchmark's
            member.config["task"] = t.name
            assert scenario_config(member.config) == t.config(task_set.scenario), (name, t.name)


def test_task_configs_train_on_a_scaled_reward():
    """BenchMARL does not normalize rewards: each task config's default training reward is
    SB3's signals times REWARD_SCALE (log_error on the moving networks), and the env it
    builds returns that reward, 0.01 of the unscaled terms' step by step."""
    for name, task_set in TASK_SETS.items():
        terms = get_task(name).config["reward_terms"]
        error = "log_error" if task_set.scenario.startswith("matos") else "std"
        assert terms == {error: REWARD_SCALE, "penalties": REWARD_SCALE} == default_reward_terms(task_set.scenario)
    assert REWARD_SCALE == 0.01
    rewards = []
    for terms in (None, {"std": 1.0, "penalties": 1.0}):
        changes = {} if terms is None else {"reward_terms": terms}
        task = get_task("gao_lawnmower", overrides={"max_cycles": 6}, **changes)
        env = task.get_env_fun(num_envs=3, continuous_actions=True, seed=11, device="cpu")()
        torch.manual_seed(0)  # the same random actions in both
        rollout = env.rollout(6, policy=None, break_when_any_done=False, auto_reset=True, tensordict=None)
        rewards.append(rollout["next", "beacons", "reward"])
    scaled, unscaled = rewards
    assert unscaled.abs().min() > 0.1  # metres per step: not already small
    torch.testing.assert_close(scaled, 0.01 * unscaled, rtol=1e-5, atol=1e-7)


def test_task_choice_and_errors():
    task = get_task("gao_sea", "two_beacons", overrides={"max_cycles": 7})
    config = scenario_config(task.config)
    assert config.beacon_kinds == ("beacon_auv", "beacon_auv") and config.max_cycles == 7
    with pytest.raises(ValueError, match="unknown coopnav task 'gao_se'; did you mean 'gao_sea'"):
        get_task("gao_se")
    with pytest.raises(ValueError, match=r"unknown task 'two_beacon' .*did you mean 'two_beacons'"):
        get_task("gao_sea", "two_beacon")
    with pytest.raises(ValueError, match="unknown task config key 'overides'"):
        get_task("gao_sea", overides={})
    register()
    from benchmarl.environments import task_config_registry

    assert task_config_registry["coopnav/sousa_ping"] is CoopNavTask.SOUSA_PING


def test_the_specs_benchmarl_reads():
    task = get_task("gao_team", overrides={"max_cycles": 5})
    env = task.get_env_fun(num_envs=4, continuous_actions=True, seed=3, device="cpu")()
    assert env.batch_size == (4,) and env.episode_seeds.tolist() == [-1] * 4
    assert task.group_map(env) == {"beacons": ["beacon_0", "beacon_1"]}
    obs = task.observation_spec(env)
    assert set(obs.keys(True, True)) == {("beacons", "observation")}
    assert obs["beacons", "observation"].shape == (2, env.obs_dim)
    assert task.state_spec(env)["state"].shape == (env.sim.state_dim + 2 * env.obs_dim,)
    assert ("beacons", "info", "beacon_error_m") in task.info_spec(env).keys(True, True)
    assert task.action_spec(env)["beacons", "action"].shape == (2, 2)
    assert task.max_steps(env) == 5 and not task.supports_discrete_actions()
    env.reset()
    assert env.episode_seeds.tolist() == [3, 4, 5, 6]
    with pytest.raises(ValueError, match="reserved seeds"):
        task.get_env_fun(num_envs=4, continuous_actions=True, seed=2**61, device="cpu")


def test_a_tiny_mappo_experiment(tmp_path, capsys):
    """MAPPO with MLPs on 512 env-steps: the run folder holds BenchMARL's logs and
    checkpoint, the policy's weights (safetensors) and run.json; the folder is then refused."""
    out = tmp_path / "run"
    assert marl.main(["--algorithm", "mappo", "--task", "gao_sea", *TINY, "--out", str(out)]) == 0
    record = json.loads((out / "run.json").read_text())
    assert record["frames"] == 512 and record["task"] == "coopnav/gao_sea" and record["seed"] == 0
    assert record["experiment_config"]["on_policy_n_envs_per_worker"] == 16
    assert record["last_batch_survey_error_m"] > 0
    weights = load_file(str(out / "policy.safetensors"))
    assert any(w.shape[-1] == 19 for w in weights.values())  # the first layer reads gao_sea's observation
    assert sorted(p.name for p in out.iterdir()) == ["benchmarl", "policy.safetensors", "run.json"]
    assert list((out / "benchmarl" / "checkpoints").glob("checkpoint_512.pt"))
    from benchmarks.marl_curves import curve  # the learning curve from BenchMARL's CSV log

    frames, errors = curve(out, "collection_info_survey_error_m")
    assert frames.tolist() == [512.0] and 0 < errors[0] < 1000
    assert marl.main(["--algorithm", "mappo", "--task", "gao_sea", *TINY, "--out", str(out)]) == 2
    assert "not empty" in capsys.readouterr().err


def test_a_diverged_run_stops_in_one_line(tmp_path, capsys, monkeypatch):
    """When the policy's actions turn NaN (the env refuses them: matos_moving_lbl from scratch
    did, docs/training/marl.md#levers-cells) the run stops with one line, status 1, and keeps
    BenchMARL's files where it says."""
    from coopnav_env import torchrl_env

    check = torchrl_env.CoopNavTorchEnv.check_actions
    calls = []

    def nan_on_the_tenth(self, action):
        calls.append(1)
        if len(calls) == 10:
            action = action * float("nan")
        return check(self, action)

    monkeypatch.setattr(torchrl_env.CoopNavTorchEnv, "check_actions", nan_on_the_tenth)
    out = tmp_path / "run"
    assert marl.main(["--algorithm", "mappo", "--task", "gao_sea", *TINY, "--out", str(out)]) == 1
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.startswith("marl: error: training diverged after about ") and "must be finite, got [nan, nan]" in err
    assert f"remove {out} to train again" in err and (out / ".partial").is_dir()


def test_bad_command_lines_fail_in_one_line(tmp_path, capsys):
    for args, message in [
        (["--algorithm", "mapo", "--task", "gao_sea"], "unknown algorithm 'mapo'; did you mean 'mappo'?"),
        (["--task", "gao_sea/deep"], "unknown task 'deep'"),
        (["--task", "gao_sea", "--set", "lr_typo=1"], "unknown experiment setting 'lr_typo'"),
        (["--task", "gao_sea", "--override", "depth=3"], "unknown scenario parameter"),
        (["--task", "gao_sea", "--seed", str(2**61)], "reserved seeds"),
        (["--task", "gao_sea", "--reward-term", "sdt=1"], "unknown reward term 'sdt'"),
        (["--task", "gao_sea", "--reward-term", "std=x"], "weight must be a number"),
        (["--task", "gao_sea", "--set", "lr=fast"], "--set lr must be a number (BenchMARL's default"),
        (["--task", "gao_sea", "--algorithm-set", "use_tanh=false"], "unknown mappo setting 'use_tanh'"),
        (["--task", "gao_sea", "--algorithm-set", "use_tanh_normal=0"], "must be like its default True, got 0"),
        (["--task", "gao_sea", "--eval-every-steps", "512", "--eval-seed", str(2**62 - 5)], "--eval-seed"),
        (["--task", "gao_sea", "--eval-every-steps", "-1"], "--eval-every-steps must be >= 0"),
    ]:
        assert marl.main([*args, "--out", str(tmp_path / "x")]) == 2
        err = capsys.readouterr().err
        assert message in err and err.count("\n") == 1, err
        assert not (tmp_path / "x").exists()  # nothing written before the checks pass


def test_a_run_keeps_its_validation_best(tmp_path):
    """``--eval-every-steps``: the policy is scored on the validation seeds every N env-steps
    and at the end; ``best/`` holds the lowest one's weights, and its recorded error is what
    the benchmark's episode runner gives the loaded folder on those seeds."""
    import numpy as np

    from evaluation.episodes import run_episodes

    out = tmp_path / "run"
    per_batch = ["--set", "on_policy_collected_frames_per_batch=512", "--set", "on_policy_minibatch_size=256"]
    args = ["--task", "gao_sea", *TINY, "--frames", "2048", *per_batch, "--eval-every-steps", "1000"]
    assert marl.main([*args, "--eval-episodes", "3", "--eval-seed", "500010", "--out", str(out)]) == 0
    record = json.loads((out / "run.json").read_text())
    history = record["validation"]
    assert [row["frames"] for row in history] == [1024, 2048]  # the first batch past 1000, then the end
    assert record["best"] == min(history, key=lambda row: row["validation_error_m"])
    assert record["validation_seeds"] == [500010, 500012]
    assert 0 < record["validation_s"] < record["wall_s"]  # the env-steps/s leave the validations out
    assert record["env_steps_per_s"] == pytest.approx(2048 / (record["wall_s"] - record["validation_s"]))
    assert sorted(p.name for p in out.iterdir()) == ["benchmarl", "best", "policy.safetensors", "run.json"]
    best = json.loads((out / "best" / "run.json").read_text())
    assert best["frames"] == record["best"]["frames"] and best["validation_seeds"] == [500010, 500012]
    config = scenario_config(get_task("gao_sea", None, overrides={"max_cycles": 20}).config)
    episodes, _ = run_episodes(config, str(out / "best"), [500010, 500011, 500012])
    assert np.mean([e["mean_error_m"] for e in episodes]) == pytest.approx(best["validation_error_m"], rel=1e-6)
    plain = tmp_path / "plain"  # validating leaves the training as it was: the same last weights
    assert marl.main([*args[:-2], "--out", str(plain)]) == 0
    assert (plain / "policy.safetensors").read_bytes() == (out / "policy.safetensors").read_bytes()
    if record["best"]["frames"] == 2048:  # the last weights are the best: the same file
        assert (out / "best" / "policy.safetensors").read_bytes() == (out / "policy.safetensors").read_bytes()
    else:
        assert (out / "best" / "policy.safetensors").read_bytes() != (out / "policy.safetensors").read_bytes()


@pytest.mark.parametrize(
    "algorithm, task, extra",
    [
        ("ippo", "sousa_ping", []),  # two ASVs, three action components
        ("mappo", "gao_team", ["--model", "gru", "--reward-term", "std=1", "--reward-term", "penalties=1"]),
        pytest.param("masac", "sousa_ping", ["--set", "off_policy_n_optimizer_steps=4"], marks=pytest.mark.slow),
        # an algorithm setting reaches BenchMARL and run.json (the loader rebuilds the actor from it)
        (
            "mappo",
            "matos_moving_lbl",
            ["--algorithm-set", "use_tanh_normal=false", "--algorithm-set", "entropy_coef=1e-3"],
        ),
    ],
)
def test_the_other_paths(tmp_path, algorithm, task, extra):
    """IPPO, a GRU policy and MASAC (its updates take about 10 s here: slow) on tiny runs."""
    out = tmp_path / algorithm
    assert marl.main(["--algorithm", algorithm, "--task", task, *TINY, *extra, "--out", str(out)]) == 0
    record = json.loads((out / "run.json").read_text())
    assert record["frames"] == 512 and record["task"] == f"coopnav/{task}"
    if "--reward-term" in extra:  # the training reward the run was given
        assert record["task_config"]["reward_terms"] == {"std": 1.0, "penalties": 1.0}
    if "--algorithm-set" in extra:
        assert record["algorithm_config"]["use_tanh_normal"] is False
        assert record["algorithm_config"]["entropy_coef"] == 1e-3
        import numpy as np

        import agents

        config = scenario_config(get_task(task, None).config)
        policy = agents.make_policy(str(out), config, agent=1)  # the actor of the run's own settings
        action = policy.act(np.full(policy.obs_dim, 0.5, dtype=np.float32))
        assert action.shape == (2,) and np.all(np.abs(action) <= 1.0) and np.all(np.isfinite(action))


@pytest.mark.slow
def test_benchmarl_run_finds_the_coopnav_tasks(tmp_path):
    """``python -m benchmarl.run algorithm=mappo task=coopnav/gao_sea``: the Hydra plugin
    (hydra_plugins/coopnav_benchmarl) adds the configs and registers the tasks."""
    cmd = [
        sys.executable,
        "-m",
        "benchmarl.run",
        "algorithm=mappo",
        "task=coopnav/gao_sea",
        "experiment=coopnav",
        "experiment.max_n_frames=512",
        "experiment.on_policy_n_envs_per_worker=16",
        "experiment.on_policy_collected_frames_per_batch=512",
        "experiment.on_policy_minibatch_size=256",
        "experiment.evaluation=false",
        "+task.overrides.max_cycles=20",
    ]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    r = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, timeout=600, env=env)
    assert r.returncode == 0, r.stderr[-2000:]
    assert list(tmp_path.glob("outputs/*/*/mappo_gao_sea_mlp__*"))


def test_marl_extra_admits_the_installed_versions():
    """pyproject's marl extra admits what is installed (and pins BenchMARL)."""
    import tomllib
    from packaging.requirements import Requirement

    extra = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]["marl"]
    import importlib.metadata as md

    for line in extra:
        req = Requirement(line)
        assert req.specifier.contains(md.version(req.name), prereleases=True), line
    assert "torch" not in {Requirement(line).name for line in extra}  # torch stays the project's pin
    assert torch.__version__.startswith("2.")


def _untrained_run(tmp_path, algorithm, task_set, model="mlp", changes=None):
    """A run folder (policy.safetensors + run.json, as ``marl.run`` writes them) of an
    untrained experiment whose weights are shaken off BenchMARL's initialisation, and
    the experiment itself."""
    import torch

    from agents.benchmarl_policy import policy_record
    from agents.training.marl_validation import save_weights
    from coopnav_env.records import atomic_write_text

    task = get_task(task_set, None, overrides={"max_cycles": 20})
    on_policy = marl._algorithm_config(algorithm, changes).on_policy()
    config = marl.experiment_config(
        None, 2, 64, {"evaluation": False, "loggers": [], "save_folder": str(tmp_path)}, on_policy
    )
    experiment = marl.build_experiment(algorithm, task, 0, config, model, algorithm_changes=changes)
    torch.manual_seed(3)
    with torch.no_grad():
        for p in experiment.policy.parameters():
            p.add_(0.3 * torch.randn_like(p))
    out = tmp_path / "run"
    out.mkdir()
    save_weights(experiment, out / "policy.safetensors")
    record = {**policy_record(experiment, algorithm, model), "task": f"coopnav/{task_set}", "task_config": task.config}
    atomic_write_text(out / "run.json", json.dumps(record))
    return out, experiment, task


@pytest.mark.parametrize(
    "algorithm, task_set, model",
    [
        ("mappo", "gao_team", "mlp"),
        ("ippo", "sousa_ping", "mlp"),
        ("mappo", "gao_team", "gru"),
        ("masac", "gao_team", "mlp"),
        ("isac", "gao_sea", "mlp"),
        ("mappo", "matos_moving_lbl", "mlp:normal"),  # --algorithm-set use_tanh_normal=false
    ],
)
def test_a_run_acts_as_benchmarl_acts(tmp_path, algorithm, task_set, model):
    """``agents.make_policy(run, config, agent=j)`` gives, step after step, the action
    BenchMARL's own policy takes in its deterministic rollout, for every beacon; a GRU
    carries its memory from step to step in the policy object (and ``reset`` clears it)."""
    import numpy as np
    from torchrl.envs.utils import ExplorationType, set_exploration_type

    import agents
    from agents.benchmarl_policy import BenchMARLPolicy

    model, _, kind = model.partition(":")
    changes = {"use_tanh_normal": False} if kind == "normal" else None
    out, experiment, task = _untrained_run(tmp_path, algorithm, task_set, model, changes)
    with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
        td = experiment.test_env.rollout(8, policy=experiment.policy, auto_reset=True)
    obs = td.get(("beacons", "observation"))[0].numpy()  # (8, N, D), environment 0
    want = td.get(("beacons", "action"))[0].numpy()
    if kind == "normal":  # an untanhed Normal's mean; the env clips it to [-1, 1], as the policy does
        assert float(np.abs(want).max()) > 1.0
        want = np.clip(want, -1.0, 1.0)
    assert float(np.abs(want).max()) > 0.05  # the weights were shaken: the check is not on zeros
    config = scenario_config(task.config)
    for j in range(config.n_beacons):
        policy = agents.make_policy(str(out), config, agent=j)
        assert isinstance(policy, BenchMARLPolicy) and policy.obs_dim == obs.shape[-1]
        got = np.stack([policy.act(obs[t, j]) for t in range(8)])
        np.testing.assert_allclose(got, want[:, j], atol=1e-5)
        if model == "gru":  # memory: the same observation answered differently after a history
            policy.reset()
            first = policy.act(obs[3, j])
            policy.reset()
            for t in range(4):
                last = policy.act(obs[t, j])
            assert np.abs(first - last).max() > 1e-4


def test_a_run_in_evaluate_and_its_refusals(tmp_path):
    """A BenchMARL run plays episodes through evaluate's path (``run_episodes``) and
    resolves to its files; another team's scenario and a damaged file get one line."""
    import agents
    from agents.benchmarl_policy import load
    from agents.formats import PolicyFormatError
    from coopnav_env import make_config
    from evaluation.episodes import run_episodes

    out, _, _ = _untrained_run(tmp_path, "mappo", "gao_team")
    config = make_config("gao_team", max_cycles=6)
    episodes, _ = run_episodes(config, str(out), [11, 12])
    assert [e["steps"] for e in episodes] == [6, 6] and all(e["mean_error_m"] > 0 for e in episodes)
    assert agents.resolve(str(out))[0].name == "policy.safetensors"
    assert load(out).config.name == "gao_team"  # bound to what it trained on
    with pytest.raises(ValueError, match="takes observations of size 34; scenario 'gao_sea' gives 19"):
        agents.load(str(out), scenario="gao_sea")
    record = json.loads((out / "run.json").read_text())
    (out / "run.json").write_text(json.dumps({**record, "model_config": {"activation_class": "os.system"}}))
    with pytest.raises(PolicyFormatError, match=r"is not a torch\.nn class"):
        load(out)
    (out / "run.json").write_text(json.dumps({**record, "model": "lstm"}))
    with pytest.raises(PolicyFormatError, match="an lstm actor cannot be loaded yet"):
        load(out)
    (out / "run.json").write_text(json.dumps({**record, "algorithm": "maddpg"}))
    with pytest.raises(PolicyFormatError, match="a maddpg run cannot be loaded"):
        load(out)


def test_a_shipped_run_answers_to_ppo(tmp_path, monkeypatch):
    """A BenchMARL run folder shipped as ``agents/policies/ppo_<scenario>`` is what "ppo" (with
    the scenario) and "ppo_<scenario>" name: loaded, built per beacon, listed, and reported by
    the benchmark as that shipped policy."""
    import shutil

    import numpy as np

    import agents
    from agents.benchmarl_policy import BenchMARLPolicy
    from coopnav_env import make_config
    from evaluation.config import resolve_trained

    out, _, _ = _untrained_run(tmp_path, "mappo", "gao_team")
    shipped = tmp_path / "policies"
    shutil.copytree(out, shipped / "ppo_gao_team")
    monkeypatch.setattr(agents, "POLICY_DIR", shipped)
    assert agents.list_policies() == ["ppo_gao_team"]
    config = make_config("gao_team", max_cycles=6)
    for name in ("ppo", "ppo_gao_team"):
        assert isinstance(agents.load(name, scenario="gao_team"), BenchMARLPolicy), name
        policy = agents.make_policy(name, config, agent=1)
        assert isinstance(policy, BenchMARLPolicy) and policy.act(np.zeros(policy.obs_dim, np.float32)).shape == (2,)
    assert resolve_trained("ppo", "gao_team")["shipped"] == "ppo_gao_team"
    with pytest.raises(ValueError, match=r"no policy 'ppo'.*shipped: ppo_gao_team$"):  # gao_sea has none here
        agents.load("ppo", scenario="gao_sea")
