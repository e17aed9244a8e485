"""PPO on the batched core in one readable loop (CleanRL's habit): MAPPO or IPPO over
``coopnav_env.torchrl_env.CoopNavTorchEnv``, with no framework between the loop and the
tensors.

    python -m agents.training.batched_ppo --scenario sousa_asv --timesteps 20000000 \\
        --out runs/sousa_asv_batched             # MAPPO, 4,096 environments, 2 epochs
    python -m agents.training.batched_ppo --scenario gao_team --critic observation ...   # IPPO
    python -m agents.training.batched_ppo --scenario gao_team --init-from ppo_gao_team \
        --critic-warmup 20 --team '{}' --team '{current_speed_mps: 0.5}' ...   # continue a shipped policy

Why it exists: BenchMARL's ``Experiment`` (``agents.training.marl``) spends 60-70 % of its
loop in its PPO update machinery (TensorDict losses, value estimators over the whole
batch; ``docs/performance.md#torchrl-throughput``); the simulator's step over a batch of
4,096 environments is a quarter of it. This loop keeps the update to what PPO needs, so the
batched core's speed reaches the training loop. It is a second trainer of the same
algorithm, not a second copy of the physics: the environment is the TorchRL view of the one
core.

**The algorithm** (Schulman et al. 2017; Yu et al. 2022 for MAPPO), each step where it is
computed below:

* actor: an MLP (tanh) from a beacon's observation to the mean of a Gaussian with a
  state-independent log standard deviation, shared by the beacons of the group; actions are
  clipped to [-1, 1] by the environment, the log-probability is the unclipped sample's;
* critic: ``"state"`` (MAPPO): an MLP on the environment's ``state`` (the privileged global
  state and every observation) with one value per beacon; ``"observation"`` (IPPO): the
  actor's input, one value each;
* advantages: GAE(γ, λ) (P1) with the value of the episode's last state bootstrapped when it
  ended by the cycle limit (truncated) and not when it terminated (P2);
* the clipped surrogate (P3), the value loss (P4), the entropy bonus, gradient clipping;
* observations and state scaled by their running mean and variance, the reward by a running
  standard deviation of the discounted return (as SB3's ``VecNormalize``; ``RunningNorm``);
* with ``--entity``, the entity observation (``coopnav_env.entity_obs``: the beacon's own
  state and role, each survey vehicle and each other beacon with its kind) through
  ``agents.entity``'s permutation-invariant encoder, then the MLP (``entity_net``; IPPO's
  critic the same network with one output), so ``--team`` may mix teams with other numbers
  of survey vehicles, and with IPPO of beacons too (``TeamEnvs``' padded slots, left out of
  the loss), and ``--init-from`` may
  name an SB3 entity policy (``ppo_gao_sea``); the entity features are scaled already (as
  SB3's entity policies train them), only the state is normalized;
* with ``--history K``, memory as a window: the actor (and IPPO's critic) sees its beacon's
  last K observations, newest first, each scaled as above (``push_window``: an episode's first
  step fills the window with its own observation); started from a policy, the older
  observations' weights start at zero (``widen_to_history``);
* with ``--role``, agent identity: the flat actor (and IPPO's critic) reads its beacon's index
  as a one-hot after the window (``role_input``), so beacons sharing the network can act apart;
  started from a policy without it, those inputs' weights start at zero;
* with ``--stage AT KEY=VALUE ...``, a curriculum: from the fraction AT of the iterations
  until the next stage, the stage's scenario parameters on top of ``--set`` (the stage with
  none is ``--set`` itself). At a stage's start the environments are built anew (episode
  seeds go on from the previous stage's, the episodes under way are dropped); the actor,
  critic, optimizer and the running scalings carry over;
* with ``--center-reward``, (P5) each step is paid r - ρ, ρ the running mean step reward
  (average-reward RL's differential reward), so a policy that can lengthen or shorten its
  episodes is not paid for the length itself; with ``--center-reward-per-team`` ρ is each
  team's own;
* with ``--norm-advantage-per-team``, each team's advantages are scaled to mean 0 and std 1
  over its own entries (per-task normalization, as PopArt's per-task scales in multi-task RL,
  Hessel et al. 2019), so a team whose rewards vary more does not outweigh the others in the
  policy's gradient; without it, over the whole batch.

**Output** (``--out``, a new or empty folder, locked for the run): ``actor.safetensors`` (the
actor's weights and the observation statistics: data, not a pickle; written every
``--save-every-steps`` and at the end), ``run.json`` (the settings, the scenario, the sizes, the
steps) and ``log.jsonl`` (one line per iteration: steps, seconds, the mean episode return and
survey error, the seconds in the simulator, the rest of collection and the update; with teams
each team's survey error, with ``--center-reward`` the ρ subtracted, with ``--eval-every-steps``
the validation error). With ``--eval-every-steps N``, ``best/`` holds the weights of the best
validation so far (a run folder of its own: its ``run.json`` adds ``validation_error_m`` and
the validation seeds), as ``train.py`` keeps its best model: a run's last weights are not
always its best.
``agents.batched_policy`` loads it as a policy. Measured: ``docs/performance.md#loop-throughput``
and ``docs/training/marl.md#levers-loop``.

**Where the parts are**: this module is the loop (``train``, top to bottom) and its output
(``save``); the settings are ``loop_config.BatchedPPOConfig``, the environments and the
validation ``loop_envs``, GAE and the running scalings ``loop_math``, the start from a policy
(``--init-from``) ``loop_init``, the command line's flags and checks ``loop_cli``. Each name is importable from
here too.

Needs the ``marl`` extra (torchrl, tensordict).
"""

