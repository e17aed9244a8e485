"""Run folders a stranger sends you (issue 25): no file outside the folder read or
copied, no silent wrong result, bounded work, one line for every error.

Each refusal: one line on stderr naming what was wrong, exit status 2, and the folder
unchanged (hashed before and after)."""

from __future__ import annotations

import errno
import hashlib
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

pytest.importorskip("stable_baselines3")
pytest.importorskip("safetensors")

from cli_runs import FAST_EVALUATION, tiny_training

import agents
from agents import convert
from agents.training import cli as train_cli
from coopnav_env.safe_load import UnsafeDataError, loads_json, loads_yaml, read_yaml
from evaluation import cli as eval_cli

ROOT = Path(__file__).resolve().parent.parent
SHIPPED = ROOT / "agents" / "policies" / "ppo_gao_sea"
FAST = FAST_EVALUATION
BOMB = 'a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]\n' + "".join(
    f"{chr(98 + i)}: &{chr(98 + i)} [" + ",".join([f"*{chr(97 + i)}"] * 9) + "]\n" for i in range(8)
)
DEEP = "x: " + "[" * 20000 + "]" * 20000 + "\n"


def tree_hash(path) -> dict:
    """relative path -> sha256 (or the link's target) of everything under ``path``."""
    path = Path(path)
    if not path.exists():
        return None
    out = {}
    for p in sorted(path.rglob("*")):
        rel = str(p.relative_to(path))
        if p.is_symlink():
            out[rel] = "-> " + os.readlink(p)
        elif p.is_file():
            out[rel] = hashlib.sha256(p.read_bytes()).hexdigest()
        else:
            out[rel] = "dir"
    return out


def one_line_exit_2(code, err, needle):
    err = err.strip()
    assert code == 2, err
    assert err.count("\n") == 0, err
    assert "Traceback" not in err
    assert needle in err, err


def evaluate(argv, capsys):
    code = eval_cli.main(argv, prog="evaluate.py")
    return code, capsys.readouterr().err


def train(argv, capsys):
    code = train_cli.main(argv)
    return code, capsys.readouterr().err


@pytest.fixture
def run(tmp_path):
    """A copy of a shipped SB3 run (model, normalization, config.yml)."""
    d = tmp_path / "run"
    d.mkdir()
    for name in ("model.safetensors", "vecnormalize.safetensors", "config.yml"):
        shutil.copy(SHIPPED / name, d / name)
    return d


@pytest.fixture
def outside(tmp_path):
    d = tmp_path / "outside"
    d.mkdir()
    for name in ("model.safetensors", "vecnormalize.safetensors"):
        shutil.copy(SHIPPED / name, d / name)
    (d / "secret.txt").write_text("not yours\n")
    return d


# ------------------------------------------------------------------------------------
# files outside the run folder
def test_symlinked_best_model_is_refused(run, outside, tmp_path, capsys):
    (run / "best_model.safetensors").symlink_to(outside / "model.safetensors")
    shutil.copy(run / "vecnormalize.safetensors", run / "best_vecnormalize.safetensors")
    before = tree_hash(run)
    with pytest.raises(agents.PolicyFormatError, match="symbolic link"):
        agents.load(run)
    code, err = evaluate(
        [
            "--scenario",
            "gao_sea",
            "--policies",
            str(run),
            "--episodes",
            "1",
            "--out",
            str(tmp_path / "o"),
            "--no-figures",
        ],
        capsys,
    )
    one_line_exit_2(code, err, "outside the run folder")
    assert tree_hash(run) == before and not (tmp_path / "o").exists()


def test_symlinked_model_file_named_directly_is_refused(run, outside):
    (run / "model.safetensors").unlink()
    (run / "model.safetensors").symlink_to(outside / "model.safetensors")
    with pytest.raises(agents.PolicyFormatError, match="outside"):
        agents.load(run / "model.safetensors")


def test_symlinked_checkpoints_folder_is_refused_by_load_and_resume(run, outside, capsys):
    for name in ("model.safetensors", "vecnormalize.safetensors"):
        (run / name).unlink()
    ckpt = outside / "ckpts"
    ckpt.mkdir()
    shutil.copy(outside / "model.safetensors", ckpt / "ckpt_0000000256.safetensors")
    shutil.copy(outside / "vecnormalize.safetensors", ckpt / "ckpt_0000000256_vecnormalize.safetensors")
    (ckpt / "last_checkpoint.json").write_text(
        json.dumps(
            {
                "num_timesteps": 256,
                "model": "ckpt_0000000256.safetensors",
                "vecnormalize": "ckpt_0000000256_vecnormalize.safetensors",
            }
        )
    )
    (run / "checkpoints").symlink_to(ckpt)
    before, before_out = tree_hash(run), tree_hash(outside)
    with pytest.raises(agents.PolicyFormatError, match="symbolic link"):
        agents.load(run)
    code, err = train(["--resume", str(run), "--no-progress"], capsys)
    one_line_exit_2(code, err, "symbolic link")
    assert tree_hash(run) == before and tree_hash(outside) == before_out


