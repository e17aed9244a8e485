"""A stable-baselines3 ``VecEnv`` over the batched core, for parameter-shared training.

    from coopnav_env.vector import CoopNavVecEnv
    venv = CoopNavVecEnv("sousa_asv", n_envs=64, seed=0)
    obs = venv.reset()                           # (64 * n_beacons, obs_dim) float32

Every beacon of every environment is one row: ``num_envs = n_envs * n_beacons`` and
row ``e * n_beacons + j`` is ``beacon_j`` of environment ``e``, so one policy drives
all beacons (parameter sharing). The rows of one environment finish together.

One ``step`` is ONE call of ``Simulator.step`` on the whole batch (per variant, see
below); the only Python loop over the batch builds SB3's list of info dicts.

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

**Actions**: ``(num_envs, 2)``; finite out-of-range values are clipped to
[-1, 1]; NaN or infinite values and wrong shapes raise ``ValueError`` naming the
environment and beacon (``views.check_action``'s rules).

**Variants (a stop-gap for domain randomization).** ``variants`` is a list of
scenario-parameter overrides (e.g. every depth x path of Sousa's Tables I-II);
the environments are split among them as evenly as possible, one ``Simulator``
per variant, environment ``e`` keeping its variant for the whole run. The
per-episode draws the core already makes (current within its spread, noise,
start bearing) stay per episode. Each variant costs one more ``Simulator.step``
call per step; true per-episode randomization needs per-environment parameters in
the core (see the issue 4 notes).
"""

from __future__ import annotations

import itertools

import numpy as np
from stable_baselines3.common.vec_env import VecEnv

from .core.sim import INFO_KEYS, Simulator
from .scenarios import make_config
from .views import action_space, observation_space

SEED_STRIDE = 1_000_003  # a prime larger than any batch: episode k of env e -> seed + e + k * SEED_STRIDE


def variant_grid(grid: dict | None) -> list:
    """The Cartesian product of ``{parameter: [values]}`` as a list of override dicts
    (``{"depth_m": [1, 5], "survey_path": ["circle"]}`` -> two variants)."""
    if not grid:
        return []
    names = list(grid)
    for name in names:
        if not isinstance(grid[name], (list, tuple)) or not grid[name]:
            raise ValueError(f"variant grid entry {name!r} must be a non-empty list of values")
    return [dict(zip(names, values)) for values in itertools.product(*(grid[n] for n in names))]


