"""The PettingZoo view of the batched core (a batch of one)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike
from pettingzoo import ParallelEnv
from pettingzoo.utils.conversions import parallel_to_aec_wrapper

from .core import make_simulator
from .names import did_you_mean
from .scenarios import make_config
from .seeds import check_seed
from .views import action_space, agent_infos, check_action, observation_space, state_space

if TYPE_CHECKING:
    from gymnasium import spaces
    from matplotlib.figure import Figure

    from .core.contract import StepResult
    from .render import EpisodeRecorder
    from .scenarios import ScenarioConfig


# what step returns: observations, rewards, terminations, truncations, infos, per agent
_Step = tuple[dict[str, np.ndarray], dict[str, float], dict[str, bool], dict[str, bool], dict[str, dict[str, Any]]]


class CoopNavParallelEnv(ParallelEnv):
    """Beacon vehicles that move to help survey vehicles navigate under water.

    Survey AUVs fly a planned path by dead reckoning (thrust model, compass, depth
    sensor; no DVL) and fuse acoustic ranges from the beacons in an EKF (Gao &
    Chitre 2010). The agents are the beacons, ``beacon_0`` ... ``beacon_{N-1}``:
    beacon AUVs (DVL) or ASVs (GPS), as the scenario's ``beacon_kinds`` says.

    **One step** is one acoustic cycle of ``ping_interval_s`` (default 20 s),
    integrated in sub-steps of ``substep_s`` (1 s). At the end of the cycle every
    beacon pings, the survey vehicles fuse what arrives and reply with their
    estimate, which the beacons may or may not receive.

    **Action** (per beacon): ``Box(-1, 1, (2,), float32)``. With
    ``action_mode="velocity"`` (default), the commanded ground velocity
    (v_east, v_north) as a fraction of the beacon's maximum speed (its norm is
    clipped to 1); with ``"heading_speed"``, (bearing / pi, speed fraction * 2 - 1).
    Turn rates are limited by the vehicle kind. Finite out-of-range actions are
    clipped; NaN, infinite or wrongly shaped actions raise ``ValueError``.
    With ``channel_mode="decide"`` (scenario ``sousa_ping``) the action is
    ``Box(-1, 1, (3,))``: the motion, then the transmit decision, transmit this
    decision slot when ``action[2] > 0`` (a (2,) action transmits every slot);
    the pings and replies then share one channel (``core/channel.py``), the reward
    gains a ``ping`` term (-``ping_penalty`` per ping) and the infos ``pings``,
    ``collisions`` and ``energy_J`` per beacon and cycle.

    **Observation** (per beacon): ``Box(-10, 10, (D,), float32)``, only what the
    beacon could know, positions divided by the scenario's ``position_scale_m``:
    own estimated position relative to the geofence centre (2), heading (sin, cos)
    of the bearing as (east, north) unit vector (2), speed fraction (1), own
    position std / 10 m (1); then per survey vehicle, from its last received reply:
    estimate relative to own position (east, north; depth / 100 m) (3), 2-sigma
    ellipse semi-axes / 50 m (2), (cos, sin) of twice the major-axis bearing (2),
    age of that reply and time since its last fused range, / (10 ping intervals)
    (2), its next ``observed_waypoints`` planned waypoints relative to its estimate
    (2 each); then the other beacons' last reported positions relative to own (2 each).

    **Reward** (per beacon): the information the survey filters gained from this
    cycle's ranges, sum over survey vehicles of log det P_before - log det P_after
    of the horizontal position covariance (shared by the team), minus
    ``safety_penalty`` if the beacon is closer than ``safety_distance_m`` to a
    survey vehicle, ``geofence_penalty`` outside the geofence, and
    ``contact_penalty`` if none of its ranges was fused this cycle.

    **Episode end**: terminated when every survey vehicle has finished its path
    (or ``mission_duration_s`` has passed, if set); truncated after ``max_cycles``.

    **Infos** (every agent, every step, and from ``reset()`` with the same keys,
    counts zero): ``survey_error_m`` (true horizontal error
    of the EKF estimate, metres, mean over survey vehicles), ``dr_error_m`` (the same
    for dead reckoning), ``cov_logdet`` (log det of the horizontal covariance, m^4),
    ``range_ok`` (a range was fused this cycle), counts ``ranges_fused``,
    ``outliers_rejected``, ``nan_rejected``, ``packets_lost``, ``filter_restarts``
    (lock-out recoveries), and each of these as a per-survey-vehicle list under
    ``<name>_per_vehicle``; per survey vehicle the true horizontal error vector
    ``survey_error_en_m`` (east, north; m) and the filter's horizontal covariance
    ``survey_cov_en_m2`` (2x2, m^2), so that anyone can check the filter's consistency;
    and the agent's own true navigation error ``beacon_error_m``.

    **The moving LBL network** (``network="moving_lbl"``, scenario
    ``matos_moving_lbl``; Matos & Cruz): the agents are two boats, ``beacon_0`` = B1
    (the frame's origin) and ``beacon_1`` = B2, which define a moving frame; one AUV
    navigates in it by the three-interval LBL exchange and a six-state moving-frame
    EKF (the package ``core/moving_network/``). Action: with ``action_mode="frame_velocity"``
    (its default) (v_x, v_y) / max speed in the frame the boats' GPS defines (x
    along B1 -> B2, y 90 degrees clockwise), norm clipped to 1. Observation
    (``core.moving_network.OBS_FIELDS``, 15 values; ``obs_layout.decode_boat``):
    role, own velocity, baseline error, the vehicle as the boats track it
    externally (position, velocity, fix age, whether it has a fix), the frame's
    bearing, own position from the tracked vehicle, elapsed time; ``matos_river``
    adds the river (``RIVER_OBS_FIELDS``: the bank offset, the river's direction and
    the river ahead from the boat), 20 values. Reward: the vehicle filter's
    information gain minus penalties for the baseline off its target, the frame
    turned, the vehicle near the baseline, a boat near the vehicle, no range fused.
    Infos add ``error_x_m``, ``error_y_m`` (moving-frame errors), ``phi_error_deg``,
    ``baseline_error_m``, ``ellipse_major_m``, ``ellipse_minor_m``, ``vehicle_y_m``.

    **The MLS sensor** (``acoustic_sensor="mls"``, scenario ``swarm_mls``; Kottege &
    Zimmer): as above, but one beacon sends per cycle (round robin) and each survey
    vehicle measures its range and azimuth with the MLS array (``core/mls/``).

    **Arguments**: ``scenario`` (a name from ``coopnav_env.list_scenarios()`` or a
    ``ScenarioConfig``), ``render_mode`` (``None``, ``"rgb_array"``, ``"human"``),
    ``seed`` (used by the first ``reset()`` without a seed), ``max_cycles``, and
    any scenario parameter by keyword; unknown names raise ``ValueError``.
    """

    # pettingzoo.ParallelEnv declares metadata an instance attribute (dict[str, Any]), as gymnasium.Env does
    metadata: dict[str, Any] = {  # noqa: RUF012
        "name": "coopnav_v0",
        "render_modes": ["human", "rgb_array"],
        "is_parallelizable": True,
        "render_fps": 4,
    }

    def __init__(
        self,
        scenario: str | ScenarioConfig = "gao_lawnmower",
        render_mode: str | None = None,
        seed: int | None = None,
        max_cycles: int | None = None,
        **overrides: Any,
    ) -> None:
        if max_cycles is not None:
            overrides["max_cycles"] = max_cycles
        self.config = make_config(scenario, **overrides)
        if render_mode not in (None, "human", "rgb_array"):
            raise ValueError(
                f"unknown render_mode {render_mode!r}{did_you_mean(render_mode, ['human', 'rgb_array'])} "
                "valid: None, 'human', 'rgb_array'"
            )
        self.render_mode = render_mode
        self.sim = make_simulator(self.config, batch_size=1)
        # the core's StepResult of the last step (training-reward wrappers read it)
        self.last_result: StepResult | None = None
        self.possible_agents = [f"beacon_{i}" for i in range(self.config.n_beacons)]
        self.agents: list[str] = []
        self._action_space = action_space(self.sim)
        self._observation_space = observation_space(self.sim)
        self.state_space = state_space(self.sim)
        self._seed = None if seed is None else check_seed(seed)
        self._seed_rng = np.random.default_rng(self._seed)
        self._recorder: EpisodeRecorder | None = None
        self._viewer: Figure | None = None

    def observation_space(self, agent: str) -> spaces.Box:
        self._check_agent(agent)
        return self._observation_space

    def action_space(self, agent: str) -> spaces.Box:
        self._check_agent(agent)
        return self._action_space

    def _check_agent(self, agent: str) -> None:
        """A one-line ``ValueError`` for a name that is none of ``possible_agents``."""
        if agent not in self.possible_agents:
            raise ValueError(
                f"unknown agent {agent!r}{did_you_mean(agent, self.possible_agents)} "
                f"agents: {', '.join(self.possible_agents)}"
            )

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, dict[str, Any]]]:
        if seed is None:
            seed = self._seed if self._seed is not None else int(self._seed_rng.integers(2**31))
            self._seed = None
        else:
            seed = check_seed(seed)
            self._seed_rng = np.random.default_rng(seed)
            self._seed = None  # an explicit seed supersedes the constructor's
        self.episode_seed = int(seed)
        obs = self.sim.reset([self.episode_seed])
        self.agents = list(self.possible_agents)
        if self.render_mode is not None:
            from .render import EpisodeRecorder

            self._recorder = EpisodeRecorder(self.config)
            self._recorder.record(self.sim.snapshot(), 0)
        # the same keys as step()'s infos (TorchRL's and BenchMARL's wrappers build their spec from these)
        info, beacon_info = self.sim.reset_info(), self.sim.reset_beacon_info()
        infos = {a: agent_infos(info, 0, beacon_info, j) for j, a in enumerate(self.agents)}
        return {a: obs[0, i] for i, a in enumerate(self.agents)}, infos

    def step(self, actions: Mapping[str, ArrayLike]) -> _Step:
        if not isinstance(actions, Mapping):
            raise ValueError(f"actions must be a dict agent -> action, got {type(actions).__name__}")
        if not self.agents:
            given = f" (actions given for agents that are not alive: {list(actions)})" if actions else ""
            raise ValueError(
                "step() with no live agents: the episode has ended or reset() was not called; "
                f"call reset() first{given}"
            )
        for a in actions:
            self._check_agent(a)  # a misspelt name: the closest
        dead = [a for a in actions if a not in self.agents]
        if dead:
            raise ValueError(f"actions given for agents that are not alive: {dead}; alive: {self.agents}")
        missing = [a for a in self.agents if a not in actions]
        if missing:
            raise ValueError(f"no action given for live agents {missing}")
        dim = self._action_space.shape[0]
        batch = np.stack([check_action(a, actions[a], dim) for a in self.agents])[None]
        res = self.last_result = self.sim.step(batch)  # the core's StepResult, for wrappers
        if self._recorder is not None:
            self._recorder.record(self.sim.snapshot(), 0)
        term, trunc = bool(res.terminated[0]), bool(res.truncated[0])
        agents = self.agents
        obs = {a: res.obs[0, i] for i, a in enumerate(agents)}
        rewards = {a: float(res.reward[0, i]) for i, a in enumerate(agents)}
        terms = dict.fromkeys(agents, term)
        truncs = dict.fromkeys(agents, trunc)
        infos = {a: agent_infos(res.info, 0, res.beacon_info, j) for j, a in enumerate(agents)}
        if term or trunc:
            self.agents = []
        if self.render_mode == "human":
            self.render()
        return obs, rewards, terms, truncs, infos

    def state(self) -> np.ndarray:
        """The true global state (``state_space``), for centralized critics."""
        if self.sim.state is None:
            raise RuntimeError("state() before reset(): call reset() first")
        return self.sim.global_state()[0]

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            import gymnasium

            gymnasium.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human'")
            return None
        from .render import draw_episode, figure_to_rgb

        if self._recorder is None:
            raise RuntimeError("render() before reset()")
        if self.render_mode == "rgb_array":
            return figure_to_rgb(draw_episode(self._recorder, self.config))
        import matplotlib.pyplot as plt

        # "human": draw into one pyplot window (a bare Figure is never shown by pyplot)
        if self._viewer is None or not plt.fignum_exists(self._viewer.number):
            self._viewer = plt.figure(figsize=(6.4, 5.6))
        draw_episode(self._recorder, self.config, fig=self._viewer)
        self._viewer.canvas.draw_idle()
        plt.pause(0.001)
        return None

    def __getstate__(self):
        state = self.__dict__.copy()
        state["_viewer"] = None  # a window does not travel between processes
        return state

    def close(self) -> None:
        if self._viewer is not None:
            import matplotlib.pyplot as plt

            plt.close(self._viewer)
            self._viewer = None


class CoopNavAEC(parallel_to_aec_wrapper):
    """A ``CoopNavParallelEnv`` as PettingZoo's AEC environment (``parallel_to_aec_wrapper``),
    each agent's action checked at its own ``step``: a NaN from beacon_0 is refused on
    beacon_0's turn and not kept (the wrapper alone stores it, fails on the last agent's turn
    and at every turn after, until reset); ``observe`` of a name that is no agent is one line
    naming the closest (a bare KeyError before)."""

    def step(self, action: Any) -> None:
        agent = self.agent_selection
        if not (self.terminations.get(agent) or self.truncations.get(agent)):
            if action is None:  # stored, it would fail every later turn until reset
                raise ValueError(f"action for {agent} is None: a live agent needs one (None is for agents done)")
            action = check_action(agent, action, self.env.action_space(agent).shape[0])
        super().step(action)

    def observe(self, agent: str) -> Any:
        self.env._check_agent(agent)
        return super().observe(agent)