def test_a_symlinked_file_inside_checkpoints_is_refused_by_resume(run, outside, capsys):
    ckpt = run / "checkpoints"
    ckpt.mkdir()
    (ckpt / "ckpt_0000000256.safetensors").symlink_to(outside / "model.safetensors")
    shutil.copy(run / "vecnormalize.safetensors", ckpt / "ckpt_0000000256_vecnormalize.safetensors")
    (ckpt / "last_checkpoint.json").write_text(
        json.dumps(
            {
                "num_timesteps": 256,
                "model": "ckpt_0000000256.safetensors",
                "vecnormalize": "ckpt_0000000256_vecnormalize.safetensors",
            }
        )
    )
    before = tree_hash(run)
    code, err = train(["--resume", str(run), "--no-progress"], capsys)
    one_line_exit_2(code, err, "symbolic link")
    assert tree_hash(run) == before


def _fake_rllib_run(base: Path, normalize_obs: bool) -> Path:
    """An RLlib run folder as train.py --backend rllib leaves it, reduced to what
    agents.resolve reads (the checkpoint marker, a module folder, the safe export)."""
    from safetensors.numpy import save_file

    run = base / "rllib_run"
    ckpt = run / "checkpoint"
    (ckpt / "learner_group" / "learner" / "rl_module" / "beacon").mkdir(parents=True)
    (ckpt / "rllib_checkpoint.json").write_text("{}")
    (run / "config.yml").write_text(
        yaml.safe_dump(
            {
                "args": {"backend": "rllib", "scenario": "gao_sea", "timesteps": 1000, "seed": 0},
                "hyperparameters": {"normalize_obs": normalize_obs},
            }
        )
    )
    export = ckpt / "policy_export"
    export.mkdir()
    save_file(
        {"w": np.zeros(2, np.float32)},
        str(export / "beacon.safetensors"),
        metadata={"coopnav": json.dumps({"format": "coopnav-rllib-module", "version": 1})},
    )
    return run


def test_symlinked_policy_export_is_refused(tmp_path, outside):
    run = _fake_rllib_run(tmp_path, normalize_obs=False)
    export = run / "checkpoint" / "policy_export"
    shutil.move(str(export), str(outside / "policy_export"))
    export.symlink_to(outside / "policy_export")
    with pytest.raises(agents.PolicyFormatError, match="symbolic link"):
        agents.resolve(run)


def test_rllib_export_without_filters_of_a_normalized_run_is_refused(tmp_path, capsys):
    """The SB3 path refuses a normalized run without its normalization; so does RLlib's
    (it would act on unnormalized observations: 2.31 vs 1.92 m, exit 0, before)."""
    run = _fake_rllib_run(tmp_path, normalize_obs=True)
    before = tree_hash(run)
    with pytest.raises(agents.PolicyFormatError, match=r"filters\.safetensors is missing"):
        agents.resolve(run)
    code, err = evaluate(
        [
            "--scenario",
            "gao_sea",
            "--policies",
            str(run),
            "--episodes",
            "1",
            "--out",
            str(tmp_path / "o"),
            "--no-figures",
        ],
        capsys,
    )
    one_line_exit_2(code, err, "filters.safetensors is missing")
    assert tree_hash(run) == before and not (tmp_path / "o").exists()
    # the same run without normalize_obs resolves (its module is read later)
    (run / "config.yml").write_text(
        (run / "config.yml").read_text().replace("normalize_obs: true", "normalize_obs: false")
    )
    assert agents.resolve(run)[0] == run / "checkpoint"


@pytest.mark.parametrize("how", ["file_in_checkpoints", "checkpoints_folder"])
def test_convert_copies_nothing_from_outside(run, tmp_path, how, capsys):
    ckpt = run / "checkpoints"
    if how == "file_in_checkpoints":
        ckpt.mkdir()
        (ckpt / "notes.txt").symlink_to("/etc/passwd")
    else:
        ckpt.symlink_to("/etc")
    out = tmp_path / "converted"
    before = tree_hash(run)
    code = convert.main([str(run), "--out", str(out), "--trust-pickle"])
    one_line_exit_2(code, capsys.readouterr().err, "symbolic link")
    assert not out.exists() and tree_hash(run) == before


