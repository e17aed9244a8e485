"""RLlib checkpoints as beacon policies (the interface of ``baselines.Policy``).

    import agents
    policy = agents.load("runs/x", scenario="sousa_asv")      # a train.py --backend rllib run
    policy = agents.load("runs/x/checkpoint")                 # an RLlib Algorithm checkpoint
    policy = agents.load("runs/x/tune/PPO_.../checkpoint_000000")   # a Tune trial's checkpoint
    action = policy.act(obs["beacon_0"])

``agents.load`` / ``agents.make_policy`` / ``agents.resolve`` hand RLlib paths to this
module (``is_rllib_path``), so ``evaluate.py --policies runs/x,fim_a`` runs an RLlib
policy beside the planners and the SB3 policies. Ray and torch are imported only
when a policy is loaded.

What is loaded, from an RLlib (new API stack) ``Algorithm`` checkpoint:

* the RLModule of the beacon's kind (``learner_group/learner/rl_module/<kind>``,
  ``RLModule.from_checkpoint``; one module per beacon kind, see
  ``coopnav_env.rllib_env``); the kind of beacon ``j`` is the scenario's
  ``beacon_kinds[j]``;
* the observation filter, if the run used one (``normalize_obs: true``: RLlib's
  MeanStdFilter, ``env_runner/env_to_module_connector/MeanStdFilter``): the beacon's
  running mean and std, frozen;
* the run's ``config.yml`` (the nearest one in the checkpoint's directory or above):
  the scenario it was trained on.

**Pickle.** RLlib's own checkpoint files are read by unpickling
(``class_and_ctor_args.pkl``, ``module_state.pkl``, the filter's ``state.pkl``), which
runs whatever code they hold. So a checkpoint is loaded from its **safe export**,
``<checkpoint>/policy_export/`` (written by train.py beside every checkpoint, or by
``python -m agents.convert CKPT --out NEW --trust-pickle``), data only:

* ``<module_id>.safetensors``: the RLModule's ``state_dict``; header metadata
  ``coopnav`` (JSON): the module class (only ``DefaultPPOTorchRLModule`` with
  ``PPOCatalog`` is rebuilt), observation and action spaces, ``inference_only``,
  ``model_config``;
* ``filters.safetensors`` (with ``normalize_obs``): each beacon's frozen MeanStdFilter
  mean and std; metadata: shape, demean, destd, clip.

A checkpoint without the export is refused (``agents.formats.PickleRefused``, one
line) unless ``trust_pickle=True`` (``--trust-pickle``), which also trusts that
checkpoint for the rest of the process. Trust only checkpoints you trained or got
from someone you trust.

Actions are deterministic: the mean of the module's Gaussian
(``forward_inference`` -> ``action_dist_inputs`` -> the inference distribution's
``to_deterministic()``), clipped to [-1, 1] (the action space; RLlib's default
action normalization is the identity on it). No memory: ``reset`` does nothing.
"""

from __future__ import annotations

import logging
import pickle
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from agents.policy import BatchPolicy, _trained_scenario
from coopnav_env.views import check_observation

CHECKPOINT_MARKER = "rllib_checkpoint.json"
MODULE_DIR = Path("learner_group") / "learner" / "rl_module"
FILTER_STATE = Path("env_runner") / "env_to_module_connector" / "MeanStdFilter" / "state.pkl"
EXPORT_DIR = "policy_export"
FILTERS_FILE = "filters.safetensors"
MODULE_FORMAT, FILTER_FORMAT = "coopnav-rllib-module", "coopnav-rllib-filters"
SMALL_NUMBER = 1e-6  # ray.rllib.utils.filter's, in MeanStdFilter's std

__all__ = ["RLlibPolicy", "find_checkpoint", "is_rllib_path", "load", "make_policy", "resolve"]


# --------------------------------------------------------------------------------------
# finding a checkpoint (no ray import: agents.resolve calls this for every path)
def _run_config_backend(directory: Path):
    path = directory / "config.yml"
    if not path.is_file():
        return None
    try:
        from coopnav_env.safe_load import read_yaml

        return ((read_yaml(path) or {}).get("args", {}) or {}).get("backend")
    except Exception:  # an unreadable config is not an RLlib run (the SB3 path refuses it)
        return None


