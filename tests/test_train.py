"""agents.training (train.py's library) and agents/: the typed configs, a tiny training
run, interrupt + resume, loading and acting.

Time-boxed: short missions (10 cycles), a 16x16 network, a few thousand steps."""

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

import agents
import coopnav_env
from agents.training import (
    EXIT_INTERRUPTED,
    ConfigError,
    EnvSpec,
    PeriodicEvalSpec,
    RLlibConfig,
    TrainConfig,
    cli,
    sb3,
    scoring,
)
from agents.training.config import config_from_record, from_dict, load_config

ROOT = Path(__file__).resolve().parents[1]
GATE = ROOT / "tests" / "data" / "converted" / "ppo_sousa_asv_gate"  # two networks and a depth gate

TINY = {
    "n_envs": 4,
    "ppo": {"n_steps": 64, "batch_size": 128, "n_epochs": 1, "policy_kwargs": {"net_arch": [16, 16]}},
    "env": {"overrides": {"max_cycles": 10, "mission_duration_s": 200.0}},
    "eval": {"every_steps": 512, "episodes": 2, "seed": 1000000, "baselines": []},
    "checkpoint_every_steps": 256,
}
ROLLOUT = 4 * 64


def _tiny_yaml(tmp_path, **changes):
    hp = json.loads(json.dumps(TINY))
    hp.update(changes)
    path = tmp_path / "tiny.yml"
    path.write_text(yaml.safe_dump(hp))
    return str(path)


def _run(tmp_path, out, timesteps, **changes):
    return cli.main(
        [
            "--scenario",
            "sousa_asv",
            "--timesteps",
            str(timesteps),
            "--seed",
            "3",
            "--out",
            str(out),
            "--config",
            _tiny_yaml(tmp_path, **changes),
            "--no-progress",
        ]
    )


def test_tiny_training_run_writes_a_loadable_policy(tmp_path, monkeypatch):
    out = tmp_path / "run"
    t0 = time.perf_counter()
    assert _run(tmp_path, out, 1000) == 0
    assert time.perf_counter() - t0 < 60
    for name in (
        "config.yml",
        "model.safetensors",
        "vecnormalize.safetensors",
        "best_model.safetensors",
        "best_vecnormalize.safetensors",
        "best.json",
        "evaluations.jsonl",
        "checkpoints/last_checkpoint.json",
    ):
        assert (out / name).is_file(), name
    assert not list(out.rglob(".*.tmp*"))  # no temporary file left behind
    assert not [f for f in out.rglob("*") if f.suffix in (".zip", ".pkl")]  # no pickle-based file
    config = yaml.safe_load((out / "config.yml").read_text())
    assert config["args"] == {"scenario": "sousa_asv", "timesteps": 1000, "seed": 3}
    assert config["hyperparameters"]["ppo"]["n_steps"] == 64
    assert config["scenario_config"]["max_cycles"] == 10 and config["command"].startswith("python train.py")
    last = json.loads((out / "checkpoints/last_checkpoint.json").read_text())
    assert last["num_timesteps"] == 4 * ROLLOUT  # 1000 rounded up to whole rollouts
    evals = [json.loads(line) for line in (out / "evaluations.jsonl").read_text().splitlines()]
    assert [e["num_timesteps"] for e in evals] == [512, 1024]
    assert all(np.isfinite(e["survey_error_m"]) for e in evals)

    policy = agents.load(out, scenario="sousa_asv")
    assert policy.model.num_timesteps in (512, 1024)  # the best evaluated model
    env = coopnav_env.parallel_env("sousa_asv", seed=0, max_cycles=5)
    obs, _ = env.reset()
    policy.reset()
    while env.agents:
        action = policy.act(obs["beacon_0"])
        assert action.shape == (2,) and action.dtype == np.float32 and np.all(np.abs(action) <= 1)
        assert np.array_equal(action, policy.act(obs["beacon_0"]))  # deterministic
        obs, *_ = env.step({"beacon_0": action})
    final = agents.load(out / "model.safetensors")
    assert final.model.num_timesteps == 4 * ROLLOUT
    assert final.act_batch(np.zeros((3, final.obs_dim))).shape == (3, 2)

    # shipped the way agents/policies/<name>/ holds it: found by name, and as "ppo" of its scenario
    shipped = tmp_path / "policies" / "ppo_sousa_asv"
    shipped.mkdir(parents=True)
    for name in ("model.safetensors", "vecnormalize.safetensors", "config.yml"):
        (shipped / name).write_bytes((out / name).read_bytes())
    monkeypatch.setattr(agents, "POLICY_DIR", tmp_path / "policies")
    assert agents.list_policies() == ["ppo_sousa_asv"]
    by_name = agents.load("ppo", scenario="sousa_asv")
    assert by_name.config.name == "sousa_asv" and by_name.config.max_cycles == 10  # the training overrides
    one = agents.make_policy("ppo", coopnav_env.make_config("sousa_asv"), seed=(0, 0), agent=0)
    two = agents.make_policy("ppo", coopnav_env.make_config("sousa_asv"), seed=(1, 0), agent=0)
    assert one.model is two.model  # loaded once
    x = np.linspace(-1, 1, one.obs_dim)
    assert np.array_equal(one.act(x), final.act(x))


