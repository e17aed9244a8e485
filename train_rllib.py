"""train.py --backend rllib: PPO beacons on Ray RLlib (new API stack), for scale-out.

    pip install -e ".[rllib]"
    python train.py --backend rllib --scenario sousa_asv --timesteps 2000000 --num-env-runners 8 --out runs/sousa_rllib
    python train.py --resume runs/sousa_rllib                        # continue it after Ctrl-C or a crash
    python train.py --backend rllib ... --ray-address auto          # on a running Ray cluster
    python train.py --backend rllib --scenario gao_sea --timesteps 200000 --out runs/sweep \\
        --tune lr=1e-4,3e-4 --tune seed=0,1,2                        # a Ray Tune grid

train.py imports this module only for ``--backend rllib`` (after checking that Ray
is installed); nothing else imports Ray.

Read top to bottom: hyperparameters (configs/rllib/<scenario>.yml, else default.yml)
-> the RLlib ``PPOConfig`` -> Ray (a small local instance, or ``--ray-address``) ->
either one training run or a Tune grid -> evaluation on fixed seeds -> files.

**The algorithm.** RLlib's PPO on the new API stack (RLModule + Learner,
``config.env_runners(...)``, ``config.learners(...)``), the environment the
PettingZoo parallel env through ``coopnav_env.rllib_env.CoopNavRLlibEnv`` (a small
``MultiAgentEnv`` adapter; its docstring says why not RLlib's
``ParallelPettingZooEnv``). Policy mapping: one RLModule per beacon kind
(``beacon_auv``, ``asv``, ``boat``, ...), shared by the beacons of that kind.
``--num-env-runners`` env runner processes sample in parallel (0: the driver
samples), each stepping ``num_envs_per_env_runner`` copies of the env (``--n-envs``
overrides it); with ``--ray-address`` they spread over the cluster's nodes. The
learner runs in the driver (``learners: {num_learners: 0}``; more learners are a
YAML setting) with ``--threads`` torch threads.

**Stop and resume.** SIGINT (Ctrl-C) or SIGTERM stops the run after the current
training iteration, writes the checkpoint and exits with status 130
(``train.EXIT_INTERRUPTED``), printing the command that continues it:
``python train.py --resume <out>``. train.py sees from ``config.yml`` that the run is
an RLlib one; the scenario, total steps, seed and hyperparameters come from there
(giving them again is an error), ``--num-env-runners`` and ``--ray-address`` may be
given anew (by default the run's runner count, on a local Ray instance). The
resumed run rebuilds the PPOConfig and restores the Algorithm from ``checkpoint/``
(``algo.restore_from_path``: the modules, their optimizers, the observation
filters, RLlib's step and iteration counts), trains until the run's total env
steps, appends to ``progress.jsonl`` and ends with the files of a finished run.
Its episodes are fresh ones (RLlib's and the environments' seed from the run's seed
and the step count, as train.py's SB3 path). A run killed without a last checkpoint
resumes from the last periodic one: the lines of ``progress.jsonl`` after it are
dropped, since those iterations are trained again. Resuming a finished run does
nothing (it evaluates the checkpoint if that had not been done) and succeeds. A Tune
grid cannot be resumed.

What a run directory holds (``--out``):

    config.yml         the exact config: command, arguments, the hyperparameter file and
                       its content, the resolved RLlib AlgorithmConfig, the scenario's
                       parameters, the beacon -> module map, versions
    checkpoint/        the RLlib Algorithm checkpoint (``algo.save_to_path``), replaced
                       whole every ``checkpoint_every_iterations``, on a stop and at the
                       end (written beside, then renamed); ``coopnav.json`` in it: steps,
                       iteration (what ``--resume`` reads)
    progress.jsonl     one line per training iteration (steps, returns, survey error, training
                       wall time summed over the sessions of a resumed run)
    evaluations.jsonl  the final evaluation on fixed seeds (``eval:``), as train.py's SB3 path
    baseline_eval.json the baselines on the same seeds

``agents.load(out)`` (and so ``evaluate.py --policies out,fim_a``) loads the policy.

**Tune** (``--tune KEY=V1,V2`` repeated): the grid of every combination, one RLlib
trial each, run by ``ray.tune.Tuner`` under ``out/tune/``; KEY is ``seed`` or a
``PPOConfig.training`` keyword (``lr``, ``gamma``, ``entropy_coeff``, ...).
Afterwards every trial's final checkpoint is evaluated on the fixed
seeds, and ``summary.csv`` and ``summary.md`` (one table: the grid values, steps,
mean episode return, the training episodes' survey error, the evaluation's
survey error, the checkpoint) are written atomically.
"""