def find_checkpoint(path: object) -> Path | None:
    """The RLlib Algorithm checkpoint directory ``path`` names, or None: ``path`` itself
    (it holds ``rllib_checkpoint.json``), or a train.py ``--backend rllib`` run
    directory (its ``checkpoint/``)."""
    p = Path(str(path))
    if not p.is_dir():
        return None
    if (p / CHECKPOINT_MARKER).is_file():
        return p
    if (p / "checkpoint" / CHECKPOINT_MARKER).is_file():
        return p / "checkpoint"
    if _run_config_backend(p) == "rllib":
        return p / "checkpoint"  # an unfinished run: resolve() says what is missing
    return None


def is_rllib_path(path: object) -> bool:
    """Whether ``path`` is an RLlib checkpoint or a train.py ``--backend rllib`` run."""
    return find_checkpoint(path) is not None


def find_run_config(checkpoint: Path) -> Path | None:
    """The nearest ``config.yml`` of a train.py rllib run at or above ``checkpoint``
    (a Tune trial's checkpoint lies in ``<run>/tune/<trial>/checkpoint_*``)."""
    for d in [checkpoint, *checkpoint.resolve().parents][:5]:
        if (d / "config.yml").is_file() and _run_config_backend(d) == "rllib":
            return d / "config.yml"
    return None


def resolve(path: str | Path, scenario: Any = None, trust_pickle: bool = False) -> tuple:
    """(checkpoint directory, None, config.yml or None), as ``agents.resolve``; raises
    ValueError if the run has no checkpoint (yet) or the checkpoint no module, and
    ``PickleRefused`` unless ``trust_pickle`` (or the checkpoint was trusted before)."""
    ckpt = find_checkpoint(path)
    if ckpt is None:
        raise ValueError(f"{path} is not an RLlib checkpoint or train.py --backend rllib run")
    from agents.safe_paths import check_tree

    check_tree(path)  # no file of the run (policy_export/, the modules) may lead outside it
    if not (ckpt / CHECKPOINT_MARKER).is_file():
        raise ValueError(f"{path} holds no RLlib checkpoint yet ({ckpt} is missing)")
    modules = ckpt / MODULE_DIR
    if not modules.is_dir() or not any(d.is_dir() for d in modules.iterdir()):
        raise ValueError(f"{ckpt} holds no RLModule ({MODULE_DIR}/<module id>)")
    from agents.formats import _TRUSTED, _check_trusted

    export = _export_files(ckpt)
    if export:
        _check_trusted(export, False)  # safetensors: refused only if one holds a pickle instead
        _check_filters(ckpt, find_run_config(ckpt))
    elif not trust_pickle and str(ckpt.resolve()) not in _TRUSTED:  # RLlib's own files are pickle-based
        from agents.formats import refuse_pickle

        refuse_pickle(ckpt, f"an RLlib checkpoint without its safe export ({EXPORT_DIR}/), read by unpickling")
    else:
        _check_trusted([ckpt], True)
    return ckpt, None, find_run_config(ckpt)


def _normalizes(ckpt: Path, config_path) -> str | None:
    """Why the run of checkpoint ``ckpt`` normalizes observations (None: it does not say so)."""
    if config_path is not None:
        from agents.formats import safe_yaml

        record = safe_yaml(config_path) or {}
        hyper = record.get("hyperparameters") if isinstance(record, dict) else None
        if isinstance(hyper, dict) and hyper.get("normalize_obs"):
            return f"{config_path} says normalize_obs: true"
    if (ckpt / FILTER_STATE).exists():
        return f"the checkpoint holds an observation filter ({FILTER_STATE})"
    return None


def _check_filters(ckpt: Path, config_path):
    """Refuse an export without ``filters.safetensors`` of a run that normalized its
    observations: its policy would act on unnormalized ones (a silently wrong result)."""
    if (ckpt / EXPORT_DIR / FILTERS_FILE).is_file():
        return
    why = _normalizes(ckpt, config_path)
    if why:
        from agents.formats import PolicyFormatError

        raise PolicyFormatError(
            f"{ckpt / EXPORT_DIR / FILTERS_FILE} is missing, but the policy was trained on "
            f"normalized observations ({why}): refused (it would act on unnormalized "
            "observations)"
        )


def _export_files(ckpt: Path) -> list:
    """The safe export's files of checkpoint ``ckpt`` (empty: none)."""
    d = ckpt / EXPORT_DIR
    return sorted(d.glob("*.safetensors")) if d.is_dir() else []


