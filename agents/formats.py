"""Policy files that hold data, not code: safetensors tensors plus plain JSON.

Loading a policy, a normalization or a training checkpoint never unpickles anything:
a pickle (an SB3 ``.zip``, a VecNormalize ``.pkl``, an RLlib checkpoint) can run
arbitrary code the moment it is read, so those formats are refused unless the caller
trusts them (``trust_pickle=True``, ``--trust-pickle``); ``python -m agents.convert``
turns a trusted one into these files.

A **model file** (``model.safetensors``, ``best_model.safetensors``,
``checkpoints/ckpt_<steps>.safetensors``) is one safetensors file:

* tensors: the ``state_dict`` of the SB3 policy network (``model.policy``), under
  its own names (``mlp_extractor.policy_net.0.weight``, ``log_std``, ...), and the
  Adam optimizer's state as ``optimizer.state.<param index>.<name>`` (``step``,
  ``exp_avg``, ``exp_avg_sq``) when it was saved;
* header metadata ``coopnav``: a JSON object, what rebuilds the network
  (``format``, ``version``, ``algo``: PPO, ``policy``: MlpPolicy,
  ``observation_space``/``action_space``: Box shape, dtype, low, high,
  ``use_sde``, ``policy_kwargs``: net_arch, activation_fn by name, log_std_init,
  features_extractor_class by name (only ``EntityExtractor``, ``agents.entity``) with
  its features_extractor_kwargs (encoder, embed_dim, heads and the entity layout),
  ...), ``num_timesteps``, ``n_updates``, ``norm_obs`` (whether it was trained on
  normalized observations) and ``optimizer`` (the param_groups' scalars).

A **normalization file** (``vecnormalize.safetensors``, ...) holds VecNormalize's
running statistics: tensors ``obs_rms.mean``, ``obs_rms.var``, ``ret_rms.mean``,
``ret_rms.var`` (float64) and metadata ``coopnav``: JSON with the counts, shapes,
``clip_obs``, ``clip_reward``, ``epsilon``, ``gamma``, ``norm_obs``, ``norm_reward``.

Read the JSON of either without Python objects:
``safetensors.safe_open(path, "np").metadata()["coopnav"]``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from coopnav_env.records import atomic_write_bytes

MODEL_FORMAT = "coopnav-sb3-policy"
VECNORM_FORMAT = "coopnav-vecnormalize"
VERSION = 1
OPTIM_PREFIX = "optimizer.state."
ACTIVATIONS = {"tanh": "Tanh", "relu": "ReLU", "elu": "ELU", "leaky_relu": "LeakyReLU"}  # name -> torch.nn class
POLICY_CLASSES = ("MlpPolicy", "ActorCriticPolicy")
PICKLE_SUFFIXES = (".zip", ".pkl", ".pickle", ".pt", ".pth")

__all__ = [
    "PickleRefused",
    "PolicyFormatError",
    "build_policy",
    "check_inside",
    "convert_command",
    "sniff",
    "legacy_model_parts",
    "legacy_vecnormalize",
    "read_model",
    "read_vecnormalize",
    "refuse_pickle",
    "restore_vecnormalize",
    "save_model",
    "save_vecnormalize",
    "vecnormalize_stats",
]


class PolicyFormatError(ValueError):
    """A policy or run file that cannot be used safely (refused pickle, missing
    normalization, a path outside its directory, a damaged file): one line."""


class PickleRefused(PolicyFormatError):
    """A file that only unpickling could read, and the caller did not trust it."""


def convert_command(path: str | Path) -> str:
    """The command that converts ``path`` (its run directory, for a file of one)."""
    path = Path(path)
    for d in (path.parent, path.parent.parent):
        if path.is_file() and (d / "config.yml").is_file():
            path = d
            break
    return f"python -m agents.convert {path} --out NEW_DIR --trust-pickle"


def refuse_pickle(path: str | Path, what: str = "a pickle-based file") -> NoReturn:
    """Raise ``PickleRefused`` for ``path`` (one line naming it and --trust-pickle)."""
    verb = "" if what.startswith("are ") else "is "
    raise PickleRefused(
        f"{path} {verb}{what}, which can run code when loaded: refused; if you trust it, pass "
        f"--trust-pickle (agents.load(..., trust_pickle=True)) or convert it once with: "
        f"{convert_command(str(path).split(' and ')[0])}"
    )


def check_inside(base: str | Path, path: str | Path, what: str = "a path") -> Path:
    """``path`` (relative to ``base`` unless absolute), resolved; a ``PolicyFormatError``
    if it leaves ``base`` (``..``, an absolute path, a symbolic link pointing out)."""
    base_r = Path(base).resolve()
    target = (Path(base) / path).resolve()
    if target != base_r and base_r not in target.parents:
        raise PolicyFormatError(f"{what} {str(path)!r} points outside {base}: refused")
    return target


# ----------------------------------------------------------------------------------
# JSON helpers
# ----------------------------------------------------------------------------------
def _num(x):
    x = float(x)
    return x if math.isfinite(x) else ("inf" if x > 0 else "-inf" if x < 0 else "nan")


def _box(space) -> dict:
    from gymnasium import spaces

    if not isinstance(space, spaces.Box):
        raise PolicyFormatError(f"only Box spaces can be saved, got {space}")
    return {
        "type": "Box",
        "shape": [int(s) for s in space.shape],
        "dtype": str(np.dtype(space.dtype)),
        "low": [_num(v) for v in np.ravel(space.low)],
        "high": [_num(v) for v in np.ravel(space.high)],
    }


def _unbox(d: dict, where):
    from gymnasium import spaces

    try:
        if d["type"] != "Box":
            raise ValueError(f"space type {d['type']!r}")
        shape = tuple(int(s) for s in d["shape"])
        dtype = np.dtype(d["dtype"])
        low = np.array([float(v) for v in d["low"]], dtype=dtype).reshape(shape)
        high = np.array([float(v) for v in d["high"]], dtype=dtype).reshape(shape)
        return spaces.Box(low=low, high=high, shape=shape, dtype=dtype)
    except (KeyError, TypeError, ValueError) as err:
        raise PolicyFormatError(f"{where}: bad space {d!r} ({err})") from None


def _plain(value, where: str):
    """``value`` if it is JSON data (numbers, strings, bools, None, lists, dicts)."""
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, (list, tuple)):
        return [_plain(v, where) for v in value]
    if isinstance(value, dict):
        return {str(k): _plain(v, where) for k, v in value.items()}
    if isinstance(value, (np.integer, np.floating, np.bool_)):
        return value.item()
    raise PolicyFormatError(f"{where} = {value!r} cannot be saved as plain data")


def _extractors() -> dict:
    """The features extractors a model file may name (``features_extractor_class``): name -> class."""
    from .entity import EntityExtractor

    return {"EntityExtractor": EntityExtractor}


def policy_kwargs_json(kwargs: dict) -> dict:
    """SB3 ``policy_kwargs`` as JSON: activation_fn and features_extractor_class by name,
    the rest plain data."""
    import torch.nn as nn

    out = {}
    for key, value in (kwargs or {}).items():
        if key == "features_extractor_class":
            names = {cls: name for name, cls in _extractors().items()}
            if value not in names:
                raise PolicyFormatError(
                    f"policy_kwargs.features_extractor_class {getattr(value, '__name__', value)!r} is not one of "
                    f"{', '.join(_extractors())}"
                )
            out[key] = names[value]
        elif key == "activation_fn":
            names = {getattr(nn, cls): name for name, cls in ACTIVATIONS.items()}
            if value not in names:
                raise PolicyFormatError(f"policy_kwargs.activation_fn {value!r} is not one of {', '.join(ACTIVATIONS)}")
            out[key] = names[value]
        else:
            out[key] = _plain(value, f"policy_kwargs.{key}")
    return out


def policy_kwargs_python(kwargs: dict | None, where: str | Path) -> dict:
    import torch.nn as nn

    out = dict(kwargs or {})
    if "activation_fn" in out:
        if out["activation_fn"] not in ACTIVATIONS:
            raise PolicyFormatError(f"{where}: unknown activation_fn {out['activation_fn']!r}")
        out["activation_fn"] = getattr(nn, ACTIVATIONS[out["activation_fn"]])
    if "features_extractor_class" in out:  # by name, from a fixed list: a file never names code to run
        extractors = _extractors()
        if out["features_extractor_class"] not in extractors:
            raise PolicyFormatError(
                f"{where}: unknown features_extractor_class {out['features_extractor_class']!r}; "
                f"valid: {', '.join(extractors)}"
            )
        out["features_extractor_class"] = extractors[out["features_extractor_class"]]
        extractor_kwargs = out.get("features_extractor_kwargs") or {}
        if not isinstance(extractor_kwargs, dict):
            raise PolicyFormatError(f"{where}: features_extractor_kwargs must be a mapping")
        from .entity import check_encoder_kwargs

        try:
            check_encoder_kwargs(**extractor_kwargs)
        except (TypeError, ValueError) as err:
            raise PolicyFormatError(f"{where}: features_extractor_kwargs: {_first_line(err)}") from None
    return out


# ----------------------------------------------------------------------------------
# saving
# ----------------------------------------------------------------------------------
def model_spec(model: Any, norm_obs: bool | None = None) -> dict:
    """The JSON that rebuilds ``model``'s policy network (an SB3 PPO)."""
    from stable_baselines3.common.policies import ActorCriticPolicy

    if type(model.policy) is not ActorCriticPolicy:
        raise PolicyFormatError(
            f"only MlpPolicy (ActorCriticPolicy) networks can be saved, got {type(model.policy).__name__}"
        )
    return {
        "format": MODEL_FORMAT,
        "version": VERSION,
        "algo": "PPO",
        "policy": "MlpPolicy",
        "observation_space": _box(model.observation_space),
        "action_space": _box(model.action_space),
        "use_sde": bool(model.use_sde),
        "policy_kwargs": policy_kwargs_json(model.policy_kwargs),
        "num_timesteps": int(model.num_timesteps),
        "n_updates": int(getattr(model, "_n_updates", 0)),
        "norm_obs": None if norm_obs is None else bool(norm_obs),
    }


