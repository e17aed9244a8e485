"""train.py --backend rllib (Ray RLlib, new API stack): the adapter, one iteration on
every scenario in local mode, a local head with two env runners, a checkpoint that
agents.load and evaluate.py use, an interrupted run resumed, a Tune grid, and bad
input.

Skipped when Ray is not installed (pip install -e ".[rllib]"), except the test of the
message train.py prints then; under CI (which installs it) a missing Ray fails instead. Time-boxed: 10-cycle
missions, 16x16 networks, one to four PPO iterations of a few dozen steps. Everything Ray starts stays on loopback (no
cluster networking: RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0 makes Ray use 127.0.0.1
for this machine) and is stopped by the test that started it.
"""

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from ray_loopback import LOOPBACK_ENV  # conftest.py has applied them already

# .ci/run runs the tests on two workers (pytest-xdist, --dist loadgroup): every test that starts Ray
# runs in one group, on one worker, one after the other (tests/test_safe_formats.py's Ray test too)
pytestmark = pytest.mark.xdist_group("ray")

ROOT = Path(__file__).resolve().parents[1]
CYCLES = 10
TINY = {
    "ppo": {"lr": 3.0e-4, "train_batch_size_per_learner": 2 * CYCLES, "minibatch_size": CYCLES, "num_epochs": 1},
    "model": {"fcnet_hiddens": [16, 16]},
    "normalize_obs": True,
    "env_runners": {"num_env_runners": 0, "num_envs_per_env_runner": 1},
    "learners": {"num_learners": 0},
    "env": {"overrides": {"max_cycles": CYCLES}},
    "reward": {"std": 1.0, "penalties": 1.0},
    "eval": {"episodes": 1, "seed": 1000000, "baselines": []},
    "checkpoint_every_iterations": 1,
    "ray": {"num_cpus": 2, "object_store_memory_mb": 100},
}


def _tiny_yaml(tmp_path, **changes) -> str:
    hp = json.loads(json.dumps(TINY))
    hp.update(changes)
    path = tmp_path / "tiny_rllib.yml"
    path.write_text(yaml.safe_dump(hp))
    return str(path)


def test_missing_ray_is_one_line_and_exit_2(tmp_path):
    """Runs whether or not Ray is installed: `import ray` is made to fail."""
    code = (
        "import runpy, sys; sys.modules['ray'] = None; "
        f"sys.argv = ['train.py', '--backend', 'rllib', '--scenario', 'sousa_asv', '--timesteps', '10', "
        f"'--out', {str(tmp_path / 'run')!r}]; runpy.run_path('train.py', run_name='__main__')"
    )
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    assert 'pip install -e ".[rllib]"' in lines[0] and "Ray" in lines[0]
    assert r.stdout == "" and not (tmp_path / "run").exists()


# ------------------------------------------------------------------------------------
# everything below needs Ray (tests/conftest.py set LOOPBACK_ENV before any import of it)

import agents  # noqa: E402
import coopnav_env  # noqa: E402
from agents.training import EXIT_INTERRUPTED, RLlibConfig, cli  # noqa: E402
from agents.training import rllib as rllib_trainer  # noqa: E402
from agents.training.config import from_dict, load_config  # noqa: E402

from optional import require  # noqa: E402


def _config(scenario, hp, num_env_runners=None) -> RLlibConfig:
    """The typed config of ``hp`` (a dict as the YAML holds it) on ``scenario``."""
    config = from_dict(RLlibConfig, {**hp, "scenario": scenario})
    if num_env_runners is not None:
        config = config.replace(env_runners={**config.env_runners, "num_env_runners": num_env_runners})
    return config


@pytest.fixture(scope="module")
def ray_mod():
    """Ray (skips the test if it is not installed, fails it under CI: tests/optional.py)."""
    require("ray.rllib")
    import ray

    return ray


@pytest.fixture(scope="module")
def local_ray(ray_mod):
    """One small local Ray instance for the local-mode tests (stopped afterwards)."""
    if ray_mod.is_initialized():
        ray_mod.shutdown()
    ray_mod.init(
        num_cpus=2,
        include_dashboard=False,
        log_to_driver=False,
        object_store_memory=100 * 2**20,
        runtime_env={"env_vars": {"PYTHONPATH": str(ROOT), **LOOPBACK_ENV}},
    )
    yield ray_mod
    ray_mod.shutdown()


