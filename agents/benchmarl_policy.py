"""BenchMARL runs as coopnav policies: ``agents.load("runs/gao_team_mappo", scenario=...)``.

A run of ``python -m agents.training.marl`` (``docs/training/marl.md``) is a folder with
``run.json`` (the algorithm, the model and its settings, the task it trained on) and
``policy.safetensors`` (the actor's weights: data, not a pickle). This module rebuilds
the actor with BenchMARL's own classes (the algorithm's ``get_policy_for_collection``,
over the specs of ``coopnav_env.torchrl_env.CoopNavTorchEnv`` for the scenario it is
bound to), loads the weights into it, and acts as BenchMARL's evaluation does:
deterministically (``ExplorationType.DETERMINISTIC``: the mode of the actor's tanh-normal).

So ``evaluate.py --policies runs/x`` and the benchmark score a BenchMARL run like any
policy, beside the planners and the SB3 policies, on the same seeds.

- **One beacon, one policy object.** ``make_policy(run, config, agent=j)`` returns the
  policy of beacon ``j``: its observation fills slot ``j`` of the group's input (the
  actor is decentralised: slot ``j``'s output depends on slot ``j``'s input only, so the
  other slots are zeros), and the action is slot ``j``'s. With
  ``share_policy_params: false`` slot ``j`` has its own weights.
- **Memory.** A recurrent actor (``--model gru``; an ``lstm`` one is refused) keeps its hidden state in
  the policy object, from one ``act`` to the next, as BenchMARL's collector carries it;
  ``reset()`` clears it (the next step is an episode's first: ``is_init``).
- **Which scenarios.** The observation size and the action size it was trained on; with
  shared parameters any number of beacons, else the number it was trained with
  (``config_problem``). Loading needs the ``marl`` extra (``pip install -e ".[marl]"``);
  without it, one line says so.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from coopnav_env.views import check_observation

from .formats import PolicyFormatError
from .policy import BatchPolicy

if TYPE_CHECKING:
    from coopnav_env.scenarios import ScenarioConfig

RUN_RECORD = "run.json"
WEIGHTS = "policy.safetensors"
# algorithms whose collection policy is the deterministic-capable actor rebuilt here
# (tested: tests/test_benchmarl.py); the others are refused with this list
LOADABLE = ("mappo", "ippo", "masac", "isac")
_RNN_HIDDEN = {"gru": "_hidden_gru_0", "lstm": "_hidden_lstm_h_0"}

__all__ = ["BenchMARLPolicy", "forget", "is_benchmarl_path", "load", "make_policy", "policy_record"]


def is_benchmarl_path(path: Any) -> bool:
    """Whether ``path`` is a BenchMARL run folder (``run.json`` naming an algorithm, beside
    ``policy.safetensors``); no import of torch or BenchMARL."""
    directory = Path(str(path))
    record = directory / RUN_RECORD
    if not (directory.is_dir() and record.is_file() and (directory / WEIGHTS).is_file()):
        return False
    try:
        from .formats import safe_json

        return "algorithm" in (safe_json(record) or {})
    except (ValueError, OSError):
        return False


def _class_name(value: Any) -> Any:
    return f"{value.__module__}.{value.__qualname__}" if isinstance(value, type) else value


def _jsonable_fields(config: Any) -> dict:
    """A BenchMARL config dataclass as JSON: classes by dotted name (``torch.nn...``)."""
    import dataclasses

    out = {}
    for field in dataclasses.fields(config):
        value = _class_name(getattr(config, field.name))
        try:
            json.dumps(value)
        except TypeError:
            continue
        out[field.name] = value
    return out


def policy_record(experiment: Any, algorithm: str, model: str) -> dict:
    """What a run folder's ``run.json`` keeps so that ``load`` can rebuild the actor: the
    algorithm, the model and their settings (BenchMARL dataclasses as JSON), the group's
    agents, observation and action sizes, and whether parameters are shared."""
    env = experiment.test_env
    group = next(iter(experiment.group_map))
    return {
        "algorithm": algorithm,
        "model": model,
        "algorithm_config": _jsonable_fields(experiment.algorithm_config),
        "model_config": _jsonable_fields(experiment.model_config),
        "share_policy_params": bool(experiment.config.share_policy_params),
        "group": group,
        "n_agents": len(experiment.group_map[group]),
        "obs_dim": int(env.full_observation_spec_unbatched[group, "observation"].shape[-1]),
        "action_dim": int(env.full_action_spec_unbatched[group, "action"].shape[-1]),
    }


def _torch_class(name: str, where: Path) -> type:
    """A class named in run.json: only ``torch.nn`` classes (a record never names code to run)."""
    import torch

    module, _, attr = str(name).rpartition(".")
    value = getattr(torch.nn, attr, None)
    if not module.startswith("torch.nn") or not isinstance(value, type):
        raise PolicyFormatError(f"{where}: {name!r} is not a torch.nn class")
    return value


def _model_config(record: dict, where: Path) -> Any:
    from benchmarl.models import GruConfig, LstmConfig, MlpConfig

    name = str(record.get("model", "mlp"))
    classes = {"mlp": MlpConfig, "gru": GruConfig, "lstm": LstmConfig}
    if name == "lstm":  # BenchMARL's LSTM carries two states; acting with it is not wired yet
        raise PolicyFormatError(f"{where}: an lstm actor cannot be loaded yet (mlp, gru can)")
    if name not in classes:
        raise PolicyFormatError(f"{where}: model {name!r} cannot be loaded (valid: {', '.join(classes)})")
    config = classes[name].get_from_yaml()  # the defaults; run.json's settings on top
    fields = dict(record.get("model_config") or {})
    import dataclasses

    known = {f.name for f in dataclasses.fields(config)}
    for key, value in fields.items():
        if key not in known:
            raise PolicyFormatError(f"{where}: unknown {name} setting {key!r}")
        if key.endswith("_class") and value is not None:
            value = _torch_class(value, where)
        setattr(config, key, value)
    return config


def _algorithm_config(record: dict, where: Path) -> Any:
    import benchmarl.algorithms as algos

    name = str(record["algorithm"])
    if name not in LOADABLE:
        raise PolicyFormatError(f"{where}: a {name} run cannot be loaded as a policy (loadable: {', '.join(LOADABLE)})")
    config = getattr(algos, f"{name.capitalize()}Config").get_from_yaml()
    for key, value in (record.get("algorithm_config") or {}).items():
        if not hasattr(config, key):
            raise PolicyFormatError(f"{where}: unknown {name} setting {key!r}")
        setattr(config, key, value)
    return config


class _Actor:
    """BenchMARL's collection policy for one scenario, with the run's weights."""

    def __init__(self, directory: Path, record: dict, config: ScenarioConfig) -> None:
        import dataclasses
        from types import SimpleNamespace

        import torch
        from benchmarl.experiment import ExperimentConfig
        from safetensors.torch import load_file

        from coopnav_env.torchrl_env import CoopNavTorchEnv

        from .training.benchmarl_task import CoopNavClass

        algorithm_config = _algorithm_config(record, directory)
        model_config = _model_config(record, directory)
        experiment_config = dataclasses.replace(
            ExperimentConfig.get_from_yaml(),
            share_policy_params=_shared(record),
            train_device="cpu",
            buffer_device="cpu",
            sampling_device="cpu",
        )
        env = CoopNavTorchEnv(config, n_envs=1, seed=0)
        task = CoopNavClass(name="COOPNAV", config={})
        holder = SimpleNamespace(  # what BenchMARL's Algorithm reads of an Experiment
            config=experiment_config,
            model_config=model_config,
            critic_model_config=model_config,
            algorithm_config=algorithm_config,
            on_policy=algorithm_config.on_policy(),
            group_map=task.group_map(env),
            observation_spec=task.observation_spec(env),
            action_spec=task.action_spec(env),
            state_spec=task.state_spec(env),
            action_mask_spec=None,
        )
        self.group = next(iter(holder.group_map))
        self.n_agents = len(holder.group_map[self.group])
        self.obs_dim = int(holder.observation_spec[self.group, "observation"].shape[-1])
        self.module = algorithm_config.get_algorithm(experiment=holder).get_policy_for_collection()
        env.close()
        weights = load_file(str(directory / WEIGHTS))
        state = self.module.state_dict()
        ours = {k for k, v in state.items() if isinstance(v, torch.Tensor)}
        if set(weights) != ours:
            raise PolicyFormatError(
                f"{directory / WEIGHTS} does not hold this actor's weights "
                f"(missing {sorted(ours - set(weights))[:2]}, unexpected {sorted(set(weights) - ours)[:2]})"
            )
        for key, value in weights.items():
            if value.shape != state[key].shape:
                raise PolicyFormatError(
                    f"{directory / WEIGHTS}: {key} has shape {tuple(value.shape)}, "
                    f"the actor for {config.name!r} needs {tuple(state[key].shape)}"
                )
            state[key] = value
        self.module.load_state_dict(state)
        self.module.eval()
        model = str(record.get("model", "mlp"))
        self.hidden_key = (self.group, _RNN_HIDDEN[model]) if model in _RNN_HIDDEN else None
        self.hidden_shape: tuple[int, ...] = (
            (self.n_agents, int(model_config.n_layers), int(model_config.hidden_size)) if self.hidden_key else ()
        )

    def __call__(self, obs: np.ndarray, agent: int, hidden: Any) -> tuple[np.ndarray, Any]:
        """Actions (M, A) of beacon ``agent`` for its observations (M, D), and the next
        hidden state (None for a feed-forward actor). ``hidden`` None: an episode's first step."""
        import torch
        from tensordict import TensorDict
        from torchrl.envs.utils import ExplorationType, set_exploration_type

        M = obs.shape[0]
        x = torch.zeros((M, self.n_agents, self.obs_dim), dtype=torch.float32)
        x[:, agent] = torch.as_tensor(obs, dtype=torch.float32)
        td = TensorDict({(self.group, "observation"): x}, batch_size=[M])
        if self.hidden_key is not None:
            first = hidden is None or hidden.shape[0] != M
            td.set("is_init", torch.full((M, 1), first, dtype=torch.bool))
            td.set(self.hidden_key, torch.zeros((M, *self.hidden_shape)) if first else hidden)
        threads = torch.get_num_threads()
        few = M <= 64 and threads != 1  # a few rows: torch's thread pool costs more than it gives
        if few:  # (5.3 -> 0.9 ms a decision with 2 threads on a busy 2-core machine)
            torch.set_num_threads(1)
        try:
            with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
                out = self.module(td)
        finally:
            if few:
                torch.set_num_threads(threads)
        action = out.get((self.group, "action"))[:, agent].numpy()
        if self.hidden_key is None:
            return action, None
        return action, out.get(("next", self.group, self.hidden_key[1]))