@pytest.mark.parametrize("what", ["zip_without_data", "zip_of_garbage"])
def test_convert_of_a_corrupt_trusted_file_is_one_line(tmp_path, what, capsys):
    """Trusted (--trust-pickle) but not what it claims: a zip without SB3's data, a zip of
    garbage; and a VecNormalize pickle cut short or holding something else. One line and
    exit 2 (a PolicyFormatError), the --out folder not left behind: they were SB3's
    AssertionError, torch's UnpicklingError and pickle's traceback (an input audit, 2026-12-07)."""
    import pickle
    import zipfile

    from agents import formats

    src = tmp_path / "model.zip"
    with zipfile.ZipFile(src, "w") as z:
        if what == "zip_without_data":
            z.writestr("notes.txt", "")
        else:
            z.writestr("data", "{]")
            z.writestr("policy.pth", b"garbage")
    out = tmp_path / "converted"
    code = convert.main([str(src), "--out", str(out), "--trust-pickle"])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and "not a stable-baselines3 model .zip" in err, err
    assert not out.exists()
    cut, other = tmp_path / "cut.pkl", tmp_path / "other.pkl"
    cut.write_bytes(b"\x80\x04\x95")
    other.write_bytes(pickle.dumps([1, 2]))
    with pytest.raises(formats.PolicyFormatError, match=r"not a VecNormalize pickle \(pickle data was truncated"):
        formats.legacy_vecnormalize(cut)
    with pytest.raises(formats.PolicyFormatError, match="it holds a list"):
        formats.legacy_vecnormalize(other)


def test_a_gate_naming_its_own_folder_is_refused_at_once(run, capsys):
    (run / "gate.yml").write_text(
        yaml.safe_dump({"kind": "depth_gate", "threshold_m": 5.0, "shallow": ".", "deep": "."})
    )
    t0 = time.perf_counter()
    with pytest.raises(agents.PolicyFormatError, match="a gate itself"):
        agents.load(run)
    assert time.perf_counter() - t0 < 1.0


# ------------------------------------------------------------------------------------
# a silent wrong result: a tampered episode row
@pytest.fixture(scope="module")
def fast_ref(tmp_path_factory):
    out = str(tmp_path_factory.mktemp("ref") / "fast")
    assert eval_cli.main(FAST + ["--out", out]) == 0
    return out


def test_a_tampered_episode_row_is_refused_on_resume(tmp_path, fast_ref, capsys):
    out = tmp_path / "o"
    shutil.copytree(fast_ref, out)
    path = out / "episodes.csv"
    lines = path.read_text().splitlines(keepends=True)
    header = lines[0].rstrip("\n").split(",")
    fields = lines[2].split(",")
    col = header.index("mean_error_m")
    value = fields[col]
    digit = next(i for i, ch in enumerate(value) if ch.isdigit() and ch != "0")
    fields[col] = value[:digit] + str((int(value[digit]) % 9) + 1) + value[digit + 1 :]  # well formed, different
    assert fields[col] != value
    lines[2] = ",".join(fields)
    path.write_text("".join(lines))
    (out / "summary.json").unlink()  # as if the run had been stopped before its summary
    before = tree_hash(out)
    code, err = evaluate(FAST + ["--out", str(out), "--resume"], capsys)
    one_line_exit_2(code, err, "does not match its checksum")
    assert tree_hash(out) == before


def test_episodes_without_checksums_are_run_again(tmp_path, fast_ref, capsys):
    out = tmp_path / "o"
    shutil.copytree(fast_ref, out)
    (out / "checksums.json").unlink()
    code, err = evaluate(FAST + ["--out", str(out), "--resume"], capsys)
    assert code == 0 and "cannot be verified" in err, err
    for name in ("summary.json", "episodes.csv", "steps.csv", "checksums.json"):
        assert (out / name).read_bytes() == (Path(fast_ref) / name).read_bytes()