# ------------------------------------------------------------------------------------
def test_adapter_replays_the_vector_rows_and_computes_the_training_reward(ray_mod):
    """Copy c of the adapter is CoopNavVecEnv's row c, episode after episode, with the
    same training reward; observations are float32 and within the space."""
    from coopnav_env.rllib_env import CoopNavRLlibEnv
    from coopnav_env.vector import CoopNavVecEnv

    terms = {"std": 1.0, "penalties": 1.0, "error": 0.5}
    env = CoopNavRLlibEnv(
        {"scenario": "sousa_asv", "seed": 7, "copy_index": 2, "reward_terms": terms, "overrides": {"max_cycles": 4}}
    )
    venv = CoopNavVecEnv("sousa_asv", n_envs=3, seed=7, reward_terms=terms, max_cycles=4)
    obs, _ = env.reset()
    vobs = venv.reset()
    assert env.possible_agents == ["beacon_0"] and obs["beacon_0"].dtype == np.float32
    assert np.allclose(obs["beacon_0"], vobs[2], atol=1e-6)
    rng = np.random.default_rng(0)
    for _ in range(10):  # two and a half episodes
        if not env.agents:
            obs, _ = env.reset()
        a = rng.uniform(-1, 1, (3, 2)).astype(np.float32)
        obs, rew, term, trunc, info = env.step({"beacon_0": a[2]})
        vobs, vrew, vdone, _ = venv.step(a)
        assert rew["beacon_0"] == pytest.approx(float(vrew[2]), rel=1e-5, abs=1e-5)
        assert (term["__all__"] or trunc["__all__"]) == bool(vdone[2])
        assert set(info["beacon_0"]) == {"survey_error_m", "dr_error_m"}
        if not vdone[2]:
            assert np.allclose(obs["beacon_0"], vobs[2], atol=1e-6)
            assert env.observation_spaces["beacon_0"].contains(obs["beacon_0"])
    assert env.last_episode_survey_error_m > 0


def test_one_module_per_beacon_kind(ray_mod):
    from coopnav_env.rllib_env import CoopNavRLlibEnv, KindMapping, module_ids, module_map

    two_kinds = coopnav_env.make_config("gao_lawnmower", beacon_kinds=("beacon_auv", "asv", "beacon_auv"))
    mapping = module_map(two_kinds)
    assert mapping == {"beacon_0": "beacon_auv", "beacon_1": "asv", "beacon_2": "beacon_auv"}
    assert module_ids(mapping) == ["beacon_auv", "asv"]
    fn = KindMapping(mapping)
    assert fn("beacon_2", None) == "beacon_auv" and fn("beacon_1") == "asv"
    env = CoopNavRLlibEnv({"scenario": two_kinds, "seed": 0})
    assert module_map(env) == mapping  # read from the env: its agents and the scenario's beacon_kinds
    for name in coopnav_env.list_scenarios():
        config = coopnav_env.make_config(name)
        m = module_map(name)
        assert list(m) == coopnav_env.parallel_env(name).possible_agents
        assert list(m.values()) == list(config.beacon_kinds)


# ------------------------------------------------------------------------------------
@pytest.mark.parametrize("scenario", coopnav_env.list_scenarios())
def test_one_iteration_in_local_mode(scenario, local_ray):
    """num_env_runners=0, num_learners=0: the driver samples and learns."""
    from coopnav_env.rllib_env import module_ids

    hp = json.loads(json.dumps(TINY))
    config, mapping = rllib_trainer.build_config(_config(scenario, hp, num_env_runners=0))
    assert config.num_env_runners == 0 and config.num_learners == 0
    algo = config.build_algo()
    try:
        result = algo.train()
        m = rllib_trainer.metrics(result)
        modules = {k for k in result["learners"] if k != "__all_modules__"}  # the modules that learnt
    finally:
        algo.stop()
    assert m["iteration"] == 1 and m["env_steps"] >= 2 * CYCLES
    assert modules == set(module_ids(mapping)) == set(coopnav_env.make_config(scenario).beacon_kinds)


def test_two_kinds_train_two_modules(local_ray):

    hp = json.loads(json.dumps(TINY))
    hp["env"]["overrides"]["beacon_kinds"] = ["beacon_auv", "asv"]
    hp["env_runners"]["num_envs_per_env_runner"] = 3
    config, _mapping = rllib_trainer.build_config(_config("gao_lawnmower", hp, num_env_runners=0))
    algo = config.build_algo()
    try:
        result = algo.train()
        copies = [e.unwrapped for e in algo.env_runner.env.envs]
    finally:
        algo.stop()
    learned = set(result["learners"]) - {"__all_modules__"}
    assert learned == {"beacon_auv", "asv"}
    # the runner's three copies run different episodes (seed + copy + k * SEED_STRIDE)
    assert sorted(c.copy_index for c in copies) == [0, 1, 2]
    assert len({c.episode_seed for c in copies}) == 3


