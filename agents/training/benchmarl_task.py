"""coopnav as a BenchMARL task family: ``CoopNavTask``, one member per benchmark task set.

    from agents.training.benchmarl_task import CoopNavTask
    task = CoopNavTask.GAO_SEA.get_from_yaml()          # configs/benchmarl/task/coopnav/gao_sea.yaml
    task.config["task"] = "two_beacons"                 # another task of the set
    Experiment(task=task, algorithm_config=MappoConfig.get_from_yaml(), ...)

Needs the ``marl`` extra (torchrl, tensordict, BenchMARL 1.5.2). The environment is
``coopnav_env.torchrl_env.CoopNavTorchEnv``: batched (BenchMARL's ``n_envs_per_worker``
environments are the core's batch, not a ``SerialEnv`` of copies), the beacons one agent
group ``"beacons"``, the privileged ``"state"`` for centralized critics (MAPPO's, MASAC's).

**Task configs** (``configs/benchmarl/task/coopnav/<task set>.yaml``, BenchMARL's task
YAML, loaded by ``get_from_yaml`` and by Hydra): ``task_set`` and ``scenario`` name an
``evaluation.tasks`` task set, ``tasks`` are its tasks' scenario overrides, ``task`` the
one trained on; ``overrides`` more scenario parameters on top (randomization bounds,
say), ``reward_terms`` the training reward (``coopnav_env.vector``'s signals; null: the
environment's; by default :func:`default_reward_terms`, scaled for BenchMARL, which does
not normalize rewards), ``state`` "privileged" or "observations". The ``tasks`` mappings are
generated from the task-set definitions (``write_task_configs``), not written by hand;
``tests/test_benchmarl.py`` fails if they drift (this module sits below ``evaluation`` in
the layers, so it reads the generated files rather than importing the task sets).

**Seeds.** BenchMARL passes the experiment's seed to every environment it builds: the
training environment's row ``e`` plays episodes seeded ``seed + e + k * SEED_STRIDE``
(as the SB3 VecEnv). BenchMARL's own evaluation environment (``evaluation_episodes``
rows) is built with the same seed, so it replays rows ``0 ..`` of the first episodes;
it is a learning curve, not a benchmark score (``evaluate.py`` and the benchmark use
their own seeds). Seeds at or above ``coopnav_env.seeds.TRAINING_SEED_LIMIT`` are refused.

**Hydra.** ``register()`` puts the members in BenchMARL's ``task_config_registry`` as
``coopnav/<task set>``; the Hydra search-path plugin ``hydra_plugins/coopnav_benchmarl``
calls it and adds ``configs/benchmarl`` to Hydra's search path, so that
``python -m benchmarl.run algorithm=mappo task=coopnav/gao_sea`` works (docs/training/marl.md).
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

from benchmarl.environments.common import Task, TaskClass
from torchrl.data import Composite

from .config import PROJECT_ROOT

if TYPE_CHECKING:
    from torchrl.envs import EnvBase

    from coopnav_env.scenarios import ScenarioConfig

__all__ = [
    "CONFIG_DIR",
    "ENV_NAME",
    "CoopNavClass",
    "CoopNavTask",
    "REWARD_SCALE",
    "default_reward_terms",
    "get_task",
    "members",
    "register",
    "scenario_config",
    "task_yaml",
    "write_task_configs",
]

ENV_NAME = "coopnav"  # BenchMARL's environment name: tasks are "coopnav/<task set>"
CONFIG_DIR = PROJECT_ROOT / "configs" / "benchmarl"  # Hydra's config root: task/, experiment/
TASK_KEYS = ("task_set", "scenario", "task", "tasks", "overrides", "reward_terms", "state")

# BenchMARL does not normalize rewards (SB3's VecNormalize and the batched loop do), and
# coopnav's are metres per step: returns run to hundreds or thousands. Measured on seeds
# 700000-700029 (docs/training/marl.md#levers-cells), 2 M env-steps of MAPPO: on gao_sea
# the environment's reward left it 57 % above the best planner, SB3's terms at weight 1
# 200 %, the same terms times 0.01 3.3 %; on gao_lawnmower 8.4 % against 1.1 %; on the
# moving network the environment's reward diverged to NaN where log_error times 0.01 did not;
# on sousa_grid, whose errors are near 1 m, weights 1, 0.05 and 0.01 gave the same within noise
# (docs/training/marl.md#levers-scaled).
REWARD_SCALE = 0.01


def default_reward_terms(scenario: str) -> dict[str, float]:
    """The task configs' training reward for BenchMARL: the signals the shipped policies
    train on (``std`` and ``penalties``, as the SB3 configs; on a moving network
    (``network="moving_lbl"``) ``log_error`` and ``penalties``, as its batched-loop runs,
    since the error can run away with a lost vehicle) times :data:`REWARD_SCALE`."""
    from coopnav_env.scenarios import make_config

    error = "log_error" if make_config(scenario).network == "moving_lbl" else "std"
    return {error: REWARD_SCALE, "penalties": REWARD_SCALE}


def _check_task_config(name: str, config: dict) -> dict:
    """The task config with its keys checked (one-line ValueError naming the closest)."""
    unknown = [k for k in config if k not in TASK_KEYS]
    if unknown:
        from coopnav_env.names import did_you_mean

        raise ValueError(
            f"coopnav/{name}: unknown task config key {unknown[0]!r}{did_you_mean(unknown[0], TASK_KEYS)} "
            f"valid: {', '.join(TASK_KEYS)}"
        )
    for key in ("scenario", "tasks", "task"):
        if config.get(key) is None:
            raise ValueError(f"coopnav/{name}: the task config needs {key!r} (configs/benchmarl/task/coopnav/)")
    tasks = config["tasks"]
    if config["task"] not in tasks:
        from coopnav_env.names import did_you_mean

        raise ValueError(
            f"coopnav/{name}: unknown task {config['task']!r} of task set "
            f"{config.get('task_set', name)!r}{did_you_mean(str(config['task']), tasks)} valid: {', '.join(tasks)}"
        )
    from coopnav_env.core.reward import check_training_terms

    try:
        check_training_terms(config.get("reward_terms"))
    except ValueError as err:
        raise ValueError(f"coopnav/{name}: {err}") from None
    return config


def _tuples(value: Any) -> Any:
    """YAML lists back to the tuples the scenario parameters are (``beacon_kinds``, bounds)."""
    if isinstance(value, (list, tuple)):
        return tuple(_tuples(v) for v in value)
    return value


def scenario_config(config: dict, name: str = "?") -> ScenarioConfig:
    """The ``ScenarioConfig`` of a coopnav task config: the scenario with the chosen
    task's overrides, then ``overrides`` on top."""
    from coopnav_env import make_config

    config = _check_task_config(name, config)
    task_overrides = dict(config["tasks"][config["task"]] or {})
    extra = dict(config.get("overrides") or {})
    merged = {k: _tuples(v) for k, v in {**task_overrides, **extra}.items()}
    return make_config(config["scenario"], **merged)


