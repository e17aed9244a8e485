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

What a run directory holds:

    config.yml                 the exact config (see agents.training.common)
    model.zip                  the final SB3 model            } loaded by agents.load(dir)
    vecnormalize.pkl           its observation normalization  }
    best_model.zip, best_vecnormalize.pkl, best.json   the best evaluated model
    checkpoints/               ckpt_<steps>.zip + ckpt_<steps>_vecnormalize.pkl (the
                               last two), last_checkpoint.json (what resume reads)
    evaluations.jsonl          one line per evaluation
    baseline_eval.json         the baselines on the evaluation seeds
    tb/                        TensorBoard logs (if tensorboard is installed)

Every file is written to a temporary name and moved into place, so an interrupted
run never leaves a half-written checkpoint. SIGINT or SIGTERM stops at the next
rollout boundary after writing a checkpoint (``EXIT_INTERRUPTED``); ``resume``
continues from the last one up to the same total step count, with fresh episodes
(the environments' episode state is not saved).

Warm start (``init_from``): the network's weights and the observation normalization
from another policy (the learning-rate schedule starts afresh; the network's shape
must match); a resumed run ignores it (the checkpoint holds the weights).
"""

from __future__ import annotations

import io
import json
import pickle
import sys
import time
from pathlib import Path

from coopnav_env.records import atomic_write_bytes, atomic_write_text, read_json

from .common import (EXIT_INTERRUPTED, new_run_dir, prepare_job, resume_command, resume_seed, run_config,
                     stop_on_signals, write_run_record)
from .config import ConfigError, TrainConfig
from .scoring import baselines_on_eval_seeds, evaluate

__all__ = ["learning_rate", "policy_kwargs", "resume", "train", "warm_start_files"]


def train(config: TrainConfig, out, resume: bool = False, *, command: str | None = None,
          hyperparameter_file=None, device: str = "cpu", threads: int = 1, progress: bool = False,
          verbose: int = 0) -> int:
    """Train ``config`` into run directory ``out`` (new, or with ``resume`` the run's own
    directory, continued from its last checkpoint). Returns 0 when done,
    ``EXIT_INTERRUPTED`` after SIGINT/SIGTERM (checkpoint written). Bad input raises
    ``ConfigError`` before anything is written. ``command`` and
    ``hyperparameter_file`` are recorded in config.yml; ``threads``: torch threads
    (1: PPO's small batches gain little from more)."""
    started = time.perf_counter()
    out = Path(out)

    # --- the run directory: a new one, or the checkpoint to continue from -----------
    if resume:
        ckpt = read_json(out / "checkpoints" / "last_checkpoint.json")
        if ckpt is None:
            raise ConfigError(f"{out} has no checkpoint to resume from (checkpoints/last_checkpoint.json)")
    else:
        new_run_dir(out)
        ckpt = None
    config.check()
    job = prepare_job(config)
    warm = warm_start_files(config.init_from) if config.init_from and not resume else None

    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.utils import set_random_seed
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    from coopnav_env.vector import CoopNavVecEnv

    # --- seeding: python, numpy, torch; the environments from the same seed ---------
    start_steps = int(ckpt["num_timesteps"]) if ckpt else 0
    run_seed = resume_seed(config.seed, start_steps) if ckpt else config.seed
    set_random_seed(run_seed)
    torch.set_num_threads(threads)

    # --- the environment: one batched simulator, VecMonitor, VecNormalize -----------
    venv = VecMonitor(CoopNavVecEnv(job.scenario_config, n_envs=config.n_envs, seed=run_seed, step_infos=False,
                                    reward_terms=job.reward_terms))
    if ckpt:
        with open(out / "checkpoints" / ckpt["vecnormalize"], "rb") as f:
            vecnorm = pickle.load(f)
        vecnorm.set_venv(venv)
        vecnorm.training = True
    else:
        norm = config.normalize
        vecnorm = VecNormalize(venv, gamma=float(config.ppo.get("gamma", 0.99)), norm_obs=norm.norm_obs,
                               norm_reward=norm.norm_reward, clip_obs=norm.clip_obs, clip_reward=norm.clip_reward,
                               epsilon=norm.epsilon)

    # --- PPO ----------------------------------------------------------------------
    tb_dir = str(out / "tb") if _installed("tensorboard") else None
    if ckpt:
        model = PPO.load(out / "checkpoints" / ckpt["model"], env=vecnorm, device=device,
                         tensorboard_log=tb_dir, verbose=verbose)
        model.set_random_seed(run_seed)
    else:
        ppo = dict(config.ppo)
        lr = learning_rate(ppo.pop("learning_rate", 3e-4))
        kwargs = policy_kwargs(ppo.pop("policy_kwargs", None))
        try:
            model = PPO(config.policy, vecnorm, learning_rate=lr, policy_kwargs=kwargs, seed=run_seed,
                        device=device, tensorboard_log=tb_dir, verbose=verbose, **ppo)
        except (TypeError, ValueError, AssertionError, KeyError) as err:
            raise ConfigError(f"bad PPO hyperparameters: {_first_line(err)}") from None
        if warm:  # weights and normalization from another policy; the optimizer state comes with the weights
            try:
                model.set_parameters(str(warm[0]), exact_match=True, device=device)
            except (RuntimeError, ValueError, KeyError) as err:
                raise ConfigError(f"init_from {warm[0]} does not fit this network: {_first_line(err)}") from None
            if warm[1] is not None:
                with open(warm[1], "rb") as f:
                    source = pickle.load(f)
                vecnorm.obs_rms, vecnorm.ret_rms = source.obs_rms.copy(), source.ret_rms.copy()
    out.mkdir(parents=True, exist_ok=True)  # the inputs are good: the first file of a new run
    if not resume:
        write_run_record(out, config, job, command=command, hyperparameter_file=hyperparameter_file)
    if tb_dir is None:  # a note, not an error: after the inputs are known to be good, on stdout
        print("note: tensorboard is not installed, so no TensorBoard logs (pip install -e '.[train]')")

    # --- baselines on the evaluation seeds (once per run) --------------------------
    ev = config.eval
    baseline_scores = read_json(out / "baseline_eval.json") or {}
    if ev.every_steps > 0:
        baseline_scores = baselines_on_eval_seeds(out, job.cells, ev.baselines, ev.episodes, ev.seed)

    # --- learn, stopping cleanly on SIGINT/SIGTERM -----------------------------------
    t0 = time.perf_counter()
    with stop_on_signals() as stop:
        callback = make_callback(out, config, job.cells, vecnorm, baseline_scores, stop,
                                 clock={"t0": t0, "started": started})
        model.learn(total_timesteps=max(config.timesteps - start_steps, 0), callback=callback,
                    progress_bar=progress and _installed("tqdm", "rich"), reset_num_timesteps=not ckpt,
                    tb_log_name="ppo")
    if stop:
        # the steps of the rollout cut short were not trained on: the checkpoint does not count them
        model.num_timesteps = getattr(callback, "trained_steps", start_steps)
        callback.checkpoint()
        print(f"stopped at {model.num_timesteps} steps; continue with: {resume_command(out)}", file=sys.stderr)
        return EXIT_INTERRUPTED

    # --- final evaluation and model, beside its normalization and config ----------
    callback.checkpoint()
    if ev.every_steps > 0 and callback.last_eval != model.num_timesteps:
        callback.evaluate()
    save_model(model, out / "model.zip")
    save_vecnormalize(vecnorm, out / "vecnormalize.pkl")
    elapsed = time.perf_counter() - t0
    trained = model.num_timesteps - start_steps
    print(f"done: {model.num_timesteps} steps ({trained} in this run, {elapsed:.0f} s, "
          f"{trained / max(elapsed, 1e-9):.0f} steps/s); model in {out}")
    return 0


def resume(out, **options) -> int:
    """Continue the SB3 run in ``out`` with its own config.yml (``train``'s keyword
    options: device, threads, progress, verbose)."""
    return train(run_config(out, TrainConfig), out, resume=True, **options)


# ----------------------------------------------------------------------------------
# pieces of train
# ----------------------------------------------------------------------------------
def warm_start_files(spec) -> tuple:
    """(model zip, vecnormalize pickle or None) of ``init_from`` (``agents.resolve``)."""
    import agents

    try:
        model, stats, _ = agents.resolve(str(spec))
    except ValueError as err:
        raise ConfigError(f"init_from: {err}") from None
    if model.name == "gate.yml":
        raise ConfigError(f"init_from: {spec!r} is a gate of two networks ({model}); name one of its networks "
                          "(the directories that file lists)")
    if model.suffix != ".zip":
        raise ConfigError(f"init_from: {spec!r} is not a stable-baselines3 model ({model}): an SB3 run or policy only")
    return model, stats


def learning_rate(value):
    """A float, or "lin_<x>": linear decay from x to 0 (rl-baselines3-zoo)."""
    if isinstance(value, str) and value.startswith("lin_"):
        start = float(value[4:])
        return lambda progress_remaining: progress_remaining * start
    return float(value)


def policy_kwargs(spec: dict | None) -> dict:
    """``ppo.policy_kwargs`` with ``activation_fn`` by name -> the torch.nn class."""
    import torch.nn as nn

    spec = dict(spec or {})
    if "activation_fn" in spec:
        table = {"tanh": nn.Tanh, "relu": nn.ReLU, "elu": nn.ELU, "leaky_relu": nn.LeakyReLU}
        spec["activation_fn"] = table[spec["activation_fn"]]  # the name was checked by TrainConfig.check
    return spec


def save_model(model, path: Path):
    buf = io.BytesIO()
    model.save(buf)
    atomic_write_bytes(path, buf.getvalue())


def save_vecnormalize(vecnorm, path: Path):
    """VecNormalize.save pickles the wrapper without its venv; the same, atomically."""
    atomic_write_bytes(path, pickle.dumps(vecnorm))


def model_actor(model, vecnorm):
    def act(obs, venv):
        return model.predict(vecnorm.normalize_obs(obs), deterministic=True)[0]

    return act


def make_callback(out: Path, config: TrainConfig, cells: list, vecnorm, baseline_scores: dict, stop, clock: dict):
    """The SB3 callback of a run: at every rollout start (the model has been trained on
    every step counted so far) checkpoint and evaluate when due; stop after a signal."""
    from stable_baselines3.common.callbacks import BaseCallback

    ckpt_dir = out / "checkpoints"
    ckpt_every, ev = config.checkpoint_every_steps, config.eval

    class RunCallback(BaseCallback):
        def _on_training_start(self):
            self.trained_steps = self.last_ckpt = self.last_eval = self.model.num_timesteps

        def _on_rollout_start(self):
            self.trained_steps = steps = self.model.num_timesteps
            if steps - self.last_ckpt >= ckpt_every:
                self.checkpoint()
            if ev.every_steps > 0 and steps - self.last_eval >= ev.every_steps:
                self.evaluate()

        def _on_step(self):
            return not stop

        def checkpoint(self):
            steps = self.model.num_timesteps
            entry = {"num_timesteps": steps, "model": f"ckpt_{steps:010d}.zip",
                     "vecnormalize": f"ckpt_{steps:010d}_vecnormalize.pkl"}
            previous = read_json(ckpt_dir / "last_checkpoint.json")
            if previous == entry:
                return
            ckpt_dir.mkdir(exist_ok=True)
            save_model(self.model, ckpt_dir / entry["model"])
            save_vecnormalize(vecnorm, ckpt_dir / entry["vecnormalize"])
            atomic_write_text(ckpt_dir / "last_checkpoint.json", json.dumps(entry))
            if previous and previous["model"] != entry["model"]:  # keep the last two
                for old in sorted(ckpt_dir.glob("ckpt_*.zip"))[:-2]:
                    old.unlink(missing_ok=True)
                    (ckpt_dir / old.name.replace(".zip", "_vecnormalize.pkl")).unlink(missing_ok=True)
            self.last_ckpt = steps

        def evaluate(self):
            t0 = time.perf_counter()
            result = evaluate(model_actor(self.model, vecnorm), cells, ev.episodes, ev.seed)
            score = result["survey_error_m"]
            now = time.perf_counter()
            record = {"num_timesteps": self.model.num_timesteps, "wall_s": round(now - clock["t0"], 1),
                      "wall_s_since_start": round(now - clock["started"], 1), "survey_error_m": score,
                      **{f"{k}_survey_error_m": v["survey_error_m"] for k, v in baseline_scores.items()}}
            if len(cells) > 1:
                record["per_cell"] = {k: round(v, 4) for k, v in result["per_cell"].items()}
                for k, v in baseline_scores.items():
                    record[f"cells_beating_{k}"] = sum(result["per_cell"][c] < v["per_cell"][c] for c in v["per_cell"])
            with open(out / "evaluations.jsonl", "a") as f:
                f.write(json.dumps(record) + "\n")
            self.logger.record("eval/survey_error_m", score)
            for k, v in baseline_scores.items():
                self.logger.record(f"eval/{k}_survey_error_m", v["survey_error_m"])
                if f"cells_beating_{k}" in record:
                    self.logger.record(f"eval/cells_beating_{k}", record[f"cells_beating_{k}"])
            best = read_json(out / "best.json")
            if best is None or score < best["survey_error_m"]:
                save_model(self.model, out / "best_model.zip")
                save_vecnormalize(vecnorm, out / "best_vecnormalize.pkl")
                atomic_write_text(out / "best.json", json.dumps(record))
            beaten = [k for k, v in baseline_scores.items() if score < v["survey_error_m"]]
            print(f"eval @ {self.model.num_timesteps}: survey_error_m {score:.3f}"
                  + "".join(f", {k} {v['survey_error_m']:.3f}" for k, v in baseline_scores.items())
                  + "".join(f", beats {k} in {record[f'cells_beating_{k}']}/{len(cells)} cells"
                            for k in baseline_scores if f"cells_beating_{k}" in record)
                  + (f" (beats {', '.join(beaten)})" if beaten else "")
                  + f" [{time.perf_counter() - t0:.1f} s]", flush=True)
            self.last_eval = self.model.num_timesteps

    return RunCallback()


def _installed(*modules) -> bool:
    import importlib.util

    return all(importlib.util.find_spec(m) is not None for m in modules)


def _first_line(err) -> str:
    return str(err).splitlines()[0] if str(err) else type(err).__name__