def test_interrupted_run_resumes_to_the_same_step_count(tmp_path):
    out = tmp_path / "run"
    total = 3000  # 12 rollouts of 256
    ckpt = out / "checkpoints" / "last_checkpoint.json"

    def interrupt_after_first_checkpoint():
        deadline = time.time() + 60
        while not ckpt.exists() and time.time() < deadline:
            time.sleep(0.01)
        os.kill(os.getpid(), signal.SIGINT)

    killer = threading.Thread(target=interrupt_after_first_checkpoint)
    killer.start()
    try:
        code = _run(tmp_path, out, total, eval={"every_steps": 0})
    finally:
        killer.join()
    assert code == EXIT_INTERRUPTED
    stopped = json.loads(ckpt.read_text())["num_timesteps"]
    assert 0 < stopped < total and stopped % ROLLOUT == 0
    assert not (out / "model.safetensors").exists()

    assert cli.main(["--resume", str(out), "--no-progress"]) == 0
    assert json.loads(ckpt.read_text())["num_timesteps"] == 12 * ROLLOUT  # what an uninterrupted run reaches
    policy = agents.load(out)
    assert policy.model.num_timesteps == 12 * ROLLOUT
    assert policy.act(np.zeros(policy.obs_dim)).shape == (2,)
    # resuming a finished run is a no-op that still succeeds
    assert cli.main(["--resume", str(out), "--no-progress"]) == 0


def _cli(*args):
    return subprocess.run(
        [sys.executable, str(ROOT / "train.py"), *args], capture_output=True, text=True, timeout=120, cwd=ROOT
    )


def test_a_linear_learning_rate_ends_at_zero_not_below(tmp_path):
    """``ppo.learning_rate: lin_<x>`` decays to 0 over the steps that really run. SB3 trains
    whole rollouts, so 1000 steps run as 1024; told 1000, its progress went to -0.024 and the
    last update used a negative rate (-2.4e-5 here, uphill). The optimizer's rate saved with the
    model is the last update's."""
    from safetensors import safe_open

    from agents.training.sb3 import learning_rate

    assert learning_rate("lin_1e-3")(1.0) == 1e-3 and learning_rate("lin_1e-3")(-0.5) == 0.0
    out = tmp_path / "run"
    ppo = {**TINY["ppo"], "learning_rate": "lin_1e-3"}
    assert _run(tmp_path, out, 1000, ppo=ppo) == 0
    with safe_open(str(out / "model.safetensors"), "pt") as f:
        groups = json.loads(f.metadata()["coopnav"])["optimizer"]["param_groups"]
    assert groups and all(g["lr"] >= 0.0 for g in groups), [g["lr"] for g in groups]
    assert all(g["lr"] < 1e-3 * ROLLOUT / 1024 + 1e-12 for g in groups)  # the last update's, near the end


def test_bad_input_is_one_line_and_exit_2(tmp_path):
    r = _cli("--scenario", "nope", "--timesteps", "10", "--out", str(tmp_path / "x"))
    assert r.returncode == 2
    assert r.stderr.strip().count("\n") == 0 and "unknown scenario 'nope'" in r.stderr and "sousa_asv" in r.stderr
    r = _cli("--resume", str(tmp_path))
    assert r.returncode == 2 and "not a train.py run directory" in r.stderr
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "f").write_text("x")
    r = _cli("--scenario", "sousa_asv", "--timesteps", "10", "--out", str(tmp_path / "full"))
    # not a run (no config.yml): --resume would not work there, so it is not suggested (issue 24)
    assert r.returncode == 2 and "--resume" not in r.stderr and "another --out" in r.stderr
    (tmp_path / "full" / "config.yml").write_text("args: {scenario: sousa_asv}\n")
    r = _cli("--scenario", "sousa_asv", "--timesteps", "10", "--out", str(tmp_path / "full"))
    assert r.returncode == 2 and f"--resume {tmp_path / 'full'}" in r.stderr
    r = _cli("--scenario", "sousa_asv", "--timesteps", "0", "--out", str(tmp_path / "y"))
    assert r.returncode == 2
    r = _cli("--resume", str(tmp_path), "--timesteps", "5")
    assert r.returncode == 2 and "drop --timesteps" in r.stderr


def test_a_bad_seed_or_device_is_one_line_and_exit_2_before_training(tmp_path):
    """Values SB3, numpy or torch would refuse with a traceback, or take silently: a seed
    outside numpy's 32 bits, a device torch cannot parse, CUDA on a machine without it."""
    cases = [
        (["--seed", "-1"], "seed must be an integer in [0, 4294967295]"),
        (["--seed", str(2**32)], "seed must be an integer in [0, 4294967295]"),
        (["--set", "seed=-1"], "seed must be an integer"),
        (["--device", "gpu"], "--device gpu: not a torch device"),
    ]
    import torch

    if not torch.cuda.is_available():
        cases.append((["--device", "cuda"], "no CUDA device"))
    from agents.training.cli import check_device

    check_device("auto")  # SB3's own value: accepted
    for extra, message in cases:
        out = tmp_path / "x"
        r = _cli("--scenario", "sousa_asv", "--timesteps", "10", "--out", str(out), *extra)
        assert r.returncode == 2 and message in r.stderr and r.stderr.strip().count("\n") == 0, (extra, r.stderr)
        assert not out.exists()


def test_no_validation_episodes_trains_without_validating(tmp_path):
    """``eval.episodes: 0`` is "no validation" (EvalSpec): the run trains, keeps its last weights
    as the model and writes no validation (it used to train, then fail building a VecEnv of
    0 environments, with no model saved)."""
    out = tmp_path / "run"
    assert _run(tmp_path, out, 300, eval={**TINY["eval"], "episodes": 0}) == 0
    assert (out / "model.safetensors").is_file() and not (out / "evaluations.jsonl").exists()
    assert agents.load(out, scenario="sousa_asv").model.num_timesteps == 2 * ROLLOUT


