"""Trained beacon policies, with the same interface as the baselines.

    import agents
    policy = agents.load("ppo_sousa_asv")            # a policy shipped in agents/policies/
    policy = agents.load("ppo", scenario="sousa_asv")  # the shipped PPO policy of a scenario
    policy = agents.load("ppo", scenario="gao_lawnmower")  # -> ppo_gao_sea (SHARED_POLICIES)
    policy = agents.load("runs/sousa_ppo")           # a run directory written by train.py
    policy.reset()
    action = policy.act(obs["beacon_0"])             # one beacon's observation -> (2,) in [-1, 1]

A policy directory (a train.py run, or ``agents/policies/<name>/``) holds the SB3
model, its VecNormalize statistics and the config it was trained with:

    config.yml                       written by train.py (scenario, hyperparameters, command)
    best_model.zip + best_vecnormalize.pkl   preferred when present (the best evaluated)
    model.zip + vecnormalize.pkl             else the final model
    checkpoints/last_checkpoint.json         else the last checkpoint (an unfinished run)

Actions are deterministic (the mean of PPO's Gaussian, clipped to [-1, 1]), and the
policy has no memory, so ``reset`` only exists for the interface.

A directory with a ``gate.yml`` instead holds two such policy directories and a gate
on the survey vehicle's depth below the beacon, as the observation gives it
(``DepthGatedPolicy``): ``{kind: depth_gate, threshold_m: 12.5, shallow: <dir>,
deep: <dir>}``, the directories relative to the gate file.

A run of ``train.py --backend rllib`` (its directory, its ``checkpoint/``, or any RLlib
Algorithm checkpoint) loads the same way, through ``agents/rllib_policy.py`` (which
imports Ray only then): ``agents.load("runs/x_rllib", scenario=...)``.
"""

from __future__ import annotations

import json
import pickle
import warnings
from pathlib import Path

import numpy as np

from .policy import BatchPolicy, _trained_scenario

POLICY_DIR = Path(__file__).resolve().parent / "policies"
# "ppo" of a scenario without a policy of its own: the shipped policy of a sister
# scenario with the same observation layout (gao_lawnmower: the lake trial of the
# gao_sea policy's sea trial; same vehicles, smaller area, weaker current).
SHARED_POLICIES = {"gao_lawnmower": "ppo_gao_sea"}

__all__ = ["DepthGatedPolicy", "PPOPolicy", "list_policies", "load", "make_policy", "resolve"]


def list_policies() -> list:
    """Names of the policies shipped in agents/policies/."""
    if not POLICY_DIR.is_dir():
        return []
    return sorted(p.name for p in POLICY_DIR.iterdir()
                  if p.is_dir() and ((p / "gate.yml").is_file() or _model_files(p) is not None))


def _model_files(directory: Path):
    """(model zip, vecnormalize pickle) of a policy directory, or None."""
    for model, stats in (("best_model.zip", "best_vecnormalize.pkl"), ("model.zip", "vecnormalize.pkl")):
        if (directory / model).is_file():
            return directory / model, directory / stats
    last = directory / "checkpoints" / "last_checkpoint.json"
    if last.is_file():
        info = json.loads(last.read_text())
        return directory / "checkpoints" / info["model"], directory / "checkpoints" / info["vecnormalize"]
    return None


def resolve(name_or_path, scenario=None) -> tuple:
    """(model zip, vecnormalize pickle or None, config.yml or None) for a name or path
    (for an RLlib run: (checkpoint directory, None, config.yml or None))."""
    from . import rllib_policy

    if rllib_policy.is_rllib_path(name_or_path):
        return rllib_policy.resolve(name_or_path, scenario)
    path = Path(str(name_or_path))
    if path.suffix == ".zip" and path.is_file():
        stem = path.name[:-4]
        candidates = [path.with_name(stem + "_vecnormalize.pkl"),
                      path.with_name("best_vecnormalize.pkl" if stem == "best_model" else "vecnormalize.pkl")]
        stats = next((c for c in candidates if c.is_file()), None)
        config = next((d / "config.yml" for d in (path.parent, path.parent.parent) if (d / "config.yml").is_file()), None)
        return path, stats, config
    if path.is_dir():
        directory = path
    else:
        name = str(name_or_path)
        if name == "ppo":
            if scenario is None:
                raise ValueError("agents.load('ppo') names the shipped PPO policy of a scenario: pass scenario=")
            scen = _scenario_name(scenario)
            name = f"ppo_{scen}"
            if not (POLICY_DIR / name).is_dir() and scen in SHARED_POLICIES:
                name = SHARED_POLICIES[scen]
        directory = POLICY_DIR / name
        if not directory.is_dir():
            shipped = list_policies()
            raise ValueError(f"no policy {name_or_path!r}: not a run directory, a .zip file or a shipped policy "
                             f"(shipped: {', '.join(shipped) if shipped else 'none yet'})")
    if (directory / "gate.yml").is_file():  # two policies and a gate: DepthGatedPolicy
        return directory / "gate.yml", None, None
    files = _model_files(directory)
    if files is None:
        raise ValueError(f"{directory} holds no model (best_model.zip, model.zip or a checkpoint)")
    model, stats = files
    config = directory / "config.yml"
    return model, (stats if stats.is_file() else None), (config if config.is_file() else None)


