"""A stable-baselines3 ``VecEnv`` over the batched core, for parameter-shared training.

    from coopnav_env.vector import CoopNavVecEnv
    venv = CoopNavVecEnv("sousa_asv", n_envs=64, seed=0)
    obs = venv.reset()                           # (64 * n_beacons, obs_dim) float32

Every beacon of every environment is one row: ``num_envs = n_envs * n_beacons`` and
row ``e * n_beacons + j`` is ``beacon_j`` of environment ``e``, so one policy drives
all beacons (parameter sharing). The rows of one environment finish together.

One ``step`` is ONE call of ``Simulator.step`` on the whole batch; the only Python
loop over the batch builds SB3's list of info dicts.

**Seeds.** Episode ``k`` (0, 1, ...) of environment ``e`` is seeded with
``seed + e + k * SEED_STRIDE``. Environment ``e`` therefore starts exactly like
``coopnav_env.parallel_env(scenario, seed=seed + e)`` (the core's random numbers
are counter-based per environment, so the transitions are identical, not only
alike), every later episode is reproducible from ``episode_seeds``, and the same
``seed`` reproduces the same run. ``seed(s)`` restarts the count at the next
``reset()``; ``reset()`` without a new seed starts the next episodes.

**Auto-reset.** When environment ``e`` ends (terminated or truncated), its rows
carry ``done=True``, ``info["terminal_observation"]`` (the last observation of
the episode) and ``info["TimeLimit.truncated"]`` (True when the episode was cut by
``max_cycles`` and not terminated, so PPO bootstraps the value there); the
observation returned is the first one of its next episode. Every row's info has
the env's info keys (see ``coopnav_env.views.agent_infos``).

**Actions**: ``(num_envs, 2)`` (``(num_envs, 3)`` with ``channel_mode="decide"``:
the third component > 0 transmits this slot); finite out-of-range values are clipped to
[-1, 1]; NaN or infinite values and wrong shapes raise ``ValueError`` naming the
environment and beacon (``views.check_action``'s rules).

**Domain randomization** is the core's: the scenario parameters
``randomize_survey_path``, ``randomize_depth_m`` and ``randomize_noise_scale``
(with the current's spreads) make every episode draw its path kind, depth and
noise scale from its own seed, inside the one ``Simulator``
(``core.sim.Simulator._initial_state``). ``episode_cells()`` (or
``get_attr("episode_cell")``) tells the (survey_path, depth_m) each environment's
current episode drew.

**Training reward** (``reward_terms``, train.py's YAML ``reward:``). By default a
row's reward is the environment's (the survey EKF's information gain minus
penalties). ``reward_terms={"error": 1.0, "penalties": 1.0}`` replaces it, for
training only, by a weighted sum of training signals, each computed from the step's
arrays: ``env``, ``error``, ``std``, ``logdet``, ``penalties``, ``rejected``. They are
registered in ``core.reward`` (kind ``"training"``, beside the environment's terms),
which documents each one (the table in the docs is generated from the registry);
``REWARD_TERMS``, ``check_reward_terms`` and ``training_reward`` here are the
registry's.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from stable_baselines3.common.vec_env import VecEnv
from stable_baselines3.common.vec_env.base_vec_env import VecEnvIndices, VecEnvObs, VecEnvStepReturn

from .core import make_simulator
from .core.reward import check_training_terms, training_reward, training_signal_names
from .scenarios import make_config
from .seeds import TRAINING_SEED_STRIDE, EpisodeSeeds
from .views import action_space, observation_space

if TYPE_CHECKING:
    from .scenarios import ScenarioConfig

SEED_STRIDE = TRAINING_SEED_STRIDE  # 1_000_003, a prime larger than any batch: episode k of env e -> seed + e + k * it
check_reward_terms = check_training_terms  # {signal: weight} validated against the registry


def __getattr__(name: str) -> tuple:
    if name == "REWARD_TERMS":  # the registered training signals (core.reward, kind "training")
        return training_signal_names()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


class CoopNavVecEnv(VecEnv):
    """``n_envs`` environments of ``scenario``, one row per beacon. See the module docstring.

    Arguments: ``scenario`` (name or ``ScenarioConfig``), ``n_envs``, ``seed`` (None: a
    random base seed), ``step_infos`` (False: only the rows whose episode ends get
    infos, at that step; building the dicts of every row is about a third of the
    step's time at 128 environments, and PPO reads none of them), ``reward_terms``
    (None: the environment's reward; else ``{term: weight}``, see the module
    docstring), and any scenario parameter by keyword (``randomize_depth_m=...``
    and the other randomization bounds included).
    """

    # VecEnv declares metadata an instance attribute (dict[str, Any]; its __init__ sets it): a ClassVar would not match
    metadata: dict[str, Any] = {"render_modes": []}  # noqa: RUF012
    action_space: spaces.Box
    observation_space: spaces.Box

    def __init__(
        self,
        scenario: str | ScenarioConfig = "gao_lawnmower",
        n_envs: int = 1,
        seed: int | None = None,
        step_infos: bool = True,
        reward_terms: Mapping[str, float] | None = None,
        **overrides: Any,
    ) -> None:
        if isinstance(n_envs, bool) or not isinstance(n_envs, (int, np.integer)) or n_envs < 1:
            raise ValueError(f"n_envs must be an int >= 1, got {n_envs!r}")
        n_envs = int(n_envs)
        self.config = make_config(scenario, **overrides)
        self.reward_terms = check_reward_terms(reward_terms)
        self.sim = make_simulator(self.config, n_envs)
        self.n_envs = n_envs
        self.n_beacons = self.sim.N
        self.obs_dim = self.sim.obs_dim
        self.render_mode = None
        self.possible_agents = [f"beacon_{j}" for j in range(self.n_beacons)]
        super().__init__(n_envs * self.n_beacons, observation_space(self.sim), action_space(self.sim))
        self._schedule = EpisodeSeeds(n_envs)  # based by self.seed() below
        self.episode_seeds = self._schedule.current  # seed of each current episode
        self.step_infos = bool(step_infos)
        self._actions: np.ndarray | None = None
        self._started = False
        self.seed(seed)

    def episode_cells(self) -> list:
        """(survey_path, depth_m) of each environment's current episode (what the core's
        randomization drew; the scenario's own values without randomization)."""
        return [self.sim.variants[v] for v in self.sim.episode_variants().tolist()]

    # ------------------------------------------------------------------------------
    def seed(self, seed: int | None = None) -> Sequence[int | None]:
        """Base seed for the episodes started from the next ``reset()`` on (None: random).
        Returns the first episode's seed of every row."""
        base = self._schedule.restart(seed)
        self._started = False
        return [base + e for e in range(self.n_envs) for _ in range(self.n_beacons)]

    def _next_seeds(self, envs: np.ndarray) -> np.ndarray:
        return self._schedule.next(envs)

    def reset(self) -> VecEnvObs:
        """Start a new episode in every environment; returns (num_envs, obs_dim)."""
        obs = self.sim.reset(self._next_seeds(np.arange(self.n_envs)))
        self._started = True
        self._actions = None
        self.reset_infos = self._row_infos(
            self.sim.reset_info(), self.sim.reset_beacon_info(), np.zeros(self.n_envs, dtype=bool)
        )
        self._reset_seeds()
        self._reset_options()
        self._last_obs = obs.reshape(self.num_envs, self.obs_dim)
        return self._last_obs

    # ------------------------------------------------------------------------------
    def check_actions(self, actions: np.ndarray) -> np.ndarray:
        """``actions`` (num_envs, D) as float64 (n_envs, n_beacons, D), clipped to [-1, 1]; D
        is the action space's 2, or 3 with ``channel_mode="decide"`` (which also takes D = 2,
        the motion alone: transmit every slot)."""
        try:
            a = np.asarray(actions, dtype=np.float64)
        except (TypeError, ValueError) as err:
            raise ValueError(f"actions are not numeric: {type(actions).__name__}") from err
        dim = self.action_space.shape[0]
        if a.shape != (self.num_envs, dim) and not (dim == 3 and a.shape == (self.num_envs, 2)):
            raise ValueError(
                f"actions must have shape ({self.num_envs}, {dim}) (one row per beacon of every "
                f"environment), got shape {a.shape}"
            )
        finite = np.isfinite(a).all(axis=1)
        if not finite.all():
            row = int(np.flatnonzero(~finite)[0])
            e, j = divmod(row, self.n_beacons)
            raise ValueError(f"action for env {e} beacon_{j} (row {row}) must be finite, got {a[row].tolist()}")
        if a.shape[1] != dim:  # the motion alone: transmit, as the fixed clock does
            a = np.concatenate([a, np.ones((self.num_envs, 1))], 1)
        return np.clip(a, -1.0, 1.0).reshape(self.n_envs, self.n_beacons, dim)

    def step_async(self, actions: np.ndarray) -> None:
        if not self._started:
            raise RuntimeError("step_async() before reset()")
        self._actions = self.check_actions(actions)

    def step_wait(self) -> VecEnvStepReturn:
        if self._actions is None:
            raise RuntimeError("step_wait() without a pending step_async()")
        actions, self._actions = self._actions, None
        res = self.sim.step(actions)
        obs, term, trunc, info = res.obs, res.terminated, res.truncated, res.info
        reward = res.reward if self.reward_terms is None else self.training_reward(res)
        done = term | trunc
        if self.step_infos:
            infos = self._row_infos(info, res.beacon_info, trunc & ~term)
        else:
            infos = [{} for _ in range(self.num_envs)]
        if done.any():
            ended = np.flatnonzero(done)
            if not self.step_infos:  # the final step's infos, on the rows that end
                full = self._row_infos(
                    {k: v[ended] for k, v in info.items()},
                    {k: v[ended] for k, v in res.beacon_info.items()},
                    (trunc & ~term)[ended],
                )
                for i, e in enumerate(ended.tolist()):
                    infos[e * self.n_beacons : (e + 1) * self.n_beacons] = full[
                        i * self.n_beacons : (i + 1) * self.n_beacons
                    ]
            final = obs[ended]  # a copy: the rows are overwritten by the reset below
            for i, e in enumerate(ended.tolist()):
                for j in range(self.n_beacons):
                    infos[e * self.n_beacons + j]["terminal_observation"] = final[i, j]
            obs = self.sim.reset(self._next_seeds(ended), done)
        self._last_obs = obs.reshape(self.num_envs, self.obs_dim)
        return (
            self._last_obs,
            reward.reshape(-1).astype(np.float32),
            np.repeat(done, self.n_beacons),
            infos,
        )

    def training_reward(self, res: Any) -> np.ndarray:
        """The weighted sum of ``reward_terms`` for this step, (n_envs, n_beacons); ``res``
        the core's StepResult. Only with ``reward_terms`` (else the step's reward is the env's)."""
        if self.reward_terms is None:
            raise ValueError("training_reward() needs reward_terms; without them the reward is the environment's")
        return training_reward(self.reward_terms, res, self.sim.reward_weights)

    def _row_infos(self, info: dict, beacon_info: dict, time_limit: np.ndarray) -> list:
        """One info dict per row: ``views.agent_infos`` of its environment and beacon
        (the aggregates computed for the whole batch at once) plus ``TimeLimit.truncated``."""
        columns = {}
        for key in self.sim.info_keys:
            v = info[key]
            if v.ndim > 2:  # a vector per survey vehicle
                columns[key] = v.tolist()
                continue
            if key == "range_ok":
                agg = v.any(axis=1)
            elif v.dtype.kind in "iub":
                agg = v.sum(axis=1)
            else:
                agg = v.mean(axis=1)
            columns[key] = agg.tolist()
            columns[key + "_per_vehicle"] = v.tolist()
        columns["TimeLimit.truncated"] = time_limit.tolist()
        keys = list(columns)
        per_env = [dict(zip(keys, values)) for values in zip(*columns.values())]
        rows = []
        for e, d in enumerate(per_env):
            for j in range(self.n_beacons):
                row = dict(d)
                row.update({k: float(v[e, j]) for k, v in beacon_info.items()})
                rows.append(row)
        return rows

    # ------------------------------------------------------------------------------
    def global_state(self) -> np.ndarray:
        """The true global state of every environment, (n_envs, state_dim), for centralized critics."""
        return self.sim.global_state()

    def close(self) -> None:
        self._actions = None

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [None] * self.num_envs

    def _row_envs(self, indices) -> list:
        return [int(i) // self.n_beacons for i in self._get_indices(indices)]

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """Per row: ``episode_seed`` its episode's seed, ``episode_cell`` its episode's
        (survey_path, depth_m), ``agent`` its beacon name, ``env_index`` its environment's
        row in ``sim`` (the batch row of ``sim.snapshot()``), ``flat_observation`` its last
        observation (the flat vector, under a wrapper such as ``EntityVecEnv`` too: what a
        planner reads); anything else (``config`` and ``sim`` included) is the VecEnv's own
        attribute."""
        envs = self._row_envs(indices)
        if attr_name == "env_index":
            return envs
        if attr_name == "flat_observation":
            if getattr(self, "_last_obs", None) is None:
                raise RuntimeError("flat_observation before reset()")
            return [self._last_obs[int(i)] for i in self._get_indices(indices)]
        if attr_name == "episode_cell":
            cells = self.episode_cells()
            return [cells[e] for e in envs]
        if attr_name == "episode_seed":
            return [int(self.episode_seeds[e]) for e in envs]
        if attr_name == "agent":
            return [self.possible_agents[int(i) % self.n_beacons] for i in self._get_indices(indices)]
        if not hasattr(self, attr_name):
            raise AttributeError(f"{type(self).__name__} has no attribute {attr_name!r}")
        value = getattr(self, attr_name)
        return [value for _ in envs]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Rows share one simulator: only attributes of the whole VecEnv can be set."""
        rows = list(self._get_indices(indices))
        if sorted(int(i) for i in rows) != list(range(self.num_envs)):
            raise ValueError("the rows of CoopNavVecEnv share one simulator: set_attr applies to all rows only")
        setattr(self, attr_name, value)

    def env_method(
        self, method_name: str, *method_args: Any, indices: VecEnvIndices = None, **method_kwargs: Any
    ) -> list[Any]:
        """Calls the VecEnv's method ``method_name`` once and returns its result for each row."""
        rows = list(self._get_indices(indices))
        method = getattr(self, method_name, None)
        if not callable(method):
            raise AttributeError(f"{type(self).__name__} has no method {method_name!r}")
        result = method(*method_args, **method_kwargs)
        return [result for _ in rows]

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]
