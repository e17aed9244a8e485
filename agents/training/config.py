"""Typed training configs: one dataclass per job, one set of defaults.

    from agents.training.config import TrainConfig, load_config
    config = load_config("configs/ppo/sousa_asv.yml", TrainConfig, scenario="sousa_asv", timesteps=2_000_000)
    config = TrainConfig(scenario="gao_lawnmower", timesteps=4096, n_envs=4, ppo={"n_steps": 128})

``TrainConfig`` is a stable-baselines3 PPO job (configs/ppo/*.yml), ``RLlibConfig`` a
Ray RLlib one (configs/rllib/*.yml). A YAML file holds the sections of one of them
(``scenario``, ``timesteps`` and ``seed`` usually come from the command line); what
it leaves out takes the defaults below. An unknown key at any level is a
``ConfigError`` (a ``ValueError``) naming the closest valid one:
``unknown eval key 'episdoes'; did you mean 'episodes'? valid: ...``.

The free-form sections are dicts checked against what reads them: ``ppo`` of a
``TrainConfig`` holds ``stable_baselines3.PPO`` keyword arguments (checked against
``PPO.__init__``'s signature), ``reward`` the training-reward terms of
``coopnav_env.vector``, ``env.overrides`` scenario parameters; the RLlib sections
(``ppo``, ``model``, ``env_runners``, ``learners``) are checked by RLlib when the
``PPOConfig`` is built (``agents.training.rllib.build_config``).

A file may start from another with ``extends: other.yml`` and set only what differs
(``read_mapping``; the experiments that continue a run do).

A run directory's ``config.yml`` holds its config as ``args`` (scenario, timesteps,
seed) and ``hyperparameters`` (the rest): ``config_from_record`` reads it back.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from coopnav_env.names import did_you_mean
from coopnav_env.seeds import VALIDATION_SEED

if TYPE_CHECKING:
    from typing_extensions import Self

_T = TypeVar("_T")

PROJECT_ROOT = Path(__file__).resolve().parents[2]
CONFIG_DIRS = {"sb3": PROJECT_ROOT / "configs" / "ppo", "rllib": PROJECT_ROOT / "configs" / "rllib"}
ACTIVATIONS = ("tanh", "relu", "elu", "leaky_relu")  # policy_kwargs.activation_fn (torch.nn's Tanh, ReLU, ...)
JOB_KEYS = ("scenario", "timesteps", "seed")  # a run record's ``args``; the rest is ``hyperparameters``
# keyword arguments of PPO.__init__ that the trainer sets itself
SB3_RESERVED = {"self", "policy", "env", "seed", "device", "tensorboard_log", "verbose", "_init_setup_model"}
LEGACY = {
    "env.variants": "env.variants is gone: set the core's per-episode randomization in env.overrides "
    "(randomize_survey_path, randomize_depth_m, randomize_noise_scale)"
}

__all__ = [
    "ConfigError",
    "EntitySpec",
    "EnvSpec",
    "EvalSpec",
    "ImitateSpec",
    "PeriodicEvalSpec",
    "NormalizeSpec",
    "RaySpec",
    "TrainConfig",
    "RLlibConfig",
    "config_class",
    "config_from_record",
    "from_dict",
    "hyperparameter_file",
    "load_config",
    "merge_configs",
    "parse_value",
    "set_path",
]


class ConfigError(ValueError):
    """Bad input: a config, a file or an option that cannot be used (one line)."""


def parse_assignments(items: Sequence[str], what: str) -> dict:
    """``KEY=VALUE`` command-line items as a dict, each VALUE read as YAML (``--set`` and the
    like of ``agents.training.marl`` and ``agents.training.batched_ppo``); one-line
    ``ConfigError`` naming ``what`` for an item without ``=``. ``1e-4`` is a number here,
    as a user means it (YAML 1.1 reads an exponent without a dot as a string)."""
    import re

    import yaml

    from coopnav_env.names import unique_assignments

    pairs = []
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise ConfigError(f"{what} takes KEY=VALUE, got {item!r}")
        parsed = yaml.safe_load(value)
        if isinstance(parsed, str) and re.fullmatch(r"[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+", parsed.strip()):
            parsed = float(parsed)
        pairs.append((key.strip(), parsed))
    try:  # a key twice with two values: which was meant?
        return unique_assignments(pairs, what)
    except ValueError as err:
        raise ConfigError(str(err)) from None


def like_default(value: Any, default: Any) -> bool:
    """Whether ``value`` may replace a setting whose default is ``default``: true or false
    for a bool, a number (not a bool) for a number, anything otherwise (the settings of
    another library's dataclasses, e.g. BenchMARL's, checked before they reach it)."""
    if isinstance(default, bool):
        return isinstance(value, bool)
    if isinstance(default, (int, float)):
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    return True


# ----------------------------------------------------------------------------------
# the sections
# ----------------------------------------------------------------------------------
OBSERVATIONS = ("flat", "entities")  # env.observation


@dataclass
class EnvSpec:
    """The training scenario: its parameters (``make_config(scenario, **overrides)``),
    the core's per-episode randomization included (``randomize_depth_m: [..]``, ...).
    ``observation``: ``flat`` (the vector of ``coopnav_env.obs_layout``) or ``entities``
    (``coopnav_env.entity_obs``: any team, read by ``agents.entity``'s encoder; the SB3
    trainer only). ``teams``: scenario overrides per team trained at once, the ``n_envs``
    environments dealt to them in turn (``coopnav_env.entity_views.MixedTeamVecEnv``; {}:
    the scenario's own team): with ``entities`` the makeup too (``n_survey`` 1-5,
    ``beacon_kinds`` of 1-3 beacons), with ``flat`` settings one simulator holds for all
    its rows (``ping_interval_s``, ``packet_loss_near``, ...); the evaluation then scores
    every team; [] trains the scenario's team only."""

    overrides: dict = field(default_factory=dict)
    observation: str = "flat"
    teams: list = field(default_factory=list)