def test_bad_hyperparameters_are_a_one_line_error(tmp_path, capsys):
    assert _run(tmp_path, tmp_path / "run", 100, ppo={"n_stepz": 3}) == 2
    err = capsys.readouterr().err.strip()
    assert "unknown ppo key 'n_stepz'; did you mean 'n_steps'?" in err and "\n" not in err
    assert _run(tmp_path, tmp_path / "run2", 100, bogus=1) == 2
    assert "unknown section 'bogus'" in capsys.readouterr().err
    # a value SB3 refuses (batch_size 1 with normalized advantages) is caught when PPO is built
    assert _run(tmp_path, tmp_path / "run3", 100, ppo={"n_steps": 64, "batch_size": 1}) == 2
    err = capsys.readouterr().err.strip()
    assert "bad PPO hyperparameters" in err and "\n" not in err
    assert not (tmp_path / "run").exists() and not (tmp_path / "run2").exists()


def test_agents_load_errors():
    with pytest.raises(ValueError, match="scenario="):
        agents.load("ppo")
    with pytest.raises(ValueError, match="no policy"):
        agents.load("no_such_policy")


@pytest.mark.parametrize("name", agents.list_policies())
def test_shipped_policies_load_and_act(name):
    policy = agents.load(name)
    assert policy.config is not None
    env = coopnav_env.parallel_env(policy.config, seed=0, max_cycles=3)
    obs, _ = env.reset()
    # one object per beacon, as evaluate.py makes them: a policy with memory keeps each one's window
    beacons = {a: agents.make_policy(name, policy.config, agent=i) for i, a in enumerate(env.possible_agents)}
    while env.agents:
        actions = {a: beacons[a].act(obs[a]) for a in env.agents}
        for a, action in actions.items():
            assert action.shape == env.action_space(a).shape and action.dtype == np.float32
            assert np.all(np.abs(action) <= 1)
        obs, *_ = env.step(actions)
    # as the shipped "ppo" of its scenario, through make_policy (evaluate.py's path), both fresh
    scenario = policy.config.name
    assert agents.resolve("ppo", scenario)[0] == agents.resolve(name)[0]
    one = agents.make_policy("ppo", coopnav_env.make_config(scenario), seed=0)
    policy.reset()
    assert np.array_equal(one.act(obs[env.possible_agents[0]]), policy.act(obs[env.possible_agents[0]]))


@pytest.mark.parametrize("scenario", coopnav_env.list_scenarios())
def test_every_scenario_names_a_shipped_policy_that_drives_it(scenario):
    """``--policies ppo`` names a shipped policy on every scenario (issue 15), and it acts
    on the scenario's own observations."""
    model, _, _ = agents.resolve("ppo", scenario)
    assert model.is_file() and model.is_relative_to(agents.POLICY_DIR)
    config = coopnav_env.make_config(scenario)
    policy = agents.make_policy("ppo", config, seed=0)
    env = coopnav_env.parallel_env(config, seed=0, max_cycles=2)
    obs, _ = env.reset()
    action = policy.act(obs[env.possible_agents[0]])
    assert action.shape == env.action_space(env.possible_agents[0]).shape and np.all(np.isfinite(action))


def test_evaluation_scores_a_baseline_on_the_same_seeds():
    config = coopnav_env.make_config("sousa_asv", max_cycles=4, mission_duration_s=80.0)
    cells = [("all", config)]
    a = scoring.evaluate(scoring.baseline_actor("fim_a"), cells, episodes=2, seed=5)
    b = scoring.evaluate(scoring.baseline_actor("fim_a"), cells, episodes=2, seed=5)
    assert a == b and len(a["survey_error_m_per_episode"]) == 2
    static = scoring.evaluate(lambda obs, venv: np.zeros((venv.num_envs, 2)), cells, episodes=2, seed=5)
    assert static["survey_error_m"] != a["survey_error_m"]


def test_eval_cells_are_fixed_scenarios_with_randomization_off():
    trained = coopnav_env.make_config(
        "sousa_asv",
        randomize_depth_m=(1.0, 50.0),
        randomize_survey_path=("circle", "spiral"),
        randomize_noise_scale=(0.5, 1.5),
    )
    cells = scoring.eval_cells(trained, {"depth_m": [1.0, 50.0], "survey_path": ["circle", "spiral"]})
    assert [label for label, _ in cells] == [
        "depth_m=1.0;survey_path=circle",
        "depth_m=1.0;survey_path=spiral",
        "depth_m=50.0;survey_path=circle",
        "depth_m=50.0;survey_path=spiral",
    ]
    for _, config in cells:
        assert config.randomize_depth_m == () and config.randomize_survey_path == ()
        assert config.randomize_noise_scale == ()
    assert cells[3][1].depth_m == 50.0 and cells[3][1].survey_path == "spiral"
    assert scoring.eval_cells(trained, {}) == [("all", trained.replace(**scoring.RANDOMIZATION_OFF))]
    short = [(label, c.replace(max_cycles=3, mission_duration_s=0.0)) for label, c in cells]
    result = scoring.evaluate(lambda obs, venv: np.zeros((venv.num_envs, 2)), short, episodes=2, seed=1)
    assert list(result["per_cell"]) == [label for label, _ in cells]
    assert result["survey_error_m"] == pytest.approx(np.mean(list(result["per_cell"].values())))


