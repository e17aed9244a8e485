"""Trained beacon policies, with the same interface as the baselines.

    import agents
    policy = agents.load("ppo_sousa_asv")            # a policy shipped in agents/policies/
    policy = agents.load("ppo", scenario="sousa_asv")  # the shipped PPO policy of a scenario
    policy = agents.load("runs/sousa_ppo")           # a run directory written by train.py
    policy.reset()
    action = policy.act(obs["beacon_0"])             # one beacon's observation -> (2,) in [-1, 1]

A policy directory (a train.py run, or ``agents/policies/<name>/``) holds the policy
network, its observation normalization and the config it was trained with, as data
only (safetensors tensors + JSON; ``agents.formats``), never a pickle:

    config.yml                                 written by train.py (scenario, hyperparameters, command)
    best_model.safetensors + best_vecnormalize.safetensors   preferred when present (the best evaluated)
    model.safetensors + vecnormalize.safetensors             else the final model
    checkpoints/last_checkpoint.json           else the last checkpoint (an unfinished run); the
                                               files it names must lie in checkpoints/

A run trained with normalized observations (its config.yml or model file says so)
whose normalization file is missing is refused (``PolicyFormatError``), rather than
acting on unnormalized observations.

The old pickle-based formats (an SB3 ``.zip``, a VecNormalize ``.pkl``, an RLlib
checkpoint) can run code when loaded: they are refused (``PickleRefused``, one line)
unless ``trust_pickle=True`` (``--trust-pickle`` of evaluate.py and train.py), which
also trusts those files for the rest of the process. ``python -m agents.convert
SRC --out NEW_DIR --trust-pickle`` converts one, once, to the safe format.

Actions are deterministic (the mean of PPO's Gaussian, clipped to [-1, 1]), and the
policy has no memory, so ``reset`` only exists for the interface.

A directory with a ``gate.yml`` instead holds two such policy directories and a gate
on the survey vehicle's depth below the beacon, as the observation gives it
(``DepthGatedPolicy``): ``{kind: depth_gate, threshold_m: 12.5, shallow: <dir>,
deep: <dir>}``, the directories relative to the gate file (and inside its directory).

A run trained on the entity observation (``env.observation: entities``; its network
has ``agents.entity.EntityExtractor``) loads as an ``agents.entity.EntityPolicy``: bound
to the scenario given (any team of up to five survey vehicles and three beacons), it
reads that scenario's flat observations. Whether a policy can drive a scenario is the
policy's to say (``policy.config_problem(config)``; ``accepts``), not a comparison of
observation sizes.

A BenchMARL run (``python -m agents.training.marl``: ``run.json`` beside
``policy.safetensors``) loads as an ``agents.benchmarl_policy.BenchMARLPolicy``, one per
beacon (``make_policy(run, config, agent=j)``), the actor rebuilt with BenchMARL's classes
(the ``marl`` extra).

A run of ``train.py --backend rllib`` (its directory, its ``checkpoint/``, or any RLlib
Algorithm checkpoint) loads the same way, through ``agents/rllib_policy.py`` (which
imports Ray only then): ``agents.load("runs/x_rllib", scenario=...)``; an RLlib
checkpoint is pickle-based, so see ``agents.rllib_policy`` for what is trusted.
"""

from __future__ import annotations

import json
import os
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from coopnav_env.names import did_you_mean
from coopnav_env.scenarios import list_scenarios
from coopnav_env.views import check_observation

from . import safe_paths
from .formats import _TRUSTED as _TRUSTED  # re-exported: agents._TRUSTED (the tests clear it)
from .formats import PickleRefused, PolicyFormatError, _check_trusted, _is_legacy, check_inside, trust_pickle
from .formats import refuse_pickle as refuse_pickle  # re-exported: agents.refuse_pickle
from .formats import safe_json as _safe_json  # bounded reads: one-line refusals
from .formats import safe_yaml as _safe_yaml
from .policy import BatchPolicy, _trained_scenario