# --------------------------------------------------------------------------------------
class _LoadedRun:
    """What every beacon's policy of one checkpoint shares: modules, filters, config."""

    def __init__(self, checkpoint: Path, config_path: Path | None):
        from agents.formats import safe_yaml

        self.checkpoint = checkpoint
        self.run_config = safe_yaml(config_path) if config_path else {}
        self.run_config = self.run_config if isinstance(self.run_config, dict) else {}
        self.trained_config = _trained_scenario(self.run_config)
        self.export = checkpoint / EXPORT_DIR if _export_files(checkpoint) else None
        self._modules: dict[str, Any] = {}
        if self.export is not None:  # data only
            self.module_ids = sorted(
                f.name[: -len(".safetensors")] for f in self.export.glob("*.safetensors") if f.name != FILTERS_FILE
            )
            self.filters = read_filters(self.export / FILTERS_FILE)
        else:  # RLlib's pickle-based files: only for a trusted checkpoint (resolve checked)
            self.module_ids = sorted(d.name for d in (checkpoint / MODULE_DIR).iterdir() if d.is_dir())
            self.filters = _load_filters(checkpoint / FILTER_STATE)

    def module(self, module_id: str):
        if module_id not in self._modules and self.export is not None:
            if module_id not in self.module_ids:
                raise ValueError(
                    f"{self.checkpoint} has no module {module_id!r} (a beacon kind); "
                    f"modules: {', '.join(self.module_ids)}"
                )
            module = read_module(self.export / f"{module_id}.safetensors")
            module.eval()
            self._modules[module_id] = module
        if module_id not in self._modules:
            from ray.rllib.core.rl_module.rl_module import RLModule

            path = self.checkpoint / MODULE_DIR / module_id
            if not path.is_dir():
                raise ValueError(
                    f"{self.checkpoint} has no module {module_id!r} (a beacon kind); "
                    f"modules: {', '.join(self.module_ids)}"
                )
            previous = logging.root.manager.disable
            logging.disable(logging.WARNING)  # RLlib warns about a deprecation in its own checkpoint format
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    loaded: Any = RLModule.from_checkpoint(str(path.resolve()))  # a TorchRLModule: a torch module
                module = loaded
            finally:
                logging.disable(previous)
            module.eval()
            self._modules[module_id] = module
        return self._modules[module_id]


def _load_filters(path: Path) -> dict:
    """{agent_id: frozen ray.rllib.utils.filter.MeanStdFilter} from the checkpoint's
    MeanStdFilter connector state (empty without one)."""
    if not path.is_file():
        return {}
    from ray.rllib.utils.filter import MeanStdFilter, RunningStat

    with open(path, "rb") as f:
        state = pickle.load(f)
    filters = {}
    for agent_id, s in (state or {}).items():
        if s.get("shape") is None or not s.get("running_stats"):
            continue
        flt = MeanStdFilter(
            tuple(int(v) for v in np.atleast_1d(s["shape"])),
            demean=s["de_mean_to_zero"],
            destd=s["de_std_to_one"],
            clip=s["clip_by_value"],
        )
        flt.running_stats = RunningStat.from_state(s["running_stats"][0])
        filters[agent_id] = flt
    return filters


class FrozenMeanStd:
    """RLlib's MeanStdFilter with frozen statistics (``update=False``): the same arithmetic."""

    def __init__(self, mean: Any, std: Any, demean: bool = True, destd: bool = True, clip: float | None = 10.0) -> None:
        self.mean, self.std = np.asarray(mean), np.asarray(std)  # their dtype, as RLlib's filter has them
        self.demean, self.destd, self.clip = bool(demean), bool(destd), clip

    def __call__(self, x, update=False):
        x = np.asarray(x)
        orig_dtype = x.dtype
        if self.demean:
            x = x - self.mean
        if self.destd:
            x = x / (self.std + SMALL_NUMBER)
        if self.clip:
            x = np.clip(x, -self.clip, self.clip)
        return x.astype(orig_dtype)


# --------------------------------------------------------------------------------------
# the safe export: writing (from a trusted checkpoint) and reading (no pickle)
def _module_spec(module) -> dict:
    from agents.formats import _box, _plain

    cls = type(module)
    if cls.__name__ != "DefaultPPOTorchRLModule":
        raise ValueError(f"only DefaultPPOTorchRLModule modules can be exported, got {cls.__name__}")
    config = module.model_config
    if not isinstance(config, dict):
        import dataclasses

        config = dataclasses.asdict(config)
    return {
        "format": MODULE_FORMAT,
        "version": 1,
        "module_class": cls.__name__,
        "catalog_class": "PPOCatalog",
        "observation_space": _box(module.observation_space),
        "action_space": _box(module.action_space),
        "inference_only": bool(module.inference_only),
        "model_config": _plain(config, "model_config"),
    }