def test_randomized_training_with_a_training_reward_and_per_cell_evaluation(tmp_path):
    out = tmp_path / "run"
    overrides = {
        "max_cycles": 10,
        "mission_duration_s": 200.0,
        "randomize_depth_m": [1.0, 50.0],
        "randomize_survey_path": ["stationary", "circle"],
        "randomize_noise_scale": [0.75, 1.25],
    }
    code = _run(
        tmp_path,
        out,
        500,
        env={"overrides": overrides},
        reward={"error": 1.0, "penalties": 1.0},
        eval={
            "every_steps": 256,
            "episodes": 1,
            "seed": 500000,
            "baselines": [],
            "cells": {"depth_m": [1.0, 50.0], "survey_path": ["stationary", "circle"]},
        },
    )
    assert code == 0
    config = yaml.safe_load((out / "config.yml").read_text())
    assert config["scenario_config"]["randomize_depth_m"] == [1.0, 50.0]
    assert config["hyperparameters"]["reward"] == {"error": 1.0, "penalties": 1.0}
    assert len(config["eval_cells"]) == 4
    evals = [json.loads(line) for line in (out / "evaluations.jsonl").read_text().splitlines()]
    assert len(evals[-1]["per_cell"]) == 4
    policy = agents.load(out)
    assert policy.config.randomize_depth_m == (1.0, 50.0)


def test_old_variants_and_bad_reward_terms_are_one_line_errors(tmp_path, capsys):
    assert _run(tmp_path, tmp_path / "a", 100, env={"variants": {"depth_m": [1.0]}}) == 2
    assert "randomize_depth_m" in capsys.readouterr().err
    assert _run(tmp_path, tmp_path / "b", 100, reward={"nope": 1.0}) == 2
    assert "unknown reward term 'nope'" in capsys.readouterr().err


@pytest.mark.parametrize("scenario", ["matos_moving_lbl", "swarm_mls"])
def test_tiny_training_run_on_the_newer_scenarios(tmp_path, scenario):
    """The trainer trains the two boats of the moving network (parameter sharing over both
    rows) and the swarm's sender; the result loads and runs in evaluate.py."""
    import evaluate

    out = tmp_path / scenario
    assert (
        cli.main(
            [
                "--scenario",
                scenario,
                "--timesteps",
                "600",
                "--seed",
                "0",
                "--out",
                str(out),
                "--config",
                _tiny_yaml(tmp_path),
                "--no-progress",
            ]
        )
        == 0
    )
    config = coopnav_env.make_config(scenario, max_cycles=6)
    eps, _steps = evaluate.run_episodes(config, str(out), [0, 1])
    assert len(eps) == 2 and all(np.isfinite(e["mean_error_m"]) for e in eps)


def test_depth_gated_policy_routes_by_the_observed_depth(tmp_path):
    """agents.DepthGatedPolicy (the ppo_sousa_asv shipped until 2026-12-05, kept in
    tests/data/converted): the shallow network acts where the survey vehicle's observed
    depth below the beacon is under the threshold."""
    from coopnav_env.obs_layout import encode

    shipped = agents.load(GATE)
    assert isinstance(shipped, agents.DepthGatedPolicy) and shipped.threshold_m == 12.5
    config = coopnav_env.make_config("sousa_asv")
    shallow = encode(config, own_en_m=[0, 0], survey_rel_m=[[20.0, 5.0, 5.0]])
    deep = encode(config, own_en_m=[0, 0], survey_rel_m=[[20.0, 5.0, 50.0]])
    assert np.array_equal(shipped.act(shallow), shipped.shallow.act(shallow))
    assert np.array_equal(shipped.act(deep), shipped.deep.act(deep))
    both = shipped.act_batch(np.stack([shallow, deep, shallow]))  # a batch: float32 round-off aside
    assert np.allclose(both[1], shipped.deep.act(deep), atol=1e-5)
    assert np.allclose(both[2], shipped.shallow.act(shallow), atol=1e-5)
    assert not np.allclose(both[0], shipped.deep.act(shallow), atol=1e-3)  # the gate made a difference
    # a gate file must say what it is
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "gate.yml").write_text("kind: depth_gate\nthreshold_m: 10\n")
    with pytest.raises(ValueError, match="expected kind: depth_gate with threshold_m, shallow and deep"):
        agents.load(bad)


def test_init_from_starts_from_another_runs_weights_and_normalization(tmp_path, capsys):
    import torch

    from agents.formats import read_vecnormalize

    source = tmp_path / "source"
    assert _run(tmp_path, source, 256, eval={"every_steps": 0}) == 0
    # learning rate 0: the warm-started weights cannot move, so they must equal the source's
    warm = tmp_path / "warm"
    assert (
        _run(
            tmp_path,
            warm,
            256,
            eval={"every_steps": 0},
            init_from=str(source),
            ppo=dict(TINY["ppo"], learning_rate=0.0),
        )
        == 0
    )
    a, b = agents.load(source).model.policy.state_dict(), agents.load(warm).model.policy.state_dict()
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)
    src_stats = read_vecnormalize(source / "vecnormalize.safetensors")
    warm_stats = read_vecnormalize(warm / "vecnormalize.safetensors")
    # the statistics continued from the source's: + the first reset's 4 observations + one rollout
    assert warm_stats["obs_count"] == pytest.approx(src_stats["obs_count"] + 4 + ROLLOUT)
    # a run from scratch with the same seed ends elsewhere: the test above can fail
    scratch = tmp_path / "scratch"
    assert _run(tmp_path, scratch, 256, eval={"every_steps": 0}, ppo=dict(TINY["ppo"], learning_rate=0.0)) == 0
    c = agents.load(scratch).model.policy.state_dict()
    assert not all(torch.equal(a[k], c[k]) for k in a)

    # a network of another shape, or a gate of two networks, is a one-line error
    assert (
        _run(
            tmp_path,
            tmp_path / "bad",
            256,
            init_from=str(source),
            ppo=dict(TINY["ppo"], policy_kwargs={"net_arch": [8]}),
        )
        == 2
    )
    assert "does not fit this network" in capsys.readouterr().err
    assert _run(tmp_path, tmp_path / "gate", 256, init_from=str(GATE)) == 2
    assert "name one of its networks" in capsys.readouterr().err


