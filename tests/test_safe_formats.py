"""Loading a run directory never executes code (agents.formats): policies, normalization
statistics and checkpoints are safetensors + JSON; pickle-based files (an old SB3
.zip/.pkl run, an RLlib checkpoint) are refused unless --trust-pickle, and a trusted
conversion path exists (python -m agents.convert). Also: a missing normalization file,
a last_checkpoint.json pointing outside the run, a run killed before its first checkpoint.

A malicious pickle here creates a marker file when unpickled; every refusal is checked
by the marker's absence, exit status 2 and one line naming the file and --trust-pickle."""

import json
import pickle
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest
import yaml

# Ray on loopback only: tests/conftest.py sets tests/ray_loopback.py's settings before any import
from cli_runs import tiny_training

import agents
from agents import convert, formats
from agents.training import cli as train_cli
from evaluation import cli as eval_cli

from optional import require

DATA = Path(__file__).resolve().parent / "data" / "shipped_policy_actions.npz"
TINY = {
    "n_envs": 4,
    "ppo": {"n_steps": 64, "batch_size": 128, "n_epochs": 1, "policy_kwargs": {"net_arch": [16, 16]}},
    "env": {"overrides": {"max_cycles": 10, "mission_duration_s": 200.0}},
    "eval": {"every_steps": 512, "episodes": 1, "seed": 1000000, "baselines": []},
    "checkpoint_every_steps": 256,
}
# the policies converted from the old pickle-based files (ppo_gao_sea was, until it was
# replaced on 2026-12-02 by a fine-tune trained in the safe format; ppo_swarm_mls until it
# was replaced on 2026-12-04 by an entity policy; the ppo_sousa_asv gate until it was
# replaced on 2026-12-05 by one network trained on this round's physics): kept under
# tests/data/converted, where they still check the conversion and the depth gate
CONVERTED = Path(__file__).resolve().parent / "data" / "converted"
CONVERTED_POLICIES = {
    "ppo_sousa_asv_deep": "ppo_sousa_asv_gate/deep",
    "ppo_sousa_asv_shallow": "ppo_sousa_asv_gate/shallow",
    "ppo_sousa_asv_shallow_ft": "ppo_sousa_asv_gate/shallow_ft",
    "ppo_sousa_asv": "ppo_sousa_asv_gate",
}


class Payload:
    """Unpickling this creates ``marker`` (what an attacker's code would do)."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, "w"))


def _evil(marker) -> bytes:
    return pickle.dumps(Payload(marker))


# ------------------------------------------------------------------------------------
# runs: one genuine tiny run in the new format, one genuine run in the old format
@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    base = tmp_path_factory.mktemp("tiny")
    out = base / "run"
    assert tiny_training(out, TINY) == 0
    return out


@pytest.fixture(scope="module")
def old_run(tiny_run, tmp_path_factory):
    """A run directory as train.py wrote it before this change: SB3 model .zip files and
    pickled VecNormalize wrappers (genuine: made by SB3 itself)."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    import coopnav_env
    from coopnav_env.vector import CoopNavVecEnv

    out = tmp_path_factory.mktemp("old") / "run"
    (out / "checkpoints").mkdir(parents=True)
    shutil.copy(tiny_run / "config.yml", out / "config.yml")
    config = coopnav_env.make_config("sousa_asv", max_cycles=10, mission_duration_s=200.0)
    venv = VecNormalize(VecMonitor(CoopNavVecEnv(config, n_envs=4, seed=3)), gamma=0.99)
    model = PPO(
        "MlpPolicy",
        venv,
        n_steps=64,
        batch_size=128,
        n_epochs=1,
        seed=3,
        policy_kwargs={"net_arch": [16, 16]},
        device="cpu",
    )
    from stable_baselines3.common.logger import Logger

    model.set_logger(Logger(None, []))  # no /tmp/SB3-<date> folder left behind
    model.learn(256)
    model.save(out / "checkpoints" / "ckpt_0000000256.zip")
    venv.save(out / "checkpoints" / "ckpt_0000000256_vecnormalize.pkl")
    (out / "checkpoints" / "last_checkpoint.json").write_text(
        json.dumps(
            {"num_timesteps": 256, "model": "ckpt_0000000256.zip", "vecnormalize": "ckpt_0000000256_vecnormalize.pkl"}
        )
    )
    model.save(out / "model.zip")
    venv.save(out / "vecnormalize.pkl")
    return out


def _copy(run, tmp_path, name="copy") -> Path:
    dst = tmp_path / name
    shutil.copytree(run, dst)
    return dst


