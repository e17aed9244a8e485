"""PPO beacon policies on Ray RLlib (new API stack), for scale-out.

    pip install -e ".[rllib]"
    python train.py --backend rllib --scenario sousa_asv --timesteps 2000000 --num-env-runners 8 --out runs/sousa_rllib
    python train.py --resume runs/sousa_rllib                        # continue it after Ctrl-C or a crash
    python train.py --backend rllib ... --ray-address auto          # on a running Ray cluster
    python train.py --backend rllib --scenario gao_sea --timesteps 200000 --out runs/sweep \\
        --tune lr=1e-4,3e-4 --tune seed=0,1,2                        # a Ray Tune grid

From Python: ``agents.training.rllib.train(RLlibConfig(...), out)``. Ray is imported
only inside the functions here, so importing this module is cheap.

The parts: ``rllib_algo`` (the RLlib ``PPOConfig`` from the job),
``rllib_checkpoints`` (the run's files), ``rllib_tune`` (a Tune grid). Read ``train``
top to bottom: the job (configs/rllib/<scenario>.yml, else default.yml, as an
``RLlibConfig``) -> the RLlib ``PPOConfig`` -> Ray (a small local instance, or
``ray_address``) -> either one training run or a Tune grid -> evaluation on fixed
seeds -> files.

**The algorithm.** RLlib's PPO on the new API stack (RLModule + Learner,
``config.env_runners(...)``, ``config.learners(...)``), the environment the
PettingZoo parallel env through ``coopnav_env.rllib_env.CoopNavRLlibEnv`` (a small
``MultiAgentEnv`` adapter; its docstring says why not RLlib's
``ParallelPettingZooEnv``). Policy mapping: one RLModule per beacon kind
(``beacon_auv``, ``asv``, ``boat``, ...), shared by the beacons of that kind.
``num_env_runners`` env runner processes sample in parallel (0: the driver samples),
each stepping ``num_envs_per_env_runner`` copies of the env; with ``ray_address``
they spread over the cluster's nodes. The learner runs in the driver (``learners:
{num_learners: 0}``; more learners are a YAML setting) with ``threads`` torch threads.

**Stop and resume.** SIGINT (Ctrl-C) or SIGTERM stops the run after the current
training iteration, writes the checkpoint and returns ``EXIT_INTERRUPTED`` (130),
printing the command that continues it: ``python train.py --resume <out> --trust-pickle``
(RLlib's checkpoint is pickle-based: the flag says you trust your own run). The
resumed run takes its config from ``config.yml`` (``num_env_runners`` and
``ray_address`` may be given anew; by default the run's runner count, on a local Ray
instance), rebuilds the PPOConfig and restores the Algorithm from ``checkpoint/``
(the modules, their optimizers, the observation filters, RLlib's step and iteration
counts), trains until the run's total env steps, appends to ``progress.jsonl`` and
ends with the files of a finished run. Its episodes are fresh ones (the seed from the
run's seed and the step count, as the SB3 trainer's). A run killed without a last
checkpoint resumes from the last periodic one: the lines of ``progress.jsonl`` after
it are dropped, since those iterations are trained again. Resuming a finished run
does nothing (it evaluates the checkpoint if that had not been done) and succeeds. A
Tune grid cannot be resumed.

What a run directory holds:

    config.yml         the exact config (agents.training.common), plus the resolved RLlib
                       AlgorithmConfig (rllib_config) and the beacon -> module map
    checkpoint/        the RLlib Algorithm checkpoint (``algo.save_to_path``), replaced
                       whole every ``checkpoint_every_iterations``, on a stop and at the
                       end (written beside, then renamed); ``coopnav.json`` in it: steps,
                       iteration (what resume reads); ``policy_export/`` in it: the
                       modules and observation filters as safetensors + JSON, what
                       agents.load reads (RLlib's own files are pickle-based)
    progress.jsonl     one line per training iteration (steps, returns, survey error, training
                       wall time summed over the sessions of a resumed run)
    evaluations.jsonl  the final evaluation on fixed seeds (``eval:``)
    baseline_eval.json the baselines on the same seeds

``agents.load(out)`` (and so the evaluation's ``--policies out,fim_a``) loads the policy,
from ``checkpoint/policy_export/`` (no pickle). **Resuming** restores RLlib's own
checkpoint, which is pickle-based: ``--resume`` needs ``--trust-pickle`` (your own run;
never a checkpoint from an untrusted source). A run stopped before its first
checkpoint starts again from scratch with its config.yml.

**Tune** (``tune={"lr": [1e-4, 3e-4], "seed": [0, 1]}``, ``--tune KEY=V1,V2`` on the
command line): the grid of every combination, one RLlib trial each, run by
``ray.tune.Tuner`` under ``out/tune/``; KEY is ``seed`` or a ``PPOConfig.training``
keyword (``lr``, ``gamma``, ``entropy_coeff``, ...). Afterwards every trial's final
checkpoint is evaluated on the fixed seeds, and ``summary.csv`` and ``summary.md``
(one table: the grid values, steps, mean episode return, the training episodes'
survey error, the evaluation's survey error, the checkpoint) are written atomically.
"""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path
from typing import Any