def _scenario_name(scenario) -> str:
    return scenario if isinstance(scenario, str) else scenario.name


class PPOPolicy(BatchPolicy):
    """A trained SB3 policy for one beacon: ``act(obs) -> action``, ``reset()``.

    ``act`` takes one beacon's observation (D,) and returns a float32 (2,) action;
    ``act_batch`` takes (M, D) and returns (M, 2). Observations are normalized with
    the run's frozen VecNormalize statistics before the network sees them.
    """

    def __init__(self, model, obs_rms=None, clip_obs=10.0, epsilon=1e-8, config=None, run_config=None, name="ppo"):
        self.model = model
        self.obs_rms = obs_rms
        self.clip_obs = float(clip_obs)
        self.epsilon = float(epsilon)
        self.config = config  # the ScenarioConfig it was trained on (None if unknown)
        self.run_config = run_config or {}
        self.name = name
        self.obs_dim = int(model.observation_space.shape[0])

    def reset(self, seed=None):
        """Stateless: nothing to clear (the interface of baselines.Policy)."""

    def normalize(self, obs: np.ndarray) -> np.ndarray:
        if self.obs_rms is None:
            return obs.astype(np.float32)
        z = (obs - self.obs_rms.mean) / np.sqrt(self.obs_rms.var + self.epsilon)
        return np.clip(z, -self.clip_obs, self.clip_obs).astype(np.float32)

    def act_batch(self, obs) -> np.ndarray:
        obs = np.asarray(obs, dtype=np.float64)
        if obs.ndim != 2 or obs.shape[1] != self.obs_dim:
            raise ValueError(f"observations must have shape (M, {self.obs_dim}), got {obs.shape}")
        action, _ = self.model.predict(self.normalize(obs), deterministic=True)
        return np.clip(action, -1.0, 1.0).astype(np.float32)

    def __repr__(self):
        scen = self.config.name if self.config is not None else "?"
        return f"PPOPolicy({self.name!r}, scenario={scen!r})"


def load(name_or_path, scenario=None, device="cpu") -> PPOPolicy:
    """A trained policy by shipped name ("ppo_sousa_asv"; "ppo" with ``scenario``), run
    directory, or model .zip. With ``scenario`` (name or ScenarioConfig) its
    observation size is checked against the policy's."""
    from . import rllib_policy

    if rllib_policy.is_rllib_path(name_or_path):  # train.py --backend rllib
        return rllib_policy.load(name_or_path, scenario=scenario, device=device)
    import yaml
    from stable_baselines3 import PPO

    model_path, stats_path, config_path = resolve(name_or_path, scenario)
    if model_path.name == "gate.yml":
        return _load_gated(model_path, scenario, device, name=Path(str(name_or_path)).name)
    model = PPO.load(model_path, device=device)
    obs_rms, clip_obs, epsilon = None, 10.0, 1e-8
    if stats_path is not None:
        with open(stats_path, "rb") as f:
            vecnorm = pickle.load(f)
        if getattr(vecnorm, "norm_obs", True):
            obs_rms = vecnorm.obs_rms
        clip_obs, epsilon = vecnorm.clip_obs, vecnorm.epsilon
    run_config, trained_config = {}, None
    if config_path is not None:
        run_config = yaml.safe_load(config_path.read_text()) or {}
        trained_config = _trained_scenario(run_config)
    policy = PPOPolicy(model, obs_rms, clip_obs, epsilon, config=trained_config, run_config=run_config,
                       name=Path(str(name_or_path)).name)
    if scenario is not None:
        from coopnav_env.obs_layout import obs_dim
        from coopnav_env.scenarios import make_config

        target = make_config(scenario) if isinstance(scenario, str) else scenario
        dim = obs_dim(target)
        if dim != policy.obs_dim:
            raise ValueError(f"policy {name_or_path!r} takes observations of size {policy.obs_dim}; "
                             f"scenario {target.name!r} gives {dim}")
        if trained_config is not None and trained_config.name != target.name:
            warnings.warn(f"policy {name_or_path!r} was trained on {trained_config.name!r}, used on {target.name!r}",
                          stacklevel=2)
        if trained_config is None:
            policy.config = target
    return policy