# ------------------------------------------------------------------------------------
# the typed configs, the library API, the command line's help, the import layering
CONFIG_FILES = sorted((ROOT / "configs" / "ppo").rglob("*.yml")) + sorted((ROOT / "configs" / "rllib").glob("*.yml"))
RUN_RECORDS = (
    sorted((ROOT / "agents" / "policies").glob("*/config.yml"))
    + sorted((ROOT / "agents" / "policies").glob("*/*/config.yml"))
    + sorted((ROOT / "tests" / "data" / "converted").glob("*/*/config.yml"))
)


def test_every_config_file_and_run_record_loads_into_its_typed_config():
    assert len(CONFIG_FILES) >= 10 and RUN_RECORDS
    for path in CONFIG_FILES:
        cls = RLlibConfig if "rllib" in path.parts else TrainConfig
        config = load_config(path, cls)
        assert isinstance(config, cls) and config.eval.seed == 500000, path
        again = from_dict(cls, config.to_dict())  # a loaded config round-trips through its dict
        assert again == config, path
    for path in RUN_RECORDS:  # the shipped policies' config.yml: args + hyperparameters
        record = yaml.safe_load(path.read_text())
        config = config_from_record(record)
        assert isinstance(config, TrainConfig) and config.scenario == record["args"]["scenario"], path
        assert config.ppo == record["hyperparameters"]["ppo"], path


@pytest.mark.parametrize(
    "data, message",
    [
        (
            {"eval": {"episdoes": 3}},
            "unknown eval key 'episdoes'; did you mean 'episodes'? valid: baselines, cells, "
            "episodes, every_steps, seed",
        ),
        ({"evals": {}}, "unknown section 'evals'; did you mean 'eval'?"),
        ({"normalize": {"norm_ob": True}}, "unknown normalize key 'norm_ob'; did you mean 'norm_obs'?"),
        ({"ppo": {"n_stepz": 3}}, "unknown ppo key 'n_stepz'; did you mean 'n_steps'?"),
        ({"eval": {"episodes": "many"}}, "eval.episodes must be an integer, got 'many'"),
        ({"eval": []}, "eval must be a mapping"),
        ({"ppo": {"policy_kwargs": {"activation_fn": "sigmoid"}}}, "unknown activation_fn 'sigmoid'"),
    ],
)
def test_an_unknown_key_or_a_wrong_type_is_a_one_line_error_naming_the_closest(tmp_path, data, message):
    with pytest.raises(ConfigError) as exc:
        from_dict(TrainConfig, data).check()
    assert message in str(exc.value) and "\n" not in str(exc.value)
    path = tmp_path / "bad.yml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ValueError, match=f"^{path}: "):  # a file's errors name it
        load_config(path, TrainConfig)
    with pytest.raises(ConfigError, match="unknown section 'every_steps'"):
        from_dict(RLlibConfig, {"every_steps": 1})
    with pytest.raises(ConfigError, match="unknown eval key 'every_steps'"):  # RLlib evaluates at the end only
        from_dict(RLlibConfig, {"eval": {"every_steps": 1}})


def test_a_config_file_extends_another(tmp_path):
    """``extends:``: the base first, then the file; sections merge key by key, lists and
    values replace, null removes (the default applies); a chain resolves through files."""
    from agents.training.config import merge_configs

    (tmp_path / "base.yml").write_text(
        "n_envs: 8\nppo: {n_steps: 64, batch_size: 128, learning_rate: 1.0e-3}\n"
        "env: {teams: [{}, {current_speed_mps: 0.5}]}\nimitate: {planner: ellipse, steps: 1000}\n"
    )
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "mid.yml").write_text("extends: ../base.yml\nppo: {learning_rate: 3.0e-4}\n")
    (tmp_path / "sub" / "top.yml").write_text(
        "extends: mid.yml\nimitate: ~\nenv: {teams: [{}]}\ninit_from: runs/somewhere\n"
    )
    config = load_config(tmp_path / "sub" / "top.yml", TrainConfig)
    assert config.n_envs == 8 and config.init_from == "runs/somewhere"
    assert config.ppo == {"n_steps": 64, "batch_size": 128, "learning_rate": 3.0e-4}  # merged
    assert config.env.teams == [{}]  # replaced whole
    assert config.imitate == TrainConfig().imitate  # removed: the default
    # without the null, the base's clone and the file's init_from conflict: the error names the file
    (tmp_path / "sub" / "clash.yml").write_text("extends: mid.yml\ninit_from: runs/somewhere\n")
    with pytest.raises(ConfigError, match=r"clash\.yml: imitate and init_from both set the starting weights"):
        load_config(tmp_path / "sub" / "clash.yml", TrainConfig)
    assert merge_configs({"a": {"b": 1, "c": 2}}, {"a": {"c": None, "d": 3}}) == {"a": {"b": 1, "d": 3}}