from coopnav_env.records import atomic_append_line

from . import runlock
from .common import (
    EXIT_INTERRUPTED,
    Job,
    new_run_dir,
    prepare_job,
    read_run_record,
    resume_command,
    resume_seed,
    run_config,
    stop_on_signals,
    write_run_record,
)
from .config import ConfigError, RLlibConfig
from .rllib_algo import build_config, config_record, cpus_per_trial
from .rllib_checkpoints import (
    _last_json_line,
    drop_lost_iterations,
    evaluate_checkpoint,
    metrics,
    resumable_checkpoint,
    save_checkpoint,
)
from .rllib_tune import check_tune, parse_tune, run_tune
from .scoring import baselines_on_eval_seeds

os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")  # no usage reports from training runs

RAY_MISSING = '--backend rllib needs Ray RLlib, which is not installed: pip install -e ".[rllib]"'

__all__ = ["build_config", "metrics", "parse_tune", "require_ray", "resume", "save_checkpoint", "train"]


@runlock.releasing
def train(
    config: RLlibConfig,
    out: str | Path,
    resume: bool = False,
    *,
    command: str | None = None,
    hyperparameter_file: str | Path | None = None,
    num_env_runners: int | None = None,
    ray_address: str | None = None,
    tune: dict | None = None,
    threads: int = 1,
    trust_pickle: bool = False,
) -> int:
    """Train ``config`` on RLlib into run directory ``out`` (new, or with ``resume`` the
    run's own directory, continued from its checkpoint). ``num_env_runners`` overrides
    ``env_runners.num_env_runners``; ``ray_address`` joins a running cluster; ``tune``
    ({key: [values]}) runs a Tune grid instead of one run. Returns 0 when done (1 if a
    Tune trial failed), ``EXIT_INTERRUPTED`` after SIGINT/SIGTERM (checkpoint
    written). Bad input raises ``ConfigError`` before anything is written. Resuming
    restores RLlib's checkpoint, which is pickle-based: refused unless ``trust_pickle``
    (``--trust-pickle``); a run stopped before its first checkpoint starts again from
    scratch with its config.yml."""
    require_ray()
    check_ray_address(ray_address)  # before anything is written
    out = Path(out)
    restart = False
    if resume:
        record = read_run_record(out)
        if record["args"].get("tune"):
            raise ConfigError(f"{out} is a Ray Tune grid (--tune): --resume continues single runs only")
        meta = resumable_checkpoint(out)
        if meta is None:
            restart = True
        elif not trust_pickle:
            from agents.formats import PickleRefused

            raise PickleRefused(
                f"{out / 'checkpoint'} is an RLlib checkpoint, which is read by unpickling and can "
                f"run code: refused; if you trust it (your own run), pass --trust-pickle"
            )
        if num_env_runners is None:
            num_env_runners = record["args"].get("num_env_runners")
    else:
        new_run_dir(out)
        meta = None
    if num_env_runners is not None:
        config = config.replace(env_runners={**config.env_runners, "num_env_runners": int(num_env_runners)})
    config.check()
    job = prepare_job(config)
    grid = check_tune(tune or {})

    import torch

    torch.set_num_threads(threads)  # the learner runs in this process (num_learners: 0)
    if meta is not None:
        assert config.timesteps is not None  # set by RLlibConfig.check()
        if int(meta["env_steps"]) >= config.timesteps:  # trained: at most the final evaluation is missing
            finish(out, meta, config, job)
            print(
                f"done: {out} is already at {meta['env_steps']} of {config.timesteps} env steps; "
                f"checkpoint in {out / 'checkpoint'}"
            )
            return 0
        drop_lost_iterations(out, int(meta["iteration"]))
        if record["args"].get("ray_address") and not ray_address:
            print(
                f"note: the run used --ray-address {record['args']['ray_address']}; resuming on a local Ray "
                "instance (pass --ray-address to join a cluster)"
            )
        # fresh episodes: the environments' and RLlib's seed from the run's seed and the step count
        algo_config, _ = build_config(config, seed=resume_seed(config.seed, int(meta["env_steps"])))
    elif restart:  # stopped before its first checkpoint: again from step 0, with its config.yml
        (out / "progress.jsonl").unlink(missing_ok=True)
        print(
            f"note: {out} has no checkpoint yet (stopped before its first one): starting it from scratch with "
            "its config.yml",
            file=sys.stderr,
        )
        algo_config, _ = build_config(config)
    else:
        algo_config, mapping = build_config(config)
        import ray

        args = {
            "backend": "rllib",
            "scenario": config.scenario,
            "timesteps": config.timesteps,
            "seed": config.seed,
            "num_env_runners": int(algo_config.num_env_runners or 0),
            "ray_address": ray_address,
            "tune": dict(grid) or None,
        }
        runlock.claim(out, new=True, command=command)  # the lock on --out: one trainer per folder
        write_run_record(
            out,
            config,
            job,
            command=command,
            hyperparameter_file=hyperparameter_file,
            args=args,
            versions={"ray": str(ray.__version__)},
            module_map=mapping,
            rllib_config=config_record(algo_config),
        )
    cpus = cpus_per_trial(algo_config)
    started = init_ray(ray_address, config, cpus if grid else cpus - 1)
    import ray

    try:
        if grid:
            return run_tune(algo_config, grid, out, config, job)
        return run_training(algo_config, out, config, job, restore=meta)
    finally:
        if started:
            ray.shutdown()