if TYPE_CHECKING:
    from coopnav_env.scenarios import ScenarioConfig

    from .entity import EntityPolicy

POLICY_DIR = Path(__file__).resolve().parent / "policies"
# (model, normalization) of a run directory, in order of preference: the safe format,
# then the old pickle-based one (refused unless trusted)
RUN_FILES = (
    ("best_model.safetensors", "best_vecnormalize.safetensors"),
    ("model.safetensors", "vecnormalize.safetensors"),
)
LEGACY_RUN_FILES = (("best_model.zip", "best_vecnormalize.pkl"), ("model.zip", "vecnormalize.pkl"))

__all__ = [
    "DepthGatedPolicy",
    "PPOPolicy",
    "PickleRefused",
    "PolicyFormatError",
    "list_policies",
    "load",
    "make_policy",
    "resolve",
    "trust_pickle",
    "untrained_entity_policy",
]


def list_policies() -> list:
    """Names of the policies shipped in agents/policies/."""
    if not POLICY_DIR.is_dir():
        return []

    from . import batched_policy, benchmarl_policy

    def has_model(p):
        try:
            return (
                (p / "gate.yml").is_file()
                or benchmarl_policy.is_benchmarl_path(p)
                or batched_policy.is_batched_path(p)
                or _model_files(p) is not None
            )
        except (ValueError, OSError):
            return False

    return sorted(p.name for p in POLICY_DIR.iterdir() if p.is_dir() and has_model(p))


def _shipped_run(name_or_path: str | Path, scenario: Any) -> Path | None:
    """The shipped policy's directory a name means ("ppo" with ``scenario``: a name, a config
    or an env; or "ppo_<scenario>") when it holds a BenchMARL run (``run.json`` +
    ``policy.safetensors``) or a batched-loop run (``run.json`` + ``actor.safetensors``);
    None otherwise."""
    from . import batched_policy, benchmarl_policy

    name = str(name_or_path)
    if not name or Path(name).exists() or "/" in name or os.sep in name:
        return None
    if name == "ppo":
        if scenario is None:
            return None
        from coopnav_env.scenarios import resolve_config

        name = f"ppo_{scenario if isinstance(scenario, str) else resolve_config(scenario).name}"
    directory = POLICY_DIR / name
    shipped_run = benchmarl_policy.is_benchmarl_path(directory) or batched_policy.is_batched_path(directory)
    return directory if shipped_run else None


def _model_files(directory: Path):
    """(model file, normalization file, which may be missing) of a policy directory, or
    None: the best model, the final one (the safe format first, then the old one), else
    the last checkpoint. A ``PolicyFormatError`` if last_checkpoint.json names a file outside checkpoints/."""
    for model, stats in RUN_FILES:
        if (directory / model).is_file():
            return directory / model, directory / stats
    for model, stats in LEGACY_RUN_FILES:
        if (directory / model).is_file():
            return directory / model, directory / stats
    last = directory / "checkpoints" / "last_checkpoint.json"
    if last.is_file():
        try:
            info = _safe_json(last)
            names = str(info["model"]), str(info["vecnormalize"])
        except (ValueError, KeyError, TypeError):
            raise PolicyFormatError(f"{last} is not a checkpoint record (model, vecnormalize)") from None
        ckpt_dir = directory / "checkpoints"
        model_file, stats_file = (check_inside(ckpt_dir, n, f"{last}: file") for n in names)
        return model_file, stats_file
    return None


def _config_norm_obs(config_path) -> bool | None:
    """Whether a run's config.yml says it trained on normalized observations (None: it
    does not say: no config, or not an SB3 run)."""
    if config_path is None:
        return None
    record = _safe_yaml(config_path) or {}
    if not isinstance(record, dict) or not isinstance(record.get("args"), dict):
        return None
    if (record["args"].get("backend") or "sb3") != "sb3":
        return None
    norm = (record.get("hyperparameters") or {}).get("normalize") or {}
    return bool(norm.get("norm_obs", True)) if isinstance(norm, dict) else None