@pytest.mark.parametrize(
    "files, message",
    [
        ({"a.yml": "extends: b.yml\n", "b.yml": "extends: a.yml\n"}, "extends cycle: a.yml -> b.yml -> a.yml"),
        ({"a.yml": "extends: a.yml\n"}, "extends cycle: a.yml -> a.yml"),
        ({"a.yml": "extends: missing.yml\n"}, "a.yml: extends 'missing.yml', but there is no such file"),
        ({"a.yml": "extends: [b.yml]\n"}, "a.yml: extends must be the path of another config file"),
    ],
)
def test_a_bad_extends_is_a_one_line_error(tmp_path, files, message):
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    with pytest.raises(ConfigError) as exc:
        load_config(tmp_path / "a.yml", TrainConfig)
    assert message in str(exc.value) and "\n" not in str(exc.value)


def test_overrides_apply_on_top_of_the_file(tmp_path):
    config = load_config(
        ROOT / "configs" / "ppo" / "sousa_asv.yml",
        TrainConfig,
        {"eval.episodes": 3, "ppo.n_steps": 32, "env.overrides.max_cycles": 5},
        scenario="sousa_asv",
        timesteps=10,
        seed=None,
    )
    assert (config.eval.episodes, config.ppo["n_steps"], config.env.overrides["max_cycles"]) == (3, 32, 5)
    assert config.ppo["batch_size"] == 4096 and config.seed == 0  # the rest is the file's, then the defaults'
    assert TrainConfig().eval.seed == coopnav_env.seeds.VALIDATION_SEED == RLlibConfig().eval.seed
    with pytest.raises(ConfigError, match="unknown eval key 'episdoes'; did you mean 'episodes'"):
        load_config(None, TrainConfig, {"eval.episdoes": 3})


def test_training_through_the_library_api(tmp_path, capsys):
    """agents.training.sb3.train(TrainConfig, out) without the command line: the run
    loads with agents.load; bad input raises ConfigError and writes nothing."""
    config = TrainConfig(
        scenario="gao_lawnmower",
        timesteps=300,
        seed=2,
        n_envs=2,
        ppo={"n_steps": 64, "batch_size": 64, "n_epochs": 1, "policy_kwargs": {"net_arch": [8]}},
        env=EnvSpec(overrides={"max_cycles": 6}),
        eval=PeriodicEvalSpec(every_steps=128, episodes=1),
        checkpoint_every_steps=128,
    )
    out = tmp_path / "lib"
    assert sb3.train(config, out) == 0
    policy = agents.load(out, scenario="gao_lawnmower")
    assert policy.config.max_cycles == 6 and policy.act(np.zeros(policy.obs_dim)).shape == (2,)
    assert agents.load(out / "model.safetensors").model.num_timesteps == 3 * 128  # 300 rounded up to whole rollouts
    record = yaml.safe_load((out / "config.yml").read_text())
    assert config_from_record(record) == config  # the record holds the whole config
    assert record["versions"]["coopnav"] and "git_commit" in record["versions"]
    from agents.training import resume

    assert resume(out) == 0  # a finished run: nothing to do
    with pytest.raises(ConfigError, match="exists and is not empty"):
        sb3.train(config, out)
    with pytest.raises(ConfigError, match="unknown scenario 'nope'"):
        sb3.train(config.replace(scenario="nope"), tmp_path / "never")
    assert not (tmp_path / "never").exists()


def test_help_teaches_defaults_required_options_and_scenarios():
    r = _cli("--help")
    assert r.returncode == 0
    text = " ".join(r.stdout.split())
    assert text.count("required unless --resume") >= 3
    for name in coopnav_env.list_scenarios():
        assert name in text
    assert "(default: 1;" in text and "(default: cpu)" in text and "500000" in text
    parser = cli.build_parser()
    assert all(a.help for a in parser._actions)  # every option has a help line


def test_importing_the_command_line_is_cheap_and_one_way():
    """agents.training.cli imports neither the evaluation nor train.py (nor torch, SB3 or Ray)."""
    code = (
        "import sys, agents.training.cli, agents.training.rllib; "
        "bad = sorted(m for m in sys.modules if m.split('.')[0] in "
        "('evaluation', 'evaluate', 'train', 'train_rllib', 'torch', 'stable_baselines3', 'ray')); "
        "print(bad)"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd="/")
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[]"
    code = "import sys, agents; print(sorted(m for m in sys.modules if m.startswith('agents.training')))"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd="/")
    assert r.stdout.strip() == "[]"  # agents does not import its training package