class DepthGatedPolicy(BatchPolicy):
    """Two trained policies and a fixed gate: ``shallow`` acts where the survey vehicle's
    depth below the beacon (its last reply, as the observation gives it; the mean over
    survey vehicles) is below ``threshold_m``, ``deep`` elsewhere. Both see the same
    observation; the gate is part of the policy, written in its gate.yml."""

    def __init__(self, shallow, deep, threshold_m: float, name="gated"):
        if shallow.obs_dim != deep.obs_dim:
            raise ValueError(f"gated policies must take the same observation: {shallow.obs_dim} != {deep.obs_dim}")
        if not np.isfinite(threshold_m):
            raise ValueError(f"threshold_m must be finite, got {threshold_m!r}")
        self.shallow, self.deep, self.threshold_m, self.name = shallow, deep, float(threshold_m), name
        self.obs_dim = deep.obs_dim
        self.config = deep.config if deep.config is not None else shallow.config

    def reset(self, seed=None):
        self.shallow.reset(seed)
        self.deep.reset(seed)

    def act_batch(self, obs) -> np.ndarray:
        from coopnav_env.obs_layout import decode

        obs = np.asarray(obs, dtype=np.float64)
        if obs.ndim != 2 or obs.shape[1] != self.obs_dim:
            raise ValueError(f"observations must have shape (M, {self.obs_dim}), got {obs.shape}")
        depth = decode(obs, self.config).depth_below_m.mean(-1)
        out = self.deep.act_batch(obs)
        shallow = depth < self.threshold_m
        if shallow.any():
            out[shallow] = self.shallow.act_batch(obs[shallow])
        return out

    def __repr__(self):
        return f"DepthGatedPolicy({self.name!r}, below {self.threshold_m} m: {self.shallow!r}, else {self.deep!r})"


def _load_gated(gate_path: Path, scenario, device, name):
    import yaml

    spec = yaml.safe_load(gate_path.read_text()) or {}
    if spec.get("kind") != "depth_gate" or not {"threshold_m", "shallow", "deep"} <= set(spec):
        raise ValueError(f"{gate_path}: expected kind: depth_gate with threshold_m, shallow and deep")
    parts = [load(gate_path.parent / spec[k], scenario=scenario, device=device) for k in ("shallow", "deep")]
    return DepthGatedPolicy(*parts, threshold_m=float(spec["threshold_m"]), name=name)


_CACHE: dict = {}


def make_policy(name_or_path, env_or_config=None, seed=None, agent=0) -> PPOPolicy:
    """``baselines.make_policy``'s signature for trained policies: one policy per beacon
    and episode is cheap, since the loaded model is shared (cached by resolved path).
    ``seed`` and ``agent`` are accepted for the interface; the policy ignores them
    (deterministic, and parameter-shared across beacons)."""
    from . import rllib_policy

    if rllib_policy.is_rllib_path(name_or_path):  # one module per beacon kind: the agent matters
        return rllib_policy.make_policy(name_or_path, env_or_config, seed=seed, agent=agent)
    scenario = None
    if env_or_config is not None:
        from coopnav_env.scenarios import resolve_config

        scenario = resolve_config(env_or_config)
    model_path, _, _ = resolve(name_or_path, scenario)
    key = (str(Path(model_path).resolve()), Path(model_path).stat().st_mtime_ns,
           None if scenario is None else scenario)
    if key not in _CACHE:
        _CACHE[key] = load(name_or_path, scenario=scenario)
    base = _CACHE[key]
    if isinstance(base, DepthGatedPolicy):  # stateless: one instance serves every beacon and episode
        return base
    return PPOPolicy(base.model, base.obs_rms, base.clip_obs, base.epsilon, config=base.config,
                     run_config=base.run_config, name=base.name)