def export(checkpoint: str | Path, out_dir: str | Path | None = None) -> Path:
    """Write the safe export of a TRUSTED RLlib checkpoint (this reads its pickles) into
    ``out_dir`` (default ``<checkpoint>/policy_export``), every file atomically."""
    import json

    from safetensors.numpy import save as save_np
    from safetensors.torch import save as save_pt

    from coopnav_env.records import atomic_write_bytes

    checkpoint = Path(checkpoint)
    out_dir = Path(out_dir) if out_dir is not None else checkpoint / EXPORT_DIR
    out_dir.mkdir(parents=True, exist_ok=True)
    run = _LoadedRun.__new__(_LoadedRun)
    run.checkpoint, run._modules, run.export = checkpoint, {}, None
    run.module_ids = sorted(d.name for d in (checkpoint / MODULE_DIR).iterdir() if d.is_dir())
    for module_id in run.module_ids:
        module = run.module(module_id)
        tensors = {k: v.detach().cpu().contiguous().clone() for k, v in module.state_dict().items()}
        atomic_write_bytes(
            out_dir / f"{module_id}.safetensors",
            save_pt(tensors, metadata={"coopnav": json.dumps(_module_spec(module))}),
        )
    filters = _load_filters(checkpoint / FILTER_STATE)
    if filters:
        tensors = {}
        meta: dict[str, Any] = {"format": FILTER_FORMAT, "version": 1, "agents": {}}
        for agent_id, flt in filters.items():
            tensors[f"{agent_id}.mean"] = np.ascontiguousarray(np.asarray(flt.running_stats.mean))  # dtype kept
            tensors[f"{agent_id}.std"] = np.ascontiguousarray(np.asarray(flt.running_stats.std))
            meta["agents"][agent_id] = {
                "demean": bool(flt.demean),
                "destd": bool(flt.destd),
                "clip": None if flt.clip is None else float(flt.clip),
            }
        atomic_write_bytes(out_dir / FILTERS_FILE, save_np(tensors, metadata={"coopnav": json.dumps(meta)}))
    return out_dir


def _open_export(path: Path, framework: str, expected: str) -> tuple:
    import json

    from safetensors import safe_open

    from agents.formats import PolicyFormatError, sniff

    sniff(path)
    try:
        with safe_open(str(path), framework=framework) as f:
            meta = json.loads((f.metadata() or {}).get("coopnav", "null"))
            tensors = {k: f.get_tensor(k) for k in f.keys()}  # noqa: SIM118 - a safetensors handle has keys(), no __iter__
    except Exception as err:  # safetensors' errors vary by version
        raise PolicyFormatError(f"{path} is not a valid safetensors file ({str(err).splitlines()[0]})") from None
    if not isinstance(meta, dict) or meta.get("format") != expected:
        raise PolicyFormatError(f"{path} is not a {expected} file (no coopnav metadata)")
    return tensors, meta


def read_module(path: Path) -> Any:
    """The RLModule of an export file: DefaultPPOTorchRLModule rebuilt from its JSON, the
    tensors loaded into it (no pickle)."""
    from agents.formats import PolicyFormatError, _unbox

    tensors, spec = _open_export(path, "pt", MODULE_FORMAT)
    if spec.get("module_class") != "DefaultPPOTorchRLModule" or spec.get("catalog_class") != "PPOCatalog":
        raise PolicyFormatError(f"{path}: unsupported module class {spec.get('module_class')!r}")
    _check_module_sizes(spec, path)  # before anything is allocated
    from ray.rllib.algorithms.ppo.ppo_catalog import PPOCatalog
    from ray.rllib.algorithms.ppo.torch.default_ppo_torch_rl_module import DefaultPPOTorchRLModule

    previous = logging.root.manager.disable
    logging.disable(logging.WARNING)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            module = DefaultPPOTorchRLModule(
                observation_space=_unbox(spec["observation_space"], path),
                action_space=_unbox(spec["action_space"], path),
                inference_only=bool(spec.get("inference_only", False)),
                model_config=dict(spec.get("model_config") or {}),
                catalog_class=PPOCatalog,
            )
    finally:
        logging.disable(previous)
    try:
        module.load_state_dict(tensors, strict=True)
    except RuntimeError as err:
        raise PolicyFormatError(f"{path} does not fit the module it describes: {str(err).splitlines()[0]}") from None
    return module