# ------------------------------------------------------------------------------------
# unbounded work from metadata or arguments
@pytest.mark.parametrize(
    "text,needle",
    [
        (BOMB, "anchors"),
        (DEEP, "nests deeper"),
        ("a: !!python/object/apply:os.system ['true']\n", "tag"),
        (b"\x80\x04\x95\xff\x00binary", "not UTF-8"),
    ],
    ids=["alias_bomb", "deep_20000", "python_tag", "binary"],
)
def test_yaml_bombs_are_refused_in_under_a_second(text, needle):
    t0 = time.perf_counter()
    with pytest.raises(UnsafeDataError, match=needle):
        loads_yaml(text, "config.yml")
    assert time.perf_counter() - t0 < 1.0


def test_deep_json_is_refused_in_under_a_second():
    t0 = time.perf_counter()
    with pytest.raises(UnsafeDataError, match="nests deeper"):
        loads_json("[" * 20000 + "]" * 20000, "run.json")
    assert time.perf_counter() - t0 < 1.0
    assert loads_json('{"a": "[[[[", "b": [1, {"c": null}]}') == {"a": "[[[[", "b": [1, {"c": None}]}


def test_shipped_yaml_files_read_with_the_bounded_loader():
    for path in list((ROOT / "configs").rglob("*.yml")) + list((ROOT / "agents" / "policies").rglob("*.yml")):
        assert read_yaml(path) == yaml.safe_load(path.read_text()), path


@pytest.mark.parametrize(
    "content,needle",
    [
        (BOMB, "anchors"),
        (DEEP, "nests deeper"),
        ("args: !!python/object/apply:os.system ['true']\n", "tag"),
        (b"\x00\xff\xfe binary", "not UTF-8"),
    ],
    ids=["alias_bomb", "deep_20000", "python_tag", "binary"],
)
def test_train_resume_of_a_hostile_config_yml_is_one_line(run, content, needle, capsys):
    path = run / "config.yml"
    path.write_bytes(content.encode() if isinstance(content, str) else content)
    before = tree_hash(run)
    t0 = time.perf_counter()
    code, err = train(["--resume", str(run), "--no-progress"], capsys)
    assert time.perf_counter() - t0 < 1.0
    one_line_exit_2(code, err, needle)
    assert tree_hash(run) == before
    with pytest.raises(agents.PolicyFormatError, match=needle):
        agents.load(run)


def test_a_2e9_layer_in_a_header_is_refused_before_allocating(run):
    from safetensors import safe_open
    from safetensors.torch import save_file

    path = run / "model.safetensors"
    with safe_open(str(path), "pt") as f:
        spec = json.loads(f.metadata()["coopnav"])
        tensors = {k: f.get_tensor(k) for k in f.keys()}  # noqa: SIM118 - a safetensors file handle, not a dict: no __iter__
    spec["policy_kwargs"]["net_arch"] = [2_000_000_000]
    save_file(tensors, str(path), metadata={"coopnav": json.dumps(spec)})
    import tracemalloc

    tracemalloc.start()
    try:
        with pytest.raises(agents.PolicyFormatError, match=r"layer width 2000000000 is outside"):
            agents.load(run)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 200e6  # the layer alone would be 8 GB of weights per input


@pytest.mark.parametrize(
    "setting,needle",
    [
        ("n_envs=10000000", "n_envs"),
        ("ppo.learning_rate=.inf", "learning_rate"),
        ("ppo.policy_kwargs.net_arch=[2000000000]", "layer width"),
        ("eval.episodes=1000000000000", "eval.episodes"),
        ("normalize.clip_obs=" + "1" + "0" * 400, "normalize.clip_obs"),
        ("env.overrides.depth_m=" + "1" + "0" * 400, "depth_m"),
        (None, "timesteps"),
        ("ppo.gamma=2", "ppo.gamma must be a number in (0, 1]"),
        ("ppo.clip_range=-1", "ppo.clip_range must be a number in (0, 10]"),
        ("ppo.ent_coef=-100", "ppo.ent_coef must be a number in [0, 10]"),
    ],
    ids=[
        "n_envs",
        "lr_inf",
        "net_arch",
        "eval_episodes",
        "clip_obs_10e400",
        "depth_10e400",
        "timesteps_1e30",
        "gamma_2",  # these three trained without a word (an input audit, 2026-12-07)
        "clip_negative",
        "ent_coef_negative",
    ],
)
def test_trainer_settings_are_bounded_before_anything_is_written(tmp_path, setting, needle, capsys):
    out = tmp_path / "run"
    steps = "1000" if setting is not None else "1" + "0" * 30
    code, err = train(
        ["--scenario", "sousa_asv", "--timesteps", steps, "--out", str(out), "--no-progress"]
        + (["--set", setting] if setting is not None else []),
        capsys,
    )
    one_line_exit_2(code, err, needle)
    assert not out.exists()