def resume(out: str | Path, **options: Any) -> int:
    """Continue the RLlib run in ``out`` with its own config.yml (``train``'s keyword
    options: num_env_runners, ray_address, threads, trust_pickle)."""
    return train(run_config(out, RLlibConfig), out, resume=True, **options)


def require_ray() -> None:
    """A ``ConfigError`` (one line: how to install it) if Ray RLlib cannot be imported."""
    try:
        import ray  # only checks it imports
        import ray.rllib  # noqa: F401
    except ImportError:
        raise ConfigError(RAY_MISSING) from None


# ----------------------------------------------------------------------------------
# Ray
# ----------------------------------------------------------------------------------
def check_ray_address(address: str | None, timeout_s: float = 5.0) -> None:
    """A one-line ``ConfigError`` unless ``address`` is None, ``auto`` or a ``host:port``
    (``ray://host:port``) that accepts a connection within ``timeout_s``: Ray itself
    retries an unreachable address without end (seen: still retrying after 400 s)."""
    if not address or address == "auto":
        return
    import socket

    where = address.removeprefix("ray://")
    host, sep, port_text = where.rpartition(":")
    if not sep or not host or not port_text.isdigit() or not 0 < int(port_text) < 65536:
        raise ConfigError(f"--ray-address {address!r}: expected 'auto' or HOST:PORT (e.g. 10.0.0.5:6379)")
    try:
        with socket.create_connection((host.strip("[]"), int(port_text)), timeout=timeout_s):
            pass
    except OSError as err:
        raise ConfigError(
            f"--ray-address {address!r}: nothing answers there ({err.strerror or type(err).__name__}); "
            "start the cluster with 'ray start --head' or leave --ray-address out for a local Ray"
        ) from None


def init_ray(address: str | None, config: RLlibConfig, cpus_needed: int) -> bool:
    """A small local Ray instance (the config's ``ray:``; no dashboard, no worker logs on
    the console), or a connection to a running cluster (``address``). Returns whether
    it started or connected Ray (False: this process was already connected, e.g. a
    test's or a notebook's ``ray.init()``, which is used as it is)."""
    import ray

    if ray.is_initialized():
        return False
    runtime_env = {"env_vars": {"RAY_USAGE_STATS_ENABLED": "0"}}  # the packages are installed: no PYTHONPATH
    if address:
        try:
            ray.init(address=address, log_to_driver=False, runtime_env=runtime_env)
        except (ConnectionError, RuntimeError, ValueError) as err:
            raise ConfigError(
                f"cannot connect to the Ray cluster at {address!r} ({' '.join(str(err).split())[:200]}); "
                "start one with 'ray start --head' (with RAY_AUTH_MODE=token: the same token on every "
                "node and here)"
            ) from None
        return True
    cores = os.cpu_count() or 1
    num_cpus = max(config.ray.num_cpus or max(cores, cpus_needed), cpus_needed)
    if num_cpus > cores:
        print(f"note: {cpus_needed} CPU(s) requested by the env runners on {cores} core(s): they share the cores")
    ray.init(
        num_cpus=int(num_cpus),
        include_dashboard=False,
        log_to_driver=False,
        object_store_memory=int(config.ray.object_store_memory_mb * 2**20),
        runtime_env=runtime_env,
    )
    return True