def _optimizer_parts(optimizer) -> tuple:
    """(tensors, JSON) of a torch optimizer's state_dict."""
    import torch

    sd = optimizer.state_dict()
    tensors: dict = {}
    state: dict = {}
    for idx, entries in sd["state"].items():
        state[str(idx)] = {}
        for name, value in entries.items():
            if isinstance(value, torch.Tensor):
                tensors[f"{OPTIM_PREFIX}{idx}.{name}"] = value.detach().cpu().contiguous().clone()
                state[str(idx)][name] = "tensor"
            else:
                state[str(idx)][name] = _plain(value, f"optimizer state {name}")
    groups = [_plain(g, "optimizer param_groups") for g in sd["param_groups"]]
    return tensors, {"class": type(optimizer).__name__, "param_groups": groups, "state": state}


def model_bytes(model: Any, norm_obs: bool | None = None, optimizer: bool = True) -> bytes:
    """The model file of an SB3 PPO ``model`` (see the module docstring)."""
    from safetensors.torch import save

    spec = model_spec(model, norm_obs)
    tensors = {k: v.detach().cpu().contiguous().clone() for k, v in model.policy.state_dict().items()}
    if optimizer and getattr(model.policy, "optimizer", None) is not None:
        opt_tensors, spec["optimizer"] = _optimizer_parts(model.policy.optimizer)
        tensors.update(opt_tensors)
    return save(tensors, metadata={"coopnav": json.dumps(spec)})


