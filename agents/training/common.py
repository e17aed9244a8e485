"""What the two trainers share: the job's scenario and evaluation cells, the run
directory and its config.yml, resume seeds, and stopping cleanly on a signal.

A run directory's ``config.yml`` (written once, atomically, when the run starts):

    command               the command line that started it
    args                  scenario, timesteps, seed (and the RLlib run's backend,
                          num_env_runners, ray_address, tune)
    hyperparameter_file   the YAML the config was loaded from (None: the defaults)
    hyperparameters       the rest of the config, every default filled in
    scenario_config       the training scenario's parameters
    eval_cells            the labels of the evaluation cells
    versions              coopnav_env.records.version_record()

``agents.load(run_dir)`` reads the scenario from it, ``--resume`` the whole config
(``config.config_from_record``).
"""

from __future__ import annotations

import contextlib
import dataclasses
import shlex
import signal
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

from coopnav_env.records import atomic_write_text, plain, read_yaml, version_record
from coopnav_env.seeds import refuse_test_seeds

from .config import ConfigError
from .scoring import eval_cells

_C = TypeVar("_C")

if TYPE_CHECKING:
    from coopnav_env.scenarios import ScenarioConfig

EXIT_BAD_INPUT = 2
EXIT_INTERRUPTED = 130

__all__ = [
    "EXIT_BAD_INPUT",
    "EXIT_INTERRUPTED",
    "Job",
    "StopFlag",
    "command_line",
    "new_run_dir",
    "planner_names",
    "prepare_job",
    "read_run_record",
    "resume_command",
    "run_config",
    "resume_seed",
    "stop_on_signals",
    "write_run_record",
]


@dataclasses.dataclass
class Job:
    """A config made concrete: the training scenario, its reward terms, the
    evaluation cells ([(label, ScenarioConfig)]) and, for a mixed-team run
    (``env.teams``), the team overrides ([] else)."""

    scenario_config: ScenarioConfig
    reward_terms: dict | None  # None: the environment's reward
    cells: list
    teams: list = dataclasses.field(default_factory=list)


def team_label(team: dict) -> str:
    """An evaluation cell's label for a team: ``n_survey=2;beacon_kinds=asv+beacon_auv``
    (``team=scenario`` for {}, the scenario's own team)."""
    if not team:
        return "team=scenario"
    return ";".join(f"{k}={'+'.join(v) if isinstance(v, (list, tuple)) else v}" for k, v in team.items())


def team_cells(scenario_config: ScenarioConfig, teams: list, cells: dict | None, entities: bool = True) -> list:
    """The evaluation cells of a mixed-team run: ``eval_cells`` of every team, each
    label prefixed with the team's (``team_label``); a ``ConfigError`` for a team the
    scenario (or, with ``entities``, the entity view) cannot take."""
    from coopnav_env.entity_obs import check_team

    out = []
    for i, team in enumerate(teams):
        t = {k: tuple(v) if isinstance(v, list) else v for k, v in team.items()}
        try:
            config = scenario_config.replace(**t)
            if entities:
                check_team(config)
        except (TypeError, ValueError) as err:
            raise ConfigError(f"env.teams[{i}]: {err}") from None
        for label, cell in eval_cells(config, cells):
            out.append((team_label(team) + ("" if label == "all" else ";" + label), cell))
    return out


def planner_names(scenario_config: ScenarioConfig, names: list) -> list:
    """``names`` (planners), and where the beacons decide when to ping
    (``channel_mode="decide"``) each with every transmit schedule: ``ellipse+clock``, ..."""
    if scenario_config.channel_mode != "decide":
        return list(names)
    from baselines.schedule import list_schedules

    return [*names, *(f"{p}+{s}" for p in names for s in list_schedules())]


def prepare_job(config: Any) -> Job:
    """Check what a config names (scenario, timesteps, scenario parameters, reward
    terms, evaluation cells and baselines) before any work; a ``ConfigError`` else."""
    from baselines import list_policies
    from coopnav_env import list_scenarios, make_config
    from coopnav_env.vector import check_reward_terms

    if config.scenario not in list_scenarios():
        from coopnav_env.names import did_you_mean

        what = (
            "no scenario given;"
            if config.scenario is None
            else f"unknown scenario {config.scenario!r}{did_you_mean(config.scenario, list_scenarios())}"
        )
        raise ConfigError(f"{what} valid scenarios: {', '.join(list_scenarios())}")
    if config.timesteps is None or config.timesteps < 1:
        raise ConfigError(f"timesteps must be a positive number of environment steps, got {config.timesteps!r}")
    try:  # the benchmark's test seeds are never trained or validated on (coopnav_env.seeds.TEST_SEEDS)
        refuse_test_seeds(config.seed, 1, "seed")
        refuse_test_seeds(config.eval.seed, config.eval.episodes, "eval.seed")
    except ValueError as err:
        raise ConfigError(str(err)) from None
    try:
        scenario_config = make_config(config.scenario, **config.env.overrides)
    except (TypeError, ValueError) as err:
        raise ConfigError(f"env.overrides: {err}") from None
    except ArithmeticError as err:  # OverflowError, ZeroDivisionError: a value the scenario's checks let through
        raise ConfigError(f"env.overrides: a value is out of range ({type(err).__name__}: {err})") from None
    try:
        reward_terms = check_reward_terms(config.reward)
    except ValueError as err:
        raise ConfigError(f"reward: {err}") from None
    env = config.env
    teams = list(getattr(env, "teams", None) or [])
    try:
        if teams:  # a mixed-team run: every team is scored
            entities = getattr(env, "observation", "flat") == "entities"
            cells = team_cells(scenario_config, teams, config.eval.cells, entities)
        else:
            cells = eval_cells(scenario_config, config.eval.cells)
    except (TypeError, ValueError) as err:
        raise ConfigError(str(err)) from None
    if getattr(env, "observation", "flat") == "entities" and not teams:
        from coopnav_env.entity_obs import team_problem

        problem = team_problem(scenario_config)
        if problem is not None:
            raise ConfigError(f"env.observation: entities: {problem}")
    valid = planner_names(scenario_config, list_policies())
    for name in config.eval.baselines:
        if name not in valid:
            from coopnav_env.names import did_you_mean

            raise ConfigError(
                f"eval.baselines: unknown policy {name!r}{did_you_mean(name, valid)} valid: {', '.join(valid)}"
            )
    return Job(scenario_config, reward_terms, cells, teams)