def _evaluate(policy, tmp_path, *extra) -> int:
    return eval_cli.main(
        [
            "--scenario",
            "sousa_asv",
            "--policies",
            str(policy),
            "--episodes",
            "1",
            "--set",
            "max_cycles=3",
            "--out",
            str(tmp_path / "eval_out"),
            "--no-figures",
            *extra,
        ]
    )


def _refused(capsys, code, marker, name):
    err = capsys.readouterr().err.strip()
    assert code == 2, err
    assert not Path(marker).exists(), "the payload ran"
    assert err.count("\n") == 0 and name in err and "--trust-pickle" in err, err
    return err


# ------------------------------------------------------------------------------------
# the shipped policies: converted, acting exactly as the old SB3 zip + pkl did
def test_converted_policies_act_as_recorded_with_the_old_files():
    """tests/data/shipped_policy_actions.npz: ~200 observations per policy from real
    episodes and the actions of the old loader (SB3 model.zip + vecnormalize.pkl),
    recorded before the conversion (the policies, once shipped, in tests/data/converted)."""
    data = np.load(DATA)
    for key, rel in CONVERTED_POLICIES.items():
        obs = data[f"{key}/obs"]
        assert obs.shape[0] == 200
        policy = agents.load(CONVERTED / rel)
        # equal up to float32 round-off: the matrix products' summation order depends on the
        # CPU's vector unit (on the machine that recorded them they are bit-identical)
        np.testing.assert_allclose(policy.act_batch(obs), data[f"{key}/actions"], rtol=0, atol=1e-6, err_msg=key)
        # one row alone: the same, float32 round-off of a batch of one aside
        assert np.allclose(policy.act(obs[0]), data[f"{key}/actions"][0], atol=1e-5), key
    for where in (agents.POLICY_DIR, CONVERTED):
        assert not [p for p in where.rglob("*") if p.suffix in (".zip", ".pkl")]


def test_loading_imports_no_unpickler(monkeypatch):
    """agents.load of a safe policy never calls pickle (nor torch.load)."""
    import torch

    def boom(*a, **k):
        raise AssertionError("unpickling during agents.load")

    agents.load("ppo_sousa_asv")  # numba's caches (its index files are pickles) loaded before the patch
    monkeypatch.setattr(pickle, "load", boom)
    monkeypatch.setattr(pickle, "loads", boom)
    monkeypatch.setattr(torch, "load", boom)
    agents._CACHE.clear()
    policy = agents.load("ppo_sousa_asv")
    assert policy.act(np.zeros(policy.obs_dim)).shape == (2,)


# ------------------------------------------------------------------------------------
# malicious pickles in every file of a new-format run directory
@pytest.mark.parametrize(
    "poison, drop",
    [
        ("best_model.safetensors", []),
        ("best_vecnormalize.safetensors", []),
        ("model.safetensors", ["best_model.safetensors"]),
        ("vecnormalize.safetensors", ["best_model.safetensors"]),
        ("checkpoints/ckpt_0000000512.safetensors", ["best_model.safetensors", "model.safetensors"]),
        ("checkpoints/ckpt_0000000512_vecnormalize.safetensors", ["best_model.safetensors", "model.safetensors"]),
    ],
)
def test_evaluate_refuses_a_pickle_in_a_run_file(tiny_run, tmp_path, capsys, poison, drop):
    run = _copy(tiny_run, tmp_path)
    for name in drop:
        (run / name).unlink()
    marker = tmp_path / "PWNED"
    (run / poison).write_bytes(_evil(marker))
    _refused(capsys, _evaluate(run, tmp_path), marker, Path(poison).name)
    with pytest.raises(agents.PickleRefused, match="--trust-pickle"):
        agents.load(run)
    assert not marker.exists()
    # --trust-pickle does not make a .safetensors file unpickled either
    assert _evaluate(run, tmp_path, "--trust-pickle") == 2
    assert not marker.exists()


@pytest.mark.parametrize(
    "poison", ["checkpoints/ckpt_0000000512.safetensors", "checkpoints/ckpt_0000000512_vecnormalize.safetensors"]
)
def test_resume_refuses_a_pickle_in_a_checkpoint(tiny_run, tmp_path, capsys, poison):
    run = _copy(tiny_run, tmp_path)
    marker = tmp_path / "PWNED"
    (run / poison).write_bytes(_evil(marker))
    _refused(capsys, train_cli.main(["--resume", str(run), "--no-progress"]), marker, Path(poison).name)


