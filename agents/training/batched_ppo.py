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

Needs the ``marl`` extra (torchrl, tensordict).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from agents.batched_policy import WEIGHTS, entity_net, is_batched_path, mlp, push_window

from .config import EntitySpec

CRITICS = ("state", "observation")
ENTITY = asdict(EntitySpec())  # --entity: train.py's default encoder, the shipped entity policies'
MAX_HISTORY = 64  # observations in the window at most (the rollout buffer grows with it)
TRAINER = "batched_ppo"  # run.json's "trainer" (agents.batched_policy.is_batched_path)


@dataclass
class BatchedPPOConfig:
    """The loop's settings (``--help`` lists them with their defaults)."""

    scenario: str = "sousa_asv"
    n_envs: int = 4096  # environments in the core's batch
    n_steps: int = 32  # steps per environment per iteration
    epochs: int = 2  # passes over each batch
    minibatch: int = 32768  # env-steps per gradient step
    learning_rate: float = 3e-4
    gamma: float = 0.95
    gae_lambda: float = 0.95
    clip_range: float = 0.2
    ent_coef: float = 0.0
    vf_coef: float = 0.5
    max_grad_norm: float = 0.5
    net: tuple[int, ...] = (128, 128)
    log_std_init: float = -1.0
    critic: str = "state"  # "state": MAPPO's centralized critic; "observation": IPPO's
    norm_obs: bool = True  # observations and state scaled by their running mean and std (SB3's VecNormalize)
    norm_reward: bool = True
    seed: int = 0
    overrides: dict[str, Any] = field(default_factory=dict)  # scenario parameters
    reward_terms: dict[str, float] | None = (
        None  # None: the env's reward; {signal: weight}: core.reward's training signals
    )
    teams: list[dict[str, Any]] = field(default_factory=list)  # per team, scenario overrides (train.py's env.teams)
    init_from: str | None = None  # a train.py run or shipped SB3 policy whose actor the run starts from
    critic_warmup_iterations: int = 0  # iterations that train only the critic (the actor held)
    # pay each step its reward minus the running mean step reward (average-reward RL's differential
    # reward): where the policy can make episodes longer or shorter, length is then worth nothing to
    # first order (docs/training/marl.md#episode-length)
    center_reward: bool = False
    center_per_team: bool = False  # with center_reward and teams: a rho per team, each its own running mean
    # with teams: the advantages scaled to mean 0, std 1 within each team (False: over the batch)
    norm_adv_per_team: bool = False
    # memory as a window: the actor (and IPPO's critic) sees the last `history` observations of its
    # beacon, newest first (the "a history of the survey's reports"); 1: the current one only
    history: int = 1
    # a curriculum: [at, overrides] pairs, `at` the fraction of the iterations from which the stage's
    # scenario parameters apply on top of `overrides` (until the next stage); empty: none
    stages: list[tuple[float, dict[str, Any]]] = field(default_factory=list)
    # validation (with an output folder): every `eval_every_steps` env-steps (0: never) and at the
    # end, the deterministic actor plays `eval_episodes` episodes seeded eval_seed + i on the
    # scenario with `overrides` (no team, no stage); the best weights so far go to <out>/best
    eval_every_steps: int = 0
    eval_episodes: int = 16
    eval_seed: int = 500_000  # coopnav_env.seeds.VALIDATION_SEED, as train.py's eval.seed
    # with teams: the validation plays `eval_episodes` episodes (the same seeds) on each team's
    # scenario and scores the mean over the teams (False: the scenario with `overrides` alone)
    eval_teams: bool = False
    # entity observations through agents.entity.EntityEncoder(**entity) (None: the flat observation)
    entity: dict[str, Any] | None = None

    @property
    def observation(self) -> str:
        """The environments' observation: ``"entities"`` with ``entity``, else ``"flat"``."""
        return "flat" if self.entity is None else "entities"

    def stage_at(self, it: int, iterations: int) -> int:
        """The index of the stage iteration ``it`` of ``iterations`` trains in (-1: before any)."""
        out = -1
        for k, (at, _) in enumerate(self.stages):
            if it >= at * iterations:
                out = k
        return out

    def check(self) -> None:
        """One-line ``ValueError`` naming the first bad setting."""
        for name in ("n_envs", "n_steps", "epochs", "minibatch"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {v!r}")
        if self.eval_teams and not self.teams:
            raise ValueError("eval_teams validates on every team: it needs teams (--team)")
        if self.critic not in CRITICS:
            raise ValueError(f"critic must be one of {', '.join(CRITICS)}, got {self.critic!r}")
        if len(self.teams) > self.n_envs or any(not isinstance(t, dict) for t in self.teams):
            raise ValueError(f"teams must be at most n_envs ({self.n_envs}) mappings of overrides, got {self.teams!r}")
        if self.center_per_team and not self.center_reward:
            raise ValueError("center_per_team needs center_reward (--center-reward)")
        if self.norm_adv_per_team and len(self.teams) < 2:
            raise ValueError("norm_adv_per_team scales each team's advantages: it needs two teams or more (--team)")
        h = self.history
        if isinstance(h, bool) or not isinstance(h, int) or not 1 <= h <= MAX_HISTORY:
            raise ValueError(f"history must be an integer in 1..{MAX_HISTORY}, got {h!r}")
        ats = [at for at, _ in self.stages]
        if any(isinstance(a, bool) or not isinstance(a, (int, float)) or not 0.0 <= a < 1.0 for a in ats) or any(
            not isinstance(o, dict) for _, o in self.stages
        ):
            raise ValueError(f"stages must be [fraction in [0, 1), overrides] pairs, got {self.stages!r}")
        if ats != sorted(ats) or len(set(ats)) != len(ats):
            raise ValueError(f"stages must start at increasing fractions, got {', '.join(map(str, ats))}")
        if self.stages and self.stages[0][0] != 0.0:
            raise ValueError(f"the first stage must start at 0 (training needs a stage from its start), got {ats[0]}")
        for name, least in (("eval_every_steps", 0), ("eval_episodes", 1), ("eval_seed", 0)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < least:
                raise ValueError(f"{name} must be an integer >= {least}, got {v!r}")
        if self.entity is not None:
            from agents.entity import check_encoder_kwargs

            if not isinstance(self.entity, dict) or set(self.entity) - set(ENTITY):
                raise ValueError(f"entity must be a mapping of {', '.join(ENTITY)}, got {self.entity!r}")
            check_encoder_kwargs(**self.entity)
        w = self.critic_warmup_iterations
        if isinstance(w, bool) or not isinstance(w, int) or w < 0:
            raise ValueError(f"critic_warmup_iterations must be an integer >= 0, got {w!r}")
        if not self.net or any(isinstance(h, bool) or not isinstance(h, int) or h < 1 for h in self.net):
            raise ValueError(f"net must be a non-empty list of layer widths >= 1, got {list(self.net)!r}")
        for name in ("gamma", "gae_lambda"):
            v = getattr(self, name)
            if not 0.0 <= v <= 1.0:
                raise ValueError(f"{name} must be in [0, 1], got {v!r}")
        for name in ("learning_rate", "clip_range", "max_grad_norm"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a positive number, got {v!r}")


def load_sb3_actor(
    source: str,
    scenario: str,
    net: Sequence[int],
    obs_dim: int,
    action_dim: int,
    reward_terms: dict[str, float] | None = None,
    history: int = 1,
    entity: dict[str, Any] | None = None,
) -> dict:
    """The actor of a train.py run, a run of this loop or a shipped policy (``agents.resolve``:
    a name such as ``ppo_gao_team``, ``ppo`` for the scenario's, or a run folder) as this
    loop's tensors:
    ``{"actor": state_dict of mlp(obs_dim, net, action_dim), "log_std", "obs_mean",
    "obs_var", "obs_count", "ret_var", "ret_count"}``. SB3's flat ``MlpPolicy`` with tanh
    (``mlp_extractor.policy_net`` then ``action_net``) is the same function as ``mlp``'s
    Linear-tanh stack, and VecNormalize's scaling is ``RunningNorm``'s, so the loop starts
    where that policy stands. The return's statistics (``ret_var``, ``ret_count``) come only
    when the run trains on the reward that policy was trained on (``reward_terms`` against its
    config.yml's ``reward``; None and {} both the environment's): another reward has another
    scale. With ``history`` > 1 the first layer is widened to the window with zeros
    (``widen_to_history``): the actor starts as the policy was. With ``entity`` (the run's
    encoder settings) the policy must be an SB3 entity policy with that encoder: its
    ``pi_features_extractor`` becomes ``entity_net``'s ``encoder``, its MLP the ``head``
    (``{"actor": state_dict of entity_net(...)}``; no observation statistics, since the
    entity features are not normalized). A loop run's actor is read from its folder
    (``_load_loop_actor``). A ``ValueError`` (one line) names what does not fit."""
    import torch

    from agents import resolve
    from agents.formats import read_model, read_vecnormalize, safe_yaml

    model, stats, config_file = resolve(source, scenario)
    if Path(str(model)).name == WEIGHTS and is_batched_path(Path(str(model)).parent):
        return _load_loop_actor(source, Path(str(model)).parent, net, obs_dim, action_dim, history, entity)
    if Path(str(model)).suffix != ".safetensors":
        raise ValueError(f"--init-from {source}: {model} is not an SB3 model file (a flat MlpPolicy run or policy)")
    spec, state, _ = read_model(model)
    kwargs = spec.get("policy_kwargs") or {}
    if spec.get("policy") != "MlpPolicy" or kwargs.get("activation_fn", "tanh") != "tanh":
        raise ValueError(
            f"--init-from {source}: {spec.get('policy')} with {kwargs.get('activation_fn')}; "
            "only SB3's MlpPolicy with tanh maps onto this loop's actor"
        )
    extractor = kwargs.get("features_extractor_class")
    if (extractor == "EntityExtractor") != (entity is not None):
        raise ValueError(
            f"--init-from {source}: an entity policy (EntityExtractor): add --entity"
            if extractor == "EntityExtractor"
            else f"--init-from {source}: a flat policy ({extractor or 'no features extractor'}); --entity needs an "
            "entity policy (ppo_gao_sea, ppo_gao_lawnmower, ...)"
        )
    if entity is not None:
        from agents.entity import check_encoder_kwargs

        fe_kwargs = dict(kwargs.get("features_extractor_kwargs") or {})
        check_encoder_kwargs(**fe_kwargs)  # its layout is this code's entity view
        own = {k: v for k, v in fe_kwargs.items() if k != "layout"}
        if {**ENTITY, **own} != entity:
            raise ValueError(f"--init-from {source}: its encoder is {own}, the run's {entity}")
    widths = [int(state[f"mlp_extractor.policy_net.{2 * i}.weight"].shape[0]) for i in range(len(net))]
    if tuple(widths) != tuple(net) or f"mlp_extractor.policy_net.{2 * len(net)}.weight" in state:
        arch = kwargs.get("net_arch")
        raise ValueError(f"--init-from {source}: its actor is {arch}, the loop's --net {','.join(map(str, net))}")
    n_in = int(state["mlp_extractor.policy_net.0.weight"].shape[1])
    if entity is not None:  # the MLP reads the encoder's features; the policy reads entity observations
        n_in = int((spec.get("observation_space") or {}).get("shape", [-1])[0])
    n_out = int(state["action_net.weight"].shape[0])
    if (n_in, n_out) != (obs_dim, action_dim):
        raise ValueError(
            f"--init-from {source}: observations {n_in} and actions {n_out}, the environment's {obs_dim} and "
            f"{action_dim} (a policy of another scenario or observation?)"
        )
    head = "head." if entity is not None else ""  # entity_net's MLP is its module "head"
    actor = {}
    for i in range(len(net)):
        for part in ("weight", "bias"):
            actor[f"{head}{2 * i}.{part}"] = state[f"mlp_extractor.policy_net.{2 * i}.{part}"]
    for part in ("weight", "bias"):
        actor[f"{head}{2 * len(net)}.{part}"] = state[f"action_net.{part}"]
    actor[f"{head}0.weight"] = widen_to_history(actor[f"{head}0.weight"], history)
    if entity is not None:  # SB3 shares one extractor between actor and critic; the actor's copy
        prefix = next(
            p for p in ("pi_features_extractor.net.", "features_extractor.net.") if any(k.startswith(p) for k in state)
        )
        actor.update({"encoder." + k[len(prefix) :]: v for k, v in state.items() if k.startswith(prefix)})
    out: dict[str, Any] = {"actor": actor, "log_std": state["log_std"]}
    if stats is not None:
        vn = read_vecnormalize(stats)
        if entity is None:
            out.update(
                obs_mean=torch.as_tensor(vn["obs_mean"], dtype=torch.float64),
                obs_var=torch.as_tensor(vn["obs_var"], dtype=torch.float64),
                obs_count=vn["obs_count"],
            )
        trained_on = None
        if config_file is not None and Path(config_file).is_file():
            hyper = (safe_yaml(config_file) or {}).get("hyperparameters") or {}
            trained_on = {k: float(v) for k, v in (hyper.get("reward") or {}).items()}
        if trained_on is not None and trained_on == dict(reward_terms or {}):
            out.update(
                ret_var=torch.as_tensor(vn["ret_var"], dtype=torch.float64).reshape(()), ret_count=vn["ret_count"]
            )
    return out


def widen_to_history(weight: Any, history: int) -> Any:
    """A first layer's weight (H, O) for a window of ``history`` observations, newest first
    (H, history x O): the newest observation's columns are ``weight``, the older ones' zeros,
    so the widened actor is the same function of the newest observation and learns what the
    older ones are worth. With ``history`` 1 the weight is returned as it is."""
    import torch

    n_out, n_in = weight.shape
    if history == 1:
        return weight
    wide = torch.zeros((n_out, n_in * history), dtype=weight.dtype)
    wide[:, :n_in] = weight
    return wide


def _load_loop_actor(
    source: str,
    directory: Path,
    net: Sequence[int],
    obs_dim: int,
    action_dim: int,
    history: int,
    entity: dict[str, Any] | None = None,
) -> dict:
    """``load_sb3_actor``'s tensors from a run of this loop (``actor.safetensors``,
    ``run.json``): its actor (widened to ``history`` if its own window is 1), log std and
    observation scaling with its count (runs saved before the count was kept: their
    env-steps), so the scaling moves as slowly as it did. Its return's scale is not kept by a
    run, so it starts anew."""
    import torch
    from safetensors.torch import load_file

    from agents.formats import safe_json

    record = safe_json(directory / "run.json")
    run = record.get("config") or {}
    own = [int(h) for h in run.get("net") or ()]
    if tuple(own) != tuple(net):
        raise ValueError(f"--init-from {source}: its actor is {own}, the loop's --net {','.join(map(str, net))}")
    if (int(record.get("obs_dim", -1)), int(record.get("action_dim", -1))) != (obs_dim, action_dim):
        raise ValueError(
            f"--init-from {source}: observations {record.get('obs_dim')} and actions {record.get('action_dim')}, "
            f"the environment's {obs_dim} and {action_dim} (a policy of another scenario or observation?)"
        )
    if run.get("entity") != entity:
        raise ValueError(f"--init-from {source}: its entity encoder is {run.get('entity')}, the run's {entity}")
    own_history = int(run.get("history", 1))
    if own_history not in (1, history):
        raise ValueError(
            f"--init-from {source}: its window is {own_history} observations, the run's --history {history}"
        )
    weights = load_file(str(directory / WEIGHTS))
    actor = {k[len("actor.") :]: v for k, v in weights.items() if k.startswith("actor.")}
    first = "head.0.weight" if entity is not None else "0.weight"
    actor[first] = widen_to_history(actor[first], history // own_history)
    out: dict[str, Any] = {"actor": actor, "log_std": weights["log_std"]}
    if "obs_mean" in weights:
        out.update(
            obs_mean=weights["obs_mean"].to(torch.float64),
            obs_var=weights["obs_var"].to(torch.float64),
            obs_count=float(weights["obs_count"][0]) if "obs_count" in weights else float(record.get("steps", 1)),
        )
    return out


def gae(reward: Any, value: Any, next_value: Any, terminated: Any, done: Any, gamma: float, lam: float) -> Any:
    """Generalized advantage estimates (Schulman et al. 2016) over a rollout of T steps
    (leading axis): (P1) delta_t = r_t + gamma V(s'_t) (1 - terminated_t) - V(s_t), with
    s'_t the state step t ended in (the last state of an episode the cycle limit cut is
    bootstrapped (P2), a terminated one is not); A_t = delta_t + gamma lam (1 - done_t)
    A_t+1: the sum stops where an episode ended, since row t+1 is then a new episode.
    ``terminated`` and ``done`` broadcast against ``reward`` (e.g. (T, B, 1) against
    (T, B, N))."""
    import torch

    adv = torch.zeros_like(reward)
    last = torch.zeros_like(reward[0])
    for t in reversed(range(reward.shape[0])):
        delta = reward[t] + gamma * next_value[t] * (1.0 - terminated[t]) - value[t]
        last = delta + gamma * lam * (1.0 - done[t]) * last
        adv[t] = last
    return adv


def normalize_advantages(adv: Any, real: Any = None, team: Any = None) -> Any:
    """Advantages (M, N) scaled to mean 0 and std 1 over the real beacons' entries (``real``:
    their mask, None: all), over the whole batch or, with ``team`` (M, N) ids, within each team
    (``--norm-advantage-per-team``). A new tensor; entries outside ``real`` are scaled with the
    batch's figures (or, per team, left as they are): the update does not read them."""
    if team is None:
        pick = adv if real is None else adv[real]
        return (adv - pick.mean()) / (pick.std() + 1e-8)
    out = adv.clone()
    for k in team.unique().tolist():
        own = team == k if real is None else (team == k) & real
        if int(own.sum()) > 1:
            out[own] = (adv[own] - adv[own].mean()) / (adv[own].std() + 1e-8)
        else:  # one entry: its advantage less its mean
            out[own] = 0.0
    return out


class RunningNorm:
    """Running mean and variance of vectors of ``shape`` (the parallel update of Chan, Golub &
    LeVeque 1979, as SB3's ``RunningMeanStd``); ``normalize(x)`` = clip((x - mean) /
    sqrt(var + 1e-8), -clip, clip), in float32."""

    def __init__(self, shape: tuple[int, ...], clip: float = 10.0) -> None:
        import torch

        self.mean = torch.zeros(shape, dtype=torch.float64)
        self.var = torch.ones(shape, dtype=torch.float64)
        self.count = 1e-4
        self.clip = clip

    def update(self, x: Any) -> None:
        x = x.reshape(-1, *self.mean.shape).double()
        n = x.shape[0]
        mean, var = x.mean(0), x.var(0, unbiased=False)
        delta, total = mean - self.mean, self.count + n
        self.var = (self.var * self.count + var * n + delta**2 * self.count * n / total) / total
        self.mean = self.mean + delta * n / total
        self.count = total

    def normalize(self, x: Any) -> Any:
        import torch

        z = (x - self.mean.float()) / torch.sqrt(self.var.float() + 1e-8)
        return z.clamp(-self.clip, self.clip)


def next_state_values(value: Any, at_ends: Any, done: Any, last_value: Any) -> Any:
    """V of the state each step ended in, (T, B, N): where the episode went on, that state is
    the next step's, so its value is ``value[t + 1]`` (``last_value`` after the rollout's last
    step); where it ended (``done`` (T, B, 1)), ``at_ends[t]``, the value of the episode's
    last state computed before the reset replaced it."""
    import torch

    following = torch.cat([value[1:], last_value[None]])
    return torch.where(done == 0.0, following, at_ends)


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


def window_input(window: Any, obs: Any, first: Any, history: int) -> tuple[Any, Any]:
    """(the window after ``obs``, the actor's input): with ``history`` 1 the observation
    itself, else ``push_window``'s window (..., K, O) and its K observations side by side
    (..., K x O), newest first. Collection, the episode ends' values and validation share it."""
    if history == 1:
        return window, obs
    window = push_window(window, obs, first)
    return window, window.flatten(-2)


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
    actor: Any, obs_norm: RunningNorm | None, config: BatchedPPOConfig, envs: Any = None
) -> list[float]:
    """Per environment of ``validation_env`` (one, or one per team with ``eval_teams``): the
    mean over ``config.eval_episodes`` episodes (seeded ``eval_seed + i``) of each episode's
    mean survey error (m) under the actor's deterministic action (the Gaussian's mean, as
    ``agents.batched_policy`` acts): what ``evaluation.episodes.run_episodes`` gives the
    saved policy on those seeds and that scenario. ``envs``: the environments of an earlier
    call to play again (re-seeded here), else new ones."""
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
            window, obs = window_input(window, obs, first, K)
            return actor(obs)

        errors.append(episode_mean_error(env, act, config.eval_seed))
    return errors


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
    OK = O * K  # the actor's input: the window of its beacon's last K observations, newest first
    entity = config.entity
    norm_actor_obs = config.norm_obs and entity is None  # entity features come scaled
    actor = mlp(OK, config.net, D, 0.01) if entity is None else entity_net(entity, config.net, D, 0.01, K)
    log_std = nn.Parameter(torch.full((D,), float(config.log_std_init)))
    init = None
    if config.init_from is not None:  # the loop starts where that policy stands; the critic is new
        init = load_sb3_actor(config.init_from, config.scenario, config.net, O, D, config.reward_terms, K, entity)
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
                window, obs = window_input(window, obs, first, K)
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
                    _, end_obs = window_input(window, end_obs, torch.zeros_like(first), K)
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
            _, last_obs = window_input(window, last_obs, first, K)
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
            per_team = validate_per_team(actor, obs_norm if norm_actor_obs else None, config, eval_env)
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
                save(out / "best", actor, log_std, config, steps, time.perf_counter() - start, O, D, norms, extra)
        if out is not None and steps // save_every_steps > (steps - M) // save_every_steps and it + 1 < iterations:
            save(out, actor, log_std, config, steps, time.perf_counter() - start, O, D, norms)
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
        save(out, actor, log_std, config, steps, seconds, O, D, norms)
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
) -> None:
    """``actor.safetensors`` and ``run.json`` in ``out`` (``agents.batched_policy`` reads
    them), each written atomically; ``extra``: more fields of ``run.json``."""
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
        "steps": steps,
        "seconds": round(seconds, 1),
        **(extra or {}),
    }
    atomic_write_bytes(out / "run.json", (json.dumps(record, indent=1) + "\n").encode())


def _team(text: str) -> dict[str, Any]:
    """One ``--team`` value: a YAML mapping of scenario overrides."""
    import yaml

    try:
        team = yaml.safe_load(text)
    except yaml.YAMLError:
        team = None
    if team is None and not text.strip():  # --team '' is the scenario as it is, as '{}'
        team = {}
    if not isinstance(team, dict):
        raise ValueError(
            f"--team takes a YAML mapping of scenario parameters, e.g. '{{current_speed_mps: 0.5}}', got {text!r}"
        )
    return team


def main(argv: Sequence[str] | None = None) -> int:
    defaults = BatchedPPOConfig()
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--scenario", default=defaults.scenario)
    p.add_argument("--timesteps", type=int, required=True, help="env-steps in all (one step of one environment)")
    p.add_argument("--out", help="new or empty folder for actor.safetensors, run.json, log.jsonl")
    p.add_argument("--critic", choices=CRITICS, default=defaults.critic, help="state: MAPPO; observation: IPPO")
    p.add_argument("--n-envs", type=int, default=defaults.n_envs)
    p.add_argument(
        "--n-steps",
        type=int,
        default=defaults.n_steps,
        help="steps per environment per rollout (default %(default)s); continuing a policy on a new critic, "
        "use about an episode's length or more (gao_sea: 256; docs/training/marl.md#levers-rollout)",
    )
    p.add_argument("--epochs", type=int, default=defaults.epochs)
    p.add_argument("--minibatch", type=int, default=defaults.minibatch)
    p.add_argument("--learning-rate", type=float, default=defaults.learning_rate)
    p.add_argument("--gamma", type=float, default=defaults.gamma)
    p.add_argument("--net", default=",".join(map(str, defaults.net)), help="hidden layer widths, e.g. 128,128")
    p.add_argument("--seed", type=int, default=defaults.seed)
    p.add_argument("--threads", type=int, default=1, help="torch threads")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="a scenario parameter (YAML value)")
    p.add_argument(
        "--reward-term",
        action="append",
        default=[],
        metavar="SIGNAL=WEIGHT",
        help="train on core.reward's training signals (repeatable, e.g. std=1 penalties=1; default: the env's reward)",
    )
    p.add_argument(
        "--team",
        action="append",
        default=[],
        metavar="YAML",
        help="a team of settings trained beside the others, as train.py's env.teams (repeatable; "
        "e.g. --team '{}' --team '{current_speed_mps: 0.5}'); the environments are dealt to the teams",
    )
    p.add_argument(
        "--init-from",
        metavar="POLICY",
        help="start the actor (and the observation scaling) from an SB3 policy or a run of this loop: a "
        "train.py run, a run folder of this loop or a shipped name (ppo_gao_team; with --entity an entity policy "
        "such as ppo_gao_sea); needs the same --net",
    )
    p.add_argument(
        "--entity",
        action="store_true",
        help="entity observations through the permutation-invariant attention encoder (agents.entity, as the SB3 "
        "entity policies): one network for any team; --team may then change the number of survey vehicles",
    )
    p.add_argument(
        "--critic-warmup",
        type=int,
        default=0,
        metavar="ITERATIONS",
        help="iterations that train only the critic before the actor moves (with --init-from)",
    )
    p.add_argument(
        "--center-reward",
        action="store_true",
        help="pay each step its reward minus the running mean step reward, so episode length is not paid for",
    )
    p.add_argument(
        "--history",
        type=int,
        default=defaults.history,
        metavar="K",
        help="memory as a window: the actor sees its beacon's last K observations, newest first (with --init-from "
        "the older ones start with zero weights, so the run starts where the policy stands)",
    )
    p.add_argument(
        "--center-reward-per-team",
        action="store_true",
        help="--center-reward with one running mean per --team (a team whose steps pay less is not paid to end "
        "its episodes sooner)",
    )
    p.add_argument(
        "--norm-advantage-per-team",
        action="store_true",
        help="with --team: scale each team's advantages to mean 0, std 1 on its own (a team whose rewards vary "
        "more does not outweigh the others); without it, over the whole batch",
    )
    p.add_argument(
        "--stage",
        action="append",
        nargs="+",
        default=[],
        metavar=("AT", "KEY=VALUE"),
        help="a curriculum stage (repeatable): from the fraction AT of training, these scenario parameters on top "
        "of --set until the next stage; the first at 0, a stage with none is --set itself, e.g. --stage 0 "
        "current_speed_spread_mps=0 --stage 0.5",
    )
    p.add_argument(
        "--eval-every-steps",
        type=int,
        default=defaults.eval_every_steps,
        metavar="N",
        help="with --out: every N env-steps and at the end, play --eval-episodes validation episodes with the "
        "deterministic actor and keep the best weights in <out>/best (a policy folder; 0: never)",
    )
    p.add_argument(
        "--eval-episodes",
        type=int,
        default=defaults.eval_episodes,
        help="validation episodes (16 are a noisy judge of small gains: the best of many validations on 16 "
        "picks noise; give 64 or more to pick between close weights)",
    )
    p.add_argument(
        "--eval-teams",
        action="store_true",
        help="with --team: validate on every team (--eval-episodes each, the same seeds) and keep the weights "
        "with the best mean over the teams (default: the scenario with --set alone)",
    )
    p.add_argument(
        "--eval-seed", type=int, default=defaults.eval_seed, help="validation episode i is seeded EVAL_SEED + i"
    )
    p.add_argument("--save-every-steps", type=int, default=5_000_000, help="also save the weights every N env-steps")
    p.add_argument("--no-progress", action="store_true")
    args = p.parse_args(argv)
    try:
        from .config import parse_assignments

        net = tuple(int(x) for x in args.net.split(","))
        overrides = parse_assignments(args.set, "--set")
        terms = {}
        for key, value in parse_assignments(args.reward_term, "--reward-term").items():
            try:
                terms[key] = float(value)
            except (TypeError, ValueError):
                raise ValueError(f"--reward-term {key}: the weight must be a number, got {value!r}") from None
        stages = []
        for item in args.stage:
            try:
                at = float(item[0])
            except ValueError:
                raise ValueError(
                    f"--stage takes AT [KEY=VALUE ...], AT a fraction in [0, 1), got {item[0]!r}"
                ) from None
            stages.append((at, parse_assignments(item[1:], "--stage")))
        config = BatchedPPOConfig(
            scenario=args.scenario,
            n_envs=args.n_envs,
            n_steps=args.n_steps,
            epochs=args.epochs,
            minibatch=args.minibatch,
            learning_rate=args.learning_rate,
            gamma=args.gamma,
            net=net,
            critic=args.critic,
            seed=args.seed,
            overrides=overrides,
            reward_terms=terms or None,
            teams=[_team(t) for t in args.team],
            init_from=args.init_from,
            center_reward=args.center_reward or args.center_reward_per_team,
            center_per_team=args.center_reward_per_team,
            norm_adv_per_team=args.norm_advantage_per_team,
            critic_warmup_iterations=args.critic_warmup,
            history=args.history,
            stages=stages,
            eval_every_steps=args.eval_every_steps,
            eval_episodes=args.eval_episodes,
            eval_seed=args.eval_seed,
            eval_teams=args.eval_teams,
            entity=dict(ENTITY) if args.entity else None,
        )
        config.check()
        if config.eval_every_steps and not args.out:
            raise ValueError("--eval-every-steps keeps the best weights in <out>/best: it needs --out")
        if args.timesteps < 1:
            raise ValueError(f"--timesteps must be >= 1, got {args.timesteps}")
        if args.save_every_steps < 1:
            raise ValueError(f"--save-every-steps must be >= 1, got {args.save_every_steps}")
        from coopnav_env.seeds import refuse_test_seeds

        refuse_test_seeds(args.seed, config.n_envs * max(1, len(config.stages)), what="--seed")
        if config.eval_every_steps:
            refuse_test_seeds(config.eval_seed, config.eval_episodes, what="--eval-seed")
        out = None
        if args.out:
            out = Path(args.out)
            if out.exists() and (not out.is_dir() or any(out.iterdir())):
                raise ValueError(f"--out {out} exists and is not an empty folder (nothing is overwritten)")
        import torch

        torch.set_num_threads(args.threads)
        small = BatchedPPOConfig(**{**asdict(config), "n_envs": max(1, len(config.teams))})
        probe = make_env(small)  # bad scenario parameters fail here, fast
        for k in range(len(config.stages)):  # and each stage's
            try:
                staged = make_env(small, k)
            except (TypeError, ValueError) as err:
                raise ValueError(f"--stage {config.stages[k][0]}: {err}") from None
            sizes = (staged.obs_dim, staged.action_dim, staged.state_dim)
            if sizes != (probe.obs_dim, probe.action_dim, probe.state_dim):
                raise ValueError(f"--stage {config.stages[k][0]}: the observation, action or state size changes")
        if config.init_from is not None:  # and a policy that does not fit
            load_sb3_actor(
                config.init_from,
                config.scenario,
                config.net,
                probe.obs_dim,
                probe.action_dim,
                history=config.history,
                entity=config.entity,
            )
        if out is not None:  # one trainer per folder (agents.training.runlock), as train.py's
            from . import runlock

            runlock.claim(
                out, new=True, command="python -m agents.training.batched_ppo " + " ".join(argv or sys.argv[1:])
            )
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
    last = result["log"][-1]
    print(
        f"{result['steps']:,} steps in {result['seconds']:.1f} s ({result['steps'] / result['seconds']:,.0f} steps/s); "
        f"last iteration: survey error {last['survey_error_m']} m"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
