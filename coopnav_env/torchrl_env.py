"""The batched core as a TorchRL environment: ``n_envs`` environments in one ``EnvBase``,
the beacons as one agent group (TorchRL's multi-agent convention, as VMAS).

    from coopnav_env.torchrl_env import CoopNavTorchEnv
    env = CoopNavTorchEnv("gao_sea", n_envs=512, seed=0)
    td = env.rollout(10)                         # batch (512, 10)
    td["next", "beacons", "reward"].shape        # (512, 10, n_beacons, 1)

Needs the ``marl`` extra (``pip install -e ".[marl]"``: torchrl, tensordict; BenchMARL
for ``agents.training.marl``). ``import coopnav_env`` does not import this module
(nor torch).

**One core, one step.** ``batch_size`` is ``(n_envs,)``, the core's batch: one env step
is ONE ``Simulator.step`` over the whole batch (no Python loop over environments, no
second copy of the physics), as ``coopnav_env.vector.CoopNavVecEnv``.

**Keys and shapes** (B = n_envs, N = beacons, S = survey vehicles):

* ``("beacons", "observation")`` (B, N, obs_dim) float32 in [-10, 10]: each beacon's
  observation (``core/observation.py``); with ``observation="entities"`` its entity form
  (``coopnav_env.entity_obs``: the beacon's own state and role, each survey vehicle and
  each other beacon with its kind, padded to a fixed size), so that one entity policy reads
  every team: (B, N, ENTITY_DIM), beacon j's row with role j;
* ``("beacons", "action")`` (B, N, D) float32 in [-1, 1]: D = 2 (the motion, see the
  scenario's ``action_mode``), 3 with ``channel_mode="decide"`` (the third component > 0
  transmits this slot; a (B, N, 2) action is accepted there too and transmits every slot);
* ``("beacons", "reward")`` (B, N, 1) float32: the environment's reward, or the training
  reward of ``reward_terms`` (``core.reward``'s training signals, as the VecEnv's);
* ``"done"``, ``"terminated"``, ``"truncated"`` (B, 1) bool at the root only: the beacons of
  one environment end together, so a per-agent copy would say nothing more (VMAS's
  convention; BenchMARL's MAPPO/IPPO/MASAC expand the root flags over the group).
  ``truncated`` is the cycle limit (``max_cycles``) without termination, the VecEnv's
  ``TimeLimit.truncated``;
* ``"state"`` (B, state_dim + N * obs_dim) float32 in [-10, 10], for centralized critics:
  **privileged** - the core's ``global_state()`` (true positions of every vehicle, the
  survey filters' estimates and error ellipses, the beacons' own navigation errors and
  headings, the current, the episode's progress) followed by every beacon's (flat)
  observation.
  A critic is not used when acting, so it may read the truth; ``state="observations"``
  gives the beacons' observations alone (B, N * obs_dim). With ``state_survey_slots`` S'
  larger than the team's S, or ``state_beacon_slots`` N' larger than its N, both parts are
  laid out for S' survey vehicles and N' beacons (zeros where the team has none, a missing
  beacon's observation all zeros: ``obs_layout.pad_slots``), so teams of 1-S' survey
  vehicles and 1-N' beacons share one size;
* ``"info"``: the VecEnv's infos per environment, as tensors: for every scalar info of
  the core (``sim.info_keys``) the aggregate over survey vehicles (mean of floats, sum of
  counts, any of ``range_ok``) under its name and the values per vehicle under
  ``<name>_per_vehicle`` (B, S); the vector infos ``survey_error_en_m`` (B, S, 2) and
  ``survey_cov_en_m2`` (B, S, 2, 2) as they are (floats float64, counts int64, flags bool,
  bit for bit the VecEnv's values);
* ``("beacons", "info")``: the per-beacon infos (``beacon_error_m``, ``beacon_away_s``, and
  with ``channel_mode="decide"`` ``pings``, ``collisions``, ``energy_J``), (B, N), dtypes as above.

The VecEnv's ``terminal_observation`` needs no key: TorchRL keeps the last observation of an
episode in ``("next", "beacons", "observation")`` and the reset's first one in the root of
the following step (``step_and_maybe_reset``).

**Seeds** (as ``CoopNavVecEnv``): episode ``k`` (0, 1, ...) of environment ``e`` is seeded
``seed + e + k * SEED_STRIDE``, so environment ``e``'s first episode is
``coopnav_env.parallel_env(scenario, seed=seed + e)`` bit for bit (the core's random numbers
are counter-based per environment). ``set_seed(s)`` restarts the count at the next full
``reset()``; ``seed=None`` draws a random base seed.

**Resets.** ``reset()`` starts a new episode in every environment; a ``"_reset"`` mask
(B, 1) restarts only those rows (``step_and_maybe_reset``, collectors), each with its next
seed, and leaves the others where they are.

**Actions** are checked as the other views check them: NaN or infinite values and wrong
shapes raise one-line ``ValueError`` naming the environment and beacon; finite values
outside [-1, 1] are clipped.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

from .core import make_simulator
from .core.reward import check_training_terms, training_reward
from .names import did_you_mean
from .scenarios import make_config
from .seeds import TRAINING_SEED_STRIDE, EpisodeSeeds
from .views import OBS_BOUND, action_dim

if TYPE_CHECKING:
    from .scenarios import ScenarioConfig

__all__ = ["GROUP", "OBSERVATIONS", "SEED_STRIDE", "STATE_KINDS", "CoopNavTorchEnv"]

GROUP = "beacons"  # the agent group: every beacon of a scenario, one shared policy by default
SEED_STRIDE = TRAINING_SEED_STRIDE  # coopnav_env.vector.SEED_STRIDE: episode k of env e -> seed + e + k * stride
STATE_KINDS = ("privileged", "observations")
OBSERVATIONS = ("flat", "entities")  # the group's observation: core/observation.py's, or its entity form

_TORCH_DTYPE = {"f": torch.float64, "i": torch.int64, "u": torch.int64, "b": torch.bool}
_NUMPY_DTYPE = {"f": np.float64, "i": np.int64, "u": np.int64, "b": np.bool_}


def _dtype(array: np.ndarray) -> torch.dtype:
    """The tensor dtype of an info array: float64, int64 or bool (as the VecEnv's values)."""
    return _TORCH_DTYPE[array.dtype.kind]


def _tensor(array: np.ndarray) -> torch.Tensor:
    """An info array as a tensor of ``_dtype(array)`` (a copy: the core reuses its arrays)."""
    return torch.from_numpy(np.array(array, dtype=_NUMPY_DTYPE[array.dtype.kind]))


class NonFiniteAction(ValueError):
    """A policy sent a NaN or infinite action (in training: the optimization diverged)."""


def _state_slots(name: str, value: Any, own: int, what: str, moving: bool, moving_has: str) -> int:
    """The number of ``what`` the state is laid out for: ``value`` (None: the team's ``own``),
    an int >= ``own``; the moving network's state has no slots to pad."""
    slots = own if value is None else value
    if isinstance(slots, bool) or not isinstance(slots, (int, np.integer)) or slots < own:
        raise ValueError(f"{name} must be an int >= the team's {own} {what}, got {slots!r}")
    if slots != own and moving:
        raise ValueError(f"{name}: the moving network's state has {moving_has}, got {slots}")
    return int(slots)


class CoopNavTorchEnv(EnvBase):
    """``n_envs`` environments of ``scenario`` (name or ``ScenarioConfig``) as one TorchRL
    ``EnvBase`` with batch size ``(n_envs,)``. See the module docstring for the keys.

    Arguments: ``seed`` (None: a random base seed), ``device`` (where the tensors are
    put; the core runs on the CPU), ``reward_terms`` (None: the environment's reward;
    ``{signal: weight}``: the training reward, ``coopnav_env.vector``'s),
    ``state`` ("privileged" or "observations", see the module docstring), ``infos``
    (False: no ``"info"`` entries, a little faster), ``observation`` ("flat" or "entities",
    see the module docstring; a team the entity view cannot read is a ``ValueError``),
    ``state_survey_slots`` (None: the team's own number of survey vehicles; a larger number
    S': the state laid out for S' of them, the missing ones' values zero, so teams of other
    sizes give states of one size and layout: a centralized critic can train over them),
    ``state_beacon_slots`` (the same for the beacons: None, the team's own number) and
    any scenario parameter by keyword.
    """

    def __init__(
        self,
        scenario: str | ScenarioConfig = "gao_lawnmower",
        n_envs: int = 1,
        seed: int | None = None,
        device: str | torch.device = "cpu",
        reward_terms: Mapping[str, float] | None = None,
        state: str = "privileged",
        infos: bool = True,
        observation: str = "flat",
        state_survey_slots: int | None = None,
        state_beacon_slots: int | None = None,
        **overrides: Any,
    ) -> None:
        if "batch_size" in overrides:  # TorchRL's own name for it is not a scenario parameter
            raise ValueError(
                f"CoopNavTorchEnv takes n_envs={overrides['batch_size']!r}, not batch_size= "
                "(its batch size is (n_envs,))"
            )
        if isinstance(n_envs, bool) or not isinstance(n_envs, (int, np.integer)) or n_envs < 1:
            raise ValueError(f"n_envs must be an int >= 1, got {n_envs!r}")
        if state not in STATE_KINDS:
            hint = did_you_mean(state, STATE_KINDS)
            raise ValueError(f"unknown state {state!r}{hint} valid: {', '.join(STATE_KINDS)}")
        if observation not in OBSERVATIONS:
            raise ValueError(
                f"unknown observation {observation!r}{did_you_mean(observation, OBSERVATIONS)} valid: "
                f"{', '.join(OBSERVATIONS)}"
            )
        n_envs = int(n_envs)
        config = make_config(scenario, **overrides)
        if observation == "entities":
            from .entity_obs import check_team

            check_team(config)
        reward_terms = check_training_terms(reward_terms)
        super().__init__(device=device, batch_size=torch.Size([n_envs]))
        self.config = config
        self.reward_terms = reward_terms
        self.sim = make_simulator(config, n_envs)
        self.n_envs = n_envs
        self.n_beacons = self.sim.N
        self.n_survey = self.sim.S
        self.observation = observation
        self.flat_obs_dim = self.sim.obs_dim  # core/observation.py's size (the state holds these)
        self.obs_dim = self.flat_obs_dim  # the group's observation's size
        if observation == "entities":
            from .entity_obs import ENTITY_DIM

            self.obs_dim = ENTITY_DIM
        self.action_dim = action_dim(self.sim)
        self.state_kind = state
        moving = config.network == "moving_lbl"
        self.state_survey_slots = _state_slots(
            "state_survey_slots", state_survey_slots, self.n_survey, "survey vehicles", moving, "one survey vehicle"
        )
        self.state_beacon_slots = _state_slots(
            "state_beacon_slots", state_beacon_slots, self.n_beacons, "beacons", moving, "its two boats"
        )
        self.infos = bool(infos)
        self.agent_names = [f"beacon_{j}" for j in range(self.n_beacons)]
        self.group_map = {GROUP: list(self.agent_names)}
        self._schedule = EpisodeSeeds(n_envs)
        self.episode_seeds = self._schedule.current  # seed of each current episode
        self._done = np.zeros(n_envs, dtype=bool)
        self._started = False
        self._set_seed(seed)
        self._make_specs()

    # ------------------------------------------------------------------------------
    @property
    def state_dim(self) -> int:
        """Length of ``"state"``: the core's state and every (flat) observation, or the
        observations; each for ``state_survey_slots`` survey vehicles and ``state_beacon_slots``
        beacons."""
        from .core import observation as layout
        from .core.sim import BEACON_STATE_DIM, SURVEY_STATE_DIM

        extra = self.state_survey_slots - self.n_survey  # both 0 on the moving network
        extra_b = self.state_beacon_slots - self.n_beacons
        flat = self.flat_obs_dim
        if extra or extra_b:
            flat = layout.obs_dim(self.state_survey_slots, self.state_beacon_slots, self.config.observed_waypoints)
        n_obs = self.state_beacon_slots * flat
        if self.state_kind != "privileged":
            return n_obs
        return n_obs + self.sim.state_dim + extra * SURVEY_STATE_DIM + extra_b * BEACON_STATE_DIM

    def _info_dtypes(self) -> tuple[dict, dict]:
        """The info entries' (shape after B, dtype), root and per beacon, read from a
        throw-away batch of one (the core's reset infos have the step's keys and dtypes)."""
        probe = make_simulator(self.config, 1)
        probe.reset(np.zeros(1, dtype=np.int64))
        root: dict[str, tuple[tuple, torch.dtype]] = {}
        for key, v in probe.reset_info().items():
            if v.ndim > 2:  # a vector per survey vehicle
                root[key] = (tuple(v.shape[1:]), _dtype(v))
                continue
            agg = torch.bool if key == "range_ok" else (torch.float64 if v.dtype.kind == "f" else torch.int64)
            root[key] = ((), agg)
            root[key + "_per_vehicle"] = ((self.n_survey,), _dtype(v))
        beacon = {key: _dtype(np.asarray(v)) for key, v in probe.reset_beacon_info().items()}
        return root, beacon

    def _make_specs(self) -> None:
        B, N, dev = self.n_envs, self.n_beacons, self.device
        group_obs: dict[str, Any] = {
            "observation": Bounded(-OBS_BOUND, OBS_BOUND, (B, N, self.obs_dim), device=dev, dtype=torch.float32)
        }
        root_obs: dict[str, Any] = {
            "state": Bounded(-OBS_BOUND, OBS_BOUND, (B, self.state_dim), device=dev, dtype=torch.float32)
        }
        if self.infos:
            root_info, beacon_info = self._info_dtypes()
            self._root_info_keys = tuple(root_info)
            group_obs["info"] = Composite(
                {k: Unbounded((B, N), device=dev, dtype=d) for k, d in beacon_info.items()}, shape=(B, N), device=dev
            )
            root_obs["info"] = Composite(
                {k: Unbounded((B, *s), device=dev, dtype=d) for k, (s, d) in root_info.items()}, shape=(B,), device=dev
            )
        self.observation_spec = Composite(
            {GROUP: Composite(group_obs, shape=(B, N), device=dev), **root_obs}, shape=(B,)
        )
        action = Bounded(-1.0, 1.0, (B, N, self.action_dim), device=dev, dtype=torch.float32)
        self.action_spec = Composite({GROUP: Composite({"action": action}, shape=(B, N), device=dev)}, shape=(B,))
        reward = Unbounded((B, N, 1), device=dev, dtype=torch.float32)
        self.reward_spec = Composite({GROUP: Composite({"reward": reward}, shape=(B, N), device=dev)}, shape=(B,))
        flag = Categorical(2, (B, 1), device=dev, dtype=torch.bool)
        self.done_spec = Composite({"done": flag, "terminated": flag.clone(), "truncated": flag.clone()}, shape=(B,))

    # ------------------------------------------------------------------------------
    def _set_seed(self, seed: int | None) -> None:
        """Base seed for the episodes started from the next full ``reset()`` on (None: random)."""
        self._schedule.restart(seed)
        self._started = False

    def _next_seeds(self, envs: np.ndarray) -> np.ndarray:
        return self._schedule.next(envs)

    def episode_cells(self) -> list:
        """(survey_path, depth_m) of each environment's current episode (the core's draw)."""
        return [self.sim.variants[v] for v in self.sim.episode_variants().tolist()]

    # ------------------------------------------------------------------------------
    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs: Any) -> TensorDictBase:
        mask = None
        if tensordict is not None and "_reset" in tensordict.keys():  # noqa: SIM118 - TensorDict has no `in`
            mask = tensordict.get("_reset").reshape(self.n_envs).cpu().numpy()
        if not self._started or mask is None or mask.all():
            self.sim.reset(self._next_seeds(np.arange(self.n_envs)))
            self._done[:] = False
            self._started = True
        elif mask.any():
            rows = np.flatnonzero(mask)
            self.sim.reset(self._next_seeds(rows), mask)
            self._done[rows] = False
        done = torch.from_numpy(self._done.copy()).reshape(self.n_envs, 1)
        out = self._output(self.sim.observe(), done, done.clone(), torch.zeros_like(done))
        if self.infos:
            self._put_infos(out, self.sim.reset_info(), self.sim.reset_beacon_info())
        return out

    def check_actions(self, action: Any) -> np.ndarray:
        """``action`` (B, N, D) as a float64 array clipped to [-1, 1]; with
        ``channel_mode="decide"`` a (B, N, 2) action gets the third component 1 (transmit).
        One-line ValueError naming the environment and beacon otherwise."""
        try:
            a = (action.detach().cpu().numpy() if torch.is_tensor(action) else np.asarray(action)).astype(np.float64)
        except (TypeError, ValueError) as err:
            raise ValueError(f"actions are not numeric: {type(action).__name__}") from err
        B, N, D = self.n_envs, self.n_beacons, self.action_dim
        if a.shape != (B, N, D) and not (D == 3 and a.shape == (B, N, 2)):
            raise ValueError(
                f"({GROUP!r}, 'action') must have shape ({B}, {N}, {D}) (environments, beacons, components), "
                f"got shape {tuple(a.shape)}"
            )
        finite = np.isfinite(a).all(-1)
        if not finite.all():
            e, j = (int(i) for i in np.argwhere(~finite)[0])
            raise NonFiniteAction(f"action for env {e} beacon_{j} must be finite, got {a[e, j].tolist()}")
        if a.shape[-1] != D:  # the motion alone: transmit, as the fixed clock does
            a = np.concatenate([a, np.ones((B, N, 1))], -1)
        return np.clip(a, -1.0, 1.0)

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        if not self._started:
            raise RuntimeError("step() before reset()")
        actions = self.check_actions(tensordict.get((GROUP, "action")))
        res = self.sim.step(actions)
        reward = (
            res.reward
            if self.reward_terms is None
            else training_reward(self.reward_terms, res, self.sim.reward_weights)
        )
        term, trunc = np.asarray(res.terminated, dtype=bool), np.asarray(res.truncated, dtype=bool)
        self._done = term | trunc
        B = self.n_envs
        out = self._output(
            res.obs,
            torch.from_numpy(self._done.copy()).reshape(B, 1),
            torch.from_numpy(term.copy()).reshape(B, 1),
            torch.from_numpy(trunc & ~term).reshape(B, 1),
        )
        out.set((GROUP, "reward"), torch.from_numpy(np.asarray(reward, dtype=np.float32)).reshape(B, self.n_beacons, 1))
        if self.infos:
            self._put_infos(out, res.info, res.beacon_info)
        return out

    def _output(self, obs: np.ndarray, done, terminated, truncated) -> TensorDict:
        B, N = self.n_envs, self.n_beacons
        obs_t = torch.from_numpy(np.ascontiguousarray(obs, dtype=np.float32))
        slots, bslots = self.state_survey_slots, self.state_beacon_slots
        padded = slots != self.n_survey or bslots != N
        if not padded:
            parts = [obs_t.reshape(B, N * self.flat_obs_dim)]
        else:  # each vehicle's values at its slot's index; a missing beacon's observation zeros
            from .obs_layout import pad_slots

            wide = pad_slots(obs_t.numpy(), self.config, slots, bslots).reshape(B, N, -1)
            rows = np.zeros((B, bslots - N, wide.shape[-1]), dtype=wide.dtype)
            parts = [torch.from_numpy(np.concatenate([wide, rows], 1)).reshape(B, -1)]
        if self.state_kind == "privileged":
            glob = self.sim.global_state()
            if padded:
                from .core.sim import pad_global_state

                glob = pad_global_state(glob, self.n_survey, slots, N, bslots)
            parts.insert(0, torch.from_numpy(glob))
        if self.observation == "entities":  # beacon j reads its own row with role j
            from .entity_obs import entity_observation

            flat = np.asarray(obs, dtype=np.float64).reshape(B, N, self.flat_obs_dim)
            obs_t = torch.from_numpy(entity_observation(flat, self.config, np.arange(N)))
        group = TensorDict({"observation": obs_t}, batch_size=(B, N), device=self.device)
        return TensorDict(
            {
                GROUP: group,
                "state": torch.cat(parts, -1),
                "done": done,
                "terminated": terminated,
                "truncated": truncated,
            },
            batch_size=(B,),
            device=self.device,
        )

    def _put_infos(self, out: TensorDictBase, info: dict, beacon_info: dict) -> None:
        """The VecEnv's infos as tensors (module docstring): aggregates over survey vehicles
        and the values per vehicle at the root, the beacons' own under the group."""
        B, N = self.n_envs, self.n_beacons
        root = {}
        for key, v in info.items():
            if v.ndim > 2:
                root[key] = _tensor(v)
                continue
            if key == "range_ok":
                agg = v.any(axis=1)
            elif v.dtype.kind in "iub":
                agg = v.sum(axis=1).astype(np.int64)
            else:
                agg = v.mean(axis=1)
            root[key] = _tensor(agg)
            root[key + "_per_vehicle"] = _tensor(v)
        out.set("info", TensorDict(root, batch_size=(B,), device=out.device))
        group = {k: _tensor(np.asarray(v)) for k, v in beacon_info.items()}
        out.set((GROUP, "info"), TensorDict(group, batch_size=(B, N), device=out.device))