@pytest.mark.parametrize("poison", ["best_model.safetensors", "best_vecnormalize.safetensors"])
def test_init_from_refuses_a_pickle(tiny_run, tmp_path, capsys, poison):
    source = _copy(tiny_run, tmp_path, "source")
    marker = tmp_path / "PWNED"
    (source / poison).write_bytes(_evil(marker))
    (tmp_path / "tiny.yml").write_text(yaml.safe_dump(dict(TINY, init_from=str(source))))
    code = train_cli.main(
        [
            "--scenario",
            "sousa_asv",
            "--timesteps",
            "256",
            "--out",
            str(tmp_path / "warm"),
            "--config",
            str(tmp_path / "tiny.yml"),
            "--no-progress",
        ]
    )
    _refused(capsys, code, marker, poison)
    assert not (tmp_path / "warm").exists()


# ------------------------------------------------------------------------------------
# the old pickle-based format: refused, unless trusted; then converted
@pytest.mark.parametrize("poison", ["vecnormalize.pkl", "model.zip", "zip entry"])
def test_an_old_format_run_is_refused_without_trust_pickle(old_run, tmp_path, capsys, poison):
    run = _copy(old_run, tmp_path)
    marker = tmp_path / "PWNED"
    if poison == "zip entry":  # a pickle in the model zip's JSON (SB3 unpickles ":serialized:" values)
        with zipfile.ZipFile(old_run / "model.zip") as z:
            entries = {n: z.read(n) for n in z.namelist()}
        data = json.loads(entries["data"])
        import base64

        data["policy_class"][":serialized:"] = base64.b64encode(_evil(marker)).decode()
        entries["data"] = json.dumps(data).encode()
        with zipfile.ZipFile(run / "model.zip", "w") as z:
            for n, b in entries.items():
                z.writestr(n, b)
    else:
        (run / poison).write_bytes(_evil(marker))
    name = "model.zip" if poison == "zip entry" else poison
    _refused(capsys, _evaluate(run, tmp_path), marker, name)
    _refused(capsys, convert.main([str(run), "--out", str(tmp_path / "new")]), marker, str(run))
    with pytest.raises(agents.PickleRefused, match="--trust-pickle"):
        agents.load(run)
    with pytest.raises(agents.PickleRefused, match="--trust-pickle"):
        agents.load(run / "model.zip")
    _refused(capsys, train_cli.main(["--resume", str(run), "--no-progress"]), marker, "ckpt_0000000256.zip")
    assert not marker.exists()


def test_trust_pickle_converts_a_genuine_old_run(old_run, tmp_path, capsys):
    new = tmp_path / "new"
    assert convert.main([str(old_run), "--out", str(new), "--trust-pickle"]) == 0
    for name in (
        "config.yml",
        "model.safetensors",
        "vecnormalize.safetensors",
        "checkpoints/last_checkpoint.json",
        "checkpoints/ckpt_0000000256.safetensors",
        "checkpoints/ckpt_0000000256_vecnormalize.safetensors",
    ):
        assert (new / name).is_file(), name
    assert not [p for p in new.rglob("*") if p.suffix in (".zip", ".pkl")]
    old = agents.load(old_run, trust_pickle=True)
    converted = agents.load(new)
    obs = np.random.default_rng(0).normal(size=(64, old.obs_dim)) * 3
    assert np.array_equal(old.act_batch(obs), converted.act_batch(obs))
    assert converted.model.num_timesteps == 256
    # and evaluate.py --trust-pickle evaluates the old run directly
    assert _evaluate(old_run, tmp_path, "--trust-pickle") == 0
    # the converted run resumes (new-format checkpoints) without the flag
    assert train_cli.main(["--resume", str(new), "--no-progress"]) == 0
    assert json.loads((new / "checkpoints" / "last_checkpoint.json").read_text())["num_timesteps"] == 512


def test_a_run_already_in_the_safe_format_has_nothing_to_convert(tiny_run, tmp_path, capsys):
    """A new-format run (or its model file) is not "read by unpickling": converting it says so
    in one line, with or without --trust-pickle (it told the user to run the command they had
    just typed, or named a checkpoint "not converted"), and writes nothing."""
    for source in (tiny_run, tiny_run / "model.safetensors"):
        for flags in ([], ["--trust-pickle"]):
            assert convert.main([str(source), "--out", str(tmp_path / "c"), *flags]) == 2
            err = capsys.readouterr().err.strip()
            assert "already in the safe format" in err and "\n" not in err and "--trust-pickle" not in err, err
            assert not (tmp_path / "c").exists()