@dataclass
class EntitySpec:
    """The entity encoder (``agents.entity.EntityEncoder``) of an ``env.observation:
    entities`` run: ``encoder`` deepsets or attention, ``embed_dim`` units per entity,
    ``heads`` attention heads (``embed_dim`` a multiple of it). PPO's ``net_arch``
    then acts on its features."""

    encoder: str = "attention"
    embed_dim: int = 64
    heads: int = 4


@dataclass
class EvalSpec:
    """Evaluation of the deterministic policy on fixed seeds: ``episodes`` per cell
    (episode ``i`` of every cell seeded ``seed + i``; 0: none), every combination of
    ``cells`` (``{parameter: [values]}``, randomization off) or the training scenario,
    and the ``baselines`` scored once on the same seeds."""

    episodes: int = 16
    seed: int = VALIDATION_SEED
    cells: dict = field(default_factory=dict)
    baselines: list = field(default_factory=list)


@dataclass
class PeriodicEvalSpec(EvalSpec):
    """``EvalSpec`` every ``every_steps`` environment steps (0: never; the best model is
    kept) and at the end (the SB3 trainer)."""

    episodes: int = 32
    every_steps: int = 100_000


@dataclass
class NormalizeSpec:
    """``stable_baselines3`` VecNormalize: saved beside the model (vecnormalize.pkl)."""

    norm_obs: bool = True
    norm_reward: bool = True
    clip_obs: float = 10.0
    clip_reward: float = 10.0
    epsilon: float = 1e-8