@pytest.mark.parametrize(
    "argv,needle",
    [
        (["--episodes", str(10**12)], "--episodes"),
        (["--batch-size", str(10**9)], "--batch-size"),
        (
            [
                "--sweep",
                "depth_m=" + ",".join(str(1 + i) for i in range(1000)),
                "--sweep",
                "max_cycles=" + ",".join(str(10 + i) for i in range(1000)),
            ],
            "cells",
        ),
        (["--set", "depth_m=" + "1" + "0" * 400], "depth_m"),
        (["--set", "depth_m=1e400"], "depth_m"),
    ],
    ids=["episodes_1e12", "batch_1e9", "sweep_1e6_cells", "depth_10e400", "depth_1e400"],
)
def test_evaluation_work_is_bounded(tmp_path, argv, needle, capsys):
    out = tmp_path / "o"
    t0 = time.perf_counter()
    code, err = evaluate(
        ["--scenario", "sousa_asv", "--policies", "static", "--out", str(out), "--no-figures"] + argv, capsys
    )
    one_line_exit_2(code, err, needle)
    assert time.perf_counter() - t0 < 30.0 and not out.exists()  # imports included, on a busy machine


def test_a_run_json_asking_for_1e12_episodes_is_refused(tmp_path, fast_ref, capsys):
    out = tmp_path / "o"
    shutil.copytree(fast_ref, out)
    rec = json.loads((out / "run.json").read_text())
    rec["episodes"] = 10**12
    (out / "run.json").write_text(json.dumps(rec))
    before = tree_hash(out)
    code, err = evaluate(FAST + ["--out", str(out), "--resume"], capsys)
    one_line_exit_2(code, err, "run.json is unreadable")
    assert tree_hash(out) == before


# ------------------------------------------------------------------------------------
# one trainer per folder
def _hold(folder: Path):
    """Another process holding the folder's lock, as a running train.py does."""
    code = (
        "import fcntl, os, sys, time; fd = os.open(sys.argv[1], os.O_RDONLY); "
        "fcntl.flock(fd, fcntl.LOCK_EX); print('held', flush=True); time.sleep(60)"
    )
    proc = subprocess.Popen([sys.executable, "-c", code, str(folder)], stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "held"
    return proc


@pytest.mark.parametrize("mode", ["resume", "out"])
def test_two_trainers_on_one_folder(run, tmp_path, mode, capsys):
    folder = run if mode == "resume" else tmp_path / "empty"
    folder.mkdir(exist_ok=True)
    before = tree_hash(folder)
    holder = _hold(folder)
    try:
        argv = (
            ["--resume", str(run)]
            if mode == "resume"
            else ["--scenario", "sousa_asv", "--timesteps", "1000", "--out", str(folder)]
        )
        code, err = train(argv + ["--no-progress"], capsys)
    finally:
        holder.kill()
        holder.wait()
    one_line_exit_2(code, err, "in use by another train.py run")
    assert tree_hash(folder) == before


def test_resume_of_a_run_without_checkpoints_never_deletes_its_evaluations(run, capsys):
    (run / "model.safetensors").unlink()
    (run / "evaluations.jsonl").write_text('{"num_timesteps": 100000, "survey_error_m": 2.0}\n')
    before = tree_hash(run)
    code, err = train(["--resume", str(run), "--no-progress"], capsys)
    one_line_exit_2(code, err, "not resumable")
    assert tree_hash(run) == before


@pytest.mark.slow
def test_a_resumed_run_gets_its_final_evaluation_back(tmp_path, capsys):
    """A run stopped after its last checkpoint but before its final evaluation: --resume
    evaluates it, and keeps the evaluations it had."""
    config = {
        "n_envs": 4,
        "checkpoint_every_steps": 256,
        "ppo": {"n_steps": 64, "batch_size": 128, "n_epochs": 1, "policy_kwargs": {"net_arch": [16, 16]}},
        "env": {"overrides": {"max_cycles": 10, "mission_duration_s": 200.0}},
        "eval": {"every_steps": 256, "episodes": 1, "seed": 1000000, "baselines": []},
    }
    out = tmp_path / "run"
    assert tiny_training(out, config) == 0
    lines = (out / "evaluations.jsonl").read_text().splitlines()
    assert [json.loads(x)["num_timesteps"] for x in lines] == [256, 512]
    (out / "evaluations.jsonl").write_text(lines[0] + "\n")  # stopped before the final evaluation
    (out / "model.safetensors").unlink()
    capsys.readouterr()
    assert train_cli.main(["--resume", str(out), "--no-progress"]) == 0
    after = (out / "evaluations.jsonl").read_text().splitlines()
    assert after[0] == lines[0] and [json.loads(x)["num_timesteps"] for x in after] == [256, 512]


def test_resuming_a_finished_run_changes_none_of_its_weights(tmp_path, capsys):
    """--resume of a run that has its steps trains nothing; SB3's learn() still reset the
    environments, which moved VecNormalize's statistics (obs count +rows, every mean), and the
    run's vecnormalize.safetensors was rewritten so that it no longer matched its model (an
    input audit, 2026-12-07). Now every weight file is byte for byte as it was."""
    import hashlib

    config = {
        "n_envs": 4,
        "checkpoint_every_steps": 512,
        "ppo": {"n_steps": 64, "batch_size": 128, "n_epochs": 1, "policy_kwargs": {"net_arch": [16, 16]}},
        "env": {"overrides": {"max_cycles": 10, "mission_duration_s": 200.0}},
        "eval": {"every_steps": 0},
    }
    out = tmp_path / "run"
    assert tiny_training(out, config) == 0

    def digests():
        return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(out.rglob("*.safetensors"))}

    before = digests()
    assert "vecnormalize.safetensors" in before
    capsys.readouterr()
    assert train_cli.main(["--resume", str(out), "--no-progress"]) == 0
    assert digests() == before