def test_trust_pickle_resumes_an_old_run(old_run, tmp_path):
    run = _copy(old_run, tmp_path)
    assert train_cli.main(["--resume", str(run), "--no-progress", "--trust-pickle"]) == 0
    last = json.loads((run / "checkpoints" / "last_checkpoint.json").read_text())
    assert last["num_timesteps"] == 512 and last["model"].endswith(".safetensors")
    assert agents.load(run).model.num_timesteps == 512


def test_an_rllib_checkpoint_is_refused_without_trust_pickle(tmp_path, capsys):
    """An RLlib checkpoint (class_and_ctor_args.pkl, the MeanStdFilter's state.pkl) is
    read by unpickling: refused before Ray is even imported."""
    from agents import rllib_policy

    ckpt = tmp_path / "rl" / "checkpoint"
    module = ckpt / rllib_policy.MODULE_DIR / "beacon_asv"
    module.mkdir(parents=True)
    marker = tmp_path / "PWNED"
    (ckpt / rllib_policy.CHECKPOINT_MARKER).write_text("{}")
    (module / "class_and_ctor_args.pkl").write_bytes(_evil(marker))
    (ckpt / rllib_policy.FILTER_STATE).parent.mkdir(parents=True)
    (ckpt / rllib_policy.FILTER_STATE).write_bytes(_evil(marker))
    with pytest.raises(agents.PickleRefused, match="--trust-pickle"):
        agents.load(ckpt, scenario="sousa_asv")
    _refused(capsys, _evaluate(ckpt, tmp_path), marker, "checkpoint")
    assert not marker.exists()


# ------------------------------------------------------------------------------------
# missing normalization, paths outside the run, a run killed before its first checkpoint
def test_a_missing_normalization_file_is_refused(tiny_run, tmp_path, capsys):
    run = _copy(tiny_run, tmp_path)
    (run / "best_vecnormalize.safetensors").unlink()
    with pytest.raises(agents.PolicyFormatError, match=r"best_vecnormalize\.safetensors is missing"):
        agents.load(run)
    assert _evaluate(run, tmp_path) == 2
    err = capsys.readouterr().err.strip()
    assert "best_vecnormalize.safetensors is missing" in err and "\n" not in err
    # a lone model file records that it was trained on normalized observations
    lone = tmp_path / "lone"
    lone.mkdir()
    shutil.copy(tiny_run / "model.safetensors", lone / "model.safetensors")
    with pytest.raises(agents.PolicyFormatError, match="normalized observations"):
        agents.load(lone / "model.safetensors")