@dataclass
class ImitateSpec:
    """Behaviour cloning of a planner before PPO (``agents.training.imitation``):
    ``planner`` (a planner that drives the scenario's network; None: off) drives the
    training environments for ``steps`` row-steps, then the actor's mean is fitted to
    its actions and the critic to the returns, ``epochs`` passes in minibatches of
    ``batch_size`` at ``learning_rate``. ``planner_kwargs`` go to the planner (and its
    transmit schedule): ``{threshold_nats: 0.45}`` for ``ellipse+event``.
    ``dagger_rounds``: after the first fit, that many rounds of DAgger (Ross, Gordon &
    Bagnell 2011): the clone drives for ``dagger_steps`` row-steps (0: ``steps``), the
    planner labels the states the clone reaches, and the clone is fitted again on all the
    data so far."""

    planner: str | None = None
    planner_kwargs: dict = field(default_factory=dict)
    steps: int = 200_000
    epochs: int = 20
    batch_size: int = 4096
    learning_rate: float = 1e-3
    dagger_rounds: int = 0
    dagger_steps: int = 0


@dataclass
class RaySpec:
    """The local Ray instance an RLlib run starts (ignored with ``--ray-address``)."""

    num_cpus: int | None = None  # None: the machine's cores (more if the env runners need more)
    object_store_memory_mb: float = 200.0
    max_concurrent_trials: int | None = None  # a Tune grid's


@dataclass
class _Job:
    """What every training job has: the scenario, the total environment steps, the
    seed, the scenario's training parameters and the training reward
    (``{term: weight}``, see ``coopnav_env.vector``; {}: the environment's reward)."""

    scenario: str | None = None
    timesteps: int | None = None
    seed: int = 0
    env: EnvSpec = field(default_factory=EnvSpec)
    reward: dict = field(default_factory=dict)

    def replace(self, **changes):
        """A copy with ``changes`` (``dataclasses.replace``)."""
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict:
        """Plain dicts and lists, as the YAML holds them."""
        return dataclasses.asdict(self)

    def hyperparameters(self) -> dict:
        """``to_dict`` without the job's scenario, timesteps and seed (a run record's
        ``hyperparameters``; those three are its ``args``)."""
        d = {k: v for k, v in self.to_dict().items() if k not in JOB_KEYS}
        keys = [k for k in d if k not in ("env", "reward")]
        at = keys.index("eval") if "eval" in keys else len(keys)
        return {k: d[k] for k in keys[:at] + ["env", "reward"] + keys[at:]}  # the YAML files' order

    def check(self) -> Self:
        """Refuse what the fields' types cannot (a ``ConfigError``); returns self."""
        from .bounds import BoundsError, check_bounds

        try:
            check_bounds(self)  # finite numbers, sizes that fit a machine
        except BoundsError as err:
            raise ConfigError(str(err)) from None
        return self


