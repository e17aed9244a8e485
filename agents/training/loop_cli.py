"""The batched PPO loop's command line (``python -m agents.training.batched_ppo``, whose
``main`` uses these): its flags (``parser``; ``--help`` lists them) and their checks before
any training (``settings``), each failure one line that ``main`` prints with exit status 2."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

from .cli import threads_arg
from .loop_config import CRITICS, ENTITY, BatchedPPOConfig
from .loop_envs import make_env
from .loop_init import load_sb3_actor


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


def parser(description: str) -> argparse.ArgumentParser:
    """The loop's flags, each with ``BatchedPPOConfig``'s default."""
    defaults = BatchedPPOConfig()
    p = argparse.ArgumentParser(description=description)
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
    p.add_argument("--threads", type=threads_arg, default=1, help="torch threads (1 to the machine's CPU count)")
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
        "such as ppo_gao_sea); needs the same --net, or for a flat run of this loop as many layers, each as wide or "
        "wider (the same function, widened: Net2WiderNet)",
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
        "a policy with no window or a shorter one, the older ones start with zero weights, so the run starts where "
        "the policy stands)",
    )
    p.add_argument(
        "--role",
        action="store_true",
        help="agent identity: the actor also reads its beacon's index (one-hot), so beacons that share the network "
        "can act apart (with --init-from a policy without it, its weights start at zero: the run starts where the "
        "policy stands); flat observations only",
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
    return p


def settings(args: argparse.Namespace, argv: Sequence[str] | None = None) -> tuple[BatchedPPOConfig, Path | None]:
    """The run's settings from parsed flags, checked before any training: the scenario's
    parameters, each stage's and the policy ``--init-from`` names are tried on a small
    environment, test seeds are refused, and ``--out`` must be a new or empty folder, which is
    then claimed for the run (``agents.training.runlock``). A ``ValueError`` (one line) names
    the first that does not fit."""
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
            raise ValueError(f"--stage takes AT [KEY=VALUE ...], AT a fraction in [0, 1), got {item[0]!r}") from None
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
        role=args.role,
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
            role_slots=probe.n_beacons if config.role else 0,
        )
    if out is not None:  # one trainer per folder (agents.training.runlock), as train.py's
        from . import runlock

        runlock.claim(out, new=True, command="python -m agents.training.batched_ppo " + " ".join(argv or sys.argv[1:]))
    return config, out