from __future__ import annotations

import dataclasses
import enum
import inspect
import json
import os
import shlex
import shutil
import signal
import sys
import time
from pathlib import Path

os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")  # no usage reports from training runs

import numpy as np
import yaml

import train
from train import atomic_write_text, fail, plain, read_json

ROOT = Path(__file__).resolve().parent
CONFIG_DIR = ROOT / "configs" / "rllib"
KNOWN_SECTIONS = {"ppo", "model", "normalize_obs", "env_runners", "learners", "env", "reward", "eval",
                  "checkpoint_every_iterations", "ray"}
SUMMARY_COLUMNS = ["trial", "env_steps", "iterations", "episode_return_mean", "train_survey_error_m",
                   "eval_survey_error_m", "checkpoint"]


# ----------------------------------------------------------------------------------
# 1. hyperparameters
# ----------------------------------------------------------------------------------
def hyperparameter_file(scenario: str, explicit: str | None) -> Path:
    return train.hyperparameter_file(scenario, explicit, CONFIG_DIR)


def load_hyperparameters(path: Path) -> dict:
    try:
        hp = yaml.safe_load(Path(path).read_text()) or {}
    except yaml.YAMLError as err:
        fail(f"{path}: not YAML: {str(err).splitlines()[0]}")
    if not isinstance(hp, dict):
        fail(f"{path}: expected a mapping of hyperparameters")
    unknown = sorted(set(hp) - KNOWN_SECTIONS)
    if unknown:
        fail(f"{path}: unknown section(s) {', '.join(unknown)} for --backend rllib; "
             f"valid: {', '.join(sorted(KNOWN_SECTIONS))}")
    for name in ("ppo", "model", "env_runners", "learners", "env", "eval", "ray"):
        if not isinstance(hp.get(name) or {}, dict):
            fail(f"{path}: {name} must be a mapping")
    extra = sorted(set(hp.get("env") or {}) - {"overrides"})
    if extra:
        fail(f"{path}: unknown env entr(y/ies) {', '.join(extra)}; valid: overrides")
    return hp


def training_keywords() -> set:
    """The keywords PPOConfig.training accepts (its own and AlgorithmConfig's)."""
    from ray.rllib.algorithms.algorithm_config import AlgorithmConfig
    from ray.rllib.algorithms.ppo import PPOConfig

    names = set()
    for fn in (PPOConfig.training, AlgorithmConfig.training):
        names |= {n for n, p in inspect.signature(fn).parameters.items()
                  if n != "self" and p.kind not in (p.VAR_KEYWORD, p.VAR_POSITIONAL)}
    return names


def parse_value(text: str):
    """'3e-4' -> 0.0003, '2' -> 2, '[64, 64]' -> [64, 64], 'tanh' -> 'tanh'."""
    text = text.strip()
    for cast in (int, float):
        try:
            return cast(text)
        except ValueError:
            pass
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError:
        return text


def parse_tune(items: list) -> dict:
    """``["lr=1e-4,3e-4", "seed=0,1,2"]`` -> ``{"lr": [1e-4, 3e-4], "seed": [0, 1, 2]}``."""
    grid = {}
    valid = training_keywords()
    for item in items:
        if "=" not in item:
            fail(f"--tune expects KEY=V1,V2,..., got {item!r}")
        key, values = item.split("=", 1)
        key = key.strip()
        if key in grid:
            fail(f"--tune {key} given twice")
        if key != "seed" and key not in valid:
            fail(f"--tune {key}: not seed or a PPOConfig.training keyword (lr, gamma, lambda_, entropy_coeff, "
                 "clip_param, num_epochs, minibatch_size, ...)")
        parsed = [parse_value(v) for v in split_values(values)]
        if not parsed or any(v is None or v == "" for v in parsed):
            fail(f"--tune {key}: empty value in {values!r}")
        if len(set(map(repr, parsed))) != len(parsed):
            fail(f"--tune {key} repeats a value")
        if key == "seed" and not all(isinstance(v, int) for v in parsed):
            fail(f"--tune seed takes integers, got {values!r}")
        grid[key] = parsed
    return grid