@dataclass
class TrainConfig(_Job):
    """A stable-baselines3 PPO job (``agents.training.sb3.train``). ``ppo``: PPO
    keyword arguments (``learning_rate`` may be ``"lin_<x>"``: linear decay from x to
    0; ``policy_kwargs.activation_fn`` a name: tanh, relu, elu, leaky_relu); {} leaves
    SB3's defaults. ``init_from``: start from another policy's weights and
    normalization (a run directory, a shipped policy name, a model .zip).
    ``action_log_std``: the log standard deviation of each action component when PPO
    starts (after ``init_from`` and ``imitate``; not on a resume), e.g. ``[-2, -2, 0]`` to
    keep a clone's motion and explore its transmit decision (None: as trained, or
    ``log_std_init``)."""

    policy: str = "MlpPolicy"
    n_envs: int = 16
    ppo: dict = field(default_factory=dict)
    normalize: NormalizeSpec = field(default_factory=NormalizeSpec)
    eval: PeriodicEvalSpec = field(default_factory=PeriodicEvalSpec)
    checkpoint_every_steps: int = 100_000
    init_from: str | None = None
    imitate: ImitateSpec = field(default_factory=ImitateSpec)
    entity: EntitySpec = field(default_factory=EntitySpec)
    action_log_std: list | None = None

    def check(self) -> Self:
        import inspect

        from stable_baselines3 import PPO

        valid = sorted(set(inspect.signature(PPO.__init__).parameters) - SB3_RESERVED)
        for key in self.ppo:
            if key not in valid:
                raise ConfigError(unknown_key_message(key, valid, "ppo key"))
        super().check()  # bounds (agents.training.bounds)
        lr = self.ppo.get("learning_rate", 3e-4)
        if isinstance(lr, str) and lr.startswith("lin_"):
            lr = lr[4:]
        try:
            float(lr)
        except (TypeError, ValueError):
            raise ConfigError(f"ppo.learning_rate must be a number or 'lin_<number>', got {lr!r}") from None
        kwargs = self.ppo.get("policy_kwargs") or {}
        if not isinstance(kwargs, dict):
            raise ConfigError(f"ppo.policy_kwargs must be a mapping, got {kwargs!r}")
        if "activation_fn" in kwargs and kwargs["activation_fn"] not in ACTIVATIONS:
            raise ConfigError(f"unknown activation_fn {kwargs['activation_fn']!r}; valid: {', '.join(ACTIVATIONS)}")
        std = self.action_log_std
        if std is not None and (
            not isinstance(std, list)
            or not std
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and -10 <= v <= 2 for v in std)
        ):
            raise ConfigError(
                f"action_log_std must be a list of numbers in [-10, 2], one per action component, got {std!r}"
            )
        im = self.imitate
        if im.planner is not None:
            for key in ("steps", "epochs", "batch_size"):
                if getattr(im, key) < 1:
                    raise ConfigError(f"imitate.{key} must be at least 1, got {getattr(im, key)}")
            if not im.learning_rate > 0:
                raise ConfigError(f"imitate.learning_rate must be positive, got {im.learning_rate}")
            for key in ("dagger_rounds", "dagger_steps"):
                value = getattr(im, key)
                if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                    raise ConfigError(f"imitate.{key} must be an integer of at least 0, got {value!r}")
            if self.init_from:
                raise ConfigError("imitate and init_from both set the starting weights: choose one")
        elif im.planner_kwargs:
            raise ConfigError("imitate.planner_kwargs needs imitate.planner (the planner they are for)")
        check_env_observation(self.env)
        if self.env.observation == "entities":
            if self.normalize.norm_obs:
                raise ConfigError(
                    "env.observation: entities needs normalize.norm_obs: false (the entity view is already "
                    "scaled, and normalizing would move its masks and one-hot kinds)"
                )
            if "features_extractor_class" in kwargs or "features_extractor_kwargs" in kwargs:
                raise ConfigError(
                    "ppo.policy_kwargs.features_extractor_class/kwargs: with env.observation: entities the "
                    "trainer sets them from the entity section (encoder, embed_dim, heads)"
                )
            from agents.entity import check_encoder_kwargs

            try:
                check_encoder_kwargs(self.entity.encoder, self.entity.embed_dim, self.entity.heads)
            except ValueError as err:
                raise ConfigError(f"entity: {err}") from None
            if len(self.env.teams) > self.n_envs:
                raise ConfigError(
                    f"n_envs ({self.n_envs}) must be at least the number of env.teams ({len(self.env.teams)})"
                )
        return self


@dataclass
class RLlibConfig(_Job):
    """A Ray RLlib PPO job (``agents.training.rllib.train``): ``ppo`` holds
    ``PPOConfig.training`` keywords, ``model`` DefaultModelConfig keys, ``env_runners``
    and ``learners`` the keywords of ``PPOConfig.env_runners`` and ``.learners``;
    ``normalize_obs``: RLlib's MeanStdFilter per agent (saved in the checkpoint)."""

    ppo: dict = field(default_factory=dict)
    model: dict = field(default_factory=dict)
    normalize_obs: bool = False
    env_runners: dict = field(default_factory=dict)
    learners: dict = field(default_factory=dict)
    eval: EvalSpec = field(default_factory=EvalSpec)
    checkpoint_every_iterations: int = 10
    ray: RaySpec = field(default_factory=RaySpec)

    def check(self) -> Self:
        check_env_observation(self.env)
        if self.env.observation != "flat":
            raise ConfigError(
                f"env.observation: {self.env.observation} is for the SB3 trainer (--backend sb3); RLlib runs "
                "read the flat observation"
            )
        return super().check()