class BenchMARLPolicy(BatchPolicy):
    """Beacon ``agent``'s policy from a BenchMARL run (see the module's docstring)."""

    def __init__(self, actor: _Actor, agent: int, config: ScenarioConfig, record: dict, name: str) -> None:
        self.actor, self.agent, self.config, self.record, self.name = actor, int(agent), config, record, name
        self.obs_dim = actor.obs_dim
        self.run_config = record
        self._hidden: Any = None

    def reset(self, seed: int | None = None) -> None:
        """Clear the memory (a recurrent actor's next step is an episode's first)."""
        self._hidden = None

    def act_batch(self, obs: np.ndarray) -> np.ndarray:
        obs = check_observation(obs, self.obs_dim, batch=True)  # shape and finite, one line
        action, self._hidden = self.actor(obs, self.agent, self._hidden)
        return np.clip(action, -1.0, 1.0).astype(np.float32)

    def config_problem(self, config: Any) -> str | None:
        return _config_problem(self.record, config)

    def __repr__(self) -> str:
        algorithm = self.record.get("algorithm")
        return f"BenchMARLPolicy({self.name!r}, {algorithm}, scenario={self.config.name!r}, agent={self.agent})"


def _config_problem(record: dict, config: Any) -> str | None:
    from coopnav_env.obs_layout import obs_dim
    from coopnav_env.views import action_dim

    dim, want = obs_dim(config), record.get("obs_dim")
    if want is not None and dim != int(want):
        return f"takes observations of size {want}; scenario {config.name!r} gives {dim}"
    adim, want_a = action_dim(config), record.get("action_dim")
    if want_a is not None and adim != int(want_a):
        return f"takes actions of size {want_a}; scenario {config.name!r} has {adim}"
    n = record.get("n_agents")
    if not _shared(record) and n is not None and config.n_beacons != int(n):
        return f"has one network per beacon for {n} beacons; scenario {config.name!r} has {config.n_beacons}"
    return None


