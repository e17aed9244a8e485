"""coopnav-warmup: the scenarios of one network stay in one process (they compile the same
kernels), bad options are one line and exit status 2, and a worker steps its scenarios."""

import subprocess
import sys

import pytest

from coopnav_env.warmup import compile_scenarios, split

ALL = [
    "gao_lawnmower",
    "gao_sea",
    "gao_team",
    "matos_moving_lbl",
    "matos_river",
    "sousa_asv",
    "sousa_ping",
    "swarm_mls",
]


def test_two_jobs_put_each_network_in_one_process():
    parts = split(ALL, 2)
    assert parts == [
        ["gao_lawnmower", "gao_sea", "gao_team", "sousa_asv", "sousa_ping", "swarm_mls"],
        ["matos_moving_lbl", "matos_river"],
    ]


def test_more_jobs_than_networks_start_one_process_per_network_and_one_job_takes_all():
    assert len(split(ALL, 8)) == 2
    (one,) = split(ALL, 1)
    assert sorted(one) == ALL
    assert split(["matos_river", "gao_sea"], 2) == [["matos_river"], ["gao_sea"]]


@pytest.mark.parametrize(
    "args, message",
    [
        (["--scenarios", "gao_se"], "unknown scenario 'gao_se'; did you mean 'gao_sea'?"),
        (["--jobs", "0"], "--jobs must be at least 1, got 0"),
    ],
)
def test_bad_options_are_one_line_and_exit_2(args, message):
    r = subprocess.run([sys.executable, "-m", "coopnav_env.warmup", *args], capture_output=True, text=True)
    assert r.returncode == 2 and message in r.stderr and r.stderr.strip().count("\n") == 0, r.stderr
    assert "compiling" not in r.stdout


def test_a_worker_steps_each_of_its_scenarios():
    times = compile_scenarios(["gao_sea", "sousa_ping"])
    assert [name for name, _ in times] == ["gao_sea", "sousa_ping"] and all(t > 0 for _, t in times)


def test_ctrl_c_stops_the_workers_quietly():
    """Ctrl-C (SIGINT to the command's whole process group, as a terminal sends it) while the
    workers start (importing the package takes them about 2 s): exit status 130, one line,
    no traceback from the workers (they run in a session of their own, out of the group's
    reach, and are terminated by the parent)."""
    import os
    import signal

    p = subprocess.Popen(
        [sys.executable, "-m", "coopnav_env.warmup"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # its own group, as a terminal's foreground job
    )
    assert "compiling" in p.stdout.readline()
    os.killpg(p.pid, signal.SIGINT)
    _, err = p.communicate(timeout=120)
    assert p.returncode == 130 and err.strip() == "coopnav-warmup: stopped", err