def check_env_observation(env: EnvSpec) -> None:
    """``env.observation`` and ``env.teams`` (a ``ConfigError`` naming the value; the
    values themselves are the scenario's to check, when the job is prepared)."""
    if env.observation not in OBSERVATIONS:
        raise ConfigError(unknown_key_message(env.observation, OBSERVATIONS, "env.observation"))
    from coopnav_env.entity_obs import MAX_BEACONS, MAX_SURVEY, MAX_TEAMS, TEAM_KEYS

    if len(env.teams) > MAX_TEAMS:
        raise ConfigError(f"env.teams: at most {MAX_TEAMS} teams, got {len(env.teams)}")
    from coopnav_env.scenarios.config import flat_name, parameter_names

    params = [p for p in parameter_names() if p not in ("name", "network")]
    for i, team in enumerate(env.teams):
        where = f"env.teams[{i}]"
        if team is None:
            team = env.teams[i] = {}
        if not isinstance(team, dict):
            raise ConfigError(f"{where} must be a mapping of scenario parameters ({{}}: the scenario's team)")
        for key in team:
            try:
                name = flat_name(str(key))  # "channel.packet_loss_far" or "packet_loss_far"
            except ValueError as err:
                raise ConfigError(f"{where}: {err}") from None
            if name not in params:
                raise ConfigError(unknown_key_message(key, params, f"{where} key"))
            if name in TEAM_KEYS and env.observation != "entities":
                raise ConfigError(
                    f"{where}.{key}: a flat-observation policy takes one team makeup; "
                    "vary n_survey or beacon_kinds with env.observation: entities"
                )
        n = team.get("n_survey", 1)
        if isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= MAX_SURVEY:
            raise ConfigError(f"{where}.n_survey must be an integer in [1, {MAX_SURVEY}], got {n!r}")
        kinds = team.get("beacon_kinds", ["beacon_auv"])
        if not isinstance(kinds, (list, tuple)) or not 1 <= len(kinds) <= MAX_BEACONS:
            raise ConfigError(f"{where}.beacon_kinds must be a list of 1-{MAX_BEACONS} beacon kinds, got {kinds!r}")
        ping = team.get("ping_interval_s", 1.0)
        if isinstance(ping, bool) or not isinstance(ping, (int, float)) or not 0 < ping <= 3600:
            raise ConfigError(f"{where}.ping_interval_s must be a number of seconds in (0, 3600], got {ping!r}")
    if len({repr(sorted(t.items())) for t in env.teams}) != len(env.teams):
        raise ConfigError("env.teams lists a team twice")


CONFIG_CLASSES = {"sb3": TrainConfig, "rllib": RLlibConfig}


def config_class(backend: str) -> type:
    """The config class of a backend ("sb3" or "rllib")."""
    try:
        return CONFIG_CLASSES[backend]
    except KeyError:
        raise ConfigError(unknown_key_message(backend, list(CONFIG_CLASSES), "backend")) from None


# ----------------------------------------------------------------------------------
# dict -> dataclass, strictly
# ----------------------------------------------------------------------------------
def unknown_key_message(key: str, valid: Iterable[str], what: str) -> str:
    """``unknown <what> 'foo'; did you mean 'bar'? valid: a, bar, c`` (the house style
    of ``coopnav_env.scenarios.base.check_overrides``)."""
    valid = sorted(valid)
    return f"unknown {what} {key!r}{did_you_mean(key, valid)} valid: {', '.join(valid)}"