def _shared(record: dict) -> bool:
    """Whether the beacons share one network (runs before ``policy_record`` kept it in
    their experiment config only)."""
    value = record.get("share_policy_params", (record.get("experiment_config") or {}).get("share_policy_params", True))
    return bool(value)


def _read_record(directory: Path) -> dict:
    from .formats import safe_json

    record = safe_json(directory / RUN_RECORD)
    if not isinstance(record, dict) or "algorithm" not in record:
        raise PolicyFormatError(f"{directory / RUN_RECORD} is not a BenchMARL run record")
    return record


def _trained_config(record: dict) -> ScenarioConfig | None:
    from .training.benchmarl_task import scenario_config

    try:
        return scenario_config(dict(record["task_config"]), str(record.get("task", "?")))
    except (KeyError, TypeError, ValueError):
        return None


def _require_marl() -> None:
    try:
        import benchmarl  # noqa: F401
        import torchrl  # noqa: F401
    except ImportError:
        raise PolicyFormatError('a BenchMARL run needs the marl extra to be loaded: pip install -e ".[marl]"') from None


_ACTORS: dict = {}


def _actor(directory: Path, record: dict, config: ScenarioConfig) -> _Actor:
    weights = (directory / WEIGHTS).stat().st_mtime_ns
    key = (str(directory.resolve()), weights, json.dumps(record, sort_keys=True), config)
    if key not in _ACTORS:
        _ACTORS[key] = _Actor(directory, record, config)
    return _ACTORS[key]