def test_a_resumed_run_keeps_its_evaluation_schedule(tmp_path):
    from agents.training.sb3 import last_evaluation_step

    (tmp_path / "evaluations.jsonl").write_text(
        "".join(json.dumps({"num_timesteps": n}) + "\n" for n in (512, 1024, 2048)) + "garbled\n"
    )
    assert last_evaluation_step(tmp_path, 1536) == 1024  # the next is due at 1024 + every_steps, as before
    assert last_evaluation_step(tmp_path, 4096) == 2048  # the final one is still due at 4096
    assert last_evaluation_step(tmp_path / "none", 10) == 0


# ------------------------------------------------------------------------------------
# disk full, read-only
@pytest.fixture
def small_tmpfs(tmp_path):
    mnt = tmp_path / "mnt"
    mnt.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(mnt)], capture_output=True, check=False)
    if r.returncode != 0:
        pytest.skip("cannot mount a tmpfs here (needs root)")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], capture_output=True, check=False)


def test_a_full_disk_during_evaluate_is_one_line(small_tmpfs, capsys):
    out = small_tmpfs / "o"
    (small_tmpfs / "filler").write_bytes(b"\0" * 40_000)  # leaves room for run.json, not for the steps
    code, err = evaluate(
        [
            "--scenario",
            "sousa_asv",
            "--set",
            "max_cycles=200",
            "--policies",
            "static,fim_a",
            "--episodes",
            "4",
            "--out",
            str(out),
            "--no-figures",
        ],
        capsys,
    )
    one_line_exit_2(code, err, "the disk is full")
    left = sorted(os.listdir(out))
    assert not [n for n in left if n.endswith(".tmp")], left  # nothing half-written
    for name in left:
        if name.endswith(".csv"):
            text = (out / name).read_text()
            assert text.endswith("\n")


def test_a_read_only_folder_during_evaluate_is_one_line(small_tmpfs, fast_ref, capsys):
    out = small_tmpfs / "o"
    shutil.copytree(fast_ref, out)
    (out / "summary.json").unlink()
    before = tree_hash(out)
    subprocess.run(["mount", "-o", "remount,ro", str(small_tmpfs)], check=True)
    code, err = evaluate(FAST + ["--out", str(out), "--resume"], capsys)
    assert code == 2 and err.strip().count("\n") == 0 and "Traceback" not in err, err
    assert "read-only" in err.lower(), err
    assert tree_hash(out) == before


@pytest.mark.parametrize(
    "failure, needle",
    [(MemoryError(), "out of memory"), (OverflowError("cannot allocate 1e20 rows"), "OverflowError: cannot allocate")],
)
def test_a_memory_error_during_evaluate_is_one_line_and_releases_the_folder(
    tmp_path, monkeypatch, capsys, failure, needle
):
    """Every failure of the machine that ``coopnav_env.failures.MACHINE_FAILURES`` names is one line
    (an OverflowError was a traceback from evaluate.py while train.py caught it)."""
    from evaluation import episodes

    def no_memory(*args, **kwargs):
        raise failure

    out = tmp_path / "o"
    with monkeypatch.context() as m:
        m.setattr(episodes, "run_episodes", no_memory)  # where evaluation.parallel finds it
        code, err = evaluate(FAST + ["--out", str(out)], capsys)
    one_line_exit_2(code, err, needle)
    assert not (out / ".evaluate.owner.json").exists()
    code, err = evaluate(FAST + ["--out", str(out), "--overwrite"], capsys)  # not "in use by another evaluation"
    assert code == 0, err