_KIND = {
    int: "an integer",
    float: "a number",
    bool: "true or false",
    str: "a string",
    dict: "a mapping",
    list: "a list",
}


def _coerce(value, hint, where: str):
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        options = [a for a in typing.get_args(hint) if a is not type(None)]
        if value is None:
            return None
        hint = options[0]
        origin = typing.get_origin(hint)
    if dataclasses.is_dataclass(hint):
        return from_dict(typing.cast(type, hint), {} if value is None else value, where)
    base = origin or hint
    if base in (dict, list) and value is None:
        return base()
    ok = {
        int: (isinstance(value, int) and not isinstance(value, bool))
        or (isinstance(value, float) and value.is_integer()),
        float: isinstance(value, (int, float)) and not isinstance(value, bool),
        bool: isinstance(value, bool),
        str: isinstance(value, str),
        dict: isinstance(value, dict),
        list: isinstance(value, (list, tuple)),
    }[base]
    if not ok:
        raise ConfigError(f"{where} must be {_KIND[base]}, got {value!r}")
    try:
        return {int: int, float: float, list: list, dict: dict}.get(base, lambda v: v)(value)
    except OverflowError:  # an integer too large for a float
        raise ConfigError(f"{where} is out of range: {value!r:.40}") from None


def from_dict(cls: type[_T], data: Any, where: str = "") -> _T:
    """``cls`` (a config dataclass) from a mapping, recursively; unknown keys, legacy
    keys and values of the wrong type are a ``ConfigError`` naming where they are."""
    if not isinstance(data, dict):
        raise ConfigError(f"{where or 'the config'} must be a mapping, got {data!r}")
    hints = typing.get_type_hints(cls)
    names = [f.name for f in dataclasses.fields(typing.cast(Any, cls)) if f.init]
    kwargs = {}
    for key, value in data.items():
        path = f"{where}.{key}" if where else str(key)
        if path in LEGACY:
            raise ConfigError(LEGACY[path])
        if key not in names:
            raise ConfigError(unknown_key_message(key, names, f"{where} key" if where else "section"))
        kwargs[key] = _coerce(value, hints[key], path)
    return cls(**kwargs)


# ----------------------------------------------------------------------------------
# files and overrides
# ----------------------------------------------------------------------------------
def parse_value(text: str) -> Any:
    """A command-line value: '3e-4' -> 0.0003, '2' -> 2, '[64, 64]' -> [64, 64],
    'true' -> True, 'null' -> None, 'tanh' -> 'tanh'."""
    from coopnav_env.safe_load import UnsafeDataError, parse_value_text

    try:
        return parse_value_text(text)
    except UnsafeDataError as err:
        raise ConfigError(str(err)) from None


def set_path(data: dict, dotted: str, value: Any) -> dict:
    """``data`` with ``data[a][b] = value`` for ``dotted`` "a.b" (sections created as
    needed; a non-mapping on the way is a ``ConfigError``)."""
    keys = dotted.split(".")
    if not all(keys):
        raise ConfigError(f"bad key {dotted!r}: expected SECTION.KEY, e.g. eval.episodes")
    node = data
    for i, key in enumerate(keys[:-1]):
        child = node.get(key)
        if child is None:
            child = node[key] = {}
        if not isinstance(child, dict):
            raise ConfigError(f"{'.'.join(keys[: i + 1])} is not a section (it is {child!r})")
        node = child
    node[keys[-1]] = value
    return data


def hyperparameter_file(backend: str, scenario: str | None, explicit: str | Path | None = None) -> Path | None:
    """The ``explicit`` file (it must exist), else ``configs/<ppo|rllib>/<scenario>.yml``,
    else that directory's ``default.yml``, else None (the dataclass defaults)."""
    if explicit:
        path = Path(explicit)
        if not path.is_file():
            raise ConfigError(f"no such hyperparameter file: {explicit}")
        return path
    directory = CONFIG_DIRS[backend]
    for name in (f"{scenario}.yml", "default.yml"):
        if (directory / name).is_file():
            return directory / name
    return None


