"""Training beacon policies: typed configs, the SB3 and RLlib trainers, their command line.

    from agents.training import TrainConfig, train
    config = TrainConfig(scenario="gao_lawnmower", timesteps=4096, n_envs=4, ppo={"n_steps": 128})
    train(config, "runs/gao_tiny")                 # 0 when done; a run directory agents.load reads
    agents.load("runs/gao_tiny")

Modules (imports one way: coopnav_env <- baselines <- agents <- agents.training):

* ``config``: ``TrainConfig`` (SB3), ``RLlibConfig`` (RLlib) and their sections;
  ``load_config`` (YAML + overrides), ``config_from_record`` (a run's config.yml).
* ``scoring``: the evaluation on fixed validation seeds both trainers use.
* ``common``: the job's scenario and cells, the run directory and its config.yml,
  resume seeds, stopping on SIGINT/SIGTERM.
* ``sb3``: ``train``/``resume`` with stable-baselines3 PPO.
* ``rllib``: ``train``/``resume`` on Ray RLlib (Ray imported only when used).
* ``cli``: ``main(argv)``, behind ``train.py`` and the ``coopnav-train`` command.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from .common import EXIT_BAD_INPUT, EXIT_INTERRUPTED, read_run_record
from .config import (
    ConfigError,
    EntitySpec,
    EnvSpec,
    EvalSpec,
    NormalizeSpec,
    PeriodicEvalSpec,
    RaySpec,
    RLlibConfig,
    TrainConfig,
    config_from_record,
    load_config,
)

__all__ = [
    "EXIT_BAD_INPUT",
    "EXIT_INTERRUPTED",
    "ConfigError",
    "EntitySpec",
    "EnvSpec",
    "EvalSpec",
    "NormalizeSpec",
    "PeriodicEvalSpec",
    "RLlibConfig",
    "RaySpec",
    "TrainConfig",
    "config_from_record",
    "load_config",
    "resume",
    "train",
]


def train(config: TrainConfig | RLlibConfig, out: str | Path, **options: Any) -> int:
    """Train ``config`` into the new run directory ``out``: ``sb3.train`` for a
    ``TrainConfig``, ``rllib.train`` for an ``RLlibConfig`` (``options``: theirs)."""
    if isinstance(config, RLlibConfig):
        from . import rllib

        return rllib.train(config, out, **options)
    from . import sb3

    return sb3.train(config, out, **options)


def resume(out: str | Path, **options: Any) -> int:
    """Continue the run in ``out`` on its own backend (its config.yml says which)."""
    from . import rllib, sb3

    backend = read_run_record(Path(out))["args"].get("backend") or "sb3"
    return (rllib if backend == "rllib" else sb3).resume(out, **options)