def split_values(text: str) -> list:
    """Split on top-level commas ('[64,64],[128,128]' -> two values): evaluate.py's parser."""
    from evaluate import split_top_level

    return split_top_level(text)


# ----------------------------------------------------------------------------------
# 2. the RLlib config
# ----------------------------------------------------------------------------------
def env_config(scenario: str, hp: dict, seed: int) -> dict:
    from coopnav_env.vector import check_reward_terms

    runners = hp.get("env_runners") or {}
    return {"scenario": scenario, "overrides": dict((hp.get("env") or {}).get("overrides") or {}), "seed": int(seed),
            "reward_terms": check_reward_terms(hp.get("reward")),
            "num_envs_per_env_runner": int(runners.get("num_envs_per_env_runner", 1) or 1)}


def build_config(scenario: str, hp: dict, seed: int, num_env_runners: int | None, hp_path="config"):
    """The PPOConfig of a run: the adapter env, one module per beacon kind, the YAML's
    ``ppo``/``model``/``env_runners``/``learners`` sections."""
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.core.rl_module.multi_rl_module import MultiRLModuleSpec
    from ray.rllib.core.rl_module.rl_module import RLModuleSpec

    from coopnav_env.rllib_env import CoopNavRLlibEnv, KindMapping, SurveyErrorMetrics, mean_std_filter, module_ids, \
        module_map

    env_cfg = env_config(scenario, hp, seed)
    mapping = module_map(scenario, env_cfg["overrides"])
    runners = dict(hp.get("env_runners") or {})
    if num_env_runners is not None:
        runners["num_env_runners"] = num_env_runners
    runners.setdefault("num_env_runners", 0)
    if hp.get("normalize_obs", False):
        runners["env_to_module_connector"] = mean_std_filter
    model = dict(hp.get("model") or {})
    try:
        config = (
            PPOConfig()
            .environment(CoopNavRLlibEnv, env_config=env_cfg, disable_env_checking=True)
            .env_runners(**runners)
            .learners(**(hp.get("learners") or {}))
            .training(**(hp.get("ppo") or {}))
            .multi_agent(policies=set(module_ids(mapping)), policy_mapping_fn=KindMapping(mapping),
                         policies_to_train=module_ids(mapping))
            .rl_module(rl_module_spec=MultiRLModuleSpec(
                rl_module_specs={m: RLModuleSpec(model_config=dict(model)) for m in module_ids(mapping)}))
            .callbacks(SurveyErrorMetrics)
            .debugging(seed=int(seed), log_level="ERROR")
            .reporting(metrics_num_episodes_for_smoothing=100)
        )
        config.validate()
    except (TypeError, ValueError, KeyError, AssertionError) as err:
        fail(f"{hp_path}: bad RLlib hyperparameters: {' '.join(str(err).split())[:300] or type(err).__name__}")
    return config, mapping


def config_record(config) -> dict:
    """The AlgorithmConfig as plain YAML-able values (callables and classes by name)."""
    def clean(v):
        if isinstance(v, enum.Enum):
            return clean(v.value)
        if isinstance(v, dict):
            return {str(k): clean(x) for k, x in v.items()}
        if isinstance(v, (list, tuple, set)):
            return [clean(x) for x in v]
        if v is None or isinstance(v, (bool, int, float, str)):
            return v
        if isinstance(v, (np.integer, np.floating)):
            return v.item()
        if isinstance(v, type) or callable(v):
            return f"{getattr(v, '__module__', '?')}.{getattr(v, '__qualname__', type(v).__name__)}"
        return repr(v)

    d = config.to_dict()
    keep = {k: v for k, v in d.items() if not k.startswith("_") or k in ("_rl_module_spec",)}
    return clean(keep)