def test_run_directory_loads_acts_and_evaluates(tmp_path, local_ray, capsys):
    import evaluate

    out = tmp_path / "run"
    argv = [
        "--backend",
        "rllib",
        "--scenario",
        "sousa_asv",
        "--timesteps",
        str(2 * CYCLES),
        "--seed",
        "3",
        "--out",
        str(out),
        "--config",
        _tiny_yaml(tmp_path),
    ]
    assert cli.main(argv) == 0
    for name in (
        "config.yml",
        "checkpoint/rllib_checkpoint.json",
        "checkpoint/coopnav.json",
        "progress.jsonl",
        "evaluations.jsonl",
        "checkpoint/learner_group/learner/rl_module/asv",
        "checkpoint/policy_export/asv.safetensors",
        "checkpoint/policy_export/filters.safetensors",
    ):
        assert (out / name).exists(), name
    assert not list(out.glob(".checkpoint*"))  # no temporary checkpoint left behind
    config = yaml.safe_load((out / "config.yml").read_text())
    assert config["args"]["backend"] == "rllib" and config["args"]["seed"] == 3
    assert config["module_map"] == {"beacon_0": "asv"}
    assert config["hyperparameters"]["ppo"]["train_batch_size_per_learner"] == 2 * CYCLES
    assert config["rllib_config"]["num_env_runners"] == 0 and "ray" in config["versions"]
    assert config["command"].startswith("python train.py --backend rllib")
    evals = [json.loads(line) for line in (out / "evaluations.jsonl").read_text().splitlines()]
    assert np.isfinite(evals[-1]["survey_error_m"])

    # agents.load: the run directory, and its checkpoint directory
    for path in (out, out / "checkpoint"):
        policy = agents.load(path, scenario="sousa_asv")
        env = coopnav_env.parallel_env("sousa_asv", seed=0, max_cycles=5)
        obs, _ = env.reset()
        while env.agents:
            action = policy.act(obs["beacon_0"])
            assert action.shape == (2,) and action.dtype == np.float32
            assert env.action_space("beacon_0").contains(action)
            assert np.array_equal(action, policy.act(obs["beacon_0"]))  # deterministic
            obs, *_ = env.step({"beacon_0": action})
    assert agents.resolve(out, "sousa_asv")[0] == out / "checkpoint"

    # evaluate.py beside a planner, one short episode
    capsys.readouterr()
    res = tmp_path / "eval"
    assert (
        evaluate.main(
            [
                "--scenario",
                "sousa_asv",
                "--policies",
                f"{out},static",
                "--episodes",
                "1",
                "--set",
                "max_cycles=5",
                "--out",
                str(res),
                "--no-figures",
            ]
        )
        == 0
    )
    summary = json.loads((res / "summary.json").read_text())
    text = json.dumps(summary)
    assert str(out) in text and "static" in text


def test_multi_beacon_checkpoint_maps_every_beacon_to_its_kind(tmp_path, local_ray):
    """Two kinds of beacon: each beacon acts through its kind's module."""

    hp = json.loads(json.dumps(TINY))
    hp["env"]["overrides"]["beacon_kinds"] = ["beacon_auv", "asv"]
    config, _ = rllib_trainer.build_config(_config("gao_lawnmower", hp, num_env_runners=0))
    algo = config.build_algo()
    try:
        algo.train()
        algo.save_to_path(str(tmp_path / "ckpt"))
    finally:
        algo.stop()
    scen = coopnav_env.make_config("gao_lawnmower", beacon_kinds=("beacon_auv", "asv"), max_cycles=3)
    with pytest.raises(agents.PickleRefused, match="--trust-pickle"):  # RLlib's own files: pickle
        agents.make_policy(tmp_path / "ckpt", scen, seed=0, agent=0)
    trusted = [agents.make_policy(tmp_path / "ckpt", scen, seed=0, agent=j, trust_pickle=True) for j in range(2)]
    from agents import rllib_policy

    rllib_policy.export(tmp_path / "ckpt")  # the safe export: the same policies, no pickle read
    rllib_policy._RUNS.clear()
    policies = [agents.make_policy(tmp_path / "ckpt", scen, seed=0, agent=j) for j in range(2)]
    assert policies[0].run.export is not None
    obs = np.random.default_rng(0).normal(size=(8, policies[0].obs_dim)).astype(np.float32)
    for a, b in zip(trusted, policies):
        assert np.array_equal(a.act_batch(obs), b.act_batch(obs))
    assert [p.module_id for p in policies] == ["beacon_auv", "asv"]
    env = coopnav_env.parallel_env(scen, seed=1)
    obs, _ = env.reset()
    while env.agents:
        actions = {a: policies[j].act(obs[a]) for j, a in enumerate(env.agents)}
        assert all(env.action_space(a).contains(v) for a, v in actions.items())
        obs, *_ = env.step(actions)


