"""benchmarks/sousa_table3.py plays its cells through the evaluation's runner: its Table I-II
quantities are the episodes' own figures, whatever the number of workers."""

from __future__ import annotations

import argparse

import numpy as np

from benchmarks.sousa_table3 import episode_moments, make_path_config, spec


def test_the_table_reads_the_evaluations_episodes(capsys):
    from benchmarks.sousa_table3 import main
    from evaluation.episodes import run_episodes

    args = argparse.Namespace(depth=20.0, ping_interval=20.0, circle_radius=30.0, duration=100.0)
    config = make_path_config("circle", args)
    seeds = [700000, 700001, 700002]
    episodes, steps = run_episodes(config, spec("fim_b", {"predictor": "chord"}), seeds)
    mean, var = episode_moments(steps, seeds)
    # eps_bar is the episode's mean error; sigma^2 its variance over the steps (not zero, not the mean's)
    np.testing.assert_allclose(mean, [e["mean_error_m"] for e in episodes], rtol=1e-12)
    assert (var > 0).all() and not np.allclose(var, mean**2)
    assert spec("fim_b", {"predictor": "chord"}) == "fim_b:predictor=chord"
    main(["--episodes", "3", "--duration", "100", "--workers", "2"])
    two = capsys.readouterr().out
    main(["--episodes", "3", "--duration", "100"])
    assert capsys.readouterr().out == two
    row = next(line for line in two.splitlines() if line.startswith("| B (chord) | eps="))
    circle = row.split(" | ")[3]  # the Circular column
    assert circle.startswith(f"eps={mean.mean():.3f} ") and f"var={var.mean():.3f}" in circle
