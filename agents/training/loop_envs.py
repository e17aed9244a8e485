"""The batched PPO loop's environments (``agents.training.batched_ppo``): the core's batch as
a TorchRL environment (``make_env``), teams of settings side by side in one batch
(``TeamEnvs``) and the validation episodes (``validate_per_team``)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from .loop_config import BatchedPPOConfig
from .loop_math import RunningNorm, window_input


class TeamEnvs:
    """Teams of settings side by side, as train.py's ``env.teams`` (``MixedTeamVecEnv``): one
    ``CoopNavTorchEnv`` per team with its share of the ``n_envs`` environments (the first
    teams one more where they do not divide), team t's environments seeded from ``seed`` +
    the number of environments before it, so no two share an episode seed. The loop sees one
    batch: ``reset`` and ``step_and_maybe_reset`` concatenate the teams' TensorDicts along
    the batch, keeping only what the loop reads (the observations, rewards, flags, the
    survey error and, with ``state``, the state; so teams with other infos, e.g. another
    number of survey vehicles under entity observations, fit). The teams must agree on the
    observation and action sizes, and with ``state`` on the state's size (``make_env`` lays
    every team's state out for the largest team's survey vehicles and beacons,
    ``CoopNavTorchEnv(state_survey_slots=..., state_beacon_slots=...)``, so MAPPO trains
    over teams of 1-5 survey vehicles and of other numbers of beacons).

    **Teams of other numbers of beacons**: the batch has ``n_beacons`` slots, the largest
    team's. A smaller team's missing beacons are padded slots: their observation a copy of
    its beacon 0's (so a network reads a real input), their reward 0, their action dropped
    before the team's environment steps (and in the state, zeros). ``agent_mask``
    (n_envs, n_beacons) is True for the real beacons; the loop leaves the others out of
    every mean, scaling and loss (None: every slot is real)."""

    def __init__(self, envs: Sequence[Any], state: bool = True) -> None:
        import torch

        from coopnav_env.torchrl_env import GROUP

        def sizes(e: Any) -> tuple[int, ...]:
            return (e.obs_dim, e.action_dim) + ((e.state_dim,) if state else ())

        what = "observation, action" + (" and state sizes" if state else " sizes")
        for i, e in enumerate(envs):
            if sizes(e) != sizes(envs[0]):
                raise ValueError(
                    f"teams[{i}]: {what} {sizes(e)}, the first team's {sizes(envs[0])}: one team makeup only"
                )
        self.envs = list(envs)
        self.sizes = [e.n_envs for e in envs]
        self.n_envs = sum(self.sizes)
        first = envs[0]
        self.n_beacons = max(e.n_beacons for e in envs)
        self.obs_dim, self.action_dim = first.obs_dim, first.action_dim
        self.state_dim = first.state_dim if state else 0
        self.agent_mask = None
        if any(e.n_beacons != self.n_beacons for e in envs):
            self.agent_mask = torch.cat(
                [torch.arange(self.n_beacons).expand(e.n_envs, -1) < e.n_beacons for e in envs], 0
            )
        root = [(GROUP, "observation"), "done", "terminated", "truncated", *(["state"] if state else [])]
        self._root = root
        self._step = [(GROUP, "action"), *[("next", k) for k in [*root, (GROUP, "reward"), ("info", "survey_error_m")]]]

    def _padded(self, td: Any) -> Any:
        """``td`` with its group entries (at ``GROUP`` and ``("next", GROUP)``) widened to
        ``n_beacons`` slots: observations by copies of beacon 0's, the rest by zeros."""
        import torch
        from tensordict import TensorDict

        from coopnav_env.torchrl_env import GROUP

        for path in ((GROUP,), ("next", GROUP)):
            group = td.get(path, None)
            if group is None or group.batch_size[1] == self.n_beacons:
                continue
            B, n = group.batch_size
            wide = {}
            for key, value in group.items():
                fill = value[:, :1] if key == "observation" else value[:, :1].new_zeros(())
                wide[key] = torch.cat([value, fill.expand(B, self.n_beacons - n, *value.shape[2:])], 1)
            td.set(path, TensorDict(wide, batch_size=(B, self.n_beacons)))
        return td

    def reset(self) -> Any:
        import torch

        return torch.cat([self._padded(e.reset().select(*self._root)) for e in self.envs], 0)

    def step_and_maybe_reset(self, td: Any) -> tuple[Any, Any]:
        import torch

        from coopnav_env.torchrl_env import GROUP

        outs, nexts, lo = [], [], 0
        for e, n in zip(self.envs, self.sizes):
            rows = td[lo : lo + n]
            if e.n_beacons != self.n_beacons:  # the team's own beacons' slots
                rows = rows.clone(False)
                rows.set(GROUP, rows.get(GROUP)[:, : e.n_beacons])
            out, nxt = e.step_and_maybe_reset(rows)
            outs.append(self._padded(out.select(*self._step)))
            nexts.append(self._padded(nxt.select(*self._root)))
            lo += n
        return torch.cat(outs, 0), torch.cat(nexts, 0)