def save_model(model: Any, path: str | Path, norm_obs: bool | None = None, optimizer: bool = True) -> None:
    """Write ``model``'s model file to ``path`` atomically."""
    atomic_write_bytes(Path(path), model_bytes(model, norm_obs, optimizer))


def vecnormalize_stats(vecnorm: Any) -> dict:
    """The running statistics and settings of a VecNormalize, as plain numbers/arrays."""
    obs_rms = getattr(vecnorm, "obs_rms", None)  # SB3 keeps none with norm_obs=False
    if isinstance(obs_rms, dict):
        raise PolicyFormatError("VecNormalize of a Dict observation space cannot be saved")
    if obs_rms is None:  # not normalized: the identity's statistics, never used (norm_obs is false)
        shape = tuple(vecnorm.observation_space.shape)
        obs_mean, obs_var, obs_count = np.zeros(shape), np.ones(shape), 0.0
    else:
        obs_mean, obs_var, obs_count = obs_rms.mean, obs_rms.var, obs_rms.count
    return {
        "obs_mean": np.asarray(obs_mean, np.float64),
        "obs_var": np.asarray(obs_var, np.float64),
        "obs_count": float(obs_count),
        "ret_mean": np.asarray(vecnorm.ret_rms.mean, np.float64),
        "ret_var": np.asarray(vecnorm.ret_rms.var, np.float64),
        "ret_count": float(vecnorm.ret_rms.count),
        "clip_obs": float(vecnorm.clip_obs),
        "clip_reward": float(vecnorm.clip_reward),
        "epsilon": float(vecnorm.epsilon),
        "gamma": float(vecnorm.gamma),
        "norm_obs": bool(vecnorm.norm_obs),
        "norm_reward": bool(vecnorm.norm_reward),
    }