def test_interrupted_run_resumes_to_the_same_step_count(tmp_path, local_ray, monkeypatch, capsys):
    """SIGTERM right after the first checkpoint: exit 130 with that checkpoint; --resume
    (nothing else on the command line) continues it to the step count of an
    uninterrupted run, and ends with the files of a finished run; resuming it again
    is a no-op."""

    total = 4 * 2 * CYCLES  # four iterations of 2 * CYCLES steps
    config = _tiny_yaml(tmp_path)
    ref, out = tmp_path / "ref", tmp_path / "run"

    def argv(run):
        return [
            "--backend",
            "rllib",
            "--scenario",
            "sousa_asv",
            "--timesteps",
            str(total),
            "--out",
            str(run),
            "--config",
            config,
        ]

    assert cli.main(argv(ref)) == 0
    reached = json.loads((ref / "checkpoint" / "coopnav.json").read_text())
    assert reached["env_steps"] >= total

    save = rllib_trainer.save_checkpoint

    def save_then_signal(algo, run_dir, meta):  # the signal arrives in the middle of the run, deterministically
        path = save(algo, run_dir, meta)
        if meta["iteration"] == 1:
            os.kill(os.getpid(), signal.SIGTERM)
        return path

    monkeypatch.setattr(rllib_trainer, "save_checkpoint", save_then_signal)
    capsys.readouterr()
    assert cli.main(argv(out)) == EXIT_INTERRUPTED
    assert f"continue with: python train.py --resume {out}" in capsys.readouterr().err
    stopped = json.loads((out / "checkpoint" / "coopnav.json").read_text())
    assert stopped["iteration"] == 1 and 0 < stopped["env_steps"] < total
    assert not (out / "evaluations.jsonl").exists() and not list(out.glob(".checkpoint*"))
    monkeypatch.undo()

    os.replace(out / "checkpoint", out / ".checkpoint.old1")  # as if killed between save_checkpoint's renames
    capsys.readouterr()
    assert cli.main(["--resume", str(out)]) == 2  # RLlib's checkpoint is pickle-based: --trust-pickle
    assert "--trust-pickle" in capsys.readouterr().err
    assert cli.main(["--resume", str(out), "--trust-pickle"]) == 0
    final = json.loads((out / "checkpoint" / "coopnav.json").read_text())
    assert (final["env_steps"], final["iteration"]) == (reached["env_steps"], reached["iteration"])
    progress = [json.loads(line) for line in (out / "progress.jsonl").read_text().splitlines()]
    assert [p["iteration"] for p in progress] == list(range(1, final["iteration"] + 1))  # appended, in order
    assert sorted(p.name for p in out.iterdir()) == sorted(p.name for p in ref.iterdir())  # a finished run's files
    evaluations = (out / "evaluations.jsonl").read_text()
    assert json.loads(evaluations)["num_timesteps"] == final["env_steps"]
    policy = agents.load(out, scenario="sousa_asv")
    env = coopnav_env.parallel_env("sousa_asv", seed=0, max_cycles=3)
    obs, _ = env.reset()
    while env.agents:
        action = policy.act(obs["beacon_0"])
        assert env.action_space("beacon_0").contains(action)
        obs, *_ = env.step({"beacon_0": action})

    # resuming a finished run is a no-op that succeeds; a conflicting --backend is one line
    assert cli.main(["--resume", str(out), "--backend", "rllib", "--trust-pickle"]) == 0
    assert (out / "evaluations.jsonl").read_text() == evaluations
    assert json.loads((out / "checkpoint" / "coopnav.json").read_text()) == final
    capsys.readouterr()
    assert cli.main(["--resume", str(out), "--backend", "sb3"]) == 2
    assert capsys.readouterr().err.strip() == f"train.py: error: {out} is a --backend rllib run; drop --backend sb3"