def forget(path: str | Path) -> None:
    """Drop the cached actors of the run folder at ``path`` (its weights may be rewritten:
    ``agents.training.marl_validation`` saves a new set at every validation)."""
    where = str(Path(str(path)).resolve())
    for key in [k for k in _ACTORS if k[0] == where]:
        del _ACTORS[key]


def load(path: str | Path, scenario: str | ScenarioConfig | None = None, agent: int = 0) -> BenchMARLPolicy:
    """Beacon ``agent``'s policy of the run at ``path``, bound to ``scenario`` (default:
    the scenario and task it trained on). One line (``ValueError``) if it cannot drive it."""
    from coopnav_env.scenarios import make_config

    directory = Path(str(path))
    record = _read_record(directory)
    _require_marl()
    trained = _trained_config(record)
    if scenario is None:
        if trained is None:
            raise PolicyFormatError(f"{directory / RUN_RECORD} names no task it trained on: pass scenario=")
        target = trained
    else:
        target = make_config(scenario) if isinstance(scenario, str) else scenario
    problem = _config_problem(record, target)
    if problem is not None:
        raise ValueError(f"policy {str(path)!r} {problem}")
    if not 0 <= int(agent) < target.n_beacons:
        raise ValueError(f"agent must be in 0..{target.n_beacons - 1} for {target.name!r}, got {agent}")
    return BenchMARLPolicy(_actor(directory, record, target), agent, target, record, name=directory.name)


def make_policy(path: str | Path, env_or_config: Any = None, seed: Any = None, agent: int = 0) -> BenchMARLPolicy:
    """``baselines.make_policy``'s signature: beacon ``agent``'s policy, a fresh object
    (its own memory) around the actor shared by every beacon and episode."""
    config = None
    if env_or_config is not None:
        from coopnav_env.scenarios import resolve_config

        config = resolve_config(env_or_config)
    return load(path, scenario=config, agent=agent)