def _model_norm_obs(model_path) -> bool | None:
    """The ``norm_obs`` a safe model file's header records (None: unknown)."""
    if _is_legacy(model_path):
        return None
    try:
        from safetensors import safe_open

        with safe_open(str(model_path), framework="np") as f:
            value = json.loads((f.metadata() or {}).get("coopnav", "{}")).get("norm_obs")
    except Exception:  # a damaged file is reported when it is loaded
        return None
    return None if value is None else bool(value)


def _check_normalization(model, stats, config):
    """The normalization file ``stats`` (or None if missing); a ``PolicyFormatError`` if
    the run was trained with normalized observations and it is missing."""
    if stats is not None and Path(stats).is_file():
        return Path(stats)
    said = _config_norm_obs(config)
    why = f"{config} says normalize.norm_obs: true"
    if said is None:
        said, why = _model_norm_obs(model), f"{model} records norm_obs: true"
    if said:
        missing = stats if stats is not None else Path(model).parent / "vecnormalize.safetensors"
        raise PolicyFormatError(
            f"{missing} is missing, but the policy was trained on normalized observations "
            f"({why}): refused (it would act on unnormalized observations)"
        )
    return None


def resolve(
    name_or_path: str | Path, scenario: str | ScenarioConfig | None = None, trust_pickle: bool = False
) -> tuple:
    """(model file, normalization file or None, config.yml or None) for a name or path
    (for an RLlib run: (checkpoint directory, None, config.yml or None); for a BenchMARL
    run: (policy.safetensors, None, run.json); for a gated policy: (gate.yml, None, None)).
    Refuses (``PolicyFormatError``) pickle-based files unless ``trust_pickle``, a missing
    normalization file of a normalized run, and checkpoint records pointing outside the
    run directory."""
    from . import batched_policy, benchmarl_policy, rllib_policy

    name_or_path = _shipped_run(name_or_path, scenario) or name_or_path
    if rllib_policy.is_rllib_path(name_or_path):
        return rllib_policy.resolve(name_or_path, scenario, trust_pickle=trust_pickle)
    if benchmarl_policy.is_benchmarl_path(name_or_path):  # safetensors weights and a JSON record
        directory = Path(str(name_or_path))
        safe_paths.check_tree(directory)
        return directory / benchmarl_policy.WEIGHTS, None, directory / benchmarl_policy.RUN_RECORD
    if batched_policy.is_batched_path(name_or_path):  # python -m agents.training.batched_ppo
        directory = Path(str(name_or_path))
        safe_paths.check_tree(directory)
        return directory / batched_policy.WEIGHTS, None, directory / batched_policy.RUN_RECORD
    path = Path(str(name_or_path))
    if path.suffix in (".zip", ".safetensors") and path.is_file():
        safe_paths.inside(path.parent, path.name, "model file")  # a link out of its folder: refused
        stem = path.name[: -len(path.suffix)]
        ext = ".pkl" if path.suffix == ".zip" else ".safetensors"
        candidates = [
            path.with_name(stem + "_vecnormalize" + ext),
            path.with_name(("best_vecnormalize" if stem == "best_model" else "vecnormalize") + ext),
        ]
        stats = next((c for c in candidates if c.is_file()), candidates[-1])
        config = next(
            (d / "config.yml" for d in (path.parent, path.parent.parent) if (d / "config.yml").is_file()), None
        )
        for extra in (stats, config):
            if extra is not None and extra.exists():
                safe_paths.inside(extra.parent, extra.name, "file")
        stats = _check_normalization(path, stats, config)
        _check_trusted([path, stats], trust_pickle)
        return path, stats, config
    if path.is_dir():
        directory = path
    else:
        name = str(name_or_path)
        if name == "ppo":
            if scenario is None:
                raise ValueError("agents.load('ppo') names the shipped PPO policy of a scenario: pass scenario=")
            scen = _scenario_name(scenario)
            if scen not in list_scenarios():  # name the scenario, not the policy
                raise ValueError(
                    f"unknown scenario {scen!r}{did_you_mean(scen, list_scenarios())} "
                    f"valid scenarios: {', '.join(list_scenarios())}"
                )
            name = f"ppo_{scen}"
        directory = POLICY_DIR / name
        if not directory.is_dir():
            shipped = list_policies()
            hint = did_you_mean(name_or_path, [*shipped, "ppo"])
            raise ValueError(
                f"no policy {name_or_path!r}: not a run directory, a model file or a shipped policy{hint} "
                f"shipped: {', '.join(shipped) if shipped else 'none yet'}"
            )
    safe_paths.check_tree(directory)  # nothing read from it may lead outside it
    if (directory / "gate.yml").is_file():  # two policies and a gate: DepthGatedPolicy
        return directory / "gate.yml", None, None
    files = _model_files(directory)
    if files is None:
        raise ValueError(f"{directory} holds no model (best_model.safetensors, model.safetensors or a checkpoint)")
    model, stats = files
    config = directory / "config.yml"
    config = config if config.is_file() else None
    stats = _check_normalization(model, stats, config)
    _check_trusted([model, stats], trust_pickle)
    return model, stats, config