def _check_module_sizes(spec: dict, path):
    from agents.formats import PolicyFormatError
    from agents.limits import LimitError, check_net_arch, check_network, check_space_size

    config = spec.get("model_config") or {}
    if not isinstance(config, dict):
        raise PolicyFormatError(f"{path}: model_config must be a mapping")
    try:
        obs = check_space_size(spec["observation_space"]["shape"], f"{path}: observation_space")
        act = check_space_size(spec["action_space"]["shape"], f"{path}: action_space")
        layers = [
            w
            for key in ("fcnet_hiddens", "head_fcnet_hiddens", "pi_head_fcnet_hiddens", "vf_head_fcnet_hiddens")
            if key in config
            for w in check_net_arch(config[key], f"{path}: model_config.{key}")
        ]
        check_network(obs, act, [[w for layer in layers for w in layer]], path)
    except (KeyError, TypeError):
        raise PolicyFormatError(f"{path}: no valid observation_space/action_space") from None
    except LimitError as err:
        raise PolicyFormatError(str(err)) from None


def read_filters(path: Path) -> dict:
    """{agent_id: FrozenMeanStd} of an export's filters file (empty without one)."""
    if not path.is_file():
        return {}
    from agents.formats import PolicyFormatError

    tensors, meta = _open_export(path, "np", FILTER_FORMAT)
    try:
        return {
            agent_id: FrozenMeanStd(
                tensors[f"{agent_id}.mean"], tensors[f"{agent_id}.std"], s["demean"], s["destd"], s["clip"]
            )
            for agent_id, s in meta["agents"].items()
        }
    except (KeyError, TypeError) as err:
        raise PolicyFormatError(f"{path}: incomplete filter statistics ({err})") from None


class RLlibPolicy(BatchPolicy):
    """One beacon's policy from an RLlib checkpoint: ``act(obs) -> action``, ``reset()``.

    ``act`` takes the beacon's observation (D,) and returns a float32 (2,) action;
    ``act_batch`` takes (M, D) observations of this beacon (e.g. M environments) and
    returns (M, 2). ``module_id`` is the beacon's kind, ``agent_id`` its name.
    """

    obs_dtype = np.float32

    def __init__(self, run: _LoadedRun, agent_index: int = 0, config: Any = None, name: str = "rllib") -> None:
        self.run = run
        self.config = config if config is not None else run.trained_config
        self.agent_index = int(agent_index)
        self.agent_id = f"beacon_{self.agent_index}"
        if self.config is not None:
            if not 0 <= self.agent_index < self.config.n_beacons:
                raise ValueError(f"agent index {agent_index} out of range for {self.config.n_beacons} beacon(s)")
            self.module_id = self.config.beacon_kinds[self.agent_index]
        elif len(run.module_ids) == 1:
            self.module_id = run.module_ids[0]
        else:
            raise ValueError(f"{run.checkpoint} has modules {run.module_ids}: pass scenario= to map beacons to them")
        self.module = run.module(self.module_id)
        self.obs_filter = run.filters.get(self.agent_id)
        self.obs_dim = int(self.module.observation_space.shape[0])
        self.name = name
        self.run_config = run.run_config

    def reset(self, seed: int | None = None) -> None:
        """Stateless: nothing to clear (the interface of baselines.Policy)."""

    def act_batch(self, obs: np.ndarray) -> np.ndarray:
        import torch
        from ray.rllib.core.columns import Columns

        obs = check_observation(obs, self.obs_dim, batch=True).astype(np.float32)  # shape and finite, one line
        if self.obs_filter is not None:
            obs = self.obs_filter(obs, update=False).astype(np.float32)
        with torch.no_grad():
            out = self.module.forward_inference({Columns.OBS: torch.from_numpy(obs)})
            dist = self.module.get_inference_action_dist_cls().from_logits(out[Columns.ACTION_DIST_INPUTS])
            action = dist.to_deterministic().sample().cpu().numpy()
        return np.clip(action.reshape(len(obs), -1), -1.0, 1.0).astype(np.float32)

    def __repr__(self):
        scen = self.config.name if self.config is not None else "?"
        return f"RLlibPolicy({self.name!r}, scenario={scen!r}, agent={self.agent_id!r}, module={self.module_id!r})"


_RUNS: dict = {}