from __future__ import annotations

import json
import math
import sys
import time
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

from agents.batched_policy import entity_net, mlp

# the loop's parts, each in its own module (and importable from here, as before the split)
from . import loop_cli
from .loop_config import CRITICS, ENTITY, MAX_HISTORY, BatchedPPOConfig
from .loop_envs import TeamEnvs, make_env, validate_per_team, validation_env
from .loop_init import load_sb3_actor, widen_layers, widen_to_history
from .loop_math import RunningNorm, gae, next_state_values, normalize_advantages, window_input

__all__ = [
    "CRITICS",
    "ENTITY",
    "MAX_HISTORY",
    "TRAINER",
    "BatchedPPOConfig",
    "RunningNorm",
    "TeamEnvs",
    "gae",
    "load_sb3_actor",
    "main",
    "make_env",
    "next_state_values",
    "normalize_advantages",
    "save",
    "train",
    "validate_per_team",
    "validation_env",
    "widen_layers",
    "widen_to_history",
    "window_input",
]

TRAINER = "batched_ppo"  # run.json's "trainer" (agents.batched_policy.is_batched_path)


def train(
    config: BatchedPPOConfig,
    total_steps: int,
    out: Path | None = None,
    progress: bool = True,
    threads: int | None = None,
    save_every_steps: int = 5_000_000,
) -> dict:
    """Trains for at least ``total_steps`` env-steps (one step of one environment); with
    ``out``, the weights and run.json are also written every ``save_every_steps`` (a run
    stopped early keeps its last save; ``run.json`` says its steps). Returns
    ``{"actor": ..., "critic": ..., "log": [...], "steps": ..., "seconds": ...}``; each log row has the
    iteration's wall seconds in the simulator (``env_s``), the rest of collection
    (``collect_s``) and the update (``update_s``); with teams, ``survey_error_m_per_team``.
    ``threads``: torch's threads, set after the environment is built (numba's start can
    reset them)."""
    import torch
    from torch import nn

    from coopnav_env.torchrl_env import GROUP

    config.check()
    torch.manual_seed(config.seed)
    iterations = max(1, math.ceil(total_steps / (config.n_envs * config.n_steps)))
    stage = config.stage_at(0, iterations)
    env = make_env(config, stage)
    if threads is not None:
        torch.set_num_threads(threads)
    B, N, O, D = env.n_envs, env.n_beacons, env.obs_dim, env.action_dim
    S = env.state_dim if config.critic == "state" else 0  # IPPO's critic reads no state
    T = config.n_steps
    K = config.history
    R = N if config.role else 0  # with role: its beacon's index as a one-hot after the window
    OK = O * K + R  # the actor's input: the window of its beacon's last K observations, newest first
    entity = config.entity
    norm_actor_obs = config.norm_obs and entity is None  # entity features come scaled
    actor = mlp(OK, config.net, D, 0.01) if entity is None else entity_net(entity, config.net, D, 0.01, K)
    log_std = nn.Parameter(torch.full((D,), float(config.log_std_init)))
    init = None
    if config.init_from is not None:  # the loop starts where that policy stands; the critic is new
        init = load_sb3_actor(config.init_from, config.scenario, config.net, O, D, config.reward_terms, K, entity, R)
        actor.load_state_dict({k: v.float() for k, v in init["actor"].items()})
        with torch.no_grad():
            log_std.copy_(init["log_std"].float())
    if config.critic == "state":
        critic = mlp(S, config.net, N, 1.0)
    else:
        critic = mlp(OK, config.net, 1, 1.0) if entity is None else entity_net(entity, config.net, 1, 1.0, K)
    params = [*actor.parameters(), log_std, *critic.parameters()]
    optimizer = torch.optim.Adam(params, lr=config.learning_rate, eps=1e-5)

    def values(state: Any, obs: Any) -> Any:  # (..., N)
        return critic(state) if config.critic == "state" else critic(obs).squeeze(-1)

    # teams of other numbers of beacons (TeamEnvs): the real beacons' slots; the padded
    # ones are left out of every mean, scaling and loss below, and out of the update's passes
    # (None: every slot is real)
    mask = getattr(env, "agent_mask", None)
    n_real = None if mask is None else mask.sum(-1)  # (B,) each row's real beacons

    # the rollout's buffers: T steps of B environments and N beacons
    obs_buf = torch.zeros(T, B, N, OK)
    state_buf = torch.zeros(T, B, S)
    act_buf = torch.zeros(T, B, N, D)
    logp_buf = torch.zeros(T, B, N)
    rew_buf = torch.zeros(T, B, N)
    val_buf = torch.zeros(T, B, N)
    next_val_buf = torch.zeros(T, B, N)
    term_buf = torch.zeros(T, B, 1)
    done_buf = torch.zeros(T, B, 1)

    ret_running = torch.zeros(B, N, dtype=torch.float64)  # discounted return, for the reward's scale
    ret_norm = RunningNorm(())
    step_norm = RunningNorm(())  # the step reward's running mean, for center_reward
    obs_norm, state_norm = RunningNorm((O,)), RunningNorm((S,))
    norms = obs_norm if norm_actor_obs else None  # what a saved policy scales its observations with
    if init is not None and "obs_mean" in init:  # its VecNormalize's statistics, as they were
        obs_norm.mean, obs_norm.var, obs_norm.count = init["obs_mean"], init["obs_var"], init["obs_count"]
    if init is not None and "ret_var" in init:  # the same reward: its return's scale too
        ret_norm.var, ret_norm.count = init["ret_var"], init["ret_count"]

    def observe(td: Any, update: bool = False) -> tuple[Any, Any]:
        """The (normalized) observations (B, N, O) and state (B, S) in ``td`` (S = 0: none)."""
        obs = td.get((GROUP, "observation"))
        state = td.get("state") if S else obs.new_zeros(obs.shape[0], 0)
        if update and norm_actor_obs:
            obs_norm.update(obs)
        if update and config.norm_obs and S:
            state_norm.update(state)
        if norm_actor_obs:
            obs = obs_norm.normalize(obs)
        if config.norm_obs and S:
            state = state_norm.normalize(state)
        return obs, state

    ep_return = torch.zeros(B)
    ep_error = torch.zeros(B, dtype=torch.float64)
    ep_len = torch.zeros(B)
    finished_returns: list[float] = []
    finished_errors: list[float] = []
    # with teams, each environment's team (its rows are contiguous) and the sum and count of the
    # errors of each team's finished episodes in the iteration
    sizes = getattr(env, "sizes", [B])
    team_of = torch.repeat_interleave(torch.arange(len(sizes)), torch.tensor(sizes))
    team_sum = torch.zeros(len(sizes), dtype=torch.float64)
    team_count = torch.zeros(len(sizes), dtype=torch.float64)
    # with center_per_team, each team's rows (a slice) and its own running mean step reward
    bounds = torch.cumsum(torch.tensor([0, *sizes]), 0).tolist()
    team_rows = [slice(bounds[k], bounds[k + 1]) for k in range(len(sizes))]
    team_norms = [RunningNorm(()) for _ in sizes]

    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=iterations * B * T, unit="step", unit_scale=True, desc=f"batched PPO {config.scenario}")
    log: list[dict] = []
    start = time.perf_counter()
    td = env.reset()
    window = torch.zeros(B, N, K, O)  # the last K normalized observations per beacon (push_window)
    first = torch.ones(B, dtype=torch.bool)  # rows whose next step is an episode's first
    steps = 0
    best_error: float | None = None  # the best validation error so far (eval_every_steps)
    eval_env = None  # the validation episodes' environment, built at the first validation
    for it in range(iterations):
        # ---- the curriculum's next stage: its environments, its episodes from their start --------
        if (now := config.stage_at(it, iterations)) != stage:
            stage = now
            env = make_env(config, stage)
            if (env.n_envs, env.n_beacons, env.obs_dim, env.action_dim) != (B, N, O, D) or (S and env.state_dim != S):
                raise ValueError(f"stages[{stage}]: the environment's sizes differ from the first stage's")
            td = env.reset()
            window.zero_()
            first = torch.ones(B, dtype=torch.bool)
            ep_return.zero_(), ep_error.zero_(), ep_len.zero_(), ret_running.zero_()
        # ---- collection -------------------------------------------------------------
        t_collect = time.perf_counter()
        env_s = 0.0
        with torch.no_grad():
            for t in range(T):
                obs, state = observe(td, update=True)
                window, obs = window_input(window, obs, first, K, R)
                mean = actor(obs)
                std = log_std.exp()
                action = mean + std * torch.randn_like(mean)
                logp = (-0.5 * ((action - mean) / std) ** 2 - log_std - 0.5 * math.log(2 * math.pi)).sum(-1)
                obs_buf[t], state_buf[t], act_buf[t], logp_buf[t] = obs, state, action, logp
                val_buf[t] = values(state, obs)
                td.set((GROUP, "action"), action)
                t0 = time.perf_counter()
                td, td_next = env.step_and_maybe_reset(td)
                env_s += time.perf_counter() - t0
                nxt = td.get("next")
                reward = nxt.get((GROUP, "reward")).squeeze(-1)
                term = nxt.get("terminated").float()
                done = nxt.get("done").float()
                # the value of the state the step ended in (P2). Where the episode goes on, that
                # state is the next step's, whose value the next step computes (filled in after
                # the loop); only an episode's last state needs its own forward pass here
                ended = done.squeeze(-1).bool()
                if ended.any():
                    end_obs, end_state = observe(nxt)
                    # the window as the episode's last state would have shown it
                    _, end_obs = window_input(window, end_obs, torch.zeros_like(first), K, R)
                    next_val_buf[t, ended] = values(end_state[ended], end_obs[ended])
                first = ended
                ep_return += reward.mean(-1) if mask is None else (reward * mask).sum(-1) / n_real
                ep_error += nxt.get(("info", "survey_error_m"))
                ep_len += 1
                if config.center_per_team:  # (P5) per team: a team whose cycles pay less is not paid to shorten them
                    reward = reward.clone()
                    for rows, norm in zip(team_rows, team_norms):
                        norm.update(reward[rows] if mask is None else reward[rows][mask[rows]])
                        reward[rows] -= norm.mean.float()
                elif config.center_reward:  # (P5) r - rho, rho the running mean step reward
                    step_norm.update(reward if mask is None else reward[mask])
                    reward = reward - step_norm.mean.float()
                if config.norm_reward:  # the running std of the discounted return (VecNormalize's)
                    ret_running = ret_running * config.gamma + reward.double()
                    ret_norm.update(ret_running if mask is None else ret_running[mask])
                    reward = torch.clamp(reward / math.sqrt(float(ret_norm.var) + 1e-8), -10.0, 10.0)
                rew_buf[t], term_buf[t], done_buf[t] = reward, term, done
                if ended.any():
                    finished_returns += ep_return[ended].tolist()
                    ended_errors = ep_error[ended] / ep_len[ended]
                    finished_errors += ended_errors.tolist()
                    team_sum.index_add_(0, team_of[ended], ended_errors)
                    team_count.index_add_(0, team_of[ended], torch.ones_like(ended_errors))
                    ep_return[ended], ep_error[ended], ep_len[ended] = 0.0, 0.0, 0.0
                    ret_running[ended] = 0.0
                td = td_next

            last_obs, last_state = observe(td)
            _, last_obs = window_input(window, last_obs, first, K, R)
            next_val_buf = next_state_values(val_buf, next_val_buf, done_buf, values(last_state, last_obs))
            adv = gae(rew_buf, val_buf, next_val_buf, term_buf, done_buf, config.gamma, config.gae_lambda)
            returns = adv + val_buf
        collect_s = time.perf_counter() - t_collect - env_s

        # ---- update -----------------------------------------------------------------
        t_update = time.perf_counter()
        M = T * B
        b_obs, b_state = obs_buf.reshape(M, N, OK), state_buf.reshape(M, S)
        b_act, b_logp = act_buf.reshape(M, N, D), logp_buf.reshape(M, N)
        b_adv, b_ret = adv.reshape(M, N), returns.reshape(M, N)
        b_real = None if mask is None else mask.expand(T, B, N).reshape(M, N)
        b_team = team_of.view(1, B, 1).expand(T, B, N).reshape(M, N) if config.norm_adv_per_team else None
        b_adv = normalize_advantages(b_adv, b_real, b_team)
        warmup = it < config.critic_warmup_iterations  # the critic learns the policy's values first
        mb = min(config.minibatch, M)
        clip_fractions = []
        for _ in range(config.epochs):
            order = torch.randperm(M)
            for lo in range(0, M, mb):
                idx = order[lo : lo + mb]
                if b_real is None:  # every slot a beacon's: (mb, N, ...)
                    obs_i, act_i, logp_i, adv_i, ret_i = (x[idx] for x in (b_obs, b_act, b_logp, b_adv, b_ret))
                    value = values(b_state[idx], obs_i)
                else:  # only the real beacons' entries (R, ...): a padded slot costs no actor pass
                    real = b_real[idx]
                    obs_i, act_i, logp_i, adv_i, ret_i = (x[idx][real] for x in (b_obs, b_act, b_logp, b_adv, b_ret))
                    # IPPO's critic reads the real beacons' observations; MAPPO's reads each row's
                    # state once, its values of the padded slots dropped
                    value = values(None, obs_i) if S == 0 else values(b_state[idx], None)[real]
                value_loss = 0.5 * (value - ret_i).pow(2).mean()  # (P4)
                if warmup:  # the actor held: its loss is not part of the step, nor its forward pass
                    loss = config.vf_coef * value_loss
                    clip_fractions.append(0.0)  # its ratio is 1
                else:
                    mean = actor(obs_i)
                    logp = (-0.5 * ((act_i - mean) / log_std.exp()) ** 2 - log_std - 0.5 * math.log(2 * math.pi)).sum(
                        -1
                    )
                    ratio = (logp - logp_i).exp()
                    # the clipped surrogate (P3)
                    clipped = ratio.clamp(1 - config.clip_range, 1 + config.clip_range)
                    policy_loss = -torch.min(ratio * adv_i, clipped * adv_i).mean()
                    entropy = (log_std + 0.5 * math.log(2 * math.pi * math.e)).sum()
                    loss = policy_loss + config.vf_coef * value_loss - config.ent_coef * entropy
                    clip_fractions.append(float(((ratio - 1).abs() > config.clip_range).float().mean()))
                optimizer.zero_grad(set_to_none=True)
                loss.backward()
                nn.utils.clip_grad_norm_(params, config.max_grad_norm)
                optimizer.step()
        update_s = time.perf_counter() - t_update

        steps += M
        row = {
            "iteration": it + 1,
            "steps": steps,
            "seconds": round(time.perf_counter() - start, 2),
            "episodes": len(finished_returns),
            "return_mean": float(sum(finished_returns) / len(finished_returns)) if finished_returns else None,
            "survey_error_m": float(sum(finished_errors) / len(finished_errors)) if finished_errors else None,
            "value_loss": float(value_loss.detach()),
            "env_s": round(env_s, 4),  # the simulator's steps and resets
            "collect_s": round(collect_s, 4),  # the rest of collection: forward passes, buffers, GAE
            "update_s": round(update_s, 4),
            "clip_fraction": float(sum(clip_fractions) / len(clip_fractions)),
            "action_std": [float(s) for s in log_std.detach().exp()],
        }
        if config.stages:
            row["stage"] = stage
        if config.center_per_team:  # each team's mean step reward subtracted
            row["reward_center"] = [float(norm.mean) for norm in team_norms]
        elif config.center_reward:  # the mean step reward subtracted, in the reward's units
            row["reward_center"] = float(step_norm.mean)
        if len(sizes) > 1:  # the mean survey error of each team's finished episodes (None: none ended)
            row["survey_error_m_per_team"] = [
                float(total / n) if n else None for total, n in zip(team_sum.tolist(), team_count.tolist())
            ]
        finished_returns, finished_errors = [], []
        team_sum.zero_(), team_count.zero_()
        every = config.eval_every_steps
        if out is not None and every and (steps // every > (steps - M) // every or it + 1 == iterations):
            if eval_env is None:  # built once: each validation re-seeds it
                eval_env = validation_env(config)
            per_team = validate_per_team(actor, obs_norm if norm_actor_obs else None, config, eval_env, R)
            row["validation_error_m"] = float(sum(per_team) / len(per_team))
            if len(per_team) > 1:
                row["validation_error_m_per_team"] = per_team
            if best_error is None or row["validation_error_m"] < best_error:
                best_error = row["validation_error_m"]
                extra = {
                    "validation_error_m": best_error,
                    "validation_seeds": [config.eval_seed, config.eval_seed + config.eval_episodes - 1],
                    **({"validation_error_m_per_team": per_team} if len(per_team) > 1 else {}),
                }
                save(
                    out / "best",
                    actor,
                    log_std,
                    config,
                    steps,
                    time.perf_counter() - start,
                    O,
                    D,
                    norms,
                    extra,
                    role_slots=R,
                )
        if out is not None and steps // save_every_steps > (steps - M) // save_every_steps and it + 1 < iterations:
            save(out, actor, log_std, config, steps, time.perf_counter() - start, O, D, norms, role_slots=R)
        log.append(row)
        if out is not None:
            with open(out / "log.jsonl", "a") as f:
                f.write(json.dumps(row) + "\n")
        if bar is not None:
            bar.update(M)
            if row["survey_error_m"] is not None:
                bar.set_postfix(error_m=f"{row['survey_error_m']:.2f}")
    if bar is not None:
        bar.close()
    seconds = time.perf_counter() - start
    if out is not None:
        save(out, actor, log_std, config, steps, seconds, O, D, norms, role_slots=R)
    return {
        "actor": actor,
        "critic": critic,
        "log_std": log_std,
        "obs_norm": obs_norm,
        "log": log,
        "steps": steps,
        "seconds": seconds,
    }


def save(
    out: Path,
    actor: Any,
    log_std: Any,
    config: BatchedPPOConfig,
    steps: int,
    seconds: float,
    obs_dim: int,
    action_dim: int,
    obs_norm: RunningNorm | None,
    extra: dict | None = None,
    role_slots: int = 0,
) -> None:
    """``actor.safetensors`` and ``run.json`` in ``out`` (``agents.batched_policy`` reads
    them), each written atomically; ``extra``: more fields of ``run.json``; ``role_slots``: the
    size of the actor's role input (0: none)."""
    import torch
    from safetensors.torch import save as save_bytes

    from coopnav_env.records import atomic_write_bytes

    tensors = {f"actor.{k}": v.detach().contiguous() for k, v in actor.state_dict().items()}
    tensors["log_std"] = log_std.detach().contiguous()
    if obs_norm is not None:  # the policy scales its observations as training did
        tensors["obs_mean"] = obs_norm.mean.float().contiguous()
        tensors["obs_var"] = obs_norm.var.float().contiguous()
        tensors["obs_count"] = torch.tensor([float(obs_norm.count)], dtype=torch.float64)  # for --init-from
    out.mkdir(exist_ok=True)
    atomic_write_bytes(out / "actor.safetensors", save_bytes(tensors))
    record = {
        "trainer": TRAINER,
        "config": asdict(config),
        "obs_dim": int(obs_dim),
        "action_dim": int(action_dim),
        **({"role_slots": int(role_slots)} if role_slots else {}),
        "steps": steps,
        "seconds": round(seconds, 1),
        **(extra or {}),
    }
    atomic_write_bytes(out / "run.json", (json.dumps(record, indent=1) + "\n").encode())


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m agents.training.batched_ppo``: the flags (``loop_cli.parser``), checked before
    any training (``loop_cli.settings``: a bad one is one line and exit status 2), then ``train``."""
    args = loop_cli.parser((__doc__ or "").split("\n")[0]).parse_args(argv)
    try:
        config, out = loop_cli.settings(args, argv)
    except (ValueError, ImportError) as err:
        print(f"batched_ppo: {err}", file=sys.stderr)
        return 2
    try:
        result = train(
            config,
            args.timesteps,
            out=out,
            progress=not args.no_progress,
            threads=args.threads,
            save_every_steps=args.save_every_steps,
        )
    finally:
        from . import runlock

        runlock.release_all()
    error = result["log"][-1]["survey_error_m"]
    last = "no episode ended" if error is None else f"survey error {error:.3f} m"
    print(
        f"{result['steps']:,} steps in {result['seconds']:.1f} s ({result['steps'] / result['seconds']:,.0f} steps/s); "
        f"last iteration: {last}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