def _scenario_name(scenario) -> str:
    return scenario if isinstance(scenario, str) else scenario.name


class LoadedModel:
    """What a loaded SB3 policy keeps of its model: the policy network (an SB3
    ``ActorCriticPolicy``), its spaces and the steps it was trained for; ``predict``
    as SB3's ``model.predict``."""

    def __init__(self, policy: Any, num_timesteps: int = 0) -> None:
        self.policy = policy
        self.observation_space = policy.observation_space
        self.action_space = policy.action_space
        self.num_timesteps = int(num_timesteps)

    def predict(self, observation: np.ndarray, deterministic: bool = True) -> tuple[np.ndarray, Any]:
        return self.policy.predict(observation, deterministic=deterministic)


class RunningStats:
    """Frozen observation statistics (``mean``, ``var``) of a run's normalization."""

    def __init__(self, mean: Any, var: Any, count: float = 0.0) -> None:
        self.mean, self.var, self.count = np.asarray(mean, np.float64), np.asarray(var, np.float64), float(count)


class PPOPolicy(BatchPolicy):
    """A trained SB3 policy for one beacon: ``act(obs) -> action``, ``reset()``.

    ``act`` takes one beacon's observation (D,) and returns a float32 action (A,), A the
    scenario's action size (2; 3 with ``channel_mode="decide"``, as ``ppo_sousa_ping``);
    ``act_batch`` takes (M, D) and returns (M, A). Observations are normalized with
    the run's frozen VecNormalize statistics before the network sees them.
    """

    def __init__(
        self,
        model: Any,
        obs_rms: RunningStats | None = None,
        clip_obs: float = 10.0,
        epsilon: float = 1e-8,
        config: ScenarioConfig | None = None,
        run_config: dict | None = None,
        name: str = "ppo",
    ) -> None:
        self.model = model
        self.obs_rms = obs_rms
        self.clip_obs = float(clip_obs)
        self.epsilon = float(epsilon)
        self.config = config  # the ScenarioConfig it was trained on (None if unknown)
        self.run_config = run_config or {}
        self.name = name
        self.obs_dim = int(model.observation_space.shape[0])

    def reset(self, seed: int | None = None) -> None:
        """Stateless: nothing to clear (the interface of baselines.Policy)."""

    def normalize(self, obs: np.ndarray) -> np.ndarray:
        if self.obs_rms is None:
            return obs.astype(np.float32)
        z = (obs - self.obs_rms.mean) / np.sqrt(self.obs_rms.var + self.epsilon)
        return np.clip(z, -self.clip_obs, self.clip_obs).astype(np.float32)

    def act_batch(self, obs: np.ndarray) -> np.ndarray:
        obs = check_observation(obs, self.obs_dim, batch=True)  # shape and finite, one line
        action, _ = self.model.predict(self.normalize(obs), deterministic=True)
        return np.clip(action, -1.0, 1.0).astype(np.float32)

    def __repr__(self):
        scen = self.config.name if self.config is not None else "?"
        return f"PPOPolicy({self.name!r}, scenario={scen!r})"