def vecnormalize_bytes(stats: dict) -> bytes:
    from safetensors.numpy import save

    tensors = {
        "obs_rms.mean": np.ascontiguousarray(stats["obs_mean"].reshape(-1)),
        "obs_rms.var": np.ascontiguousarray(stats["obs_var"].reshape(-1)),
        "ret_rms.mean": np.ascontiguousarray(np.reshape(stats["ret_mean"], -1)),
        "ret_rms.var": np.ascontiguousarray(np.reshape(stats["ret_var"], -1)),
    }
    meta = {
        "format": VECNORM_FORMAT,
        "version": VERSION,
        "obs_shape": list(np.shape(stats["obs_mean"])),
        "ret_shape": list(np.shape(stats["ret_mean"])),
        **{
            k: stats[k]
            for k in (
                "obs_count",
                "ret_count",
                "clip_obs",
                "clip_reward",
                "epsilon",
                "gamma",
                "norm_obs",
                "norm_reward",
            )
        },
    }
    return save(tensors, metadata={"coopnav": json.dumps(meta)})


def save_vecnormalize(vecnorm: Any, path: str | Path) -> None:
    """Write a VecNormalize's statistics (or a ``vecnormalize_stats`` dict) to ``path`` atomically."""
    stats = vecnorm if isinstance(vecnorm, dict) else vecnormalize_stats(vecnorm)
    atomic_write_bytes(Path(path), vecnormalize_bytes(stats))


# ----------------------------------------------------------------------------------
# loading (no pickle)
# ----------------------------------------------------------------------------------
def sniff(path: str | Path) -> None:
    """Refuse ``path`` if its name or its first bytes say pickle or zip (SB3's format);
    reads two bytes, never unpickles."""
    path = Path(path)
    if path.suffix in PICKLE_SUFFIXES:
        refuse_pickle(path)
    try:
        with path.open("rb") as f:
            head = f.read(2)
    except OSError as err:
        raise PolicyFormatError(f"cannot read {path}: {err.strerror or err}") from None
    if head[:1] == b"\x80" or head[:2] == b"PK":  # a pickle (protocol 2+) or a zip archive
        raise PickleRefused(
            f"{path} should be a safetensors file but holds a pickle or a zip archive, which can "
            "run code when loaded: refused, even with --trust-pickle (convert a trusted original "
            "with: python -m agents.convert SRC --out NEW_DIR --trust-pickle)"
        )


def _open(path, framework: str, expected: str) -> tuple:
    """(tensors, metadata JSON) of a safetensors file; a one-line error for anything else."""
    from safetensors import safe_open

    path = Path(path)
    sniff(path)
    try:
        with safe_open(str(path), framework=framework) as f:
            meta = (f.metadata() or {}).get("coopnav")
            tensors = {k: f.get_tensor(k) for k in f.keys()}  # noqa: SIM118 - a safetensors handle has keys(), no __iter__
    except Exception as err:  # safetensors' errors vary by version
        raise PolicyFormatError(f"{path} is not a valid safetensors file ({_first_line(err)})") from None
    from coopnav_env.safe_load import loads_json

    try:
        spec = loads_json(meta, f"{path} header", max_bytes=16 << 20) if meta is not None else None
    except ValueError:
        spec = None
    if not isinstance(spec, dict) or spec.get("format") != expected:
        raise PolicyFormatError(f"{path} is not a {expected} file (no coopnav metadata)")
    if not isinstance(spec.get("version", 0), int) or spec.get("version", 0) > VERSION:
        raise PolicyFormatError(
            f"{path}: {expected} version {spec.get('version')} is newer than this code reads ({VERSION})"
        )
    return tensors, spec


