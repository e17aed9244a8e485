"""The entity observation (``coopnav_env.entity_obs``) on the views: wrappers over the
one core, so the flat vector stays what the existing policies read.

    from coopnav_env.entity_views import EntityVecEnv, MixedTeamVecEnv, entity_parallel_env
    venv = EntityVecEnv(CoopNavVecEnv("gao_sea", n_envs=8, seed=0))     # rows (8 * N, ENTITY_DIM)
    env = entity_parallel_env("gao_team", seed=0)                       # PettingZoo, obs (ENTITY_DIM,)
    mixed = MixedTeamVecEnv("swarm_mls", teams=[{}, {"n_survey": 5},
                            {"beacon_kinds": ["beacon_auv", "beacon_auv"]}], n_envs=12, seed=0)

* ``EntityVecEnv``: a ``CoopNavVecEnv`` whose rows (and ``terminal_observation``
  infos) are entity observations; row ``e * N + j`` is beacon j of environment e, as
  underneath, and beacon j's role input says so.
* ``MixedTeamVecEnv``: several teams of one scenario family behind one SB3 VecEnv, for
  training one policy on every team at once (the team makeup randomized over the
  batch). ``teams`` is a list of team overrides: any scenario parameter (``n_survey``,
  ``beacon_kinds``, and settings one simulator holds for all its rows, such as
  ``ping_interval_s`` or the channel's ``packet_loss_near``/``far``: a second value is a
  second team; {}: the scenario's own team). The rows are entity observations, or with
  ``observation="flat"`` the flat vector, for teams whose flat observations have one size
  (a flat policy takes one team makeup, but may see several settings). The ``n_envs``
  environments are dealt to the teams in turn
  (team i gets ``n_envs // T`` plus one of the remainder for i < ``n_envs % T``), so the
  number of rows is fixed: the sum over teams of environments x beacons.
  **Seeds**: the environments are numbered through the teams in order (g = 0 ..
  n_envs - 1) and environment g plays episode k with seed ``seed + g + k *
  SEED_STRIDE``, the numbering of one ``CoopNavVecEnv``: the same ``seed`` reproduces
  the run, and no two environments share a seed.
* ``entity_parallel_env``: the PettingZoo ``ParallelEnv`` (batch of one) with entity
  observations; everything else (actions, rewards, infos, ``state()``) is the env's.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np
from pettingzoo.utils.wrappers import BaseParallelWrapper
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper
from stable_baselines3.common.vec_env.base_vec_env import VecEnvIndices, VecEnvObs, VecEnvStepReturn

from .entity_obs import (
    MAX_BEACONS,
    MAX_SURVEY,
    MAX_TEAMS,
    TEAM_KEYS,
    check_team,
    entity_observation,
    entity_space,
    row_agents,
)
from .scenarios import make_config
from .vector import CoopNavVecEnv

if TYPE_CHECKING:
    from gymnasium import spaces

    from .scenarios import ScenarioConfig

VIEWS = ("entities", "flat")  # MixedTeamVecEnv's observation

__all__ = ["MAX_TEAMS", "TEAM_KEYS", "EntityParallelEnv", "EntityVecEnv", "MixedTeamVecEnv", "entity_parallel_env"]


class EntityVecEnv(VecEnvWrapper):
    """A ``CoopNavVecEnv`` seen through the entity observation (see the module docstring).
    ``ValueError`` for a scenario the entity view cannot read (``entity_obs.check_team``)."""

    venv: CoopNavVecEnv

    def __init__(self, venv: CoopNavVecEnv) -> None:
        check_team(venv.config)
        super().__init__(venv, observation_space=entity_space())
        self.config = venv.config
        self.n_beacons = venv.n_beacons
        self.agents_of_rows = row_agents(venv.num_envs, venv.n_beacons)

    def convert(self, obs: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """Flat rows (of ``rows``, default all) -> entity rows."""
        agents = self.agents_of_rows if rows is None else self.agents_of_rows[rows]
        return entity_observation(obs, self.config, agents)

    def reset(self) -> VecEnvObs:
        return self.convert(np.asarray(self.venv.reset()))

    def step_wait(self) -> VecEnvStepReturn:
        obs, reward, done, infos = self.venv.step_wait()
        ended = [i for i, info in enumerate(infos) if "terminal_observation" in info]
        if ended:
            rows = np.array(ended)
            final = self.convert(np.stack([infos[i]["terminal_observation"] for i in ended]), rows)
            for k, i in enumerate(ended):
                infos[i]["terminal_observation"] = final[k]
        return self.convert(np.asarray(obs)), reward, done, infos


def _check_team(team: Any, i: int) -> dict:
    if not isinstance(team, Mapping):
        raise ValueError(f"teams[{i}] must be a mapping of scenario parameters ({{}}: the scenario's), got {team!r}")
    return {k: tuple(v) if isinstance(v, list) else v for k, v in team.items()}


class MixedTeamVecEnv(VecEnv):
    """Teams of one scenario behind one VecEnv (see the module docstring). Arguments:
    ``scenario``, ``teams`` (scenario overrides per team; at most ``MAX_TEAMS``),
    ``n_envs`` (environments in all, at least one per team), ``seed``, ``step_infos``,
    ``reward_terms`` and scenario ``overrides`` as ``CoopNavVecEnv``'s, and
    ``observation`` (``"entities"``, or ``"flat"`` for teams of one observation size).
    ``get_attr("config")`` and ``get_attr("agent")`` say which team's scenario and which
    beacon each row is."""

    # VecEnv declares metadata an instance attribute (its __init__ sets it)
    metadata: dict[str, Any] = {"render_modes": []}  # noqa: RUF012

    def __init__(
        self,
        scenario: str | ScenarioConfig,
        teams: Sequence[Mapping[str, Any]],
        n_envs: int,
        seed: int | None = None,
        step_infos: bool = False,
        reward_terms: Mapping[str, float] | None = None,
        observation: str = "entities",
        **overrides: Any,
    ) -> None:
        if observation not in VIEWS:
            raise ValueError(f"observation must be one of {', '.join(VIEWS)}, got {observation!r}")
        entities = observation == "entities"
        if isinstance(teams, (str, bytes, Mapping)) or not isinstance(teams, Sequence) or not teams:
            raise ValueError(f"teams must be a non-empty list of team overrides, got {teams!r}")
        if len(teams) > MAX_TEAMS:
            raise ValueError(f"at most MAX_TEAMS={MAX_TEAMS} teams, got {len(teams)}")
        if isinstance(n_envs, bool) or not isinstance(n_envs, (int, np.integer)) or n_envs < len(teams):
            raise ValueError(f"n_envs must be an int >= the number of teams ({len(teams)}), got {n_envs!r}")
        team_overrides = [_check_team(t, i) for i, t in enumerate(teams)]
        self.configs = []
        for i, t in enumerate(team_overrides):
            try:
                config = make_config(scenario, **{**overrides, **t})
                if entities:
                    check_team(config)
            except (TypeError, ValueError) as err:
                hint = f" (entity teams: n_survey 1-{MAX_SURVEY}, 1-{MAX_BEACONS} beacons)" if entities else ""
                raise ValueError(f"teams[{i}] {t}: {err}{hint}") from None
            self.configs.append(config)
        counts = [int(n_envs) // len(teams) + (i < int(n_envs) % len(teams)) for i in range(len(teams))]
        self.team_envs = counts
        self.teams = team_overrides
        self.observation = observation
        subs: list[Any] = [
            CoopNavVecEnv(c, n_envs=n, seed=0, step_infos=step_infos, reward_terms=reward_terms)
            for c, n in zip(self.configs, counts)
        ]
        if entities:
            subs = [EntityVecEnv(s) for s in subs]
        else:
            sizes = [s.observation_space.shape for s in subs]
            if len(set(sizes)) > 1:
                raise ValueError(
                    f"the teams' flat observations differ in size ({sizes}): a flat policy takes one team "
                    "makeup; vary n_survey or beacon_kinds with observation='entities'"
                )
        self.subs = subs
        dims = {tuple(s.action_space.shape or ()) for s in self.subs}
        if len(dims) > 1:
            raise ValueError(f"the teams' action spaces differ ({sorted(dims)}): one scenario family only")
        self.config = self.configs[0]
        self.env_offsets = np.cumsum([0, *counts[:-1]]).tolist()  # first global environment of each team
        rows = [s.num_envs for s in self.subs]
        self.row_offsets = np.cumsum([0, *rows]).tolist()
        self.render_mode = None
        space = entity_space() if entities else self.subs[0].observation_space
        super().__init__(int(sum(rows)), space, self.subs[0].action_space)
        self.seed(seed)

    def _simulator(self, t: int) -> CoopNavVecEnv:
        sub = self.subs[t]
        return sub.venv if isinstance(sub, EntityVecEnv) else sub

    # ------------------------------------------------------------------------------
    def seed(self, seed: int | None = None) -> Sequence[int | None]:
        """Base seed for the episodes from the next ``reset()`` on (None: random):
        environment g (counted through the teams) plays episode k with ``seed + g + k *
        SEED_STRIDE``. Returns each row's first episode seed."""
        if seed is None:
            seed = int(np.random.SeedSequence().generate_state(1, dtype=np.uint32)[0] >> 1)
        out: list[int | None] = []
        for t, offset in enumerate(self.env_offsets):
            out += list(self._simulator(t).seed(int(seed) + offset))
        self._base_seed = int(seed)
        return out

    @property
    def episode_seeds(self) -> np.ndarray:
        """Each environment's current episode seed, in the global numbering."""
        return np.concatenate([self._simulator(t).episode_seeds for t in range(len(self.subs))])

    def reset(self) -> VecEnvObs:
        return np.concatenate([s.reset() for s in self.subs])

    def step_async(self, actions: np.ndarray) -> None:
        a = np.asarray(actions)
        if a.ndim != 2 or a.shape[0] != self.num_envs:
            dim = self.action_space.shape[0] if self.action_space.shape else 0
            raise ValueError(f"actions must have shape ({self.num_envs}, {dim}), got {a.shape}")
        for sub, lo, hi in zip(self.subs, self.row_offsets[:-1], self.row_offsets[1:]):
            sub.step_async(a[lo:hi])

    def step_wait(self) -> VecEnvStepReturn:
        parts = [s.step_wait() for s in self.subs]
        obs = np.concatenate([p[0] for p in parts])
        reward = np.concatenate([p[1] for p in parts])
        done = np.concatenate([p[2] for p in parts])
        infos = [info for p in parts for info in p[3]]
        return obs, reward, done, infos

    def close(self) -> None:
        for s in self.subs:
            s.close()

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [None] * self.num_envs

    # ------------------------------------------------------------------------------
    def _where(self, indices: VecEnvIndices) -> list:
        """(team, row in the team) of each row of ``indices``."""
        out = []
        for i in self._get_indices(indices):
            t = int(np.searchsorted(self.row_offsets, int(i), side="right")) - 1
            out.append((t, int(i) - self.row_offsets[t]))
        return out

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """Per row: the attribute of its team's ``CoopNavVecEnv`` row (``episode_seed``,
        ``episode_cell``, ``agent``, ``config``, ...)."""
        where = self._where(indices)
        by_team: dict[int, list[int]] = {}
        for t, r in where:
            by_team.setdefault(t, []).append(r)
        # one call per team (imitation reads every row's flat vector each step)
        values = {t: iter(self.subs[t].get_attr(attr_name, rows)) for t, rows in by_team.items()}
        return [next(values[t]) for t, _ in where]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """The rows share their teams' simulators: only attributes of every row can be set."""
        if sorted(int(i) for i in self._get_indices(indices)) != list(range(self.num_envs)):
            raise ValueError("the rows of MixedTeamVecEnv share simulators: set_attr applies to all rows only")
        for s in self.subs:
            s.set_attr(attr_name, value)

    def env_method(
        self, method_name: str, *method_args: Any, indices: VecEnvIndices = None, **method_kwargs: Any
    ) -> list[Any]:
        """Calls each team's ``method_name`` once; each row gets its team's result."""
        results = {}
        out = []
        for t, _ in self._where(indices):
            if t not in results:
                results[t] = self.subs[t].env_method(method_name, *method_args, indices=[0], **method_kwargs)[0]
            out.append(results[t])
        return out

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]


