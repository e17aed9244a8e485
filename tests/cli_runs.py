"""What several test files run through the command-line front ends: the fast evaluation
every reliability test starts from, and the tiny SB3 training run the format and safety
tests read (imported as ``from cli_runs import ...``, as ``optional``)."""

from __future__ import annotations

from pathlib import Path

import yaml

# a fast evaluation: one batch per episode, so several batch files are written
FAST_EVALUATION = [
    "--scenario",
    "gao_lawnmower",
    "--set",
    "max_cycles=12",
    "--policies",
    "static,fim_a",
    "--episodes",
    "3",
    "--batch-size",
    "1",
    "--no-figures",
]


def tiny_training(out: Path, config: dict, scenario: str = "sousa_asv") -> int:
    """``train.py`` for 512 steps (seed 3) with ``config`` written beside ``out`` as
    tiny.yml; returns the exit status."""
    from agents.training import cli as train_cli

    path = Path(out).parent / "tiny.yml"
    path.write_text(yaml.safe_dump(config))
    argv = ["--scenario", scenario, "--timesteps", "512", "--seed", "3", "--out", str(out)]
    return train_cli.main(argv + ["--config", str(path), "--no-progress"])