# ----------------------------------------------------------------------------------
# the run directory
# ----------------------------------------------------------------------------------
def resume_command(out: str | Path) -> str:
    return f"python train.py --resume {out}"


def new_run_dir(out: str | Path) -> Path:
    """``out`` as the directory of a new run: absent or empty (a ``ConfigError`` else)."""
    from .runlock import check_not_in_use

    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ConfigError(f"--out {out} is a file")
    check_not_in_use(out)
    if out.exists() and any(out.iterdir()):
        if (out / "config.yml").is_file():
            raise ConfigError(f"{out} exists and is not empty; use --resume {out} to continue it, or another --out")
        raise ConfigError(
            f"{out} exists and is not empty, and is not a train.py run (no config.yml); use another --out"
        )
    return out


def read_run_record(out: str | Path) -> dict:
    """The ``config.yml`` of run directory ``out`` (a ``ConfigError`` if there is none)."""
    from coopnav_env.safe_load import UnsafeDataError

    out = Path(out)
    try:
        record = read_yaml(out / "config.yml") if out.is_dir() else None
    except UnsafeDataError as err:  # an alias bomb, a !!python tag, binary bytes, ...: one line
        raise ConfigError(f"{err} (not a usable train.py run record)") from None
    if not isinstance(record, dict) or not isinstance(record.get("args"), dict):
        raise ConfigError(f"{out} is not a train.py run directory (no config.yml)")
    return record


def run_config(out: str | Path, cls: type[_C]) -> _C:
    """The config (``cls``) of run directory ``out``, from its config.yml."""
    from .config import config_from_record

    try:
        return config_from_record(read_run_record(out), cls)
    except ConfigError as err:
        if "not a train.py run directory" in str(err):
            raise
        raise ConfigError(f"{Path(out) / 'config.yml'}: {err}") from None


def command_line(argv: list[str] | None = None) -> str:
    """``python train.py <argv>`` (``sys.argv[1:]`` by default), shell-quoted."""
    return "python train.py " + " ".join(shlex.quote(a) for a in (sys.argv[1:] if argv is None else argv))


def write_run_record(
    out: Path,
    config: Any,
    job: Job,
    *,
    command: str | None = None,
    hyperparameter_file: str | Path | None = None,
    args: dict | None = None,
    versions: dict | None = None,
    **extra: Any,
) -> dict:
    """Write ``out/config.yml`` (see the module docstring) atomically; returns it.
    ``args``: the record's args (default: scenario, timesteps, seed); ``versions``:
    more version entries (e.g. Ray's); ``extra``: more top-level entries."""
    record = {
        "command": command,
        "args": args
        if args is not None
        else {"scenario": config.scenario, "timesteps": config.timesteps, "seed": config.seed},
        "hyperparameter_file": None if hyperparameter_file is None else str(hyperparameter_file),
        "hyperparameters": config.hyperparameters(),
        **extra,
        "scenario_config": job.scenario_config.to_flat_dict(),
        "eval_cells": [label for label, _ in job.cells],
        "versions": {**version_record(), **(versions or {})},
    }
    import yaml

    atomic_write_text(out / "config.yml", yaml.safe_dump(plain(record), sort_keys=False))
    return record


def resume_seed(seed: int, steps: int) -> int:
    """The seed of a run resumed at ``steps``: deterministic, and (almost surely) not
    repeating the first run's episodes."""
    return int(np.random.SeedSequence([int(seed) % 2**32, steps]).generate_state(1)[0] >> 1)


# ----------------------------------------------------------------------------------
# SIGINT / SIGTERM
# ----------------------------------------------------------------------------------
class StopFlag:
    """Set by SIGINT or SIGTERM while ``stop_on_signals`` is active."""

    def __init__(self) -> None:
        self.requested = False

    def __bool__(self):
        return self.requested


@contextlib.contextmanager
def stop_on_signals() -> Iterator[StopFlag]:
    """While active, SIGINT and SIGTERM set the yielded ``StopFlag`` (the trainer
    checkpoints and returns ``EXIT_INTERRUPTED`` at its next boundary); a second
    signal acts as usual (KeyboardInterrupt, termination). Outside the main thread
    (where signals cannot be caught) the flag is never set."""
    flag = StopFlag()

    def request_stop(signum, frame):
        flag.requested = True
        signal.signal(signum, signal.default_int_handler if signum == signal.SIGINT else signal.SIG_DFL)

    if threading.current_thread() is not threading.main_thread():
        yield flag
        return
    old = {s: signal.signal(s, request_stop) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield flag
    finally:
        for s, h in old.items():
            signal.signal(s, h)