class CoopNavClass(TaskClass):
    """A coopnav task set for BenchMARL (``TaskClass``): builds ``CoopNavTorchEnv``."""

    def get_env_fun(
        self, num_envs: int, continuous_actions: bool, seed: int | None, device: Any
    ) -> Callable[[], EnvBase]:
        from coopnav_env.seeds import refuse_test_seeds
        from coopnav_env.torchrl_env import CoopNavTorchEnv

        config = copy.deepcopy(self.config)
        scenario = scenario_config(config, self.name.lower())
        base_seed = 0 if seed is None else int(seed)
        refuse_test_seeds(base_seed, int(num_envs), what="BenchMARL seed")
        reward_terms = config.get("reward_terms") or None
        state = config.get("state") or "privileged"
        return lambda: CoopNavTorchEnv(
            scenario, n_envs=num_envs, seed=base_seed, device=device, reward_terms=reward_terms, state=state
        )

    def supports_continuous_actions(self) -> bool:
        return True

    def supports_discrete_actions(self) -> bool:
        return False

    def has_render(self, env: EnvBase) -> bool:
        return False

    def max_steps(self, env: EnvBase) -> int:
        return int(env.config.max_cycles)

    def group_map(self, env: EnvBase) -> dict[str, list[str]]:
        return dict(env.group_map)

    def observation_spec(self, env: EnvBase) -> Composite:
        """The groups' observations (without the infos and the state)."""
        spec = env.full_observation_spec_unbatched.clone()
        for key in ("state", "info"):
            if key in spec.keys():  # noqa: SIM118 - a Composite spec: membership through its keys
                del spec[key]
        for group in self.group_map(env):
            if "info" in spec[group].keys():  # noqa: SIM118 - as above
                del spec[(group, "info")]
        return spec

    def info_spec(self, env: EnvBase) -> Composite | None:
        spec = env.full_observation_spec_unbatched
        infos = {group: Composite({"info": spec[group, "info"].clone()}) for group in self.group_map(env)}
        if not all("info" in spec[g].keys() for g in infos):  # noqa: SIM118 - as above
            return None
        return Composite(infos)

    def state_spec(self, env: EnvBase) -> Composite | None:
        return Composite({"state": env.full_observation_spec_unbatched["state"].clone()})

    def action_spec(self, env: EnvBase) -> Composite:
        return env.full_action_spec_unbatched

    def action_mask_spec(self, env: EnvBase) -> Composite | None:
        return None

    @staticmethod
    def env_name() -> str:
        return ENV_NAME

    @staticmethod
    def log_info(batch: Any) -> dict[str, float]:
        """The mean true survey error over the episodes' last steps in the batch (the
        benchmark's score is the mean over the episode; this is its end point, for the
        learning curve); BenchMARL logs the mean of every ``"info"`` entry besides."""
        done = batch.get(("next", "done")).squeeze(-1)
        if not done.any():
            return {}
        err = batch.get(("next", "info", "survey_error_m"))[done]
        return {"collection/info/final_survey_error_m": float(err.float().mean())}