def load_model(model_path: str | Path, device: str = "cpu") -> LoadedModel:
    """The policy network of a model file (safe format; a trusted .zip only after
    ``resolve`` accepted it)."""
    from . import formats

    if _is_legacy(model_path):
        _check_trusted([model_path], False)
        ppo = formats.legacy_model(model_path, device=device)
        return LoadedModel(ppo.policy, ppo.num_timesteps)
    spec, state, _ = formats.read_model(model_path)
    return LoadedModel(formats.build_policy(spec, state, where=model_path, device=device), spec.get("num_timesteps", 0))


def load_stats(stats_path: str | Path | None) -> dict | None:
    """A normalization file's statistics (``formats.vecnormalize_stats``' dict), or None."""
    from . import formats

    if stats_path is None:
        return None
    if _is_legacy(stats_path):
        _check_trusted([stats_path], False)
        return formats.legacy_vecnormalize(stats_path)
    return formats.read_vecnormalize(stats_path)


def load(
    name_or_path: str | Path,
    scenario: str | ScenarioConfig | None = None,
    device: str = "cpu",
    trust_pickle: bool = False,
) -> BatchPolicy:
    """A trained policy by shipped name ("ppo_sousa_asv"; "ppo" with ``scenario``), run
    directory, or model file. With ``scenario`` (name or ScenarioConfig) its
    observation size is checked against the policy's. Nothing is unpickled unless
    ``trust_pickle`` (then an old SB3 .zip/.pkl or an RLlib checkpoint loads)."""
    from . import batched_policy, benchmarl_policy, rllib_policy

    name_or_path = _shipped_run(name_or_path, scenario) or name_or_path  # a shipped BenchMARL or loop run
    if rllib_policy.is_rllib_path(name_or_path):  # train.py --backend rllib
        return rllib_policy.load(name_or_path, scenario=scenario, device=device, trust_pickle=trust_pickle)
    if benchmarl_policy.is_benchmarl_path(name_or_path):  # python -m agents.training.marl
        return benchmarl_policy.load(name_or_path, scenario=scenario)
    if batched_policy.is_batched_path(name_or_path):  # python -m agents.training.batched_ppo
        return batched_policy.load(name_or_path, scenario=scenario)
    model_path, stats_path, config_path = resolve(name_or_path, scenario, trust_pickle=trust_pickle)
    if model_path.name == "gate.yml":
        return _load_gated(model_path, scenario, device, name=Path(str(name_or_path)).name, trust_pickle=trust_pickle)
    model = load_model(model_path, device=device)
    obs_rms, clip_obs, epsilon = None, 10.0, 1e-8
    stats = load_stats(stats_path)
    if stats is not None:
        if stats["norm_obs"]:
            obs_rms = RunningStats(stats["obs_mean"], stats["obs_var"], stats["obs_count"])
        clip_obs, epsilon = stats["clip_obs"], stats["epsilon"]
    run_config: Any = {}
    trained_config = None
    if config_path is not None:
        run_config = _safe_yaml(config_path) or {}
        if not isinstance(run_config, dict):
            raise PolicyFormatError(f"{config_path}: expected a mapping (a train.py run record)")
        trained_config = _trained_scenario(run_config)
    policy: BatchPolicy = PPOPolicy(
        model,
        obs_rms,
        clip_obs,
        epsilon,
        config=trained_config,
        run_config=run_config,
        name=Path(str(name_or_path)).name,
    )
    if obs_rms is not None and obs_rms.mean.shape != (policy.obs_dim,):
        raise PolicyFormatError(
            f"{stats_path}: normalization of shape {obs_rms.mean.shape} does not fit the "
            f"network's observations ({policy.obs_dim},)"
        )
    from .entity import EntityPolicy, is_entity_model

    if is_entity_model(model):  # reads entity observations: bound to a team below (or unbound)
        policy = EntityPolicy(policy)
    if scenario is not None:
        from coopnav_env.scenarios import make_config

        target = make_config(scenario) if isinstance(scenario, str) else scenario
        problem = policy.config_problem(target)  # the policy says which scenarios it takes
        if problem is not None:
            raise ValueError(f"policy {name_or_path!r} {problem}")
        if trained_config is not None and trained_config.name != target.name:
            warnings.warn(
                f"policy {name_or_path!r} was trained on {trained_config.name!r}, used on {target.name!r}", stacklevel=2
            )
        if isinstance(policy, EntityPolicy):
            return policy.for_config(target)
        if trained_config is None:
            policy.config = target
    elif isinstance(policy, EntityPolicy) and trained_config is not None and policy.accepts(trained_config):
        return policy.for_config(trained_config)
    return policy


