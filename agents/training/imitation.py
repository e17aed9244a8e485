"""Behaviour cloning of a planner into a PPO policy before reinforcement learning.

A config's ``imitate:`` block (``ImitateSpec``) names a planner that drives the
scenario's network (``baselines``: ``river_escort``, ``abeam``, ``ellipse``, ...). Before
PPO's first rollout, ``imitate``:

1. drives the training environments (the run's own ``CoopNavVecEnv``, or flat
   ``MixedTeamVecEnv`` of ``env.teams``, under its VecNormalize, seeded as the run) with
   the planner for ``steps`` row-steps, each row a beacon with its own planner copy for
   its team's scenario (reset when its episode ends), recording the raw
   observations, the planner's actions, the rewards PPO would see (normalized when the
   run normalizes rewards) and the episode ends; VecNormalize's observation statistics
   are updated on the way, as they would be by training;
2. fits, with Adam, the actor's mean action to the planner's action (mean squared
   error) and the critic to the discounted returns of those rewards (``gamma`` of the
   PPO config; the returns of the rows' unfinished last episodes are cut at the end of
   the collection), ``epochs`` passes over the data in minibatches of ``batch_size``,
   on the observations normalized with the final statistics. The action noise
   (``log_std``) is left at ``log_std_init``.

PPO then starts from a policy that acts like the planner, with a critic that knows
roughly what that is worth: the field's remedy (demonstration-initialized RL) when
exploring from scratch rarely finds what a heuristic does by construction, as in
``matos_river``, where boats must escort a vehicle 1.6 km down a winding river. The
environment steps spent here are reported (``imitation`` in the run's config.yml and
on stdout), not counted in ``timesteps``.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

__all__ = ["imitate"]


def collect(
    vecnorm: Any,
    raw_env: Any,
    planner: str,
    steps: int,
    seed: int,
    progress: bool = False,
    planner_kwargs: dict | None = None,
    driver: Any = None,
) -> dict:
    """Drive ``vecnorm`` (a VecNormalize over ``raw_env``'s rows, possibly through other
    wrappers) with ``planner`` (built with ``planner_kwargs``) for at least ``steps``
    row-steps (``progress``: a bar on a terminal, a line a minute elsewhere; the planners'
    minutes can be many). A privileged planner (the oracle) is told its row's truth before
    each decision, as the evaluation tells it (``baselines.tell_truth``), so the clone is of
    the oracle, not of the planner it falls back to without the truth. ``driver``: DAgger's
    collection, ``driver(raw observations) -> actions`` drives instead and the planner's
    actions are only recorded (its labels of the states the driver reaches)."""
    from baselines import make_policy
    from coopnav_env.progress import Progress

    rows = raw_env.num_envs
    # each row's scenario (a MixedTeamVecEnv row: its team's) and beacon name
    configs, agents = raw_env.get_attr("config"), raw_env.get_attr("agent")
    kw = dict(planner_kwargs or {})
    policies = [make_policy(planner, configs[r], seed=(seed, r), agent=agents[r], **kw) for r in range(rows)]
    truth = None  # per row (its simulator, its environment's row there), for a privileged planner
    if any(getattr(p, "privileged", False) for p in policies):
        truth = list(zip(raw_env.get_attr("sim"), raw_env.get_attr("env_index")))
    # entity rows (EntityVecEnv, MixedTeamVecEnv of entities): the policy learns from the entity
    # observation, the planners read each row's flat vector underneath (its team's own size)
    from coopnav_env.entity_views import EntityVecEnv, MixedTeamVecEnv

    entity = isinstance(raw_env, EntityVecEnv) or (
        isinstance(raw_env, MixedTeamVecEnv) and raw_env.observation == "entities"
    )
    vecnorm.reset()
    raw = vecnorm.get_original_obs()
    n_steps = -(-steps // rows)
    obs = np.empty((n_steps, rows, raw.shape[-1]), dtype=np.float32)
    acts = np.empty((n_steps, rows, raw_env.action_space.shape[0]), dtype=np.float32)
    rewards = np.empty((n_steps, rows), dtype=np.float32)
    dones = np.empty((n_steps, rows), dtype=bool)
    bar = Progress(
        n_steps * rows, unit="row-step", desc=f"imitating {planner}", mode=None if progress else "off", every_s=60.0
    )
    with bar:
        for t in range(n_steps):
            obs[t] = raw
            if truth is not None:
                tell_rows(policies, truth)
            seen = raw_env.get_attr("flat_observation") if entity else raw
            acts[t] = np.stack([p.act(seen[r]) for r, p in enumerate(policies)])
            _, rewards[t], dones[t], _ = vecnorm.step(acts[t] if driver is None else driver(raw))
            raw = vecnorm.get_original_obs()
            for r in np.flatnonzero(dones[t]):
                policies[r].reset()
            bar.update(rows)
    return {"obs": obs, "actions": acts, "rewards": rewards, "dones": dones}


def tell_rows(policies: list, truth: list) -> None:
    """Give each privileged policy of ``policies`` (one per VecEnv row) its row's truth:
    ``truth[r]`` is (the row's simulator, its environment's batch row); one snapshot per
    simulator."""
    from baselines import tell_truth

    by_sim: dict[int, tuple[Any, dict[int, list]]] = {}  # id(sim) -> (sim, {its row: the policies there})
    for p, (sim, b) in zip(policies, truth):
        by_sim.setdefault(id(sim), (sim, {}))[1].setdefault(b, []).append(p)
    for sim, by_row in by_sim.values():
        tell_truth(by_row, sim)


def discounted_returns(rewards: np.ndarray, dones: np.ndarray, gamma: float) -> np.ndarray:
    """Per row, sum_k gamma^k r_{t+k} up to the episode's end (rewards, dones (T, rows));
    the rows' last, unfinished episodes are cut at T."""
    out = np.zeros_like(rewards, dtype=np.float64)
    running = np.zeros(rewards.shape[1])
    for t in range(rewards.shape[0] - 1, -1, -1):
        running = rewards[t] + gamma * running * (~dones[t])
        out[t] = running
    return out


