"""benchmarks/sim_profile.py: the simulator's rate and its fusion kernel's share, with
one-line refusals of bad input (exit status 2)."""

import re

from benchmarks import sim_profile


def test_reports_the_rate_and_the_kernel_share(capsys):
    assert sim_profile.main(["--scenario", "gao_lawnmower", "--batch", "3", "--steps", "2", "--warmup", "1"]) == 0
    out = capsys.readouterr().out
    m = re.search(r"gao_lawnmower, 3 environments, 2 steps: ([\d,]+) env-steps/s; fusion kernel (\d+) %", out)
    assert m and int(m.group(1).replace(",", "")) > 0 and 0 <= int(m.group(2)) <= 100


def test_bad_input_is_one_line_and_exit_2(capsys):
    for argv, needle in [
        (["--batch", "0"], "--batch"),
        (["--scenario", "sousa_asw"], "sousa_asw"),
        (["--set", "range_outlier_model"], "KEY=VALUE"),
    ]:
        assert sim_profile.main(argv) == 2, argv
        err = capsys.readouterr().err
        lines = err.strip().splitlines()
        assert len(lines) == 1 and needle in lines[0] and "Traceback" not in err, (argv, err)