class CoopNavTask(Task):
    """The benchmark's task sets (``evaluation.tasks``) as BenchMARL tasks ``coopnav/<name>``.
    Each member's config (``get_from_yaml``) holds its tasks; ``config["task"]`` picks one."""

    SOUSA_GRID = None
    GAO_LAWNMOWER = None
    GAO_SEA = None
    GAO_TEAM = None
    SWARM_MLS = None
    SOUSA_PING = None
    MATOS_MOVING_LBL = None
    MATOS_RIVER = None
    SHIFTS_SOUSA_ASV = None  # issue 23's shifts, one set per scenario (evaluation.tasks._SHIFTS)
    SHIFTS_GAO_LAWNMOWER = None
    SHIFTS_GAO_SEA = None
    SHIFTS_GAO_TEAM = None
    SHIFTS_SWARM_MLS = None
    SHIFTS_SOUSA_PING = None
    SHIFTS_MATOS_MOVING_LBL = None
    SHIFTS_MATOS_RIVER = None

    @staticmethod
    def associated_class() -> type[TaskClass]:
        return CoopNavClass

    def get_from_yaml(self, path: str | None = None) -> TaskClass:
        """The task with its config from ``path`` (default: ``configs/benchmarl/task/coopnav/<name>.yaml``)."""
        from benchmarl.utils import _read_yaml_config

        path = path or str(CONFIG_DIR / "task" / ENV_NAME / f"{self.name.lower()}.yaml")
        if not Path(path).is_file():
            raise FileNotFoundError(f"no coopnav task config {path} (write_task_configs writes them)")
        config = _check_task_config(self.name.lower(), _read_yaml_config(path))
        return self.get_task(config=config)


def members() -> list:
    """``CoopNavTask``'s members in order (BenchMARL's ``Task`` is untyped: mypy does not
    see the Enum behind it)."""
    return list(cast(Any, CoopNavTask))