MAX_EXTENDS = 8  # the longest chain of ``extends:`` a config file may start


def read_mapping(path: str | Path, _chain: tuple[Path, ...] = ()) -> dict:
    """A YAML file's mapping ({} if empty); anything else is a ``ConfigError``.

    A file may start from another: ``extends: base.yml`` (a path relative to the file's
    own folder) reads that file first (itself possibly extending another), then merges
    this one on top (``merge_configs``): sections merge key by key, any other value
    replaces the base's, and a key set to null (``~``) is removed so that its default
    applies (``imitate: ~`` in a file that continues a cloned run with ``init_from``).
    A cycle, or a chain longer than ``MAX_EXTENDS``, is a ``ConfigError``."""
    from coopnav_env.safe_load import UnsafeDataError, read_yaml

    try:
        data = read_yaml(path)  # bounded: no aliases, size and depth limits
    except UnsafeDataError as err:
        raise ConfigError(str(err)) from None
    if data is None and not Path(path).is_file():
        raise ConfigError(f"no such file: {path}")
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a mapping of hyperparameters")
    if "extends" not in data:
        return data
    base = data.pop("extends")
    if not isinstance(base, str) or not base:
        raise ConfigError(f"{path}: extends must be the path of another config file, got {base!r}")
    here = Path(path).resolve()
    chain = (*_chain, here)
    parent = (here.parent / base).resolve()
    if parent in chain:
        raise ConfigError(f"{path}: extends cycle: {' -> '.join(p.name for p in (*chain, parent))}")
    if len(chain) > MAX_EXTENDS:
        raise ConfigError(f"{path}: more than {MAX_EXTENDS} files in its extends chain")
    if not parent.is_file():
        raise ConfigError(f"{path}: extends {base!r}, but there is no such file ({parent})")
    return merge_configs(read_mapping(parent, chain), data)


def merge_configs(base: dict, top: dict) -> dict:
    """``top`` over ``base``: a key in both whose values are both mappings merges
    recursively; otherwise ``top``'s value replaces ``base``'s (lists too: ``env.teams``
    is the whole list); a ``top`` value of None removes the key. Neither input changes."""
    out = dict(base)
    for key, value in top.items():
        if value is None:
            out.pop(key, None)
        elif isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = merge_configs(out[key], value)
        else:
            out[key] = value
    return out


def load_config(
    path: str | Path | None = None, cls: type[_Job] = TrainConfig, settings: dict | None = None, **fields: Any
) -> Any:
    """``cls`` from the YAML file ``path`` (None: the defaults), then ``settings``
    (``{"eval.episodes": 4, ...}``, dotted paths) and ``fields`` (top-level values
    that are not None: ``scenario=``, ``timesteps=``, ``seed=``, ...) on top; checked.
    Errors name the file."""
    data = read_mapping(path) if path is not None else {}
    if path is not None:
        try:
            from_dict(cls, data).check()  # the file alone: its errors name it
        except ConfigError as err:
            raise ConfigError(f"{path}: {err}") from None
    for dotted, value in (settings or {}).items():
        set_path(data, dotted, value)
    data.update({k: v for k, v in fields.items() if v is not None})
    return from_dict(cls, data).check()


def config_from_record(record: dict, cls: type | None = None) -> Any:
    """The config of a run from its ``config.yml`` (``args`` + ``hyperparameters``);
    ``cls`` None: the one of the record's backend (``args.backend``, sb3 if absent)."""
    if not isinstance(record, dict) or not isinstance(record.get("args"), dict):
        raise ConfigError("not a run record (no args)")
    args = record["args"]
    cls = cls or config_class(args.get("backend") or "sb3")
    data = dict(record.get("hyperparameters") or {})
    data.update({k: args[k] for k in JOB_KEYS if args.get(k) is not None})
    return from_dict(cls, data).check()
