"""The batched PPO loop's settings (``agents.training.batched_ppo``): ``BatchedPPOConfig``,
one field per command-line flag, and its ``check``, which names the first bad setting in one
line."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

from .config import EntitySpec

CRITICS = ("state", "observation")
ENTITY = asdict(EntitySpec())  # --entity: train.py's default encoder, the shipped entity policies'
MAX_HISTORY = 64  # observations in the window at most (the rollout buffer grows with it)


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
    # agent identity: the flat actor (and IPPO's critic) reads its beacon's index as a one-hot after
    # its window (agents.batched_policy.role_input), so beacons sharing the network can act apart
    # (the entity view has a role input of its own)
    role: bool = False

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
        if self.role and self.entity is not None:
            raise ValueError("role is for flat observations: the entity view has its own role input (drop --role)")
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