# ----------------------------------------------------------------------------------
# 3. Ray
# ----------------------------------------------------------------------------------
def init_ray(address: str | None, hp: dict, cpus_needed: int) -> bool:
    """A small local Ray instance (the YAML's ``ray:``; no dashboard, no worker logs on
    the console), or a connection to a running cluster (``--ray-address``). Returns
    whether it started or connected Ray (False: this process was already connected,
    e.g. a test's or a notebook's ``ray.init()``, which is used as it is)."""
    import ray

    if ray.is_initialized():
        return False

    pythonpath = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH", "")) if p)
    runtime_env = {"env_vars": {"PYTHONPATH": pythonpath, "RAY_USAGE_STATS_ENABLED": "0"}}
    if address:
        try:
            ray.init(address=address, log_to_driver=False, runtime_env=runtime_env)
        except (ConnectionError, RuntimeError, ValueError) as err:
            fail(f"cannot connect to the Ray cluster at {address!r} ({' '.join(str(err).split())[:200]}); "
                 "start one with 'ray start --head' (with RAY_AUTH_MODE=token: the same token on every node and here)")
        return True
    rc = hp.get("ray") or {}
    cores = os.cpu_count() or 1
    num_cpus = rc.get("num_cpus") or max(cores, cpus_needed)
    if cpus_needed > num_cpus:
        num_cpus = cpus_needed
    if num_cpus > cores:
        print(f"note: {cpus_needed} CPU(s) requested by the env runners on {cores} core(s): they share the cores")
    ray.init(num_cpus=int(num_cpus), include_dashboard=False, log_to_driver=False,
             object_store_memory=int(float(rc.get("object_store_memory_mb", 200)) * 2**20),
             runtime_env=runtime_env)
    return True


def cpus_per_trial(config) -> int:
    runners = int(config.num_env_runners or 0)
    return int(np.ceil(runners * float(config.num_cpus_per_env_runner or 1))) + 1


# ----------------------------------------------------------------------------------
# 4. files
# ----------------------------------------------------------------------------------
def save_checkpoint(algo, out: Path, meta: dict) -> Path:
    """The Algorithm checkpoint in ``out/checkpoint``, replaced whole: written to a
    temporary directory beside it, then renamed into place."""
    final = out / "checkpoint"
    tmp = out / f".checkpoint.tmp{os.getpid()}"
    old = out / f".checkpoint.old{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    algo.save_to_path(str(tmp.resolve()))
    atomic_write_text(tmp / "coopnav.json", json.dumps(meta))
    if final.exists():
        os.replace(final, old)
    os.replace(tmp, final)
    shutil.rmtree(old, ignore_errors=True)
    return final


def resumable_checkpoint(out: Path) -> dict | None:
    """The ``coopnav.json`` of ``out/checkpoint`` (None: nothing to resume from), after
    tidying what a killed ``save_checkpoint`` may have left: if the process died between
    its two renames (no ``checkpoint/``), the newest complete checkpoint beside it
    (``.checkpoint.tmp*`` holds ``coopnav.json`` only once complete; ``.checkpoint.old*``
    is a former ``checkpoint/``) is put back; the other leftovers are removed."""
    from agents.rllib_policy import CHECKPOINT_MARKER

    final = out / "checkpoint"
    meta = read_json(final / "coopnav.json")
    spares = [d for d in out.glob(".checkpoint.*") if d.is_dir()]
    if meta is None and not final.exists():
        complete = [(read_json(d / "coopnav.json"), d) for d in spares if (d / CHECKPOINT_MARKER).is_file()]
        complete = [(m, d) for m, d in complete if m is not None]
        if complete:
            meta, best = max(complete, key=lambda md: int(md[0].get("iteration", 0)))
            os.replace(best, final)
            print(f"note: restored {final} from {best.name} (the last save was cut short)", file=sys.stderr)
    for d in spares:
        shutil.rmtree(d, ignore_errors=True)
    if meta is None or "env_steps" not in meta or "iteration" not in meta:
        return None
    return meta