def make_env(config: BatchedPPOConfig, stage: int = -1) -> Any:
    """The core's batch as a TorchRL environment; with ``config.teams`` a ``TeamEnvs``;
    ``stage`` k >= 0: the curriculum's stage k (its overrides on top of ``config.overrides``,
    episode seeds from ``config.seed + k * n_envs``, so no stage replays another's)."""
    from coopnav_env.scenarios import make_config
    from coopnav_env.torchrl_env import CoopNavTorchEnv

    state = "privileged" if config.critic == "state" else "observations"
    overrides = {**config.overrides, **(config.stages[stage][1] if stage >= 0 else {})}
    base_seed = config.seed + max(stage, 0) * config.n_envs
    slots = beacon_slots = None  # teams of other sizes: one state layout for the largest
    if config.teams and config.critic == "state":
        try:
            made = [make_config(config.scenario, **{**overrides, **team}) for team in config.teams]
            slots, beacon_slots = max(c.n_survey for c in made), max(c.n_beacons for c in made)
        except (TypeError, ValueError):
            slots = beacon_slots = None  # the team's own error, below, names it

    def one(n_envs: int, first: int, team: dict[str, Any]) -> Any:  # first: the environments before it
        return CoopNavTorchEnv(
            config.scenario,
            n_envs=n_envs,
            seed=base_seed + first,
            infos=True,
            state=state,
            reward_terms=config.reward_terms,
            observation=config.observation,
            state_survey_slots=slots,
            state_beacon_slots=beacon_slots,
            **{**overrides, **team},
        )

    if not config.teams:
        return one(config.n_envs, 0, {})
    k = len(config.teams)
    counts = [config.n_envs // k + (i < config.n_envs % k) for i in range(k)]
    envs, first = [], 0
    for i, (team, n) in enumerate(zip(config.teams, counts)):
        try:
            envs.append(one(n, first, team))
        except (TypeError, ValueError) as err:
            raise ValueError(f"teams[{i}] {team}: {err}") from None
        first += n
    return TeamEnvs(envs, state=config.critic == "state")


def validation_env(config: BatchedPPOConfig) -> list:
    """The environments ``validate_per_team`` plays its episodes in: the scenario with
    ``config.overrides``, or with ``eval_teams`` one per team (its overrides on top)."""
    from coopnav_env.torchrl_env import CoopNavTorchEnv

    teams = config.teams if config.eval_teams and config.teams else [{}]
    return [
        CoopNavTorchEnv(
            config.scenario,
            n_envs=config.eval_episodes,
            seed=config.eval_seed,
            infos=True,
            observation=config.observation,
            **{**config.overrides, **team},
        )
        for team in teams
    ]


def validate_per_team(
    actor: Any, obs_norm: RunningNorm | None, config: BatchedPPOConfig, envs: Any = None, role_slots: int = 0
) -> list[float]:
    """Per environment of ``validation_env`` (one, or one per team with ``eval_teams``): the
    mean over ``config.eval_episodes`` episodes (seeded ``eval_seed + i``) of each episode's
    mean survey error (m) under the actor's deterministic action (the Gaussian's mean, as
    ``agents.batched_policy`` acts): what ``evaluation.episodes.run_episodes`` gives the
    saved policy on those seeds and that scenario. ``envs``: the environments of an earlier
    call to play again (re-seeded here), else new ones. ``role_slots``: the actor's role input
    (0: none), each beacon's index as training gave it."""
    import torch

    from .scoring import episode_mean_error

    E, K = config.eval_episodes, config.history
    errors = []
    for env in envs if envs is not None else validation_env(config):
        window = torch.zeros(E, env.n_beacons, K, env.obs_dim)

        def act(obs: Any, first: Any) -> Any:
            nonlocal window
            if obs_norm is not None:
                obs = obs_norm.normalize(obs)
            window, obs = window_input(window, obs, first, K, role_slots)
            return actor(obs)

        errors.append(episode_mean_error(env, act, config.eval_seed))
    return errors