class CoopNavVecEnv(VecEnv):
    """``n_envs`` environments of ``scenario``, one row per beacon. See the module docstring.

    Arguments: ``scenario`` (name or ``ScenarioConfig``), ``n_envs``, ``seed`` (None: a
    random base seed), ``variants`` (list of override dicts, or None), ``step_infos``
    (False: only the rows whose episode ends get infos, at that step; building the
    dicts of every row is about a third of the step's time at 128 environments, and
    PPO reads none of them), and any scenario parameter by keyword (applied before
    the variants).
    """

    metadata = {"render_modes": []}

    def __init__(self, scenario="gao_lawnmower", n_envs: int = 1, seed=None, variants=None, step_infos: bool = True,
                 **overrides):
        if isinstance(n_envs, bool) or not isinstance(n_envs, (int, np.integer)) or n_envs < 1:
            raise ValueError(f"n_envs must be an int >= 1, got {n_envs!r}")
        n_envs = int(n_envs)
        base = make_config(scenario, **overrides)
        configs = [base.replace(**dict(v)) for v in variants] if variants else [base]
        if n_envs < len(configs):
            raise ValueError(f"n_envs ({n_envs}) must be at least the number of variants ({len(configs)})")
        sizes = [n_envs // len(configs) + (g < n_envs % len(configs)) for g in range(len(configs))]
        self.sims = [Simulator(cfg, b) for cfg, b in zip(configs, sizes)]
        dims = {(s.obs_dim, s.N, s.S) for s in self.sims}
        if len(dims) != 1:
            raise ValueError("all variants must keep n_survey, beacon_kinds and observed_waypoints "
                             f"(observation sizes differ: {sorted(dims)})")
        self.config = base
        self.configs = configs
        self.variants = [dict(v) for v in variants] if variants else []
        self.n_envs = n_envs
        self.n_beacons = self.sims[0].N
        self.obs_dim = self.sims[0].obs_dim
        self._slices = []
        start = 0
        for b in sizes:
            self._slices.append(slice(start, start + b))
            start += b
        self.env_variant = np.repeat(np.arange(len(configs)), sizes)  # variant index of each environment
        self.render_mode = None
        self.possible_agents = [f"beacon_{j}" for j in range(self.n_beacons)]
        super().__init__(n_envs * self.n_beacons, observation_space(self.sims[0]), action_space())
        self._base_seed = None
        self._episode = np.zeros(n_envs, dtype=np.int64)  # episodes started per environment
        self.episode_seeds = np.full(n_envs, -1, dtype=np.int64)  # seed of each current episode
        self.step_infos = bool(step_infos)
        self._actions = None
        self._started = False
        self.seed(seed)

    # ------------------------------------------------------------------------------
    def seed(self, seed=None):
        """Base seed for the episodes started from the next ``reset()`` on (None: random).
        Returns the first episode's seed of every row."""
        if seed is None:
            seed = int(np.random.SeedSequence().generate_state(1, dtype=np.uint32)[0] >> 1)
        self._base_seed = int(seed)
        self._episode[:] = 0
        self._started = False
        return [self._base_seed + e for e in range(self.n_envs) for _ in range(self.n_beacons)]

    def _next_seeds(self, envs: np.ndarray) -> np.ndarray:
        seeds = self._base_seed + envs + self._episode[envs] * SEED_STRIDE
        self._episode[envs] += 1
        self.episode_seeds[envs] = seeds
        return seeds

    def reset(self):
        """Start a new episode in every environment; returns (num_envs, obs_dim)."""
        seeds = self._next_seeds(np.arange(self.n_envs))
        obs = np.concatenate([sim.reset(seeds[sl]) for sim, sl in zip(self.sims, self._slices)])
        self._started = True
        self._actions = None
        self.reset_infos = [{} for _ in range(self.num_envs)]
        self._reset_seeds()
        self._reset_options()
        return obs.reshape(self.num_envs, self.obs_dim)

    # ------------------------------------------------------------------------------
    def check_actions(self, actions) -> np.ndarray:
        """``actions`` (num_envs, 2) as float64 (n_envs, n_beacons, 2), clipped to [-1, 1]."""
        try:
            a = np.asarray(actions, dtype=np.float64)
        except (TypeError, ValueError) as err:
            raise ValueError(f"actions are not numeric: {type(actions).__name__}") from err
        if a.shape != (self.num_envs, 2):
            raise ValueError(f"actions must have shape ({self.num_envs}, 2) (one row per beacon of every "
                             f"environment), got shape {a.shape}")
        finite = np.isfinite(a).all(axis=1)
        if not finite.all():
            row = int(np.flatnonzero(~finite)[0])
            e, j = divmod(row, self.n_beacons)
            raise ValueError(f"action for env {e} beacon_{j} (row {row}) must be finite, got {a[row].tolist()}")
        return np.clip(a, -1.0, 1.0).reshape(self.n_envs, self.n_beacons, 2)

    def step_async(self, actions):
        if not self._started:
            raise RuntimeError("step_async() before reset()")
        self._actions = self.check_actions(actions)

    def step_wait(self):
        if self._actions is None:
            raise RuntimeError("step_wait() without a pending step_async()")
        actions, self._actions = self._actions, None
        if len(self.sims) == 1:
            res = self.sims[0].step(actions)
            obs, reward, term, trunc, info = res.obs, res.reward, res.terminated, res.truncated, res.info
        else:
            parts = [sim.step(actions[sl]) for sim, sl in zip(self.sims, self._slices)]
            obs = np.concatenate([p.obs for p in parts])
            reward = np.concatenate([p.reward for p in parts])
            term = np.concatenate([p.terminated for p in parts])
            trunc = np.concatenate([p.truncated for p in parts])
            info = {k: np.concatenate([p.info[k] for p in parts]) for k in INFO_KEYS}
        done = term | trunc
        if self.step_infos:
            infos = self._row_infos(info, trunc & ~term)
        else:
            infos = [{} for _ in range(self.num_envs)]
        if done.any():
            ended = np.flatnonzero(done)
            if not self.step_infos:  # the final step's infos, on the rows that end
                full = self._row_infos({k: v[ended] for k, v in info.items()}, (trunc & ~term)[ended])
                for i, e in enumerate(ended.tolist()):
                    infos[e * self.n_beacons:(e + 1) * self.n_beacons] = full[i * self.n_beacons:(i + 1) * self.n_beacons]
            final = obs[ended]  # a copy: the rows are overwritten by the reset below
            for i, e in enumerate(ended.tolist()):
                for j in range(self.n_beacons):
                    infos[e * self.n_beacons + j]["terminal_observation"] = final[i, j]
            seeds = self._next_seeds(ended)
            obs = obs.copy()
            for sim, sl in zip(self.sims, self._slices):
                mask = done[sl]
                if mask.any():
                    obs[sl][mask] = sim.reset(seeds[np.isin(ended, np.arange(sl.start, sl.stop))], mask)[mask]
        return (obs.reshape(self.num_envs, self.obs_dim), reward.reshape(-1).astype(np.float32),
                np.repeat(done, self.n_beacons), infos)

    def _row_infos(self, info: dict, time_limit: np.ndarray) -> list:
        """One info dict per row: ``views.agent_infos`` of its environment (computed for
        the whole batch at once) plus ``TimeLimit.truncated``."""
        columns = {}
        for key in INFO_KEYS:
            v = info[key]
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
        if self.n_beacons == 1:
            return per_env
        return [dict(d) for d in per_env for _ in range(self.n_beacons)]

    # ------------------------------------------------------------------------------
    def global_state(self) -> np.ndarray:
        """The true global state of every environment, (n_envs, state_dim), for centralized critics."""
        return np.concatenate([sim.global_state() for sim in self.sims])

    def close(self):
        self._actions = None

    def get_images(self):
        return [None] * self.num_envs

    def _row_envs(self, indices) -> list:
        return [int(i) // self.n_beacons for i in self._get_indices(indices)]

    def get_attr(self, attr_name, indices=None):
        """Per row: ``config`` is its variant's config, ``episode_seed`` its episode's seed,
        ``agent`` its beacon name; anything else is the VecEnv's own attribute."""
        envs = self._row_envs(indices)
        if attr_name == "config":
            return [self.configs[self.env_variant[e]] for e in envs]
        if attr_name == "episode_seed":
            return [int(self.episode_seeds[e]) for e in envs]
        if attr_name == "agent":
            return [self.possible_agents[int(i) % self.n_beacons] for i in self._get_indices(indices)]
        if not hasattr(self, attr_name):
            raise AttributeError(f"{type(self).__name__} has no attribute {attr_name!r}")
        value = getattr(self, attr_name)
        return [value for _ in envs]

    def set_attr(self, attr_name, value, indices=None):
        """Rows share one simulator: only attributes of the whole VecEnv can be set."""
        rows = list(self._get_indices(indices))
        if sorted(int(i) for i in rows) != list(range(self.num_envs)):
            raise ValueError("the rows of CoopNavVecEnv share one simulator: set_attr applies to all rows only")
        setattr(self, attr_name, value)

    def env_method(self, method_name, *method_args, indices=None, **method_kwargs):
        """Calls the VecEnv's method ``method_name`` once and returns its result for each row."""
        rows = list(self._get_indices(indices))
        method = getattr(self, method_name, None)
        if not callable(method):
            raise AttributeError(f"{type(self).__name__} has no method {method_name!r}")
        result = method(*method_args, **method_kwargs)
        return [result for _ in rows]

    def env_is_wrapped(self, wrapper_class, indices=None):
        return [False for _ in self._get_indices(indices)]
