"""The evaluation loses nothing and says what went wrong in one line: one run owns an
output directory (a second writer is refused), an earlier result is replaced only with
--overwrite, --resume keeps only complete episodes of the same run and gives a
summary.json byte-identical to an uninterrupted run's (also after SIGKILL at random
moments), bad input is one line with exit status 2 and nothing written, and Ctrl-C /
SIGTERM exit 130 printing the command that resumes."""

from __future__ import annotations

import json
import os
import random
import shlex
import shutil
import signal
import subprocess
import sys
import time

import pytest
from cli_runs import FAST_EVALUATION

from coopnav_env.seeds import MAX_SEED
from evaluation import cli

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
EVALUATE = [sys.executable, os.path.join(ROOT, "evaluate.py")]

FAST = FAST_EVALUATION
# a run of a few seconds (episodes of ~240 steps), to be killed, interrupted or locked out
LONG = [
    "--scenario",
    "sousa_asv",
    "--set",
    "max_cycles=200",
    "--policies",
    "static,fim_a",
    "--episodes",
    "3",
    "--batch-size",
    "1",
    "--no-figures",
]


def files(path) -> dict:
    """name -> bytes of every file in ``path`` (None if it does not exist)."""
    if not os.path.isdir(path):
        return None
    return {
        n: open(os.path.join(path, n), "rb").read()
        for n in sorted(os.listdir(path))
        if os.path.isfile(os.path.join(path, n))
    }


def settled(path) -> set:
    """Names of the files in ``path`` other than an atomic write's temporary
    (``.<name>.<random>.tmp``, coopnav_env.records), which a running writer creates and
    renames away at any moment."""
    return {n for n in os.listdir(path) if not (n.startswith(".") and n.endswith(".tmp"))}


def results(path) -> dict:
    """The result files that must not differ between a resumed and an uninterrupted run."""
    return {
        n: open(os.path.join(path, n), "rb").read() for n in ("summary.json", "summary.md", "episodes.csv", "steps.csv")
    }


def run_main(argv, capsys):
    code = cli.main(argv, prog="evaluate.py")
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def _default_sigint():
    # a test suite started in the background by a non-interactive shell (`cmd &`, as CI may)
    # hands its children SIGINT ignored, and Python then never raises KeyboardInterrupt:
    # the child gets the default disposition, as a command typed in a terminal has
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def start(argv):
    return subprocess.Popen(
        EVALUATE + argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT, preexec_fn=_default_sigint
    )


def wait_for(path, proc, timeout=60.0):
    """Wait until ``path`` exists (the process still running); False if it ended first."""
    t0 = time.monotonic()
    while not os.path.exists(path):
        if proc.poll() is not None:
            return False
        assert time.monotonic() - t0 < timeout, f"{path} never appeared"
        time.sleep(0.02)
    return True


@pytest.fixture(scope="module")
def fast_ref(tmp_path_factory):
    out = str(tmp_path_factory.mktemp("ref") / "fast")
    assert cli.main(FAST + ["--out", out]) == 0
    return out


@pytest.fixture(scope="module")
def long_ref(tmp_path_factory):
    out = str(tmp_path_factory.mktemp("ref") / "long")
    assert cli.main(LONG + ["--out", out]) == 0
    return out


# ------------------------------------------------------------------------------------
# one run owns --out


def test_a_second_writer_is_refused_and_the_first_run_is_intact(tmp_path, capsys, long_ref):
    out = str(tmp_path / "o")
    first = start(LONG + ["--out", out])
    try:
        assert wait_for(os.path.join(out, ".evaluate.owner.json"), first), first.communicate()
        before = settled(out)  # the first run is writing: compare names, not bytes
        code, stdout, err = run_main(LONG + ["--out", out], capsys)
        assert code == 2 and stdout == ""
        assert len(err.strip().splitlines()) == 1 and "in use by another evaluation" in err, err
        assert f"pid {first.pid}" in err
        code, _, err = run_main(LONG + ["--out", out, "--resume"], capsys)  # nor with --resume, --overwrite
        assert code == 2 and "in use" in err
        code, _, err = run_main(LONG + ["--out", out, "--overwrite"], capsys)
        assert code == 2 and "in use" in err
        assert before <= settled(out)  # the refused runs removed nothing
    finally:
        stdout, stderr = first.communicate(timeout=120)
    assert first.returncode == 0, stderr
    assert results(out) == results(long_ref)
    assert not os.path.exists(os.path.join(out, ".evaluate.owner.json"))