def test_an_entity_policy_clones_a_planner_over_teams(tmp_path):
    """imitate: with env.observation: entities: a tiny run over a one- and a two-beacon team
    clones ellipse (each team's planner on its own flat vector), scores the clone at step 0 and
    saves an entity policy that drives both teams."""
    out = tmp_path / "bc_entity"
    changes = {
        "imitate": {"planner": "ellipse", "steps": 600, "epochs": 2, "batch_size": 128},
        "env": {
            "overrides": {"max_cycles": 10},
            "observation": "entities",
            "teams": [{}, {"beacon_kinds": ["beacon_auv", "beacon_auv"]}],
        },
        "normalize": {"norm_obs": False},
        "entity": {"encoder": "deepsets", "embed_dim": 16, "heads": 1},
    }
    argv = ["--scenario", "gao_lawnmower", "--timesteps", "256", "--seed", "0", "--out", str(out)]
    assert cli.main([*argv, "--config", _tiny_yaml(tmp_path, **changes), "--no-progress"]) == 0
    record = yaml.safe_load((out / "config.yml").read_text())
    assert record["imitation"]["planner"] == "ellipse" and record["imitation"]["steps"] >= 600
    evals = [json.loads(line) for line in (out / "evaluations.jsonl").read_text().splitlines()]
    assert evals[0]["num_timesteps"] == 0
    for team in ({}, {"beacon_kinds": ["beacon_auv", "beacon_auv"]}):
        config = coopnav_env.make_config("gao_lawnmower", max_cycles=3, **team)
        policy = agents.load(out / "model.safetensors", scenario=config)
        env = coopnav_env.parallel_env(config, seed=5)
        obs, _ = env.reset()
        assert all(np.isfinite(policy.act(o)).all() for o in obs.values())


def test_imitation_clones_the_planner_before_ppo(tmp_path):
    """The imitate: path (agents.training.imitation): a tiny run clones the circle planner,
    evaluates the clone at step 0, records what it did; the clone acts like the planner on
    an episode it never saw."""
    from baselines import make_policy

    out = tmp_path / "bc"
    changes = {
        "imitate": {"planner": "circle", "steps": 2000, "epochs": 30, "batch_size": 256},
        "ppo": {**TINY["ppo"], "learning_rate": 1e-9, "policy_kwargs": {"net_arch": [64, 64]}},
    }
    assert (
        cli.main(
            [
                "--scenario",
                "sousa_asv",
                "--timesteps",
                "256",
                "--seed",
                "0",
                "--out",
                str(out),
                "--config",
                _tiny_yaml(tmp_path, **changes),
                "--no-progress",
            ]
        )
        == 0
    )
    record = yaml.safe_load((out / "config.yml").read_text())
    assert record["imitation"]["planner"] == "circle" and record["imitation"]["steps"] >= 2000
    assert record["hyperparameters"]["imitate"]["planner"] == "circle"
    evals = [json.loads(line) for line in (out / "evaluations.jsonl").read_text().splitlines()]
    assert evals[0]["num_timesteps"] == 0  # the clone, scored before PPO changes it

    config = coopnav_env.make_config("sousa_asv", max_cycles=10, mission_duration_s=200.0)
    clone = agents.load(out / "model.safetensors", scenario=config)
    env = coopnav_env.parallel_env(config, seed=12345)
    planner = make_policy("circle", config, seed=0)
    obs, _ = env.reset()
    errors = []
    while env.agents:
        o = obs["beacon_0"]
        want = planner.act(o)
        errors.append(np.abs(clone.act(o) - want).mean())
        obs, *_ = env.step({"beacon_0": want})
    # an untrained network acts ~0, off by ~0.6 on average; the clone follows the planner
    assert np.mean(errors) < 0.25, np.mean(errors)


def test_imitation_refuses_a_planner_that_cannot_drive_the_scenario(tmp_path, capsys):
    out = tmp_path / "never"
    code = cli.main(
        [
            "--scenario",
            "sousa_asv",
            "--timesteps",
            "256",
            "--out",
            str(out),
            "--config",
            _tiny_yaml(tmp_path, imitate={"planner": "abeam"}),
            "--no-progress",
        ]
    )
    err = capsys.readouterr().err.strip()
    assert code == 2 and "imitate.planner 'abeam' cannot drive 'sousa_asv'" in err and "\n" not in err
    assert not out.exists()
    # a schedule only where the beacons decide when to ping (sousa_ping), and a named one
    for scenario, planner, want in (
        ("sousa_asv", "ellipse+clock", "imitate.planner 'ellipse+clock' cannot drive 'sousa_asv'"),
        ("sousa_ping", "ellipse+clocks", "did you mean 'ellipse+clock'?"),
    ):
        code = cli.main(
            ["--scenario", scenario, "--timesteps", "256", "--out", str(out), "--no-progress"]
            + ["--config", _tiny_yaml(tmp_path, imitate={"planner": planner})]
        )
        err = capsys.readouterr().err.strip()
        assert code == 2 and want in err and "\n" not in err, err


def _transmit_fraction(run):
    """The share of slots in which the clone in ``run`` transmits, both ASVs of one
    10-slot ``sousa_ping`` episode (seed 12345)."""
    config = coopnav_env.make_config("sousa_ping", max_cycles=10, mission_duration_s=200.0)
    clone = agents.load(run / "model.safetensors", scenario=config)
    env = coopnav_env.parallel_env(config, seed=12345)
    obs, _ = env.reset()
    transmit = []
    while env.agents:
        actions = {a: clone.act(o) for a, o in obs.items()}
        transmit += [float(act[2]) > 0 for act in actions.values()]
        obs, *_ = env.step(actions)
    return float(np.mean(transmit))