def drop_lost_iterations(out: Path, iteration: int):
    """Keep the lines of ``progress.jsonl`` up to ``iteration`` (the checkpoint a resumed
    run continues from): a run killed without a last checkpoint logged iterations whose
    training the checkpoint does not hold, and the resumed run trains them again."""
    path = out / "progress.jsonl"
    if not path.is_file():
        return
    lines = path.read_text().splitlines()

    def kept(line):
        try:
            return int(json.loads(line)["iteration"]) <= iteration
        except (ValueError, KeyError, TypeError):  # a line cut short by the kill
            return False

    keep = [line for line in lines if kept(line)]
    if len(keep) != len(lines):
        atomic_write_text(path, "".join(line + "\n" for line in keep))


def metrics(result: dict) -> dict:
    """The few numbers of an RLlib result that a run records."""
    er = result.get("env_runners", {}) or {}

    def num(v):
        try:
            v = float(v)
        except (TypeError, ValueError):
            return None
        return v if np.isfinite(v) else None

    steps = result.get("num_env_steps_sampled_lifetime", er.get("num_env_steps_sampled_lifetime", 0))
    return {"iteration": int(result.get("training_iteration", 0)), "env_steps": int(num(steps) or 0),
            "episode_return_mean": num(er.get("episode_return_mean")),
            "survey_error_m": num(er.get("survey_error_m")),
            "episodes": int(num(er.get("num_episodes_lifetime")) or 0),
            "time_s": num(result.get("time_total_s"))}


def versions() -> dict:
    import ray

    return {**train.versions(), "ray": str(ray.__version__)}


def evaluate_checkpoint(path, scenario_config, cells, ev: dict) -> dict | None:
    """The deterministic policy of checkpoint ``path`` on the fixed evaluation seeds
    (train.py's ``evaluate``: survey_error_m over every step of every episode)."""
    episodes = int(ev.get("episodes", 16))
    if episodes <= 0:
        return None
    from agents.rllib_policy import batch_actor

    return train.evaluate(batch_actor(path, scenario_config), cells, episodes, int(ev.get("seed", 500000)))


def baselines_on_eval_seeds(out: Path, cells, ev: dict) -> dict:
    """train.py's, with this backend's evaluation defaults (16 episodes, seeds 500000..)."""
    episodes = int(ev.get("episodes", 16))
    if episodes <= 0:
        return read_json(out / "baseline_eval.json") or {}
    return train.baselines_on_eval_seeds(out, cells, ev.get("baselines"), episodes, int(ev.get("seed", 500000)))


