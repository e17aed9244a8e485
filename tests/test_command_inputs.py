"""Bad input to the front ends that an input audit found taken silently (2026-12-07): each
case is one line and exit status 2 now, and nothing is written. Each test fails on the code
before its fix."""

from __future__ import annotations

import socket
import time

import pytest

from coopnav_env.names import unique_assignments
from coopnav_env.safe_load import UnsafeDataError, loads_yaml


def _train(argv, capsys):
    from agents.training import cli

    code = cli.main(argv)
    return code, capsys.readouterr().err


# ---------------------------------------------------------------------------------------
# one key twice: which value was meant?


def test_a_key_given_twice_with_two_values_is_refused_and_the_same_value_twice_is_not():
    assert unique_assignments([("a", 1), ("b", 2), ("a", 1)], "--set") == {"a": 1, "b": 2}
    with pytest.raises(ValueError, match="--set a given twice, as 1 and 3"):
        unique_assignments([("a", 1), ("a", 3)], "--set")


def test_train_refuses_a_set_key_given_twice(tmp_path, capsys):
    out = tmp_path / "run"
    # an unknown scenario too, refused later: the old code would have said that (not trained)
    argv = ["--scenario", "nope", "--timesteps", "100", "--out", str(out)]
    code, err = _train(argv + ["--set", "ppo.gamma=0.9", "--set", "ppo.gamma=0.8"], capsys)
    assert code == 2 and "--set ppo.gamma given twice, as 0.9 and 0.8" in err
    assert len(err.strip().splitlines()[-1:]) == 1 and not out.exists()


def test_the_batched_loop_and_benchmarl_settings_refuse_a_key_given_twice():
    from agents.training.config import ConfigError, parse_assignments

    assert parse_assignments(["lr=1e-4", "lr=0.0001"], "--set") == {"lr": 1e-4}  # the same number twice
    with pytest.raises(ConfigError, match="--set lr given twice"):
        parse_assignments(["lr=1e-4", "lr=3e-4"], "--set")


def test_the_benchmark_refuses_a_set_key_given_twice(tmp_path, capsys):
    from evaluation import benchmark

    # an unknown policy too, refused later: the old code would have said that (not run the set)
    argv = ["--tasks", "gao_sea", "--policies", "nope", "--out", str(tmp_path / "b")]
    code = benchmark.main(argv + ["--set", "depth_m=5", "--set", "depth_m=6"])
    err = capsys.readouterr().err
    assert code == 2 and "--set depth_m given twice, as '5' and '6'" in err
    assert not (tmp_path / "b").exists()


def test_a_yaml_key_given_twice_is_refused_with_its_line_and_keys_in_different_mappings_are_not():
    with pytest.raises(UnsafeDataError, match=r"key 'ppo' given twice \(line 4\)"):
        loads_yaml("ppo:\n  n_steps: 8\nseed: 1\nppo:\n  n_steps: 16\n")
    with pytest.raises(UnsafeDataError, match="key 'b' given twice"):
        loads_yaml("a: {b: 1, c: [1, 2], b: 2}")
    # the same key in sibling mappings, a value equal to a key, and keys after a nested list
    assert loads_yaml("l:\n  - {a: 1}\n  - {a: 2}\nm: a\na: [1, {m: 2}]\n") == {
        "l": [{"a": 1}, {"a": 2}],
        "m": "a",
        "a": [1, {"m": 2}],
    }


def test_train_refuses_a_config_file_with_a_duplicate_section(tmp_path, capsys):
    config = tmp_path / "dup.yml"
    config.write_text("ppo:\n  n_steps: 8\nppo:\n  n_steps: 16\n")
    out = tmp_path / "run"
    argv = ["--scenario", "gao_sea", "--timesteps", "100", "--out", str(out), "--config", str(config)]
    code, err = _train(argv, capsys)
    assert code == 2 and "key 'ppo' given twice (line 3)" in err and not out.exists()


# ---------------------------------------------------------------------------------------
# train.py's own options