@pytest.mark.parametrize(
    "run_args, argv, needle",
    [
        (
            {"scenario": "sousa_asv", "timesteps": 10, "seed": 0},
            ["--backend", "rllib"],
            "is a --backend sb3 run; drop --backend rllib",
        ),
        (
            {"scenario": "sousa_asv", "timesteps": 10, "seed": 0},
            ["--num-env-runners", "2"],
            "--num-env-runners only with --backend rllib",
        ),
        (
            {"backend": "rllib", "scenario": "sousa_asv", "timesteps": 10, "seed": 0, "tune": {"lr": [1e-4, 3e-4]}},
            [],
            "is a Ray Tune grid (--tune): --resume continues single runs only",
        ),
    ],
)
def test_resume_takes_the_backend_from_the_run(tmp_path, capsys, ray_mod, run_args, argv, needle):

    (tmp_path / "config.yml").write_text(
        yaml.safe_dump(
            {"args": run_args, "hyperparameter_file": "x.yml", "hyperparameters": json.loads(json.dumps(TINY))}
        )
    )
    assert cli.main(["--resume", str(tmp_path), *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0], err


def test_tune_grid_writes_one_summary_table(tmp_path, local_ray):

    out = tmp_path / "sweep"
    argv = [
        "--backend",
        "rllib",
        "--scenario",
        "gao_lawnmower",
        "--timesteps",
        str(2 * CYCLES),
        "--out",
        str(out),
        "--config",
        _tiny_yaml(tmp_path),
        "--tune",
        "lr=1e-4,3e-4",
    ]
    assert cli.main(argv) == 0
    rows = (out / "summary.csv").read_text().splitlines()
    assert rows[0].split(",")[:3] == ["trial", "lr", "env_steps"]
    assert len(rows) == 3
    lrs = sorted(float(r.split(",")[1]) for r in rows[1:])
    assert lrs == [1e-4, 3e-4]
    md = (out / "summary.md").read_text()
    assert md.startswith("| trial | lr |") and md.count("\n") == 4
    assert not list(out.glob(".*.tmp*"))
    ckpt = out / rows[1].split(",")[-1]
    assert (ckpt / "rllib_checkpoint.json").is_file()
    policy = agents.load(ckpt, scenario="gao_lawnmower")  # a trial's checkpoint finds the run's config.yml
    assert policy.config.name == "gao_lawnmower"
    assert "," not in str(ckpt) and "=" not in ckpt.parent.name  # usable in evaluate.py --policies A,B


@pytest.mark.parametrize(
    "argv, needle",
    [
        (["--backend", "rllib", "--tune", "bogus=1,2"], "--tune bogus"),
        (["--backend", "rllib", "--tune", "lr"], "--tune expects KEY=V1,V2"),
        (["--backend", "rllib", "--tune", "seed=0,0.5"], "seed takes integers"),
        (["--num-env-runners", "2"], "only with --backend rllib"),
        (["--backend", "rllib", "--resume", "no/such/run"], "not a train.py run directory"),
        (["--resume", "no/such/run", "--tune", "lr=1e-4,3e-4"], "drop --tune"),
        (["--backend", "rllib", "--num-env-runners", "-1"], "must be >= 0"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, ray_mod, argv, needle):

    if "--resume" not in argv:
        argv = argv + ["--scenario", "sousa_asv", "--timesteps", "10", "--out", str(tmp_path / "run")]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0], err
    assert not (tmp_path / "run").exists()


def test_shipped_configs_build(ray_mod):
    """configs/rllib/*.yml give valid RLlib configs (default.yml on every scenario)."""

    for path in sorted((ROOT / "configs" / "rllib").glob("*.yml")):
        names = [path.stem] if path.stem != "default" else coopnav_env.list_scenarios()
        for name in names:
            config, mapping = rllib_trainer.build_config(load_config(path, RLlibConfig, scenario=name))
            assert config.num_env_runners >= 0 and set(mapping) == set(coopnav_env.parallel_env(name).possible_agents)


@pytest.mark.parametrize(
    "yml, needle",
    [
        ("ppo: {n_steps: 5}", "unknown ppo key (PPOConfig.training keyword) 'n_steps'"),
        ("ppo: {minibatch_size: 500, train_batch_size_per_learner: 100}", "minibatch_size"),
        ("policy: MlpPolicy", "unknown section 'policy'"),
        ("eval: {episdoes: 3}", "unknown eval key 'episdoes'; did you mean 'episodes'?"),
        ("reward: {bogus: 1}", "unknown reward term"),
    ],
)
def test_bad_hyperparameters_are_one_line(tmp_path, capsys, ray_mod, yml, needle):

    path = tmp_path / "bad.yml"
    path.write_text(yml)
    assert (
        cli.main(
            [
                "--backend",
                "rllib",
                "--scenario",
                "sousa_asv",
                "--timesteps",
                "10",
                "--out",
                str(tmp_path / "run"),
                "--config",
                str(path),
            ]
        )
        == 2
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0], err
    assert not (tmp_path / "run").exists()


# ------------------------------------------------------------------------------------
def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _kill_group(pgid: int, sig):
    try:
        os.killpg(pgid, sig)
    except ProcessLookupError:  # already gone
        pass


def test_local_head_and_two_env_runners(tmp_path, monkeypatch, ray_mod):
    """`ray start --head` on loopback (started and stopped here), `--ray-address` to it,
    two env runners, one training iteration."""

    ray = ray_mod
    if ray.is_initialized():
        ray.shutdown()
    for k, v in LOOPBACK_ENV.items():
        monkeypatch.setenv(k, v)
    temp_dir = tempfile.mkdtemp(prefix="rt", dir="/tmp")  # short: Ray's socket paths
    port = _free_port()
    ports = {
        f"--{name}": _free_port()
        for name in (
            "ray-client-server-port",
            "dashboard-port",
            "dashboard-agent-listen-port",
            "dashboard-agent-grpc-port",
            "metrics-export-port",
            "runtime-env-agent-port",
        )
    }
    log = open(Path(temp_dir) / "head.log", "w")
    t_start = time.monotonic()
    head = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "ray.scripts.scripts",
            "start",
            "--head",
            "--block",
            f"--port={port}",
            "--node-ip-address=127.0.0.1",
            "--num-cpus=2",
            "--include-dashboard=false",
            "--object-store-memory=100000000",
            f"--temp-dir={temp_dir}",
            "--disable-usage-stats",
            *(f"{k}={v}" for k, v in ports.items()),
        ],
        stdout=log,
        stderr=subprocess.STDOUT,
        env={**os.environ, **LOOPBACK_ENV, "PYTHONPATH": str(ROOT), "RAY_GRACEFUL_SHUTDOWN_DRAIN_TIMEOUT_S": "0"},
        start_new_session=True,
    )
    try:
        deadline = time.monotonic() + 60
        while True:
            assert head.poll() is None, (Path(temp_dir) / "head.log").read_text()[-2000:]
            try:
                socket.create_connection(("127.0.0.1", port), timeout=1).close()
                break
            except OSError:
                assert time.monotonic() < deadline, "the Ray head did not come up"
                time.sleep(0.3)
        out = tmp_path / "run"
        argv = [
            "--backend",
            "rllib",
            "--scenario",
            "gao_lawnmower",
            "--timesteps",
            str(2 * CYCLES),
            "--num-env-runners",
            "2",
            "--ray-address",
            f"127.0.0.1:{port}",
            "--out",
            str(out),
            "--config",
            _tiny_yaml(tmp_path, eval={"episodes": 0}),
        ]
        t_up = time.monotonic()
        assert cli.main(argv) == 0
        print(f"head up in {t_up - t_start:.1f} s, trained in {time.monotonic() - t_up:.1f} s")
        assert not ray.is_initialized()  # the trainer disconnected
        config = yaml.safe_load((out / "config.yml").read_text())
        assert config["args"]["num_env_runners"] == 2 and config["args"]["ray_address"] == f"127.0.0.1:{port}"
        progress = [json.loads(line) for line in (out / "progress.jsonl").read_text().splitlines()]
        assert progress[-1]["env_steps"] >= 2 * CYCLES
        assert agents.load(out, scenario="gao_lawnmower").module_id == "beacon_auv"
    finally:
        if ray.is_initialized():
            ray.shutdown()
        t_stop = time.monotonic()
        _kill_group(head.pid, signal.SIGTERM)  # our own session: the head and what it started
        try:
            head.wait(timeout=40)
            print(f"head stopped in {time.monotonic() - t_stop:.1f} s")
        except subprocess.TimeoutExpired:
            _kill_group(head.pid, signal.SIGKILL)
            head.wait(timeout=10)
        log.close()
    time.sleep(0.5)
    left = subprocess.run(["pgrep", "-f", temp_dir], capture_output=True, text=True).stdout.split()
    assert not left, f"processes of the test's Ray head still running: {left}"
    shutil.rmtree(temp_dir, ignore_errors=True)