def test_an_earlier_result_needs_resume_or_overwrite(tmp_path, capsys, fast_ref):
    out = str(tmp_path / "o")
    shutil.copytree(fast_ref, out)
    before = files(out)
    for argv in (FAST, FAST[:-5] + ["--episodes", "2", "--seed", "9"]):  # the same run or another
        code, stdout, err = run_main(argv + ["--out", out], capsys)
        assert code == 2 and stdout == ""
        assert len(err.strip().splitlines()) == 1, err
        assert "already holds a finished evaluation" in err and "--resume" in err and "--overwrite" in err
        assert files(out) == before
    # an interrupted (unfinished) result too
    os.unlink(os.path.join(out, "summary.json"))
    code, _, err = run_main(FAST + ["--out", out], capsys)
    assert code == 2 and "unfinished evaluation" in err
    # --overwrite replaces it
    code, _, err = run_main(
        [
            "--scenario",
            "gao_lawnmower",
            "--set",
            "max_cycles=5",
            "--policies",
            "static",
            "--episodes",
            "2",
            "--out",
            out,
            "--overwrite",
            "--no-figures",
        ],
        capsys,
    )
    assert code == 0, err
    run = json.loads(open(os.path.join(out, "run.json")).read())
    assert run["policies"] == ["static"] and run["episodes"] == 2 and run["overrides"] == {"max_cycles": 5}
    summary = json.loads(open(os.path.join(out, "summary.json")).read())
    assert list(summary["policies"]) == ["static"]
    assert len(open(os.path.join(out, "episodes.csv")).read().splitlines()) == 1 + 2


# ------------------------------------------------------------------------------------
# --resume keeps only what is complete, of the same run


def test_a_noop_resume_changes_nothing(tmp_path, capsys, fast_ref):
    out = str(tmp_path / "o")
    shutil.copytree(fast_ref, out)
    code, _, err = run_main(FAST + ["--out", out, "--resume"], capsys)
    assert code == 0 and "0 to run" in err
    assert results(out) == results(fast_ref)


@pytest.mark.parametrize("damage", ["drop_lines", "cut_mid_line", "garble_number", "binary"])
def test_truncated_or_garbled_steps_are_run_again(tmp_path, capsys, fast_ref, damage):
    out = str(tmp_path / "o")
    shutil.copytree(fast_ref, out)
    path = os.path.join(out, "steps.csv")
    text = open(path).read()
    lines = text.splitlines(keepends=True)
    if damage == "drop_lines":  # the last episode loses its last 3 steps
        open(path, "w").write("".join(lines[:-3]))
    elif damage == "cut_mid_line":
        open(path, "w").write(text[:-7])
    elif damage == "garble_number":
        fields = lines[5].split(",")
        fields[5] = "1.2.3"
        lines[5] = ",".join(fields)
        open(path, "w").write("".join(lines))
    else:
        open(path, "wb").write(b"\x00\xff\xfe garbage")
    code, _, err = run_main(FAST + ["--out", out, "--resume"], capsys)
    assert code == 0, err
    assert "run again" in err, err
    assert results(out) == results(fast_ref)


