"""The single-beacon Gymnasium view of the batched core (a batch of one).

``gymnasium.make("coopnav/gao_lawnmower-v0")`` gives the scenario's only beacon as
a Gymnasium agent: same observation, action and reward as ``beacon_0`` of the
PettingZoo env (see ``CoopNavParallelEnv``), so single-agent libraries work.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np
from numpy.typing import ArrayLike

from .core import make_simulator
from .names import did_you_mean
from .scenarios import make_config
from .seeds import check_seed
from .views import action_space, agent_infos, check_action, observation_space

if TYPE_CHECKING:
    from gymnasium import spaces

    from .render import EpisodeRecorder
    from .scenarios import ScenarioConfig


class CoopNavGymEnv(gym.Env):
    # gymnasium.Env declares metadata an instance attribute (dict[str, Any]): a ClassVar would not match it
    metadata: dict[str, Any] = {"render_modes": ["rgb_array"], "render_fps": 4}  # noqa: RUF012
    action_space: spaces.Box
    observation_space: spaces.Box

    def __init__(
        self, scenario: str | ScenarioConfig = "gao_lawnmower", render_mode: str | None = None, **overrides: Any
    ) -> None:
        self.config = make_config(scenario, **overrides)
        if self.config.n_beacons != 1:
            raise ValueError(
                f"the Gymnasium view needs a scenario with one beacon; {self.config.name} has "
                f"{self.config.n_beacons} (use coopnav_env.parallel_env)"
            )
        if render_mode not in (None, "rgb_array"):
            hint = did_you_mean(render_mode, ["rgb_array"])
            raise ValueError(f"unknown render_mode {render_mode!r}{hint} valid: None, 'rgb_array'")
        self.render_mode = render_mode
        self.sim = make_simulator(self.config, batch_size=1)
        self.action_space = action_space(self.sim)
        self.observation_space = observation_space(self.sim)
        self._recorder: EpisodeRecorder | None = None
        self._ended = True  # no episode yet: reset() first
        self.episode_seed: int | None = None

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """As ``parallel_env``'s: ``reset(seed=s)`` plays episode s (the same episode as
        ``parallel_env(...).reset(seed=s)`` and row s of the VecEnv), a seed checked by
        ``coopnav_env.seeds.check_seed``; ``reset()`` the next episode of the generator the
        last seed started (Gymnasium's ``np_random``)."""
        if seed is not None:
            seed = check_seed(seed)
        super().reset(seed=seed)
        episode_seed = seed if seed is not None else int(self.np_random.integers(2**31))
        self.episode_seed = episode_seed
        self._ended = False
        obs = self.sim.reset([episode_seed])
        if self.render_mode is not None:
            from .render import EpisodeRecorder

            self._recorder = EpisodeRecorder(self.config)
            self._recorder.record(self.sim.snapshot(), 0)
        return obs[0, 0], agent_infos(self.sim.reset_info(), 0, self.sim.reset_beacon_info())  # step()'s keys

    def step(self, action: ArrayLike) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        if self._ended:  # the simulator would run on past the episode's end, its error growing unbounded
            raise ValueError(
                "step() after the episode ended (terminated or truncated) or before reset(): call reset() first"
            )
        a = check_action("beacon_0", action, self.action_space.shape[0])
        res = self.sim.step(a[None, None])
        self._ended = bool(res.terminated[0]) or bool(res.truncated[0])
        if self._recorder is not None:
            self._recorder.record(self.sim.snapshot(), 0)
        return (
            res.obs[0, 0],
            float(res.reward[0, 0]),
            bool(res.terminated[0]),
            bool(res.truncated[0]),
            agent_infos(res.info, 0, res.beacon_info),
        )

    def render(self) -> np.ndarray | None:
        if self.render_mode != "rgb_array" or self._recorder is None:
            return None
        from .render import draw_episode, figure_to_rgb

        return figure_to_rgb(draw_episode(self._recorder, self.config))