def test_a_last_checkpoint_pointing_outside_is_refused(tiny_run, tmp_path, capsys):
    run = _copy(tiny_run, tmp_path)
    for name in ("best_model.safetensors", "model.safetensors"):
        (run / name).unlink()
    shutil.copy(tiny_run / "model.safetensors", tmp_path / "outside.safetensors")
    last = run / "checkpoints" / "last_checkpoint.json"
    entry = json.loads(last.read_text())
    entry["model"] = "../../outside.safetensors"
    last.write_text(json.dumps(entry))
    with pytest.raises(agents.PolicyFormatError, match="points outside"):
        agents.load(run)
    assert _evaluate(run, tmp_path) == 2
    err = capsys.readouterr().err.strip()
    assert "points outside" in err and "\n" not in err
    assert train_cli.main(["--resume", str(run), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert "points outside" in err and "\n" not in err


def test_a_run_killed_before_its_first_checkpoint_resumes_from_scratch(tiny_run, tmp_path, capsys):
    run = tmp_path / "killed"
    run.mkdir()
    shutil.copy(tiny_run / "config.yml", run / "config.yml")  # what a run killed early leaves
    assert train_cli.main(["--resume", str(run), "--no-progress"]) == 0
    err = capsys.readouterr().err
    assert "starting it from scratch" in err
    assert (run / "model.safetensors").is_file()
    assert json.loads((run / "checkpoints" / "last_checkpoint.json").read_text())["num_timesteps"] == 512
    assert [json.loads(x)["num_timesteps"] for x in (run / "evaluations.jsonl").read_text().splitlines()] == [512]
    # the same run from scratch: the same weights as the original (same seed, same config)
    a = agents.load(run / "model.safetensors").model.policy.state_dict()
    b = agents.load(tiny_run / "model.safetensors").model.policy.state_dict()
    assert all(np.array_equal(a[k].numpy(), b[k].numpy()) for k in a)


def test_safe_files_hold_json_readable_without_python_objects(tiny_run):
    from safetensors import safe_open

    with safe_open(str(tiny_run / "model.safetensors"), "np") as f:
        spec = json.loads(f.metadata()["coopnav"])
        keys = list(f.keys())
    assert spec["format"] == formats.MODEL_FORMAT and spec["policy_kwargs"]["net_arch"] == [16, 16]
    assert spec["num_timesteps"] == 512 and spec["norm_obs"] is True
    assert "log_std" in keys and any(k.startswith(formats.OPTIM_PREFIX) for k in keys)
    stats = formats.read_vecnormalize(tiny_run / "vecnormalize.safetensors")
    assert stats["obs_mean"].shape == (agents.load(tiny_run).obs_dim,) and stats["norm_obs"]


# ------------------------------------------------------------------------------------
# RLlib: the safe export train.py writes beside every checkpoint; RLlib's own pickles unread
@pytest.mark.xdist_group("ray")  # .ci/run's workers: one Ray at a time (tests/test_rllib.py's group)
def test_rllib_checkpoints_load_from_their_safe_export(tmp_path, capsys):
    require("ray.rllib")
    import ray

    from agents import rllib_policy
    from agents.training import RLlibConfig
    from agents.training import rllib as rllib_trainer
    from agents.training.config import from_dict

    cycles = 10
    hp = {
        "scenario": "sousa_asv",
        "normalize_obs": True,
        "model": {"fcnet_hiddens": [16, 16]},
        "ppo": {"train_batch_size_per_learner": 2 * cycles, "minibatch_size": cycles, "num_epochs": 1},
        "env_runners": {"num_env_runners": 0, "num_envs_per_env_runner": 1},
        "learners": {"num_learners": 0},
        "env": {"overrides": {"max_cycles": cycles}},
    }
    if ray.is_initialized():
        ray.shutdown()
    ray.init(
        num_cpus=2,
        include_dashboard=False,
        log_to_driver=False,
        object_store_memory=100 * 2**20,
        runtime_env={
            "env_vars": {
                "PYTHONPATH": str(Path(__file__).resolve().parents[1]),
                "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "0",
            }
        },
    )
    try:
        algo_config, _ = rllib_trainer.build_config(from_dict(RLlibConfig, hp))
        algo = algo_config.build_algo()
        try:
            m = rllib_trainer.metrics(algo.train())
            run = tmp_path / "run"
            run.mkdir()
            ckpt = rllib_trainer.save_checkpoint(algo, run, m)  # what train.py writes
        finally:
            algo.stop()
    finally:
        ray.shutdown()
    assert (ckpt / rllib_policy.EXPORT_DIR / "asv.safetensors").is_file()
    obs = np.random.default_rng(0).normal(size=(16, 19)).astype(np.float32)
    trusted = rllib_policy.load(ckpt, scenario="sousa_asv", trust_pickle=True)
    expected = trusted.act_batch(obs)

    # RLlib's own pickles poisoned: never read, the export acts the same
    safe = _copy(ckpt, tmp_path, "safe")
    marker = tmp_path / "PWNED"
    (safe / rllib_policy.FILTER_STATE).write_bytes(_evil(marker))
    for f in (safe / rllib_policy.MODULE_DIR).rglob("*.pkl"):
        f.write_bytes(_evil(marker))
    agents._TRUSTED.clear()
    rllib_policy._RUNS.clear()
    policy = agents.load(safe, scenario="sousa_asv")
    assert policy.run.export is not None and np.array_equal(policy.act_batch(obs), expected)
    assert not marker.exists()

    # the export's filter file poisoned: refused, in Python and by evaluate.py
    (safe / rllib_policy.EXPORT_DIR / rllib_policy.FILTERS_FILE).write_bytes(_evil(marker))
    rllib_policy._RUNS.clear()
    with pytest.raises(agents.PickleRefused, match="--trust-pickle"):
        agents.load(safe, scenario="sousa_asv")
    capsys.readouterr()
    _refused(capsys, _evaluate(safe, tmp_path), marker, rllib_policy.FILTERS_FILE)

    # without its export: refused unless trusted; agents.convert --trust-pickle adds it
    bare = _copy(ckpt, tmp_path, "bare")
    shutil.rmtree(bare / rllib_policy.EXPORT_DIR)
    with pytest.raises(agents.PickleRefused, match="--trust-pickle"):
        agents.load(bare, scenario="sousa_asv")
    assert convert.main([str(bare), "--out", str(tmp_path / "converted"), "--trust-pickle"]) == 0
    agents._TRUSTED.clear()
    rllib_policy._RUNS.clear()
    converted = agents.load(tmp_path / "converted", scenario="sousa_asv")
    assert converted.run.export is not None and np.array_equal(converted.act_batch(obs), expected)