class EntityParallelEnv(BaseParallelWrapper):
    """A ``CoopNavParallelEnv`` whose observations are entity observations (beacon_j's
    with role j); ``ValueError`` for a scenario the entity view cannot read."""

    def __init__(self, env: Any) -> None:
        check_team(env.config)
        super().__init__(env)
        self._space = entity_space()
        self._index = {a: j for j, a in enumerate(env.possible_agents)}

    def observation_space(self, agent: str) -> spaces.Box:
        return self._space

    def _convert(self, obs: dict) -> dict:
        if not obs:
            return {}
        agents = list(obs)
        flat = entity_observation(np.stack([obs[a] for a in agents]), self.env.config, [self._index[a] for a in agents])
        return dict(zip(agents, flat))

    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[dict, dict]:
        obs, infos = self.env.reset(seed=seed, options=options)
        return self._convert(obs), infos

    def step(self, actions: Any) -> tuple:
        obs, rewards, terms, truncs, infos = self.env.step(actions)
        return self._convert(obs), rewards, terms, truncs, infos


def entity_parallel_env(scenario: str | ScenarioConfig = "gao_lawnmower", **kwargs: Any) -> EntityParallelEnv:
    """``coopnav_env.parallel_env(scenario, **kwargs)`` with entity observations."""
    from . import parallel_env

    return EntityParallelEnv(parallel_env(scenario, **kwargs))