def untrained_entity_policy(
    action_dim: int = 2,
    encoder: str = "attention",
    embed_dim: int = 32,
    heads: int = 4,
    net_arch: tuple = (64,),
    seed: int = 0,
    config: Any = None,
) -> EntityPolicy:
    """An entity policy with fresh weights (torch seeded with ``seed``): the network an
    ``env.observation: entities`` run starts from, built through the safe format's
    ``formats.build_policy`` (for tests and tools: it drives any team it accepts)."""
    import torch
    from gymnasium import spaces

    from coopnav_env.entity_obs import LAYOUT, entity_space

    from .entity import EntityPolicy
    from .formats import _box, build_policy

    torch.manual_seed(int(seed))
    spec = {
        "policy": "MlpPolicy",
        "observation_space": _box(entity_space()),
        "action_space": _box(spaces.Box(-1.0, 1.0, shape=(int(action_dim),), dtype=np.float32)),
        "policy_kwargs": {
            "net_arch": list(net_arch),
            "features_extractor_class": "EntityExtractor",
            "features_extractor_kwargs": {
                "encoder": encoder,
                "embed_dim": embed_dim,
                "heads": heads,
                "layout": LAYOUT.to_dict(),
            },
        },
    }
    base = PPOPolicy(LoadedModel(build_policy(spec, where="untrained entity policy")), name="untrained_entity")
    return EntityPolicy(base, config)


class DepthGatedPolicy(BatchPolicy):
    """Two trained policies and a fixed gate: ``shallow`` acts where the survey vehicle's
    depth below the beacon (its last reply, as the observation gives it; the mean over
    survey vehicles) is below ``threshold_m``, ``deep`` elsewhere. Both see the same
    observation; the gate is part of the policy, written in its gate.yml."""

    def __init__(self, shallow: BatchPolicy, deep: BatchPolicy, threshold_m: float, name: str = "gated") -> None:
        if shallow.obs_dim != deep.obs_dim:
            raise ValueError(f"gated policies must take the same observation: {shallow.obs_dim} != {deep.obs_dim}")
        if not np.isfinite(threshold_m):
            raise ValueError(f"threshold_m must be finite, got {threshold_m!r}")
        self.shallow, self.deep, self.threshold_m, self.name = shallow, deep, float(threshold_m), name
        self.obs_dim = deep.obs_dim
        self.config = deep.config if deep.config is not None else shallow.config

    def reset(self, seed: int | None = None) -> None:
        self.shallow.reset(seed)
        self.deep.reset(seed)

    def act_batch(self, obs: np.ndarray) -> np.ndarray:
        from coopnav_env.obs_layout import decode

        obs = check_observation(obs, self.obs_dim, batch=True)  # shape and finite, one line
        depth = decode(obs, self.config).depth_below_m.mean(-1)
        out = self.deep.act_batch(obs)
        shallow = depth < self.threshold_m
        if shallow.any():
            out[shallow] = self.shallow.act_batch(obs[shallow])
        return out

    def __repr__(self):
        return f"DepthGatedPolicy({self.name!r}, below {self.threshold_m} m: {self.shallow!r}, else {self.deep!r})"