# ----------------------------------------------------------------------------------
# 5. one training run
# ----------------------------------------------------------------------------------
def run_training(config, out: Path, total: int, hp: dict, scenario_config, cells, restore: dict | None = None) -> int:
    """Train until ``total`` env steps (RLlib's lifetime count), checkpointing every
    ``checkpoint_every_iterations`` and at the end, then evaluate. ``restore``: the
    ``coopnav.json`` of ``out/checkpoint``, which the Algorithm is restored from first
    (``restore_from_path``: the modules, optimizers, observation filters, the step and
    iteration counts). SIGINT/SIGTERM: stop after the current iteration, checkpoint,
    return ``train.EXIT_INTERRUPTED``."""
    ckpt_every = int(hp.get("checkpoint_every_iterations", 10) or 0)
    state = {"stop": False}

    def request_stop(signum, frame):
        state["stop"] = True
        signal.signal(signum, signal.default_int_handler if signum == signal.SIGINT else signal.SIG_DFL)

    m = dict(restore) if restore else {"env_steps": 0, "iteration": 0}
    start_steps, saved_iteration = int(m["env_steps"]), (int(m["iteration"]) if restore else None)
    wall_before = float(m.get("wall_s") or 0.0)  # training time of the sessions before this one
    old_handlers = {s: signal.signal(s, request_stop) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        t0 = time.perf_counter()
        algo = config.build_algo()
        try:
            if restore:
                algo.restore_from_path(str((out / "checkpoint").resolve()))
            print(f"{'built and restored' if restore else 'built'} in {time.perf_counter() - t0:.1f} s: "
                  f"{config.num_env_runners} env runner(s) x {config.num_envs_per_env_runner} env(s), "
                  f"{config.num_learners} remote learner(s)"
                  + (f"; resuming at {start_steps} env steps, iteration {saved_iteration}" if restore else ""),
                  flush=True)
            t_train = time.perf_counter()
            while m["env_steps"] < total and not state["stop"]:
                m = metrics(algo.train())
                session = time.perf_counter() - t_train
                m["wall_s"] = round(wall_before + session, 2)
                with open(out / "progress.jsonl", "a") as f:
                    f.write(json.dumps(m) + "\n")
                rate = (m["env_steps"] - start_steps) / max(session, 1e-9)
                print(f"iter {m['iteration']}: {m['env_steps']} env steps ({rate:.0f}/s), return "
                      f"{_fmt(m['episode_return_mean'])}, survey_error_m {_fmt(m['survey_error_m'])}", flush=True)
                if ckpt_every and m["iteration"] % ckpt_every == 0:
                    save_checkpoint(algo, out, m)
                    saved_iteration = m["iteration"]
            if saved_iteration != m["iteration"]:
                save_checkpoint(algo, out, m)
        finally:
            algo.stop()
    finally:
        for s, h in old_handlers.items():
            signal.signal(s, h)
    if state["stop"]:
        print(f"stopped at {m['env_steps']} env steps (iteration {m['iteration']}), checkpoint in "
              f"{out / 'checkpoint'}; continue with: python train.py --resume {out}", file=sys.stderr)
        return train.EXIT_INTERRUPTED
    finish(out, m, hp, scenario_config, cells)
    wall = time.perf_counter() - t_train
    print(f"done: {m['env_steps']} env steps ({m['env_steps'] - start_steps} in this run, {wall:.0f} s, "
          f"{(m['env_steps'] - start_steps) / max(wall, 1e-9):.0f}/s); checkpoint in {out / 'checkpoint'}")
    return 0


def finish(out: Path, m: dict, hp: dict, scenario_config, cells):
    """The final evaluation of ``out/checkpoint`` (``m``: its coopnav.json) on the fixed
    seeds, appended to evaluations.jsonl, unless that file already ends with it."""
    ev = hp.get("eval") or {}
    done = _last_json_line(out / "evaluations.jsonl")
    if done is not None and done.get("num_timesteps") == m["env_steps"] and done.get("iteration") == m["iteration"]:
        return
    result = evaluate_checkpoint(out / "checkpoint", scenario_config, cells, ev)
    if result is None:
        return
    baseline = baselines_on_eval_seeds(out, cells, ev)
    record = {"num_timesteps": m["env_steps"], "iteration": m["iteration"],
              "survey_error_m": result["survey_error_m"],
              **{f"{k}_survey_error_m": v["survey_error_m"] for k, v in baseline.items()}}
    if len(cells) > 1:
        record["per_cell"] = {k: round(v, 4) for k, v in result["per_cell"].items()}
    with open(out / "evaluations.jsonl", "a") as f:
        f.write(json.dumps(record) + "\n")
    print(f"eval: survey_error_m {result['survey_error_m']:.3f}"
          + "".join(f", {k} {v['survey_error_m']:.3f}" for k, v in baseline.items()))


def _last_json_line(path: Path) -> dict | None:
    try:
        lines = path.read_text().splitlines()
    except FileNotFoundError:
        return None
    for line in reversed(lines):
        try:
            return json.loads(line)
        except ValueError:  # a line cut short
            continue
    return None


def _fmt(v):
    return "n/a" if v is None else f"{v:.3f}"


# ----------------------------------------------------------------------------------
# 6. a Tune grid
# ----------------------------------------------------------------------------------
def run_tune(config, grid: dict, out: Path, total: int, hp: dict, scenario_config, cells, base_env_config) -> int:
    from ray import tune

    param_space = config.to_dict()
    for key, values in grid.items():
        name = "lambda" if key == "lambda_" else key
        param_space[name] = tune.grid_search(values)
    if "seed" in grid:  # every trial's environments from its own seed
        param_space["env_config"] = tune.sample_from(lambda spec: {**base_env_config, "seed": int(spec.config["seed"])})
    rc = hp.get("ray") or {}
    tuner = tune.Tuner(
        config.algo_class, param_space=param_space,  # the class: the name "PPO" makes Tune import every algorithm
        tune_config=tune.TuneConfig(max_concurrent_trials=rc.get("max_concurrent_trials"), reuse_actors=False,
                                    trial_name_creator=_trial_name, trial_dirname_creator=_trial_name),
        run_config=tune.RunConfig(name="tune", storage_path=str(out.resolve()), verbose=0,
                                  stop={"num_env_steps_sampled_lifetime": total},
                                  checkpoint_config=tune.CheckpointConfig(checkpoint_at_end=True, num_to_keep=1)))
    t0 = time.perf_counter()
    results = tuner.fit()
    print(f"tune: {len(results)} trial(s) in {time.perf_counter() - t0:.0f} s", flush=True)
    rows = []
    for r in sorted(results, key=lambda r: r.path):
        trial_cfg = r.config or {}
        row = {"trial": Path(r.path).name}
        for key in grid:
            row[key] = trial_cfg.get("lambda" if key == "lambda_" else key)
        if r.error is not None:
            row.update({"env_steps": None, "iterations": None, "episode_return_mean": None,
                        "train_survey_error_m": None, "eval_survey_error_m": None,
                        "checkpoint": f"error: {' '.join(str(r.error).split())[:120]}"})
            rows.append(row)
            continue
        m = metrics(r.metrics or {})
        ckpt = Path(r.checkpoint.path) if r.checkpoint is not None else None
        evaluation = evaluate_checkpoint(ckpt, scenario_config, cells, hp.get("eval") or {}) if ckpt else None
        row.update({"env_steps": m["env_steps"], "iterations": m["iteration"],
                    "episode_return_mean": m["episode_return_mean"], "train_survey_error_m": m["survey_error_m"],
                    "eval_survey_error_m": evaluation["survey_error_m"] if evaluation else None,
                    "checkpoint": str(ckpt.relative_to(out.resolve())) if ckpt else None})
        rows.append(row)
    columns = ["trial", *grid, *SUMMARY_COLUMNS[1:]]
    write_summary(out, columns, rows)
    print((out / "summary.md").read_text())
    failed = [r for r in rows if str(r.get("checkpoint") or "").startswith("error")]
    if failed:
        print(f"{len(failed)} trial(s) failed; see {out / 'tune'}", file=sys.stderr)
        return 1
    return 0


def _trial_name(trial) -> str:
    """``trial_<index>_<grid values>`` from Tune's experiment tag, without commas (evaluate.py's
    ``--policies`` separator) or '=': ``trial_1_lr-0.0003_seed-0``."""
    tag = str(trial.experiment_tag).replace(",", "_").replace("=", "-").replace("/", "_").replace(" ", "")
    return f"trial_{tag}"[:120]


def write_summary(out: Path, columns: list, rows: list):
    """summary.csv and summary.md (the same table), each written atomically."""
    import csv
    import io

    def cell(v):
        if isinstance(v, float):
            return f"{v:.6g}"
        return "" if v is None else str(v)

    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(columns)
    for r in rows:
        w.writerow([cell(r.get(c)) for c in columns])
    atomic_write_text(out / "summary.csv", buf.getvalue())
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(cell(r.get(c)) for c in columns) + " |" for r in rows]
    atomic_write_text(out / "summary.md", "\n".join(lines) + "\n")