def register() -> None:
    """Add ``coopnav/<task set>`` to BenchMARL's ``task_config_registry`` (for
    ``benchmarl.run`` and ``load_experiment_from_hydra``; idempotent)."""
    from benchmarl.environments import task_config_registry

    for member in members():
        task_config_registry[f"{ENV_NAME}/{member.name.lower()}"] = member


def get_task(name: str, task: str | None = None, **changes: Any) -> TaskClass:
    """The BenchMARL task of task set ``name`` from its YAML; ``task`` picks a task of the
    set, ``changes`` replace other config keys (``overrides``, ``reward_terms``, ``state``)."""
    try:
        member = cast(Any, CoopNavTask)[name.upper()]
    except KeyError:
        from coopnav_env.names import did_you_mean

        names = [m.name.lower() for m in members()]
        raise ValueError(
            f"unknown coopnav task {name!r}{did_you_mean(name, names)} valid: {', '.join(names)}"
        ) from None
    out = member.get_from_yaml()
    if task is not None:
        out.config["task"] = task
    out.config.update(changes)
    _check_task_config(name, out.config)
    return out


# ---------------------------------------------------------------------------------------
# the task configs, generated from the task sets (evaluation.tasks passes them in)


def _plain(value: Any) -> Any:
    if isinstance(value, (tuple, list)):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    return value


def task_yaml(task_set: Any) -> str:
    """The BenchMARL task YAML of one ``evaluation.tasks.TaskSet`` (any object with
    ``name``, ``scenario``, ``about`` and ``tasks`` of ``name``/``overrides``)."""
    import yaml

    tasks = {t.name: _plain(dict(t.overrides)) for t in task_set.tasks}
    head = (
        f"# coopnav/{task_set.name} for BenchMARL: {task_set.about}\n"
        "# Generated from evaluation/tasks.py by agents.training.benchmarl_task.write_task_configs;\n"
        "# tests/test_benchmarl.py checks that they agree: change the task set there, not the tasks here.\n"
    )
    body = yaml.safe_dump(
        {"task_set": task_set.name, "scenario": task_set.scenario}, sort_keys=False, default_flow_style=False
    )
    body += f"task: {yaml.safe_dump(task_set.tasks[0].name).splitlines()[0]}  # the task trained on (one of tasks)\n"
    body += "tasks:  # name -> scenario overrides, the benchmark's\n"
    for name, overrides in tasks.items():
        flow = yaml.safe_dump(overrides, default_flow_style=True, width=1000).strip()
        body += f"  {yaml.safe_dump(name).splitlines()[0]}: {flow}\n"
    terms = yaml.safe_dump(default_reward_terms(task_set.scenario), default_flow_style=True, sort_keys=False).strip()
    body += (
        "overrides: {}  # more scenario parameters on top of the task's (randomization bounds, ...)\n"
        f"reward_terms: {terms}  # training reward {{signal: weight}} (coopnav_env.vector.REWARD_TERMS), scaled:\n"
        "  # BenchMARL does not normalize rewards (benchmarl_task.REWARD_SCALE); null: the env's, unscaled\n"
        "state: privileged  # the critics' state: privileged (core's global state + observations) or observations\n"
    )
    return head + body


def write_task_configs(task_sets: Iterable[Any], directory: str | Path | None = None) -> list[Path]:
    """Write ``task_yaml`` of every task set to ``directory`` (default
    ``configs/benchmarl/task/coopnav``), atomically; returns the paths. Run as

        python -c "from evaluation.tasks import TASK_SETS; \\
            from agents.training.benchmarl_task import write_task_configs as w; w(TASK_SETS.values())"
    """
    from coopnav_env.records import atomic_write_text

    directory = Path(directory) if directory is not None else CONFIG_DIR / "task" / ENV_NAME
    directory.mkdir(parents=True, exist_ok=True)
    paths = []
    for task_set in task_sets:
        path = directory / f"{task_set.name}.yaml"
        atomic_write_text(path, task_yaml(task_set))
        paths.append(path)
    return paths