@pytest.mark.parametrize("damage", ["garble_field", "short_row", "duplicate", "extra_line", "header"])
def test_garbled_episodes_csv_rows_are_run_again(tmp_path, capsys, fast_ref, damage):
    out = str(tmp_path / "o")
    shutil.copytree(fast_ref, out)
    path = os.path.join(out, "episodes.csv")
    lines = open(path).read().splitlines(keepends=True)
    if damage == "garble_field":
        fields = lines[2].split(",")
        fields[4] = "twelve"  # steps
        lines[2] = ",".join(fields)
    elif damage == "short_row":
        lines[3] = ",".join(lines[3].split(",")[:6]) + "\n"
    elif damage == "duplicate":
        lines.append(lines[1])
    elif damage == "extra_line":
        lines.insert(2, "this,is,not,an,episode\n")
    else:
        lines[0] = lines[0].replace("mean_error_m", "mean_err")
    open(path, "w").write("".join(lines))
    code, _, err = run_main(FAST + ["--out", out, "--resume"], capsys)
    assert code == 0, err
    assert "run again" in err, err
    assert results(out) == results(fast_ref)


@pytest.mark.parametrize(
    "argv,needle",
    [
        (["--seed", "7"], "--seed"),
        (["--set", "max_cycles=11"], "--set"),
        (["--scenario", "gao_sea"], "--scenario"),
        (["--sweep", "depth_m=5,20"], "--sweep"),
    ],
)
def test_resume_refuses_a_run_of_other_arguments(tmp_path, capsys, fast_ref, argv, needle):
    out = str(tmp_path / "o")
    shutil.copytree(fast_ref, out)
    before = files(out)
    args = list(FAST)
    for i in range(0, len(argv), 2):  # replace or add the option
        if argv[i] in args and argv[i] != "--set":
            args[args.index(argv[i]) + 1] = argv[i + 1]
        elif argv[i] == "--set":
            args[args.index("--set") + 1] = argv[i + 1]
        else:
            args += argv[i : i + 2]
    code, stdout, err = run_main(args + ["--out", out, "--resume"], capsys)
    assert code == 2 and stdout == ""
    assert len(err.strip().splitlines()) == 1 and "cannot resume" in err and needle in err, err
    assert files(out) == before


@pytest.mark.parametrize("content", ["{not json", "[]", '{"scenario": "gao_lawnmower"}', None])
def test_resume_refuses_an_unreadable_run_json(tmp_path, capsys, fast_ref, content):
    out = str(tmp_path / "o")
    shutil.copytree(fast_ref, out)
    if content is None:
        os.unlink(os.path.join(out, "run.json"))
    else:
        open(os.path.join(out, "run.json"), "w").write(content)
    before = files(out)
    code, _, err = run_main(FAST + ["--out", out, "--resume"], capsys)
    assert code == 2
    assert len(err.strip().splitlines()) == 1 and "run.json" in err and "--overwrite" in err, err
    assert files(out) == before


def test_resume_extends_policies_and_episodes_consistently(tmp_path, capsys, fast_ref):
    """A run of static (2 episodes) resumed with --policies fim_a --episodes 3 covers both
    policies and 3 episodes: the run of static,fim_a with 3 episodes, byte for byte."""
    out = str(tmp_path / "o")
    part = [a if a != "static,fim_a" else "static" for a in FAST]
    part[part.index("--episodes") + 1] = "2"
    assert run_main(part + ["--out", out], capsys)[0] == 0
    resume = [a if a != "static,fim_a" else "fim_a" for a in FAST]
    code, _, err = run_main(resume + ["--out", out, "--resume"], capsys)
    assert code == 0, err
    assert "now covers 3 of static, fim_a" in err
    assert results(out) == results(fast_ref)
    run = json.loads(open(os.path.join(out, "run.json")).read())
    assert run["policies"] == ["static", "fim_a"] and run["episodes"] == 3
    # fewer episodes, no --policies: nothing is dropped, nothing changes
    code, _, err = run_main(
        [
            "--scenario",
            "gao_lawnmower",
            "--set",
            "max_cycles=12",
            "--episodes",
            "1",
            "--batch-size",
            "1",
            "--no-figures",
            "--out",
            out,
            "--resume",
        ],
        capsys,
    )
    assert code == 0, err
    assert results(out) == results(fast_ref)