def imitate(model: Any, vecnorm: Any, raw_env: Any, spec: Any, seed: int, progress: bool = False) -> dict:
    """Clone ``spec.planner`` into ``model`` (an SB3 PPO whose env is ``vecnorm``), then run
    ``spec.dagger_rounds`` rounds of DAgger; returns what was done (steps, final losses,
    seconds; per DAgger round, the clone's action error on the states it reached before it
    was fitted again). ``progress``: ``collect``'s."""
    from coopnav_env.progress import stage

    t0 = time.perf_counter()
    stage(
        f"imitation: {spec.planner} drives the training environments for {spec.steps:,} row-steps, "
        "then the clone is fitted"
    )
    data = [collect(vecnorm, raw_env, spec.planner, spec.steps, seed, progress, spec.planner_kwargs)]
    fit = _fit(model, vecnorm, data, spec, seed)
    rounds = []
    for k in range(int(getattr(spec, "dagger_rounds", 0))):
        steps = int(getattr(spec, "dagger_steps", 0)) or spec.steps
        stage(f"DAgger round {k + 1}: the clone drives for {steps:,} row-steps, {spec.planner} labels its states")

        def drive(raw: np.ndarray) -> np.ndarray:
            return model.predict(vecnorm.normalize_obs(raw), deterministic=True)[0]

        data.append(collect(vecnorm, raw_env, spec.planner, steps, seed + k + 1, progress, spec.planner_kwargs, drive))
        x, a, _ = _tensors(model, vecnorm, data[-1:])
        before = _action_rms(model.policy, x, a)  # the clone against the planner where the clone went
        fit = _fit(model, vecnorm, data, spec, seed + k + 1)
        rounds.append({"steps": int(data[-1]["actions"][..., 0].size), "action_rms_error_before": round(before, 4)})
    out = {
        "planner": spec.planner,
        "planner_kwargs": dict(spec.planner_kwargs),
        "steps": int(sum(d["actions"][..., 0].size for d in data)),
        "epochs": spec.epochs,
        **fit,
        "seconds": round(time.perf_counter() - t0, 1),
    }
    if rounds:
        out["dagger"] = rounds
    return out


def _tensors(model: Any, vecnorm: Any, data: list) -> tuple:
    """(normalized observations, planner actions, discounted returns) of ``data`` (collect's
    outputs), as float32 tensors on the model's device."""
    import torch

    gamma = float(model.gamma)
    obs = np.concatenate([d["obs"].reshape(-1, d["obs"].shape[-1]) for d in data])
    acts = np.concatenate([d["actions"].reshape(-1, d["actions"].shape[-1]) for d in data])
    returns = np.concatenate([discounted_returns(d["rewards"], d["dones"], gamma).reshape(-1) for d in data])
    device = model.policy.device
    x = torch.as_tensor(vecnorm.normalize_obs(obs), dtype=torch.float32, device=device)
    a = torch.as_tensor(acts, dtype=torch.float32, device=device)
    g = torch.as_tensor(returns, dtype=torch.float32, device=device)
    return x, a, g


def _action_rms(policy: Any, x: Any, a: Any) -> float:
    """The RMS of the clone's mean action (clipped to the box) minus the planner's ``a`` at the
    normalized observations ``x``."""
    import torch

    policy.set_training_mode(False)
    with torch.no_grad():  # in batches: an entity encoder over every row at once is large
        sq = sum(
            float(
                (
                    (policy.get_distribution(x[i : i + 65536]).distribution.mean.clamp(-1.0, 1.0) - a[i : i + 65536])
                    ** 2
                ).sum()
            )
            for i in range(0, len(x), 65536)
        )
    return float(np.sqrt(sq / a.numel()))


def _fit(model: Any, vecnorm: Any, data: list, spec: Any, seed: int) -> dict:
    """Fit the actor's mean to the planner's actions and the critic to the returns over all of
    ``data``: ``spec.epochs`` passes in minibatches; returns the last losses and the RMS."""
    import torch

    x, a, g = _tensors(model, vecnorm, data)
    policy = model.policy
    optimizer = torch.optim.Adam(policy.parameters(), lr=spec.learning_rate)
    rng = np.random.default_rng(seed)
    n = len(x)
    actor_loss = critic_loss = float("nan")
    policy.set_training_mode(True)
    for _ in range(spec.epochs):
        order = torch.as_tensor(rng.permutation(n), device=x.device)
        for start in range(0, n, spec.batch_size):
            idx = order[start : start + spec.batch_size]
            mean = policy.get_distribution(x[idx]).distribution.mean
            value = policy.predict_values(x[idx]).squeeze(-1)
            la = ((mean - a[idx]) ** 2).mean()
            lv = ((value - g[idx]) ** 2).mean()
            optimizer.zero_grad()
            (la + 0.5 * lv).backward()
            torch.nn.utils.clip_grad_norm_(policy.parameters(), 0.5)
            optimizer.step()
            actor_loss, critic_loss = float(la.detach()), float(lv.detach())
    policy.set_training_mode(False)
    return {
        "action_rms_error": round(_action_rms(policy, x, a), 4),
        "actor_loss": round(actor_loss, 5),
        "critic_loss": round(critic_loss, 5),
    }