def read_model(path: str | Path) -> tuple:
    """(spec JSON, policy state_dict, optimizer state_dict or None) of a model file."""
    tensors, spec = _open(path, "pt", MODEL_FORMAT)
    policy = {k: v for k, v in tensors.items() if not k.startswith(OPTIM_PREFIX)}
    optim = None
    if spec.get("optimizer"):
        o = spec["optimizer"]
        state = {}
        for idx, entries in o.get("state", {}).items():
            state[int(idx)] = {
                name: (tensors[f"{OPTIM_PREFIX}{idx}.{name}"] if value == "tensor" else value)
                for name, value in entries.items()
            }
        groups = []
        for g in o.get("param_groups", []):
            g = dict(g)
            if isinstance(g.get("betas"), list):
                g["betas"] = tuple(g["betas"])
            groups.append(g)
        optim = {"state": state, "param_groups": groups}
    return spec, policy, optim


def build_policy(
    spec: dict, state: dict | None = None, where: str | Path = "model", device: str = "cpu", learning_rate: Any = 0.0
) -> Any:
    """The SB3 ActorCriticPolicy ``spec`` describes, with ``state`` loaded (strict)."""
    from stable_baselines3.common.policies import ActorCriticPolicy

    if spec.get("policy") not in POLICY_CLASSES:
        raise PolicyFormatError(f"{where}: unsupported policy class {spec.get('policy')!r}")
    _check_header_sizes(spec, where)  # before anything is allocated
    kwargs = policy_kwargs_python(spec.get("policy_kwargs"), where)
    try:
        policy = ActorCriticPolicy(
            _unbox(spec["observation_space"], where),
            _unbox(spec["action_space"], where),
            lambda _: float(learning_rate),
            use_sde=bool(spec.get("use_sde", False)),
            **kwargs,
        )
    except (TypeError, ValueError, KeyError) as err:
        raise PolicyFormatError(f"{where}: cannot rebuild the network ({_first_line(err)})") from None
    if state is not None:
        load_policy_state(policy, state, where)
    policy.to(device)
    policy.set_training_mode(False)
    return policy


def _check_header_sizes(spec: dict, where):
    from .limits import LimitError, check_net_arch, check_network, check_space_size

    try:
        obs = check_space_size(spec["observation_space"]["shape"], f"{where}: observation_space")
        act = check_space_size(spec["action_space"]["shape"], f"{where}: action_space")
        kwargs = spec.get("policy_kwargs") or {}
        if not isinstance(kwargs, dict):
            raise PolicyFormatError(f"{where}: policy_kwargs must be a mapping")
        check_network(obs, act, check_net_arch(kwargs.get("net_arch"), f"{where}: net_arch"), where)
    except (KeyError, TypeError):
        raise PolicyFormatError(f"{where}: no valid observation_space/action_space") from None
    except LimitError as err:
        raise PolicyFormatError(str(err)) from None


def safe_yaml(path: str | Path) -> Any:
    """A run's YAML file, bounded (``coopnav_env.safe_load``); a ``PolicyFormatError`` else."""
    from coopnav_env.safe_load import UnsafeDataError, read_yaml

    try:
        return read_yaml(path)
    except UnsafeDataError as err:
        raise PolicyFormatError(str(err)) from None


def safe_json(path: str | Path) -> Any:
    """A run's JSON file, bounded (``coopnav_env.safe_load``); a ``PolicyFormatError`` else."""
    from coopnav_env.safe_load import UnsafeDataError, read_json

    try:
        return read_json(path)
    except UnsafeDataError as err:
        raise PolicyFormatError(str(err)) from None


def load_policy_state(policy: Any, state: dict, where: str | Path) -> None:
    try:
        policy.load_state_dict(state, strict=True)
    except RuntimeError as err:
        raise PolicyFormatError(f"{where} does not fit the network: {_first_line(err)}") from None


def read_vecnormalize(path: str | Path) -> dict:
    """A normalization file -> ``vecnormalize_stats``'s dict."""
    tensors, meta = _open(path, "np", VECNORM_FORMAT)
    try:
        stats = {
            "obs_mean": tensors["obs_rms.mean"].reshape(meta["obs_shape"]),
            "obs_var": tensors["obs_rms.var"].reshape(meta["obs_shape"]),
            "ret_mean": tensors["ret_rms.mean"].reshape(meta["ret_shape"]),
            "ret_var": tensors["ret_rms.var"].reshape(meta["ret_shape"]),
        }
        for key in ("obs_count", "ret_count", "clip_obs", "clip_reward", "epsilon", "gamma"):
            stats[key] = float(meta[key])
        for key in ("norm_obs", "norm_reward"):
            stats[key] = bool(meta[key])
    except (KeyError, ValueError, TypeError) as err:
        raise PolicyFormatError(f"{path}: incomplete normalization statistics ({_first_line(err)})") from None
    return stats