def test_imitation_of_a_planner_on_a_schedule(tmp_path, capsys, monkeypatch):
    """sousa_ping's beacons decide when to ping: the clone copies a planner with its transmit
    schedule (ellipse+clock: both ASVs ping in every slot, staggered), so the clone transmits
    in every slot too."""
    out = tmp_path / "bc_clock"
    changes = {
        "imitate": {"planner": "ellipse+clock", "steps": 2000, "epochs": 30, "batch_size": 256},
        "ppo": {**TINY["ppo"], "learning_rate": 1e-9, "policy_kwargs": {"net_arch": [64, 64]}},
        "eval": {**TINY["eval"], "baselines": ["ellipse+clock"]},  # validated against the schedule too
    }
    argv = ["--scenario", "sousa_ping", "--timesteps", "256", "--seed", "0", "--out", str(out), "--no-progress"]
    monkeypatch.setenv("COOPNAV_PROGRESS", "lines")  # the stage lines (the suite silences them)
    assert cli.main([*argv, "--config", _tiny_yaml(tmp_path, **changes)]) == 0
    # the planners' collection can take minutes: it says so before it starts
    assert "imitation: ellipse+clock drives the training environments for 2,000 row-steps" in capsys.readouterr().err
    record = yaml.safe_load((out / "config.yml").read_text())
    assert record["imitation"]["planner"] == "ellipse+clock" and record["imitation"]["action_rms_error"] < 0.3
    baseline = json.loads((out / "baseline_eval.json").read_text())
    assert "ellipse+clock" in json.dumps(baseline), baseline
    transmit = _transmit_fraction(out)
    assert transmit > 0.9, transmit


def test_imitation_passes_planner_kwargs_to_the_planner(tmp_path, capsys):
    """``imitate.planner_kwargs`` reach the planner and its schedule: a clone of
    ``ellipse+event`` whose threshold no range reaches never transmits (at the default 0.5
    nats, 91 of 120 slots), and a keyword neither takes is refused by name before anything
    is written."""
    out = tmp_path / "never"
    bad = {"imitate": {"planner": "ellipse+event", "planner_kwargs": {"threshold": 0.4}}}
    argv = ["--scenario", "sousa_ping", "--timesteps", "256", "--seed", "0", "--no-progress"]
    assert cli.main([*argv, "--out", str(out), "--config", _tiny_yaml(tmp_path, **bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert "imitate.planner_kwargs {'threshold': 0.4}:" in err and "threshold" in err and "\n" not in err, err
    assert not out.exists()
    with pytest.raises(ConfigError, match=r"imitate\.planner_kwargs needs imitate\.planner"):
        from_dict(TrainConfig, {"imitate": {"planner_kwargs": {"threshold_nats": 0.4}}}).check()
    out = tmp_path / "silent"
    changes = {
        "imitate": {
            "planner": "ellipse+event",
            "planner_kwargs": {"threshold_nats": 1e9},
            "steps": 2000,
            "epochs": 30,
            "batch_size": 256,
        },
        "ppo": {**TINY["ppo"], "learning_rate": 1e-9, "policy_kwargs": {"net_arch": [64, 64]}},
        "eval": {**TINY["eval"], "baselines": ["ellipse+clock"]},
    }
    assert cli.main([*argv, "--out", str(out), "--config", _tiny_yaml(tmp_path, **changes)]) == 0
    record = yaml.safe_load((out / "config.yml").read_text())
    assert record["imitation"]["planner_kwargs"] == {"threshold_nats": 1e9}
    transmit = _transmit_fraction(out)
    assert transmit < 0.1, transmit


def test_action_log_std_sets_the_exploration_per_action_component(tmp_path, capsys):
    """``action_log_std`` is the policy's log std when PPO starts (here with a learning rate
    that cannot move it), one value per action component; another length is refused by
    name before anything is written."""
    from safetensors.numpy import load_file

    out = tmp_path / "std"
    changes = {"ppo": {**TINY["ppo"], "learning_rate": 1e-12}, "action_log_std": [-1.5, 0.5]}
    argv = ["--scenario", "sousa_asv", "--timesteps", "256", "--seed", "0", "--out", str(out), "--no-progress"]
    assert cli.main([*argv, "--config", _tiny_yaml(tmp_path, **changes)]) == 0
    weights = load_file(str(out / "model.safetensors"))
    log_std = [v for k, v in weights.items() if k.endswith("log_std")]
    assert len(log_std) == 1
    np.testing.assert_allclose(log_std[0], [-1.5, 0.5], atol=1e-6)
    capsys.readouterr()
    bad = tmp_path / "bad"
    argv = ["--scenario", "sousa_asv", "--timesteps", "256", "--out", str(bad), "--no-progress"]
    code = cli.main([*argv, "--config", _tiny_yaml(tmp_path, action_log_std=[-2.0, -2.0, 0.0])])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "action_log_std has 3 values; sousa_asv's actions have 2" in err and "\n" not in err
    assert not bad.exists()
    code = cli.main([*argv, "--config", _tiny_yaml(tmp_path, action_log_std=[-2.0, "wide"])])
    assert code == 2 and "action_log_std must be a list of numbers" in capsys.readouterr().err


def test_command_line_assignments_read_an_exponent_as_a_number():
    """``--set lr=1e-4`` (the marl help's own example) is 1e-4, not the string YAML 1.1 makes
    of an exponent without a dot; other values stay YAML's."""
    from agents.training.config import ConfigError, parse_assignments

    got = parse_assignments(["lr=1e-4", "g=0.98", "n=3", "s=-2.5E+1", "name=e5", "xs=[1, 2]"], "--set")
    assert got == {"lr": 1e-4, "g": 0.98, "n": 3, "s": -25.0, "name": "e5", "xs": [1, 2]}
    assert isinstance(got["lr"], float)
    with pytest.raises(ConfigError, match="--set takes KEY=VALUE"):
        parse_assignments(["lr"], "--set")