# ----------------------------------------------------------------------------------
# one training run
# ----------------------------------------------------------------------------------
def run_training(algo_config: Any, out: Path, config: RLlibConfig, job: Job, restore: dict | None = None) -> int:
    """Train until ``config.timesteps`` env steps (RLlib's lifetime count), checkpointing
    every ``checkpoint_every_iterations`` and at the end, then evaluate. ``restore``: the
    ``coopnav.json`` of ``out/checkpoint``, which the Algorithm is restored from first.
    SIGINT/SIGTERM: stop after the current iteration, checkpoint, return
    ``EXIT_INTERRUPTED``."""
    ckpt_every = config.checkpoint_every_iterations
    m = dict(restore) if restore else {"env_steps": 0, "iteration": 0}
    start_steps, saved_iteration = int(m["env_steps"]), (int(m["iteration"]) if restore else None)
    wall_before = float(m.get("wall_s") or 0.0)  # training time of the sessions before this one
    with stop_on_signals() as stop:
        t0 = time.perf_counter()
        algo = algo_config.build_algo()
        try:
            if restore:
                algo.restore_from_path(str((out / "checkpoint").resolve()))
            print(
                f"{'built and restored' if restore else 'built'} in {time.perf_counter() - t0:.1f} s: "
                f"{algo_config.num_env_runners} env runner(s) x {algo_config.num_envs_per_env_runner} env(s), "
                f"{algo_config.num_learners} remote learner(s)"
                + (f"; resuming at {start_steps} env steps, iteration {saved_iteration}" if restore else ""),
                flush=True,
            )
            t_train = time.perf_counter()
            assert config.timesteps is not None  # set by RLlibConfig.check()
            while m["env_steps"] < config.timesteps and not stop:
                m = metrics(algo.train())
                session = time.perf_counter() - t_train
                m["wall_s"] = round(wall_before + session, 2)
                atomic_append_line(out / "progress.jsonl", json.dumps(m))
                rate = (m["env_steps"] - start_steps) / max(session, 1e-9)
                print(
                    f"iter {m['iteration']}: {m['env_steps']} env steps ({rate:.0f}/s), return "
                    f"{_metres(m['episode_return_mean'])}, survey_error_m {_metres(m['survey_error_m'])}",
                    flush=True,
                )
                if ckpt_every and m["iteration"] % ckpt_every == 0:
                    save_checkpoint(algo, out, m)
                    saved_iteration = m["iteration"]
            if saved_iteration != m["iteration"]:
                save_checkpoint(algo, out, m)
        finally:
            algo.stop()
    if stop:
        print(
            f"stopped at {m['env_steps']} env steps (iteration {m['iteration']}), checkpoint in "
            f"{out / 'checkpoint'}; continue with: {resume_command(out)} --trust-pickle",
            file=sys.stderr,
        )
        return EXIT_INTERRUPTED
    finish(out, m, config, job)
    wall = time.perf_counter() - t_train
    print(
        f"done: {m['env_steps']} env steps ({m['env_steps'] - start_steps} in this run, {wall:.0f} s, "
        f"{(m['env_steps'] - start_steps) / max(wall, 1e-9):.0f}/s); checkpoint in {out / 'checkpoint'}"
    )
    return 0


def finish(out: Path, m: dict, config: RLlibConfig, job: Job) -> None:
    """The final evaluation of ``out/checkpoint`` (``m``: its coopnav.json) on the fixed
    seeds, appended to evaluations.jsonl, unless that file already ends with it."""
    done = _last_json_line(out / "evaluations.jsonl")
    if done is not None and done.get("num_timesteps") == m["env_steps"] and done.get("iteration") == m["iteration"]:
        return
    result = evaluate_checkpoint(out / "checkpoint", config, job)
    if result is None:
        return
    ev = config.eval
    baseline = baselines_on_eval_seeds(out, job.cells, ev.baselines, ev.episodes, ev.seed)
    record = {
        "num_timesteps": m["env_steps"],
        "iteration": m["iteration"],
        "survey_error_m": result["survey_error_m"],
        **{f"{k}_survey_error_m": v["survey_error_m"] for k, v in baseline.items()},
    }
    if len(job.cells) > 1:
        record["per_cell"] = {k: round(v, 4) for k, v in result["per_cell"].items()}
    atomic_append_line(out / "evaluations.jsonl", json.dumps(record))  # never a half-written line
    print(
        f"eval: survey_error_m {result['survey_error_m']:.3f}"
        + "".join(f", {k} {v['survey_error_m']:.3f}" for k, v in baseline.items())
    )


def _metres(v) -> str:
    return "n/a" if v is None else f"{v:.3f}"
