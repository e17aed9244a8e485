"""PPO beacon policies with stable-baselines3 on one machine.

    from agents.training import TrainConfig, sb3
    config = TrainConfig(scenario="gao_lawnmower", timesteps=20_000, n_envs=8, ppo={"n_steps": 128})
    sb3.train(config, "runs/gao_ppo")          # 0 when done, EXIT_INTERRUPTED after a signal
    sb3.resume("runs/gao_ppo")                 # continue it from its last checkpoint

Read ``train`` top to bottom: the run directory -> the job (scenario, reward,
evaluation cells) -> seeding -> the vectorized environment -> PPO -> the baselines on
the evaluation seeds -> learn (a callback checkpoints, evaluates, keeps the best
model, stops on a signal) -> final save. Every beacon of every environment is one
row of the batch, so one policy drives them all (parameter sharing:
``coopnav_env.vector.CoopNavVecEnv``).

What a run directory holds (data only, no pickle: ``agents.formats``):

    config.yml                 the exact config (see agents.training.common)
    model.safetensors          the final policy network (+ optimizer)  } loaded by agents.load(dir)
    vecnormalize.safetensors   its observation normalization           }
    best_model.safetensors, best_vecnormalize.safetensors, best.json   the best evaluated model
    checkpoints/               ckpt_<steps>.safetensors (weights, Adam state, step count) +
                               ckpt_<steps>_vecnormalize.safetensors (the last two),
                               last_checkpoint.json (what resume reads)
    evaluations.jsonl          one line per evaluation
    baseline_eval.json         the baselines on the evaluation seeds
    learning_curve.png         agents.training.curve: validation error against steps and time
    tb/                        TensorBoard logs (if tensorboard is installed)

Every file is written to a temporary name and moved into place, so an interrupted
run never leaves a half-written checkpoint. SIGINT or SIGTERM stops at the next
rollout boundary after writing a checkpoint (``EXIT_INTERRUPTED``); ``resume``
continues from the last one up to the same total step count, with fresh episodes
(the environments' episode state is not saved): PPO is rebuilt from config.yml and
the checkpoint's weights, optimizer state and step count are loaded into it. A run
stopped before its first checkpoint (config.yml, no checkpoint) resumes from
scratch with its config.yml (a note on stderr says so). A run directory of the old
pickle-based format (``.zip``/``.pkl`` checkpoints) is refused unless
``trust_pickle`` (``--trust-pickle``), and so is a ``last_checkpoint.json`` naming a
file outside ``checkpoints/``.

Entity policies (``env.observation: entities``, ``docs/training/entity.md``): the
rows are read as entities (``coopnav_env.entity_views``), with ``env.teams`` several
teams at once (``MixedTeamVecEnv``, built by ``make_training_env``); the network gets
``agents.entity.EntityExtractor`` (``entity_policy_kwargs``) and the validation reads
the evaluation environments' rows as entities (``entity_actor``), one cell per team.

Warm start (``init_from``): the network's weights, optimizer state and observation
normalization from another policy (the learning-rate schedule starts afresh; the
network's shape must match); a resumed run ignores it (the checkpoint holds the
weights). Pickle-based sources are refused unless ``trust_pickle``.
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from agents import formats
from coopnav_env.records import atomic_append_line, atomic_write_text, read_json

from . import runlock
from .common import (
    EXIT_INTERRUPTED,
    new_run_dir,
    planner_names,
    prepare_job,
    resume_command,
    resume_seed,
    run_config,
    stop_on_signals,
    write_run_record,
)
from .config import ConfigError, TrainConfig
from .sb3_files import (
    _first_line,
    checkpoint_files,
    last_evaluation_step,
    load_state,
    read_stats,
    restart_from_scratch,
    restore_stats,
    warm_start_files,
)
from .scoring import baselines_on_eval_seeds, evaluate

__all__ = ["learning_rate", "policy_kwargs", "resume", "train", "warm_start_files"]


@runlock.releasing
def train(
    config: TrainConfig,
    out: str | Path,
    resume: bool = False,
    *,
    command: str | None = None,
    hyperparameter_file: str | Path | None = None,
    device: str = "cpu",
    threads: int = 1,
    progress: bool = False,
    verbose: int = 0,
    trust_pickle: bool = False,
) -> int:
    """Train ``config`` into run directory ``out`` (new, or with ``resume`` the run's own
    directory, continued from its last checkpoint). Returns 0 when done,
    ``EXIT_INTERRUPTED`` after SIGINT/SIGTERM (checkpoint written). Bad input raises
    ``ConfigError`` before anything is written. ``command`` and
    ``hyperparameter_file`` are recorded in config.yml; ``threads``: torch threads
    (1: PPO's small batches gain little from more); ``trust_pickle``: accept
    pickle-based checkpoints and ``init_from`` files (they can run code)."""
    started = time.perf_counter()
    out = Path(out)

    # --- the run directory: a new one, or the checkpoint to continue from -----------
    ckpt = None
    if resume:
        ckpt = checkpoint_files(out, trust_pickle)
    else:
        new_run_dir(out)
    config.check()
    job = prepare_job(config)
    if resume and ckpt is None:  # stopped before its first checkpoint: start it again with its config.yml
        restart_from_scratch(out)
    warm = warm_start_files(config.init_from, trust_pickle) if config.init_from and not ckpt else None
    if config.imitate.planner is not None:
        from baselines import list_policies

        valid = planner_names(job.scenario_config, list_policies(job.scenario_config.network))
        planner = config.imitate.planner
        if planner not in valid:
            from coopnav_env.names import did_you_mean

            raise ConfigError(
                f"imitate.planner {planner!r} cannot drive {config.scenario!r}{did_you_mean(planner, valid)} "
                f"valid: {', '.join(valid)}"
            )
        if config.imitate.planner_kwargs:  # built once here, so a bad keyword fails before any work
            from baselines import make_policy

            try:
                make_policy(planner, job.scenario_config, seed=0, agent=0, **config.imitate.planner_kwargs)
            except (TypeError, ValueError) as err:
                raise ConfigError(f"imitate.planner_kwargs {config.imitate.planner_kwargs!r}: {err}") from None

    from coopnav_env.progress import stage

    stage(
        f"train.py: PPO on {config.scenario}, {config.timesteps:,} steps into {out}; loading torch and "
        "stable-baselines3"
    )
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.utils import set_random_seed
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    # --- seeding: python, numpy, torch; the environments from the same seed ---------
    start_steps = int(ckpt["num_timesteps"]) if ckpt else 0
    run_seed = resume_seed(config.seed, start_steps) if ckpt else config.seed
    set_random_seed(run_seed)
    torch.set_num_threads(threads)

    # --- the environment: one batched simulator, VecMonitor, VecNormalize -----------
    stage(
        f"building {config.n_envs} environments of {config.scenario} (the first run compiles the simulator: "
        "about a minute)"
    )
    raw_env = make_training_env(config, job, run_seed)
    dim = int(raw_env.action_space.shape[0])
    if config.action_log_std is not None and len(config.action_log_std) != dim:
        raw_env.close()
        raise ConfigError(
            f"action_log_std has {len(config.action_log_std)} values; {config.scenario}'s actions have {dim}"
        )
    venv = VecMonitor(raw_env)
    ckpt_stats = read_stats(ckpt["vecnormalize"]) if ckpt else None
    if ckpt and ckpt_stats is not None:  # the checkpoint's statistics and settings, training on
        s = ckpt_stats
        vecnorm = VecNormalize(
            venv,
            gamma=s["gamma"],
            norm_obs=s["norm_obs"],
            norm_reward=s["norm_reward"],
            clip_obs=s["clip_obs"],
            clip_reward=s["clip_reward"],
            epsilon=s["epsilon"],
        )
        restore_stats(vecnorm, s, ckpt["vecnormalize"])
    else:
        norm = config.normalize
        vecnorm = VecNormalize(
            venv,
            gamma=float(config.ppo.get("gamma", 0.99)),
            norm_obs=norm.norm_obs,
            norm_reward=norm.norm_reward,
            clip_obs=norm.clip_obs,
            clip_reward=norm.clip_reward,
            epsilon=norm.epsilon,
        )

    # --- PPO: built from the config; a checkpoint's or init_from's state loaded into it
    tb_dir = str(out / "tb") if _installed("tensorboard") else None
    if ckpt and ckpt["model"].suffix == ".zip":  # an old run's checkpoint, trusted (--trust-pickle)
        model = PPO.load(ckpt["model"], env=vecnorm, device=device, tensorboard_log=tb_dir, verbose=verbose)
        model.set_random_seed(run_seed)
    else:
        ppo = dict(config.ppo)
        lr = learning_rate(ppo.pop("learning_rate", 3e-4))
        kwargs = policy_kwargs(ppo.pop("policy_kwargs", None))
        if config.env.observation == "entities":  # the permutation-invariant encoder reads the entities
            kwargs.update(entity_policy_kwargs(config))
        try:
            model = PPO(
                config.policy,
                vecnorm,
                learning_rate=lr,
                policy_kwargs=kwargs,
                seed=run_seed,
                device=device,
                tensorboard_log=tb_dir,
                verbose=verbose,
                **ppo,
            )
        except (TypeError, ValueError, AssertionError, KeyError) as err:
            raise ConfigError(f"bad PPO hyperparameters: {_first_line(err)}") from None
        if ckpt:  # weights, optimizer state and step count of the checkpoint
            load_state(model, ckpt["model"], device, what=f"checkpoint {ckpt['model']}", restore_steps=True)
        elif warm:  # weights, optimizer state and normalization from another policy
            load_state(model, warm[0], device, what=f"init_from {warm[0]}")
            if warm[1] is not None:
                warm_stats = read_stats(warm[1])
                assert warm_stats is not None  # load_stats of a path: its statistics, or it raises
                restore_stats(vecnorm, warm_stats, warm[1])
    if tb_dir is None:  # SB3's own logger would make an empty /tmp/SB3-<date> folder per run
        from stable_baselines3.common.logger import HumanOutputFormat, Logger

        model.set_logger(Logger(None, [HumanOutputFormat(sys.stdout)] if verbose else []))
    imitation = None
    if config.imitate.planner is not None and not ckpt:  # behaviour cloning before PPO (a resumed run has it)
        from .imitation import imitate

        imitation = imitate(model, vecnorm, raw_env, config.imitate, run_seed, progress)
        print(
            f"imitated {imitation['planner']}: {imitation['steps']} steps, action rms error "
            f"{imitation['action_rms_error']}, {imitation['seconds']} s",
            flush=True,
        )
    if config.action_log_std is not None and not ckpt:  # the exploration PPO starts with, per action component
        import torch

        with torch.no_grad():
            model.policy.log_std.copy_(torch.as_tensor(config.action_log_std, dtype=model.policy.log_std.dtype))
    runlock.claim(out, new=not resume, command=command)  # the inputs are good: lock --out, the first file of a new run
    if not resume:
        write_run_record(
            out,
            config,
            job,
            command=command,
            hyperparameter_file=hyperparameter_file,
            **({"imitation": imitation} if imitation else {}),
        )
    if tb_dir is None:  # a note, not an error: after the inputs are known to be good, on stdout
        print("note: tensorboard is not installed, so no TensorBoard logs (pip install -e '.[train]')")

    # --- baselines on the evaluation seeds (once per run) --------------------------
    ev = config.eval
    baseline_scores = read_json(out / "baseline_eval.json") or {}
    if ev.every_steps > 0:
        todo = [b for b in ev.baselines or [] if b not in baseline_scores]
        if todo and ev.episodes > 0:
            stage(
                f"scoring the planners {', '.join(todo)} on the validation seeds ({ev.episodes} episodes x "
                f"{len(job.cells)} cells): the lines PPO's validations are compared with"
            )
        baseline_scores = baselines_on_eval_seeds(out, job.cells, ev.baselines, ev.episodes, ev.seed)

    # --- learn, stopping cleanly on SIGINT/SIGTERM -----------------------------------
    # the steps that will really run: SB3 trains whole rollouts (n_steps x rows), so it
    # rounds the remaining steps up; the bar's total is that, and never passed
    rollout = int(model.n_steps) * int(vecnorm.num_envs)
    assert config.timesteps is not None  # set by TrainConfig.check()
    remaining = max(config.timesteps - start_steps, 0)
    will_run = -(-remaining // rollout) * rollout
    every = f", a validation every {ev.every_steps:,}" if ev.every_steps > 0 else ""
    stage(
        f"training: {will_run:,} steps in {will_run // rollout} rollouts of {rollout:,} (n_steps "
        f"{model.n_steps} x {vecnorm.num_envs} rows){every}"
    )
    t0 = time.perf_counter()
    from coopnav_env.progress import Progress

    bar = Progress(will_run, unit="step", desc="training", mode=None if progress else "off", every_s=60.0)
    with stop_on_signals() as stop, bar:
        callback = make_callback(
            out, config, job.cells, vecnorm, baseline_scores, stop, clock={"t0": t0, "started": started, "bar": bar}
        )
        # a run that has its steps already (a resume of a finished run) trains nothing, but SB3's
        # learn() still resets the environments, which moves VecNormalize's statistics: the saved
        # normalizer would no longer be the model's (an input audit). Kept as they were.
        kept = formats.vecnormalize_stats(vecnorm) if will_run == 0 else None
        model.learn(  # will_run, not remaining: SB3's progress (1 -> 0) then ends at 0, and lin_<x> with it
            total_timesteps=will_run,
            callback=callback,
            progress_bar=False,
            reset_num_timesteps=not ckpt,
            tb_log_name="ppo",
        )
        if kept is not None:
            formats.restore_vecnormalize(vecnorm, kept)
    if stop:
        # the steps of the rollout cut short were not trained on: the checkpoint does not count them
        model.num_timesteps = getattr(callback, "trained_steps", start_steps)
        callback.checkpoint()
        _draw_curve(out)
        print(f"stopped at {model.num_timesteps} steps; continue with: {resume_command(out)}", file=sys.stderr)
        return EXIT_INTERRUPTED

    # --- final evaluation and model, beside its normalization and config ----------
    callback.checkpoint()
    if ev.every_steps > 0 and callback.last_eval != model.num_timesteps:
        callback.evaluate()
    save_model(model, out / "model.safetensors", vecnorm)
    save_vecnormalize(vecnorm, out / "vecnormalize.safetensors")
    curve = _draw_curve(out)
    elapsed = time.perf_counter() - t0
    trained = model.num_timesteps - start_steps
    print(
        f"done: {model.num_timesteps} steps ({trained} in this run, {elapsed:.0f} s, "
        f"{trained / max(elapsed, 1e-9):.0f} steps/s); model in {out}"
        + (f"; learning curve in {curve}" if curve else "")
    )
    return 0


def _draw_curve(out: Path):
    """``learning_curve.png`` (``agents.training.curve``); None without a validation, or
    if matplotlib fails (a figure never fails a run: the line on stderr says why)."""
    from .curve import draw_learning_curve

    try:
        return draw_learning_curve(out)
    except Exception as err:  # the model is saved; the figure is a convenience
        print(f"note: learning_curve.png not drawn: {_first_line(err)}", file=sys.stderr)
        return None


def resume(out: str | Path, **options: Any) -> int:
    """Continue the SB3 run in ``out`` with its own config.yml (``train``'s keyword
    options: device, threads, progress, verbose, trust_pickle)."""
    return train(run_config(out, TrainConfig), out, resume=True, **options)


# ----------------------------------------------------------------------------------
# pieces of train
# ----------------------------------------------------------------------------------
def learning_rate(value: float | str) -> float | Callable[[float], float]:
    """A float, or "lin_<x>": linear decay from x to 0 (rl-baselines3-zoo), held at 0 past the
    end (SB3's progress goes below 0 when it trains more steps than it was told, and a negative
    rate would step uphill)."""
    if isinstance(value, str) and value.startswith("lin_"):
        start = float(value[4:])
        return lambda progress_remaining: max(progress_remaining, 0.0) * start
    return float(value)


def policy_kwargs(spec: dict | None) -> dict:
    """``ppo.policy_kwargs`` with ``activation_fn`` by name -> the torch.nn class."""
    import torch.nn as nn

    spec = dict(spec or {})
    if "activation_fn" in spec:
        table = {"tanh": nn.Tanh, "relu": nn.ReLU, "elu": nn.ELU, "leaky_relu": nn.LeakyReLU}
        spec["activation_fn"] = table[spec["activation_fn"]]  # the name was checked by TrainConfig.check
    return spec


def save_model(model: Any, path: Path, vecnorm: Any = None) -> None:
    """The model file (network weights, optimizer state, step count; ``agents.formats``), atomically."""
    formats.save_model(model, path, norm_obs=None if vecnorm is None else vecnorm.norm_obs)


def save_vecnormalize(vecnorm: Any, path: Path) -> None:
    """The VecNormalize running statistics and settings (``agents.formats``), atomically."""
    formats.save_vecnormalize(vecnorm, path)


def model_actor(model: Any, vecnorm: Any) -> Callable[[np.ndarray, Any], np.ndarray]:
    def act(obs: np.ndarray, venv: Any) -> np.ndarray:
        return model.predict(vecnorm.normalize_obs(obs), deterministic=True)[0]

    return act


def entity_actor(model: Any, vecnorm: Any) -> Callable[[np.ndarray, Any], np.ndarray]:
    """``model_actor`` for an entity policy: the flat rows of an evaluation
    ``CoopNavVecEnv`` read as entities (row ``e * N + j`` is beacon j) first."""
    from coopnav_env.entity_obs import entity_observation, row_agents

    def act(obs: np.ndarray, venv: Any) -> np.ndarray:
        x = entity_observation(obs, venv.config, row_agents(venv.num_envs, venv.n_beacons))
        return model.predict(vecnorm.normalize_obs(x), deterministic=True)[0]

    return act


def entity_policy_kwargs(config: TrainConfig) -> dict:
    """The ``policy_kwargs`` an entity run adds: ``agents.entity.EntityExtractor`` with the
    config's ``entity`` section and the entity layout (saved with the model)."""
    from agents.entity import EntityExtractor
    from coopnav_env.entity_obs import LAYOUT

    e = config.entity
    return {
        "features_extractor_class": EntityExtractor,
        "features_extractor_kwargs": {
            "encoder": e.encoder,
            "embed_dim": int(e.embed_dim),
            "heads": int(e.heads),
            "layout": LAYOUT.to_dict(),
        },
    }


def make_training_env(config: TrainConfig, job: Any, seed: int) -> Any:
    """The training VecEnv (before VecMonitor and VecNormalize): a ``CoopNavVecEnv`` of
    the scenario; with ``env.observation: entities`` seen as entities
    (``coopnav_env.entity_views.EntityVecEnv``), and with ``env.teams`` every team at once,
    flat or entities (``MixedTeamVecEnv``: the ``n_envs`` environments dealt to the teams, seeds
    ``seed + g + k * SEED_STRIDE`` for environment g's episode k)."""
    from coopnav_env.entity_views import EntityVecEnv, MixedTeamVecEnv
    from coopnav_env.vector import CoopNavVecEnv

    try:
        if job.teams:
            return MixedTeamVecEnv(
                job.scenario_config,
                job.teams,
                config.n_envs,
                seed=seed,
                step_infos=False,
                reward_terms=job.reward_terms,
                observation=config.env.observation,
            )
        venv = CoopNavVecEnv(
            job.scenario_config, n_envs=config.n_envs, seed=seed, step_infos=False, reward_terms=job.reward_terms
        )
        return EntityVecEnv(venv) if config.env.observation == "entities" else venv
    except ValueError as err:
        raise ConfigError(f"env: {_first_line(err)}") from None


def make_callback(
    out: Path, config: TrainConfig, cells: list, vecnorm: Any, baseline_scores: dict, stop: Any, clock: dict
) -> Any:
    """The SB3 callback of a run: at every rollout start (the model has been trained on
    every step counted so far) checkpoint and evaluate when due; stop after a signal."""
    from stable_baselines3.common.callbacks import BaseCallback

    ckpt_dir = out / "checkpoints"
    ckpt_every, ev = config.checkpoint_every_steps, config.eval

    class RunCallback(BaseCallback):
        def _on_training_start(self):
            self.trained_steps = self.last_ckpt = self.last_eval = self.model.num_timesteps
            if self.model.num_timesteps > 0:  # resumed: the run's schedule (and its final evaluation) goes on
                self.last_eval = last_evaluation_step(out, self.model.num_timesteps)
            if config.imitate.planner is not None and ev.every_steps > 0 and self.model.num_timesteps == 0:
                self.evaluate()  # the cloned planner, before PPO changes it

        def _on_rollout_start(self):
            self.trained_steps = steps = self.model.num_timesteps
            if steps - self.last_ckpt >= ckpt_every:
                self.checkpoint()
            if ev.every_steps > 0 and steps - self.last_eval >= ev.every_steps:
                self.evaluate()

        def _on_step(self):
            clock["bar"].update(self.training_env.num_envs)
            return not stop

        def checkpoint(self):
            steps = self.model.num_timesteps
            entry: dict[str, Any] = {
                "num_timesteps": steps,
                "model": f"ckpt_{steps:010d}.safetensors",
                "vecnormalize": f"ckpt_{steps:010d}_vecnormalize.safetensors",
            }
            previous = read_json(ckpt_dir / "last_checkpoint.json")
            if previous == entry:
                return
            ckpt_dir.mkdir(exist_ok=True)
            save_model(self.model, ckpt_dir / entry["model"], vecnorm)
            save_vecnormalize(vecnorm, ckpt_dir / entry["vecnormalize"])
            atomic_write_text(ckpt_dir / "last_checkpoint.json", json.dumps(entry))
            if previous and previous["model"] != entry["model"]:  # keep the last two
                models = sorted(
                    p for p in ckpt_dir.glob("ckpt_*.safetensors") if not p.name.endswith("_vecnormalize.safetensors")
                )
                for old in models[:-2]:
                    old.unlink(missing_ok=True)
                    (ckpt_dir / old.name.replace(".safetensors", "_vecnormalize.safetensors")).unlink(missing_ok=True)
            self.last_ckpt = steps

        def evaluate(self):
            if ev.episodes <= 0:  # eval.episodes 0: no validation (the last weights are the model)
                return
            clock["bar"].stage(f"validating at {self.model.num_timesteps:,} steps")
            t0 = time.perf_counter()
            actor = entity_actor if config.env.observation == "entities" else model_actor
            result = evaluate(actor(self.model, vecnorm), cells, ev.episodes, ev.seed)
            score = result["survey_error_m"]
            now = time.perf_counter()
            clock["eval_s"] = clock.get("eval_s", 0.0) + (now - t0)
            # wall_s: since learning started, validations included; train_s: without them
            record = {
                "num_timesteps": self.model.num_timesteps,
                "wall_s": round(now - clock["t0"], 1),
                "train_s": round(now - clock["t0"] - clock["eval_s"], 1),
                "wall_s_since_start": round(now - clock["started"], 1),
                "survey_error_m": score,
                **{f"{k}_survey_error_m": v["survey_error_m"] for k, v in baseline_scores.items()},
            }
            if len(cells) > 1:
                record["per_cell"] = {k: round(v, 4) for k, v in result["per_cell"].items()}
                for k, v in baseline_scores.items():
                    record[f"cells_beating_{k}"] = sum(result["per_cell"][c] < v["per_cell"][c] for c in v["per_cell"])
            atomic_append_line(out / "evaluations.jsonl", json.dumps(record))  # never a half-written line
            self.logger.record("eval/survey_error_m", score)
            for k, v in baseline_scores.items():
                self.logger.record(f"eval/{k}_survey_error_m", v["survey_error_m"])
                if f"cells_beating_{k}" in record:
                    self.logger.record(f"eval/cells_beating_{k}", record[f"cells_beating_{k}"])
            best = read_json(out / "best.json")
            if best is None or score < best["survey_error_m"]:
                save_model(self.model, out / "best_model.safetensors", vecnorm)
                save_vecnormalize(vecnorm, out / "best_vecnormalize.safetensors")
                atomic_write_text(out / "best.json", json.dumps(record))
            beaten = [k for k, v in baseline_scores.items() if score < v["survey_error_m"]]
            clock["bar"].write(
                f"eval @ {self.model.num_timesteps}: survey_error_m {score:.3f}"
                + "".join(f", {k} {v['survey_error_m']:.3f}" for k, v in baseline_scores.items())
                + "".join(
                    f", beats {k} in {record[f'cells_beating_{k}']}/{len(cells)} cells"
                    for k in baseline_scores
                    if f"cells_beating_{k}" in record
                )
                + (f" (beats {', '.join(beaten)})" if beaten else "")
                + f" [{time.perf_counter() - t0:.1f} s]",
                stream=sys.stdout,
            )
            clock["bar"].stage("training")
            self.last_eval = self.model.num_timesteps

    return RunCallback()


def _installed(*modules) -> bool:
    import importlib.util

    return all(importlib.util.find_spec(m) is not None for m in modules)