def _run(path, scenario=None, trust_pickle=False) -> _LoadedRun:
    ckpt, _, config_path = resolve(path, scenario, trust_pickle=trust_pickle)
    marker = ckpt / CHECKPOINT_MARKER
    key = (str(ckpt.resolve()), marker.stat().st_mtime_ns)
    if key not in _RUNS:
        _RUNS[key] = _LoadedRun(ckpt, config_path)
    return _RUNS[key]


def _target(scenario):
    if scenario is None:
        return None
    from coopnav_env.scenarios import resolve_config

    return resolve_config(scenario)


def _obs_dim(config) -> int:
    """The observation size of a scenario (as agents.load checks an SB3 policy's)."""
    try:
        from coopnav_env.obs_layout import obs_dim
    except ImportError:  # an older core: one simulator
        from coopnav_env.core.sim import Simulator

        return int(Simulator(config, 1).obs_dim)
    return int(obs_dim(config))


def load(
    path: str | Path, scenario: Any = None, agent: int = 0, device: str = "cpu", trust_pickle: bool = False
) -> RLlibPolicy:
    """The policy of beacon ``agent`` (index or "beacon_k") from an RLlib checkpoint or
    run directory. With ``scenario`` (name, ScenarioConfig or env) the observation
    size is checked and the beacon's kind picks the module; without it, the scenario
    the run trained on. Refused unless ``trust_pickle`` (see the module docstring)."""
    if device != "cpu":
        raise ValueError("RLlib policies load on the CPU")
    if isinstance(agent, str):
        if not agent.startswith("beacon_") or not agent[7:].isdigit():
            raise ValueError(f"agent must be an index or 'beacon_<k>', got {agent!r}")
        agent = int(agent[7:])
    run = _run(path, scenario, trust_pickle=trust_pickle)
    target = _target(scenario)
    policy = RLlibPolicy(
        run, agent, config=target if target is not None else run.trained_config, name=Path(str(path)).name
    )
    if target is not None:
        dim = _obs_dim(target)
        if dim != policy.obs_dim:
            raise ValueError(
                f"policy {str(path)!r} takes observations of size {policy.obs_dim}; "
                f"scenario {target.name!r} gives {dim}"
            )
        trained = run.trained_config
        if trained is not None and trained.name != target.name:
            warnings.warn(
                f"policy {str(path)!r} was trained on {trained.name!r}, used on {target.name!r}", stacklevel=2
            )
    return policy


def make_policy(
    path: str | Path,
    env_or_config: Any = None,
    seed: int | Sequence[int] | None = None,
    agent: int = 0,
    trust_pickle: bool = False,
) -> RLlibPolicy:
    """``baselines.make_policy``'s signature: one policy per beacon and episode is cheap
    (the loaded modules are shared). ``seed`` is accepted for the interface."""
    return load(path, scenario=env_or_config, agent=agent, trust_pickle=trust_pickle)


def batch_actor(path: str | Path, config: Any) -> Callable[[np.ndarray, Any], np.ndarray]:
    """``act(obs (n_envs * N, D), venv) -> (n_envs * N, 2)`` for train.py's ``evaluate``:
    every beacon's rows through its kind's module, all environments at once (the
    trainer's own checkpoint, just written: trusted)."""
    policies = [load(path, scenario=config, agent=j, trust_pickle=True) for j in range(config.n_beacons)]
    N = config.n_beacons

    def act(obs: np.ndarray, venv: Any) -> np.ndarray:
        out = np.empty((len(obs), 2), dtype=np.float32)
        for j, policy in enumerate(policies):
            out[j::N] = policy.act_batch(obs[j::N])
        return out

    return act


def convert(src: str | Path, out: str | Path) -> Path:
    """``agents.convert`` of a TRUSTED RLlib run or checkpoint: a copy of it (an RLlib run
    directory stays resumable with --trust-pickle) with the safe export written into its
    checkpoint, which ``agents.load`` then reads without unpickling."""
    import shutil

    src, out = Path(src), Path(out)
    ckpt = find_checkpoint(src)
    if ckpt is None or not (ckpt / CHECKPOINT_MARKER).is_file():
        from agents.formats import PolicyFormatError

        raise PolicyFormatError(f"{src} holds no RLlib checkpoint")
    if out.is_dir() and not any(out.iterdir()):  # agents.convert allows an empty --out: copytree creates it
        out.rmdir()
    shutil.copytree(src, out, symlinks=True)
    new_ckpt = out / ckpt.relative_to(src) if ckpt != src else out
    shutil.rmtree(new_ckpt / EXPORT_DIR, ignore_errors=True)  # never keep an export that came with it
    export(new_ckpt)
    return new_ckpt