def test_a_nan_is_an_error_naming_the_episode(tmp_path, capsys, monkeypatch):
    import evaluation.episodes as episodes

    real = episodes.run_episodes

    def with_nan(config, policy, seeds, progress=None, act_seconds=None, keep_steps=True):
        eps, sts = real(config, policy, seeds, progress, act_seconds, keep_steps)
        if policy == "fim_a" and 1 in seeds:
            sts[2]["survey_error_m"] = float("nan")
        return eps, sts

    monkeypatch.setattr(episodes, "run_episodes", with_nan)  # where evaluation.parallel finds it
    out = tmp_path / "o"
    code, stdout, err = run_main(FAST + ["--out", str(out)], capsys)
    assert code == 1 and stdout == ""
    assert len(err.strip().splitlines()) == 1, err
    assert "episode 1 (seed 1) of policy 'fim_a'" in err and "survey_error_m is nan" in err, err
    assert not (out / "summary.json").exists()
    assert (out / "episodes.csv").exists()  # the episodes stay on disk


# ------------------------------------------------------------------------------------
# bad input: one line, exit status 2, nothing written


def _shipped(name):
    import agents

    if name not in agents.list_policies():
        pytest.skip(f"{name} is not shipped")


@pytest.mark.parametrize(
    "argv,needle",
    [
        (["--scenario", "sousa_asv", "--policies", "perpendicular"], "perpendicular"),
        (["--scenario", "matos_moving_lbl", "--policies", "fim_a"], "fim_a"),
        (["--seed", str(2**63)], "--seed"),
        (["--seed", str(MAX_SEED)], "seed"),  # with 2 episodes the second seed is too large
        (["--seed", "-1"], "--seed"),
        (["--seed", "1.5"], "--seed"),
        (["--seed", "seven"], "--seed"),
        (["--episodes", "-2"], "--episodes"),
        (["--resume", "--overwrite"], "--overwrite"),
    ],
)
def test_bad_input_is_one_line_exit_2_nothing_written(tmp_path, capsys, argv, needle):
    out = tmp_path / "never"
    base = [
        "--scenario",
        "gao_lawnmower",
        "--set",
        "max_cycles=3",
        "--policies",
        "static",
        "--episodes",
        "2",
        "--no-figures",
    ]
    code, stdout, err = run_main(base + argv + ["--out", str(out)], capsys)
    assert code == 2 and stdout == ""
    assert len(err.strip().splitlines()) == 1 and needle in err, err
    assert "Traceback" not in err
    assert not out.exists()


def test_the_largest_seed_runs(tmp_path, capsys):
    code, _, err = run_main(
        [
            "--scenario",
            "gao_lawnmower",
            "--set",
            "max_cycles=3",
            "--policies",
            "static,random",
            "--episodes",
            "1",
            "--seed",
            str(MAX_SEED),
            "--no-figures",
            "--out",
            str(tmp_path / "o"),
        ],
        capsys,
    )
    assert code == 0, err