def test_enospc_during_train_in_process_is_one_line(tmp_path, monkeypatch, capsys):
    """A full disk at train.py's first write (os.replace of an atomic write fails)."""
    from coopnav_env import records

    def full(src, dst, *a, **k):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(dst))

    monkeypatch.setattr(records.os, "replace", full)
    out = tmp_path / "new"
    code, err = train(
        [
            "--scenario",
            "sousa_asv",
            "--timesteps",
            "64",
            "--out",
            str(out),
            "--set",
            "n_envs=1",
            "--set",
            "ppo.n_steps=64",
            "--set",
            "ppo.batch_size=64",
            "--set",
            "eval.every_steps=0",
            "--no-progress",
        ],
        capsys,
    )
    one_line_exit_2(code, err, "the disk is full")
    assert not [p for p in out.rglob("*") if p.name.endswith(".tmp")]


@pytest.mark.slow
def test_enospc_during_train_is_one_line_and_nothing_half_written(run, tmp_path):
    """train.py in a subprocess whose os.replace fails with ENOSPC (a full disk)."""
    shim = tmp_path / "shim"
    shim.mkdir()
    (shim / "sitecustomize.py").write_text(
        "import errno, os\n_real = os.replace\n"
        "def _full(src, dst, *a, **k):\n"
        "    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(dst))\n"
        "os.replace = _full\n"
    )
    out = tmp_path / "new"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(shim), str(ROOT)]))
    r = subprocess.run(
        [
            sys.executable,
            str(ROOT / "train.py"),
            "--scenario",
            "sousa_asv",
            "--timesteps",
            "64",
            "--out",
            str(out),
            "--set",
            "n_envs=1",
            "--set",
            "ppo.n_steps=64",
            "--set",
            "ppo.batch_size=64",
            "--set",
            "eval.every_steps=0",
            "--set",
            "eval.episodes=0",
            "--no-progress",
        ],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    one_line_exit_2(r.returncode, r.stderr, "the disk is full")
    assert not [p for p in out.rglob("*") if p.name.endswith(".tmp")]


# ------------------------------------------------------------------------------------
# scenario parameters: fixed on the config branch (coopnav_env/scenarios/base.py)


@pytest.mark.parametrize(
    "scenario,key,value",
    [
        ("sousa_asv", "substep_s", 5e-324),
        ("sousa_asv", "depth_m", 10**400),
        ("matos_river", "river_width_m", 5e-324),
        ("sousa_asv", "depth_m", 1e400),
    ],
)
def test_make_config_refuses_out_of_range_values_in_one_line(scenario, key, value):
    import coopnav_env

    with pytest.raises(ValueError) as info:
        coopnav_env.make_config(scenario, **{key: value})
    assert key in str(info.value) and "\n" not in str(info.value)


@pytest.mark.parametrize(
    "scenario,setting",
    [
        ("sousa_asv", "substep_s=5e-324"),
        ("sousa_asv", "depth_m=" + "1" + "0" * 400),
        ("matos_river", "river_width_m=5e-324"),
    ],
)
def test_evaluate_set_refuses_out_of_range_values_in_one_line(tmp_path, scenario, setting, capsys):
    out = tmp_path / "o"
    code, err = evaluate(
        [
            "--scenario",
            scenario,
            "--policies",
            "static",
            "--episodes",
            "1",
            "--out",
            str(out),
            "--set",
            setting,
            "--no-figures",
        ],
        capsys,
    )
    one_line_exit_2(code, err, setting.split("=")[0])
    assert not out.exists()


def test_a_folder_that_cannot_be_written_is_refused_before_anything_is_built(tmp_path, monkeypatch, capsys):
    """``records.check_writable``: a folder under a file, or one whose nearest existing
    parent refuses a new file (permission denied; faked here, since the tests may run as
    root), is one line, before train.py builds an environment or the benchmark and
    evaluate.py check their policies (which can compile the simulator for a minute)."""
    import tempfile

    from agents.training import cli as train_cli
    from coopnav_env.records import check_writable
    from evaluation import benchmark
    from evaluation import cli as evaluate_cli

    (tmp_path / "file").write_text("x")
    with pytest.raises(OSError, match="lies under a file"):
        check_writable(tmp_path / "file" / "run")
    check_writable(tmp_path / "new" / "deeper")  # a writable parent: fine, nothing left behind
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]
    with monkeypatch.context() as m:  # a root that does not exist (a missing drive): an error, not a loop
        m.setattr("os.path.exists", lambda path: False)
        with pytest.raises(OSError, match="does not exist"):
            check_writable(tmp_path / "run")

    def refuse(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(tempfile, "mkstemp", refuse)
    with pytest.raises(OSError, match=r"cannot write in .* \(Permission denied\)"):
        check_writable(tmp_path / "run")
    out = str(tmp_path / "run")
    assert train_cli.main(["--scenario", "sousa_asv", "--timesteps", "10", "--out", out, "--no-progress"]) == 2
    assert benchmark.main(["--tasks", "gao_sea", "--episodes", "2", "--out", out]) == 2
    assert evaluate_cli.main(["--scenario", "gao_sea", "--episodes", "2", "--out", out]) == 2
    err = capsys.readouterr().err
    assert err.count("Permission denied") == 3 and "Traceback" not in err, err
    assert not (tmp_path / "run").exists()


def test_a_resumed_run_in_a_folder_that_cannot_be_written_is_refused(run, monkeypatch, capsys):
    """``--resume`` writes checkpoints into the run's folder: a folder that refuses a new file
    (faked, since the tests may run as root) is one line, exit 2, before anything is built,
    and the folder is left as it was; ``evaluate.py --resume`` likewise."""
    import tempfile

    before = tree_hash(run)

    def refuse(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(tempfile, "mkstemp", refuse)
    code, err = train(["--resume", str(run), "--no-progress"], capsys)
    one_line_exit_2(code, err, "Permission denied")
    assert "--resume" in err
    assert tree_hash(run) == before
    code, err = evaluate(["--scenario", "gao_sea", "--episodes", "2", "--out", str(run / "eval"), "--resume"], capsys)
    one_line_exit_2(code, err, "Permission denied")
    assert tree_hash(run) == before


def test_a_benchmark_tables_path_is_checked_before_its_runs(tmp_path, capsys):
    """``records.check_output_file`` for the benchmark scripts' tables (--markdown, --out, --json,
    --cache): a folder, or a path under a file, is one line and exit 2 before any episode runs (it
    was a FileNotFoundError traceback after the runs, or a folder's table written nowhere); a
    folder not made yet is made when the table is written (an input audit, 2026-12-07)."""
    from benchmarks import nees_per_cycle, planners_vs_floors
    from coopnav_env.records import atomic_write_text, check_output_file

    (tmp_path / "file").write_text("x")
    with pytest.raises(OSError, match="is a folder, not a file"):
        check_output_file(tmp_path)
    with pytest.raises(OSError, match="is a file, not a folder"):
        check_output_file(tmp_path / "file" / "table.md")
    check_output_file(tmp_path / "new" / "table.md")  # fine: made when written
    atomic_write_text(tmp_path / "new" / "table.md", "| a |\n")
    assert (tmp_path / "new" / "table.md").read_text() == "| a |\n"

    assert nees_per_cycle.main(["--runs", "2", "--cases", "0", "--markdown", str(tmp_path)]) == 2
    assert "--markdown" in capsys.readouterr().err
    assert nees_per_cycle.main(["--runs", "2", "--cases", "0", "--seed", "-1"]) == 2
    assert "--seed must be in" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_info:
        planners_vs_floors.main(["--episodes", "2", "--markdown", str(tmp_path / "file" / "t.md")])
    assert exit_info.value.code == 2
    assert "--markdown" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("args", "what"),
    [
        (["--rllib-runners", "abc"], "--rllib-runners: whole numbers"),
        (["--envs-per-runner", "0"], "--envs-per-runner must be at least 1"),
        (["--scenario", "gao-sea"], "did you mean 'gao_sea'"),
    ],
)
def test_rllib_vs_sb3_refuses_bad_input_in_one_line(capsys, args, what):
    """They were a ValueError traceback and RLlib's ConfigError after SB3's timing had run (an
    input audit): now argparse's line and exit 2 before anything is built."""
    from benchmarks import rllib_vs_sb3

    with pytest.raises(SystemExit) as exit_info:
        rllib_vs_sb3.main(args)
    assert exit_info.value.code == 2 and what in capsys.readouterr().err