def restore_vecnormalize(vecnorm: Any, stats: dict) -> Any:
    """Put ``stats`` into a VecNormalize (its running statistics; training mode kept;
    the observation's only where it normalizes observations)."""
    shape = tuple(vecnorm.observation_space.shape)
    if tuple(np.shape(stats["obs_mean"])) != shape:
        raise PolicyFormatError(
            f"normalization statistics of shape {np.shape(stats['obs_mean'])} do not fit observations of shape {shape}"
        )
    if getattr(vecnorm, "obs_rms", None) is not None:
        vecnorm.obs_rms.mean, vecnorm.obs_rms.var = stats["obs_mean"].copy(), stats["obs_var"].copy()
        vecnorm.obs_rms.count = stats["obs_count"]
    for key, name in (("ret_mean", "mean"), ("ret_var", "var")):
        value = stats[key]
        setattr(vecnorm.ret_rms, name, np.float64(value) if np.ndim(value) == 0 else np.array(value, np.float64))
    vecnorm.ret_rms.count = stats["ret_count"]
    return vecnorm


# ----------------------------------------------------------------------------------
# the old pickle formats: only for a caller who trusts the file
# ----------------------------------------------------------------------------------
def legacy_model(path: str | Path, device: str = "cpu") -> Any:
    """An SB3 model .zip (``PPO.load``: UNPICKLES; call only for a trusted file)."""
    from stable_baselines3 import PPO

    try:
        return PPO.load(str(path), device=device)
    except (MemoryError, OSError):  # the machine's, not the file's: as they are
        raise
    except Exception as err:  # a corrupt or foreign zip: SB3 and torch raise anything (an assert, an unpickling error)
        raise PolicyFormatError(f"{path}: not a stable-baselines3 model .zip ({_first_line(err)})") from None


def legacy_vecnormalize(path: str | Path) -> dict:
    """A VecNormalize .pkl (UNPICKLES; call only for a trusted file) -> stats dict."""
    import pickle

    with open(path, "rb") as f:
        try:
            vecnorm = pickle.load(f)  # the caller trusts this file (--trust-pickle)
        except (MemoryError, OSError):
            raise
        except Exception as err:  # truncated, empty or not a pickle
            raise PolicyFormatError(f"{path}: not a VecNormalize pickle ({_first_line(err)})") from None
    if not hasattr(vecnorm, "observation_space"):
        raise PolicyFormatError(f"{path}: not a VecNormalize pickle (it holds a {type(vecnorm).__name__})")
    return vecnormalize_stats(vecnorm)


def legacy_model_parts(path: str | Path, norm_obs: bool | None = None, device: str = "cpu") -> tuple:
    """(spec, policy state_dict, optimizer state_dict) of a trusted SB3 .zip."""
    model = legacy_model(path, device)
    spec = model_spec(model, norm_obs)
    return spec, model.policy.state_dict(), model.policy.optimizer.state_dict()


def _first_line(err) -> str:
    return str(err).splitlines()[0] if str(err) else type(err).__name__


# --- which pickle-based files the caller trusted, for this process ----------------------
_TRUSTED: set = set()  # pickle-based files the caller trusted (trust_pickle=True) in this process


def trust_pickle(*paths: str | Path | None) -> None:
    """Trust these pickle-based files (resolved paths) for the rest of the process, as
    ``trust_pickle=True`` does for the files it resolves."""
    for path in paths:
        if path is not None:
            _TRUSTED.add(str(Path(path).resolve()))


def _is_legacy(path) -> bool:
    return path is not None and Path(path).suffix != ".safetensors"


def _check_trusted(paths, trusted: bool):
    """Refuse the pickle-based ones of ``paths`` unless ``trusted`` (then remember them),
    and safe-format files that hold a pickle or a zip archive instead."""
    for path in paths:
        if path is not None and not _is_legacy(path) and Path(path).is_file():
            sniff(path)
    legacy = [p for p in paths if _is_legacy(p)]
    if trusted:
        trust_pickle(*legacy)
        return
    untrusted = [str(p) for p in legacy if str(Path(p).resolve()) not in _TRUSTED]
    if untrusted:
        refuse_pickle(
            " and ".join(untrusted), "a pickle-based file" if len(untrusted) == 1 else "are pickle-based files"
        )