def test_ppo_on_a_scenario_without_a_shipped_policy(tmp_path, capsys, monkeypatch):
    """Every registered scenario ships one (tests/test_train.py); a scenario without one
    (here: an empty policy directory) is one line naming the scenarios that have one."""
    import agents

    monkeypatch.setattr(agents, "POLICY_DIR", tmp_path / "no_policies")
    out = tmp_path / "never"
    code, _, err = run_main(["--scenario", "matos_moving_lbl", "--policies", "ppo", "--out", str(out)], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "'matos_moving_lbl' has no shipped policy" in err and "valid: ppo" not in err
    assert "scenarios with one: none" in err
    assert not out.exists()


def test_a_model_that_does_not_fit_the_scenario(tmp_path, capsys):
    _shipped("ppo_gao_team")
    out = tmp_path / "never"
    code, _, err = run_main(
        [
            "--scenario",
            "gao_lawnmower",
            "--set",
            "max_cycles=3",
            "--policies",
            "static,ppo_gao_team",
            "--episodes",
            "1",
            "--out",
            str(out),
        ],
        capsys,
    )
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "ppo_gao_team" in err and "observations" in err and "Traceback" not in err
    assert not out.exists()


def test_a_corrupt_model(tmp_path, capsys):
    _shipped("ppo_gao_sea")
    import agents

    policy = tmp_path / "corrupt"
    shutil.copytree(os.path.join(agents.POLICY_DIR, "ppo_gao_sea"), policy)
    models = [n for n in os.listdir(policy) if n.startswith(("model.", "best_model."))]
    assert models
    for n in models:
        (policy / n).write_bytes(b"this is no model")
    out = tmp_path / "never"
    code, _, err = run_main(
        [
            "--scenario",
            "gao_lawnmower",
            "--set",
            "max_cycles=3",
            "--policies",
            f"{policy},static",
            "--episodes",
            "1",
            "--out",
            str(out),
        ],
        capsys,
    )
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert str(policy) in err and "Traceback" not in err
    assert not out.exists()


def test_bad_input_into_an_existing_result_changes_nothing(tmp_path, capsys, fast_ref):
    out = str(tmp_path / "o")
    shutil.copytree(fast_ref, out)
    before = files(out)
    for argv in (["--policies", "static,perpendicular"], ["--seed", str(2**63)], ["--set", "max_cycles=0.5"]):
        args = list(FAST)
        for i in range(0, len(argv), 2):
            if argv[i] in args:
                args[args.index(argv[i]) + 1] = argv[i + 1]
            else:
                args += argv[i : i + 2]
        code, _, err = run_main(args + ["--out", out, "--resume"], capsys)
        assert code == 2 and len(err.strip().splitlines()) == 1, err
        assert files(out) == before


# ------------------------------------------------------------------------------------
# interrupted runs: exit 130, the resume command, and an exact resume


def _resume_argv(err: str) -> list:
    line = [ln for ln in err.splitlines() if "resume with: " in ln]
    assert len(line) == 1, err
    cmd = shlex.split(line[0].split("resume with: ", 1)[1])
    assert cmd[:2] == ["python", "evaluate.py"] and cmd[-1] == "--resume", cmd
    return cmd[2:]


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_interrupt_exits_130_and_the_printed_command_resumes(tmp_path, long_ref, sig):
    out = str(tmp_path / "o")
    proc = start(LONG + ["--out", out])
    assert wait_for(os.path.join(out, "episodes.csv"), proc), proc.communicate()
    proc.send_signal(sig)
    stdout, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert stdout == ""
    assert len(err.strip().splitlines()) == 1 and "interrupted" in err, err
    assert "Traceback" not in err
    assert not os.path.exists(os.path.join(out, "summary.json"))
    assert len(open(os.path.join(out, "episodes.csv")).read().splitlines()) >= 2  # at least one batch kept
    done = subprocess.run(EVALUATE + _resume_argv(err), capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "already done" in done.stderr
    assert results(out) == results(long_ref)


def test_an_interrupt_with_two_workers_stops_them_and_resumes_exactly(tmp_path, long_ref):
    """SIGTERM during a ``--workers 2`` run: exit 130 with the resume command, no worker left
    running, and the resumed files (one worker) equal an uninterrupted one-worker run's."""
    out = str(tmp_path / "o")
    proc = start(LONG + ["--out", out, "--workers", "2"])
    assert wait_for(os.path.join(out, "episodes.csv"), proc), proc.communicate()
    workers = subprocess.run(["pgrep", "-P", str(proc.pid)], capture_output=True, text=True).stdout.split()
    proc.send_signal(signal.SIGTERM)
    stdout, err = proc.communicate(timeout=60)
    assert proc.returncode == 130 and stdout == "", err
    assert len(err.strip().splitlines()) == 1 and "interrupted" in err and "--workers 2" in err, err
    assert workers, "the run had no worker processes"
    time.sleep(0.5)
    alive = [w for w in workers if os.path.exists(f"/proc/{w}") and "Z" not in _proc_state(w)]
    assert not alive, alive
    argv = [a for a in _resume_argv(err) if a not in ("--workers", "2")]
    done = subprocess.run(EVALUATE + argv, capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert done.returncode == 0, done.stderr
    assert results(out) == results(long_ref)


def _proc_state(pid: str) -> str:
    try:
        return open(f"/proc/{pid}/stat").read().split(")")[-1].split()[0]
    except OSError:
        return "gone"


def _kill_and_resume(out, delays):
    """Start the run, SIGKILL it after each delay (resuming each time), then resume to the end."""
    for delay in delays:
        proc = start(LONG + ["--out", out] + (["--resume"] if os.path.exists(out) else []))
        time.sleep(delay)
        proc.kill()
        proc.communicate()
    done = subprocess.run(
        EVALUATE + LONG + ["--out", out, "--resume"], capture_output=True, text=True, cwd=ROOT, timeout=180
    )
    assert done.returncode == 0, done.stderr
    return done


def test_resume_after_sigkill_after_the_first_batch_is_exact(tmp_path, long_ref):
    out = str(tmp_path / "o")
    proc = start(LONG + ["--out", out])
    assert wait_for(os.path.join(out, "episodes.csv"), proc), proc.communicate()
    proc.kill()
    proc.communicate()
    assert not os.path.exists(os.path.join(out, "summary.json"))
    done = subprocess.run(
        EVALUATE + LONG + ["--out", out, "--resume"], capture_output=True, text=True, cwd=ROOT, timeout=180
    )
    assert done.returncode == 0, done.stderr
    assert results(out) == results(long_ref)


@pytest.mark.slow
@pytest.mark.parametrize("trial", range(3))
def test_resume_after_sigkill_at_random_moments_is_exact(tmp_path, long_ref, trial):
    rng = random.Random(1000 + trial)
    out = str(tmp_path / "o")
    _kill_and_resume(out, [rng.uniform(0.5, 3.0) for _ in range(3)])
    assert results(out) == results(long_ref)


def test_set_parses_tuples_of_names_and_checks_the_length_of_points(tmp_path, capsys):
    """beacon_kinds takes any number of names (quotes optional); survey_area_m exactly two numbers."""
    from evaluation.config import parse_value

    assert parse_value("beacon_kinds", "asv,beacon_auv") == ("asv", "beacon_auv")
    assert parse_value("beacon_kinds", "['asv', 'beacon_auv']") == ("asv", "beacon_auv")
    assert parse_value("beacon_kinds", "asv") == ("asv",)
    assert parse_value("survey_area_m", "100, 80") == (100.0, 80.0)
    assert parse_value("randomize_survey_path", "lawnmower,spiral") == ("lawnmower", "spiral")
    assert parse_value("randomize_depth_m", "3,20") == (3.0, 20.0)
    code, _, err = run_main(
        ["--scenario", "gao_sea", "--set", "survey_area_m=1,2,3", "--out", str(tmp_path / "never")], capsys
    )
    assert code == 2 and err.strip() == "evaluate.py: error: survey_area_m takes 2 values, got 3", err
    code, _, err = run_main(
        ["--scenario", "gao_sea", "--set", "beacon_kinds=asv,,", "--out", str(tmp_path / "never")], capsys
    )
    assert code == 2 and "bad value" in err and "beacon_kinds" in err and len(err.strip().splitlines()) == 1
    code, _, err = run_main(
        ["--scenario", "gao_sea", "--set", "beacon_kinds=asv,boat_x", "--out", str(tmp_path / "never")], capsys
    )
    assert code == 2 and "boat_x" in err and len(err.strip().splitlines()) == 1, err