# ----------------------------------------------------------------------------------
# 7. main
# ----------------------------------------------------------------------------------
def main(args, argv=None) -> int:
    """``args``: train.py's parsed arguments (``--backend rllib``, or ``--resume`` of a
    run whose config.yml says rllib)."""
    from coopnav_env import list_scenarios, make_config

    if args.resume:
        out = Path(args.resume)
        saved = read_json(out / "config.yml", load=yaml.safe_load)
        run = saved["args"]
        if run.get("tune"):
            fail(f"{out} is a Ray Tune grid (--tune): --resume continues single runs only")
        path, hp = saved["hyperparameter_file"], saved["hyperparameters"]
        scenario, total, seed = run["scenario"], int(run["timesteps"]), int(run["seed"])
        meta = resumable_checkpoint(out)
        if meta is None:
            fail(f"{out} has no checkpoint to resume from (checkpoint/coopnav.json); start it again with --out")
    else:
        if args.scenario not in list_scenarios():
            fail(f"unknown scenario {args.scenario!r}; valid scenarios: {', '.join(list_scenarios())}")
        out = Path(args.out)
        if out.exists() and not out.is_dir():
            fail(f"--out {out} is a file")
        if out.exists() and any(out.iterdir()):
            fail(f"{out} exists and is not empty; use --resume {out} to continue it, or another --out")
        path = hyperparameter_file(args.scenario, args.config)
        hp = load_hyperparameters(path)
        if args.n_envs:
            hp.setdefault("env_runners", {})["num_envs_per_env_runner"] = args.n_envs
        scenario, total, seed, meta = args.scenario, int(args.timesteps), int(args.seed), None
    overrides = dict((hp.get("env") or {}).get("overrides") or {})
    try:
        scenario_config = make_config(scenario, **overrides)
    except ValueError as err:
        fail(f"{path}: {err}")
    try:
        cells = train.eval_cells(scenario_config, hp.get("eval") or {})
    except ValueError as err:
        fail(f"{path}: {err}")
    from coopnav_env.vector import check_reward_terms

    try:
        check_reward_terms(hp.get("reward"))
    except ValueError as err:
        fail(f"{path}: reward: {err}")
    for name in (hp.get("eval") or {}).get("baselines") or []:
        from baselines import list_policies

        if name not in list_policies():
            fail(f"{path}: eval.baselines: unknown policy {name!r}; valid: {', '.join(list_policies())}")
    grid = parse_tune(args.tune or [])
    import torch

    torch.set_num_threads(args.threads)  # the learner runs in this process (num_learners: 0)
    if meta is not None:  # --resume
        if int(meta["env_steps"]) >= total:  # trained: at most the final evaluation is missing
            finish(out, meta, hp, scenario_config, cells)
            print(f"done: {out} is already at {meta['env_steps']} of {total} env steps; checkpoint in "
                  f"{out / 'checkpoint'}")
            return 0
        drop_lost_iterations(out, int(meta["iteration"]))
        runners = args.num_env_runners if args.num_env_runners is not None else run.get("num_env_runners")
        if run.get("ray_address") and not args.ray_address:
            print(f"note: the run used --ray-address {run['ray_address']}; resuming on a local Ray instance "
                  "(pass --ray-address to join a cluster)")
        # fresh episodes: the environments' and RLlib's seed from the run's seed and the step count
        config, _ = build_config(scenario, hp, train.resume_seed(seed, int(meta["env_steps"])), runners, hp_path=path)
    else:
        config, mapping = build_config(scenario, hp, seed, args.num_env_runners, hp_path=path)
        run = {"backend": "rllib", "scenario": scenario, "timesteps": total, "seed": seed,
               "num_env_runners": int(config.num_env_runners or 0), "ray_address": args.ray_address,
               "tune": {k: v for k, v in grid.items()} or None}
        out.mkdir(parents=True, exist_ok=True)
        record = {
            "command": "python train.py " + " ".join(shlex.quote(a) for a in (sys.argv[1:] if argv is None else argv)),
            "args": run, "hyperparameter_file": str(path), "hyperparameters": hp,
            "module_map": mapping, "rllib_config": config_record(config),
            "scenario_config": dataclasses.asdict(scenario_config),
            "eval_cells": [label for label, _ in cells], "versions": versions(),
        }
        atomic_write_text(out / "config.yml", yaml.safe_dump(plain(record), sort_keys=False))
    started = init_ray(args.ray_address, hp, cpus_per_trial(config) - 1 if not grid else cpus_per_trial(config))
    import ray

    try:
        if grid:
            return run_tune(config, grid, out, total, hp, scenario_config, cells, env_config(scenario, hp, seed))
        return run_training(config, out, total, hp, scenario_config, cells, restore=meta)
    finally:
        if started:
            ray.shutdown()
