"""coopnav under Ray RLlib's multi-agent API (new API stack): env adapter and policy mapping.

    from coopnav_env.rllib_env import CoopNavRLlibEnv, module_map, KindMapping
    config.environment(CoopNavRLlibEnv, env_config={"scenario": "sousa_asv", "seed": 0})
    kinds = module_map("sousa_asv")              # {"beacon_0": "asv"}
    config.multi_agent(policies=set(kinds.values()), policy_mapping_fn=KindMapping(kinds))

**Why an adapter and not** ``ray.rllib.env.wrappers.pettingzoo_env.ParallelPettingZooEnv``.
The adapter below still runs the PettingZoo parallel env
(:class:`coopnav_env.pettingzoo_env.CoopNavParallelEnv`) step for step; it replaces
RLlib's wrapper, which falls short here in four ways (ray 2.50-2.60):

* **Agent order.** The wrapper builds its agent ids from a ``set``, so
  ``possible_agents`` comes out in hash order, which differs between the processes
  of a cluster (string hashing is salted per process). The adapter keeps the env's
  order ``beacon_0 ... beacon_{N-1}``.
* **Spaces.** It sets only the old API stack's ``observation_space``/``action_space``
  Dicts; the adapter sets the new stack's ``observation_spaces``/``action_spaces``.
* **Seeds.** RLlib passes ``config.seed + worker_index`` at an env runner's first
  reset, and a vectorized runner's sub-env ``i`` gets ``+ i``: runner 1's first
  environment repeats runner 0's second one. The adapter seeds episodes like
  ``CoopNavVecEnv`` seeds its rows: episode ``k`` of environment copy ``c`` is
  ``seed + c + k * SEED_STRIDE``, with ``c = worker_index * num_envs_per_env_runner +
  i`` and ``i`` the copy's number among the runner's ``num_envs_per_env_runner``
  copies, so no two copies of a run share an episode (and copy ``c`` replays
  ``CoopNavVecEnv(seed=seed)``'s row ``c``, tested). An explicit ``reset(seed=s)`` is
  honoured only if the adapter was built without a seed.
* **Training reward.** train.py's YAML ``reward:`` block (``{term: weight}``,
  ``coopnav_env.vector.REWARD_TERMS``: the "std" and "penalties" signals the shipped
  SB3 policies were trained with) replaces the env's reward during training; the
  wrapper can only pass the env's reward through. The adapter computes the same
  terms with the same function as ``CoopNavVecEnv`` (``vector.training_reward``).

It also casts observations to the space's float32 and, by default, trims the infos
to ``survey_error_m`` and ``dr_error_m`` (RLlib keeps every info dict of every
step in its episodes; ``full_infos=True`` passes the env's infos unchanged).

**Policy mapping: one RLModule per beacon kind.** ``module_map`` reads the agents
and their kinds from the env (``possible_agents`` and the scenario's
``beacon_kinds``: "beacon_auv", "asv", or any kind a scenario adds, e.g. "boat"):
beacons of the same kind share one module (parameter sharing), different kinds
get different modules. The module id is the kind's name.

Everything here runs inside RLlib's env runner processes, so it lives in the
installed package (``coopnav_env``); the trainer that builds it is ``agents.training.rllib``.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np
from ray.rllib.env.multi_agent_env import MultiAgentEnv

from .pettingzoo_env import CoopNavParallelEnv
from .scenarios import ScenarioConfig, make_config
from .vector import SEED_STRIDE, check_reward_terms, training_reward

# what step returns: observations, rewards, terminations, truncations, infos, per agent
_Step = tuple[dict, dict, dict, dict, dict]

_COPIES = itertools.count()  # environment copies made in this process (a runner's sub-envs, in order)


def scenario_config(scenario: str | ScenarioConfig, overrides: Mapping[str, Any] | None = None) -> ScenarioConfig:
    """A ScenarioConfig from a name (with ``overrides``) or a ScenarioConfig."""
    if isinstance(scenario, ScenarioConfig):
        return scenario.replace(**(overrides or {})) if overrides else scenario
    return make_config(scenario, **(overrides or {}))


def module_map(scenario_or_env: Any, overrides: Mapping[str, Any] | None = None) -> dict:
    """``{agent_id: module_id}`` for a scenario (name or config) or an env: each
    beacon is mapped to the module of its kind (the module id is the kind)."""
    env = scenario_or_env
    if isinstance(env, (str, ScenarioConfig)):
        config = scenario_config(env, overrides)
        agents = [f"beacon_{i}" for i in range(config.n_beacons)]  # CoopNavParallelEnv.possible_agents
    else:
        inner = getattr(env, "par_env", env)
        config, agents = inner.config, list(inner.possible_agents)
    kinds = tuple(config.beacon_kinds)
    if len(kinds) != len(agents):
        raise ValueError(f"{len(agents)} agents but {len(kinds)} beacon kinds in scenario {config.name!r}")
    return dict(zip(agents, kinds))


def module_ids(mapping: dict) -> list:
    """The module ids of a ``module_map``, in order of first appearance."""
    return list(dict.fromkeys(mapping.values()))


class KindMapping:
    """RLlib's ``policy_mapping_fn``: agent id -> the module of its kind. A picklable
    object (it travels to every env runner), not a closure."""

    def __init__(self, mapping: dict) -> None:
        self.mapping = dict(mapping)

    def __call__(self, agent_id, episode=None, **kwargs):
        try:
            return self.mapping[agent_id]
        except KeyError:
            raise KeyError(f"no module for agent {agent_id!r}; agents: {sorted(self.mapping)}") from None

    def __repr__(self):
        return f"KindMapping({self.mapping!r})"


class CoopNavRLlibEnv(MultiAgentEnv):
    """A coopnav scenario as an RLlib ``MultiAgentEnv`` (new API stack): one
    ``CoopNavParallelEnv`` inside. See the module docstring for why not RLlib's
    ``ParallelPettingZooEnv``.

    ``env_config`` (a dict or RLlib's ``EnvContext``):

    * ``scenario``: name or ScenarioConfig (default "gao_lawnmower");
    * ``overrides``: scenario parameters (train.py's YAML ``env.overrides``);
    * ``seed``: base seed (None: random); episode ``k`` of copy ``c`` is
      ``seed + c + k * SEED_STRIDE``;
    * ``reward_terms``: ``{term: weight}`` training reward (None or {}: the env's);
    * ``full_infos``: pass the env's infos unchanged (default: only
      ``survey_error_m`` and ``dr_error_m``);
    * ``num_envs_per_env_runner``: to number the copies (default 1);
    * ``copy_index``: set the copy number explicitly (tests, benchmarks).
    """

    def __init__(self, env_config: Mapping[str, Any] | None = None) -> None:
        super().__init__()
        cfg = dict(env_config or {})
        self.env = CoopNavParallelEnv(scenario_config(cfg.get("scenario", "gao_lawnmower"), cfg.get("overrides")))
        self.config = self.env.config
        self.reward_terms = check_reward_terms(cfg.get("reward_terms"))
        self.full_infos = bool(cfg.get("full_infos", False))
        worker = int(getattr(env_config, "worker_index", 0) or 0)
        per_runner = max(int(cfg.get("num_envs_per_env_runner", 1) or 1), 1)
        if "copy_index" in cfg:
            self.copy_index = int(cfg["copy_index"])
        else:  # a runner makes its per_runner copies one after the other
            self.copy_index = worker * per_runner + next(_COPIES) % per_runner
        seed = cfg.get("seed")
        self.base_seed = None if seed is None else int(seed)
        self._episodes = 0
        self._rng = np.random.default_rng()
        self.possible_agents = list(self.env.possible_agents)
        self.agents = []
        self.observation_spaces = {a: self.env.observation_space(a) for a in self.env.possible_agents}
        self.action_spaces = {a: self.env.action_space(a) for a in self.env.possible_agents}
        # the old API stack's names, which some RLlib utilities still read
        # (ray types agent ids as Hashable; ours are str, which gymnasium's Dict wants)
        self.observation_space = gym.spaces.Dict(self.observation_spaces)  # type: ignore[arg-type]
        self.action_space = gym.spaces.Dict(self.action_spaces)  # type: ignore[arg-type]
        self.episode_seed: int | None = None
        self._err_sum, self._err_steps = 0.0, 0
        self.last_episode_survey_error_m: float | None = None  # mean survey_error_m of the last finished episode

    def next_seed(self) -> int:
        if self.base_seed is None:
            return int(self._rng.integers(2**31))
        seed = self.base_seed + self.copy_index + self._episodes * SEED_STRIDE
        self._episodes += 1
        return seed

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[dict, dict]:
        if seed is not None and self.base_seed is None:
            self.base_seed, self._episodes, self.copy_index = int(seed), 0, 0
        self.episode_seed = self.next_seed()
        self._err_sum, self._err_steps = 0.0, 0
        obs, infos = self.env.reset(seed=self.episode_seed, options=options)
        self.agents = list(self.env.agents)
        return {a: np.asarray(o, dtype=np.float32) for a, o in obs.items()}, infos

    # RLlib's MultiAgentEnv steps per-agent dicts, unlike the gymnasium.Env it derives from
    def step(self, action_dict: dict) -> _Step:  # type: ignore[override]
        obs, rewards, terms, truncs, infos = self.env.step(action_dict)
        if self.reward_terms is not None:
            rewards = self.training_reward(rewards)
        first = next(iter(infos.values()), None)
        if first is not None:
            self._err_sum += first["survey_error_m"]
            self._err_steps += 1
        if not self.env.agents and self._err_steps:
            self.last_episode_survey_error_m = self._err_sum / self._err_steps
        if not self.full_infos:
            infos = {
                a: {"survey_error_m": i["survey_error_m"], "dr_error_m": i["dr_error_m"]} for a, i in infos.items()
            }
        obs = {a: np.asarray(o, dtype=np.float32) for a, o in obs.items()}
        terms = dict(terms, __all__=all(terms.values()))
        truncs = dict(truncs, __all__=all(truncs.values()))
        self.agents = list(self.env.agents)
        return obs, rewards, terms, truncs, infos

    def training_reward(self, env_rewards: dict) -> dict:
        """``vector.training_reward``'s weighted terms for the one environment, from the
        core's StepResult of this step (``CoopNavParallelEnv.last_result``)."""
        assert self.reward_terms is not None  # step() calls this only with reward terms
        total = training_reward(self.reward_terms, self.env.last_result, self.env.sim.reward_weights)[0]
        return {a: float(total[i]) for i, a in enumerate(env_rewards)}

    def render(self) -> np.ndarray | None:  # type: ignore[override]  # RLlib's base renders nothing
        return self.env.render()

    def close(self) -> None:
        self.env.close()


def mean_std_filter(env: Any = None, spaces: Any = None, device: Any = None) -> Any:
    """``config.env_runners(env_to_module_connector=...)``: RLlib's running mean/std
    observation filter, one per agent (the YAML's ``normalize_obs: true``). Its
    statistics are saved in the checkpoint (``env_runner/env_to_module_connector``)
    and ``agents.rllib_policy`` applies them, frozen, when the policy acts."""
    from ray.rllib.connectors.env_to_module import MeanStdFilter

    return MeanStdFilter(multi_agent=True)


def _callback_base():
    from ray.rllib.callbacks.callbacks import RLlibCallback

    return RLlibCallback


class SurveyErrorMetrics(_callback_base()):  # type: ignore[misc]  # Ray's base, imported when defined
    """Logs each finished episode's mean true survey error (``survey_error_m``, the
    evaluation's score; the trained reward may be another signal) to RLlib's
    results as ``env_runners/survey_error_m`` (mean over the last 100 episodes)."""

    def on_episode_end(
        self,
        *,
        episode: Any = None,
        env_runner: Any = None,
        metrics_logger: Any = None,
        env: Any = None,
        env_index: int = 0,
        **kwargs: Any,
    ) -> None:
        try:
            inner = env.envs[env_index].unwrapped
        except (AttributeError, IndexError, TypeError):
            return
        value = getattr(inner, "last_episode_survey_error_m", None)
        if value is not None and metrics_logger is not None:
            metrics_logger.log_value("survey_error_m", float(value), reduce="mean", window=100)