def _load_gated(gate_path: Path, scenario, device, name, trust_pickle=False):
    spec = _safe_yaml(gate_path) or {}
    if (
        not isinstance(spec, dict)
        or spec.get("kind") != "depth_gate"
        or not {"threshold_m", "shallow", "deep"} <= set(spec)
    ):
        raise ValueError(f"{gate_path}: expected kind: depth_gate with threshold_m, shallow and deep")
    dirs = [check_inside(gate_path.parent, str(spec[k]), f"{gate_path}: {k}") for k in ("shallow", "deep")]
    for key, d in zip(("shallow", "deep"), dirs):  # a gate of gates (or of itself) would recurse
        if d == gate_path.parent.resolve() or (d / "gate.yml").exists():
            raise PolicyFormatError(
                f"{gate_path}: {key} names {spec[key]!r}, a gate itself: a gate's networks "
                "must be trained policies, not gates"
            )
    try:
        threshold = float(spec["threshold_m"])
    except (TypeError, ValueError, OverflowError):
        raise PolicyFormatError(f"{gate_path}: threshold_m must be a number, got {spec['threshold_m']!r}") from None
    parts = [load(d, scenario=scenario, device=device, trust_pickle=trust_pickle) for d in dirs]
    return DepthGatedPolicy(parts[0], parts[1], threshold_m=threshold, name=name)


_CACHE: dict = {}


def make_policy(
    name_or_path: str | Path,
    env_or_config: Any = None,
    seed: int | Sequence[int] | None = None,
    agent: int = 0,
    trust_pickle: bool = False,
) -> BatchPolicy:
    """``baselines.make_policy``'s signature for trained policies: one policy per beacon
    and episode is cheap, since the loaded model is shared (cached by resolved path).
    ``seed`` is accepted for the interface and ignored (the policies act deterministically);
    ``agent`` is the beacon's index, which an entity policy reads as its role input and a
    network-per-beacon run (RLlib, BenchMARL) uses to pick its module; a flat SB3 policy
    shares one network across beacons and ignores it. ``trust_pickle``: as ``load``."""
    from . import batched_policy, benchmarl_policy, rllib_policy

    name_or_path = _shipped_run(name_or_path, env_or_config) or name_or_path  # a shipped BenchMARL or loop run
    if rllib_policy.is_rllib_path(name_or_path):  # one module per beacon kind: the agent matters
        return rllib_policy.make_policy(name_or_path, env_or_config, seed=seed, agent=agent, trust_pickle=trust_pickle)
    if benchmarl_policy.is_benchmarl_path(name_or_path):  # its own memory per beacon and episode
        return benchmarl_policy.make_policy(name_or_path, env_or_config, seed=seed, agent=agent)
    if batched_policy.is_batched_path(name_or_path):  # a fresh object per beacon and episode (its own window)
        return batched_policy.make_policy(name_or_path, env_or_config, agent=agent)
    scenario = None
    if env_or_config is not None:
        from coopnav_env.scenarios import resolve_config

        scenario = resolve_config(env_or_config)
    model_path, _, _ = resolve(name_or_path, scenario, trust_pickle=trust_pickle)
    key = (str(Path(model_path).resolve()), Path(model_path).stat().st_mtime_ns, None if scenario is None else scenario)
    if key not in _CACHE:
        _CACHE[key] = load(name_or_path, scenario=scenario, trust_pickle=trust_pickle)
    base = _CACHE[key]
    if isinstance(base, DepthGatedPolicy):  # stateless: one instance serves every beacon and episode
        return base
    from .entity import EntityPolicy

    if isinstance(base, EntityPolicy):  # the beacon's index is its role input
        return base.for_config(base.config, agent=agent)
    return PPOPolicy(
        base.model,
        base.obs_rms,
        base.clip_obs,
        base.epsilon,
        config=base.config,
        run_config=base.run_config,
        name=base.name,
    )