def test_train_refuses_an_empty_out_instead_of_training_into_the_working_folder(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, err = _train(["--scenario", "nope", "--timesteps", "100", "--out", ""], capsys)
    assert code == 2 and "--out is empty" in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("value", ["7", "-3"])
def test_train_refuses_a_verbosity_outside_the_range_its_help_gives(value, tmp_path, capsys):
    code, err = _train(
        ["--scenario", "gao_sea", "--timesteps", "100", "--out", str(tmp_path / "r"), "--verbose", value], capsys
    )
    assert code == 2 and "--verbose" in err and not (tmp_path / "r").exists()


def _fake_run(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    (run / "config.yml").write_text("args: {scenario: gao_sea, backend: sb3}\n")
    return run


def test_plot_refuses_run_options_it_would_ignore(tmp_path, capsys):
    run = _fake_run(tmp_path)
    code, err = _train(["--plot", str(run), "--scenario", "gao_sea", "--timesteps", "5"], capsys)
    assert code == 2 and "drop --scenario, --timesteps" in err


def test_plot_says_an_unreadable_log_is_unreadable_not_missing(tmp_path, capsys):
    run = _fake_run(tmp_path)
    code, err = _train(["--plot", str(run)], capsys)
    assert code == 2 and "has no validation yet" in err
    (run / "evaluations.jsonl").write_text("{\n")
    code, err = _train(["--plot", str(run)], capsys)
    assert code == 2 and "holds no readable validation line" in err


def test_an_unreachable_ray_address_is_refused_at_once_not_retried_for_ever():
    from agents.training.config import ConfigError
    from agents.training.rllib import check_ray_address

    with socket.socket() as free:  # a port nothing listens on: bound, then closed
        free.bind(("127.0.0.1", 0))
        port = free.getsockname()[1]
    start = time.monotonic()
    with pytest.raises(ConfigError, match="nothing answers there"):
        check_ray_address(f"127.0.0.1:{port}")
    assert time.monotonic() - start < 6
    for bad in ("abc", "host:", ":6379", "host:99999"):
        with pytest.raises(ConfigError, match="expected 'auto' or HOST:PORT"):
            check_ray_address(bad)
    with socket.socket() as server:  # something answers: accepted
        server.bind(("127.0.0.1", 0))
        server.listen(1)
        check_ray_address(f"127.0.0.1:{server.getsockname()[1]}")
        check_ray_address(f"ray://127.0.0.1:{server.getsockname()[1]}")
    check_ray_address(None)
    check_ray_address("auto")


# ---------------------------------------------------------------------------------------
# evaluate.py


def _evaluate(argv, capsys):
    from evaluation import cli

    code = cli.main(argv, prog="evaluate.py")
    return code, capsys.readouterr().err


def test_a_transmit_schedule_left_empty_is_refused_not_labelled_as_the_default(tmp_path, capsys):
    argv = ["--scenario", "sousa_ping", "--policies", "fim_a+", "--episodes", "1", "--no-figures"]
    code, err = _evaluate(argv + ["--out", str(tmp_path / "e")], capsys)
    assert code == 2 and "'fim_a+' names no transmit schedule" in err
    assert not (tmp_path / "e").exists()


@pytest.mark.parametrize("held", ["benchmark", "train"])
def test_evaluate_refuses_a_folder_holding_a_benchmark_result_or_a_training_run(held, tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    if held == "benchmark":
        (out / "results.json").write_text("{}")
        want = "holds a benchmark result (results.json)"
    else:
        (out / "config.yml").write_text("args: {}\n")
        (out / "model.safetensors").write_bytes(b"")
        want = "holds a train.py run"
    before = sorted(p.name for p in out.iterdir())
    argv = ["--scenario", "gao_sea", "--policies", "static", "--episodes", "1", "--no-figures", "--out", str(out)]
    for extra in ([], ["--overwrite"]):  # --overwrite would clear only evaluate's own files
        code, err = _evaluate(argv + extra, capsys)
        assert code == 2 and want in err
    assert sorted(p.name for p in out.iterdir()) == before


def test_a_training_run_without_tensorboard_leaves_nothing_in_the_temporary_folder(tmp_path, monkeypatch):
    """SB3's default logger makes an empty /tmp/SB3-<date> folder per learn() when no
    TensorBoard folder is given (CI does not install TensorBoard): 2 per CI run, for ever."""
    import tempfile

    from cli_runs import tiny_training

    from agents.training import sb3

    real = sb3._installed
    monkeypatch.setattr(sb3, "_installed", lambda *m: False if "tensorboard" in m else real(*m))
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    config = {
        "n_envs": 2,
        "ppo": {"n_steps": 64, "batch_size": 128, "n_epochs": 1, "policy_kwargs": {"net_arch": [8]}},
        "env": {"overrides": {"max_cycles": 10, "mission_duration_s": 200.0}},
        "eval": {"every_steps": 512, "episodes": 1, "seed": 1000000, "baselines": []},
    }
    assert tiny_training(tmp_path / "run", config) == 0
    assert not (tmp_path / "run" / "tb").exists()
    assert [p.name for p in scratch.iterdir() if p.name.startswith("SB3-")] == []


def test_the_benchmark_refuses_a_training_run_folder_but_not_a_stray_config_file(tmp_path, capsys):
    from evaluation import benchmark

    out = tmp_path / "run"
    out.mkdir()
    (out / "config.yml").write_text("args: {}\n")
    # an unknown policy too, refused after the folder: a folder taken is seen by that message
    argv = ["--tasks", "gao_sea", "--policies", "nope", "--episodes", "2", "--no-figures", "--out", str(out)]
    assert benchmark.main(argv) == 2
    assert "nope" in capsys.readouterr().err  # a config.yml alone is someone's file, not a run
    (out / "model.safetensors").write_bytes(b"")
    assert benchmark.main(argv + ["--overwrite"]) == 2
    err = capsys.readouterr().err
    assert "holds a train.py run" in err and "nope" not in err


# ---------------------------------------------------------------------------------------
# a mistyped option: the one meant, where one is close


def test_option_hint_names_the_closest_option_without_the_dashes_and_never_help():
    from coopnav_env.names import option_hint

    opts = ["-h", "--help", "--out", "--policies", "--workers", "--episodes"]
    assert option_hint("unrecognized arguments: --outdir x", opts).endswith("; did you mean --out?")
    assert option_hint("unrecognized arguments: --Episodes=3", opts).endswith("; did you mean --episodes?")
    two = option_hint("unrecognized arguments: --polices ppo --workrs 2", opts)
    assert two.endswith("; did you mean --policies for --polices, --workers for --workrs?")
    assert option_hint("unrecognized arguments: --cell a=1", opts) == "unrecognized arguments: --cell a=1"
    assert option_hint("unrecognized arguments: --hlep", opts) == "unrecognized arguments: --hlep"
    assert (
        option_hint("argument --episodes: invalid int value: 'x'", opts)
        == "argument --episodes: invalid int value: 'x'"
    )


@pytest.mark.parametrize(
    "module, argv, meant",
    [
        ("agents.training.cli", ["--scenario", "gao_sea", "--timesteps", "10", "--outdir", "x"], "--out"),
        ("evaluation.cli", ["--scenario", "gao_sea", "--polices", "ppo"], "--policies"),
        ("evaluation.benchmark", ["--tasks", "gao_sea", "--workrs", "2"], "--workers"),
    ],
)
def test_each_front_end_names_the_option_meant(module, argv, meant):
    """train.py, evaluate.py and the benchmark said only "unrecognized arguments: --outdir x"."""
    import importlib

    parser = importlib.import_module(module).build_parser()
    with pytest.raises(Exception, match=f"did you mean {meant}\\?") as err:
        parser.parse_args(argv)
    assert "\n" not in str(err.value)
