"""The training command line (``train.py``, ``coopnav-train``): argparse -> config -> trainer.

    coopnav-train --scenario sousa_asv --timesteps 2000000 --out runs/sousa_ppo
    python -m agents.training.cli --resume runs/sousa_ppo

``main(argv)`` returns the exit status: 0 done, 1 a Tune trial failed, 2 bad input
(one line on stderr, nothing written), 130 stopped by SIGINT/SIGTERM after a
checkpoint (the line on stderr says how to continue).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from agents.formats import PolicyFormatError
from coopnav_env.names import unique_assignments
from coopnav_env.seeds import VALIDATION_SEED

from . import rllib, sb3
from .common import EXIT_BAD_INPUT, command_line, read_run_record
from .config import CONFIG_DIRS, ConfigError, config_class, hyperparameter_file, load_config, parse_value

RUN_SETTINGS = ("scenario", "timesteps", "seed", "out", "n_envs", "config", "set", "tune")  # not with --resume
RLLIB_ONLY = ("num_env_runners", "ray_address", "tune")


def _epilog(prog: str = "train.py") -> str:
    from coopnav_env import list_scenarios

    return f"""\
scenarios: {", ".join(list_scenarios())}

examples:
  {prog} --scenario sousa_asv --timesteps 2000000 --out runs/sousa_ppo
  {prog} --scenario gao_sea --timesteps 500000 --out runs/g --set eval.episodes=8 --set ppo.learning_rate=lin_1e-3
  {prog} --resume runs/sousa_ppo                 continue an interrupted run (either backend)
  {prog} --plot runs/sousa_ppo                   redraw its learning_curve.png
  {prog} --backend rllib --scenario sousa_asv --timesteps 2000000 --num-env-runners 8 --out runs/sousa_rllib
  {prog} --backend rllib --scenario gao_sea --timesteps 200000 --out runs/sweep --tune lr=1e-4,3e-4 --tune seed=0,1

progress: a bar on a terminal, one line per stage (and every minute) elsewhere; --no-progress: none.

the config: --config FILE, else {_rel(CONFIG_DIRS["sb3"])}/<scenario>.yml ({_rel(CONFIG_DIRS["rllib"])}/ with
--backend rllib), else default.yml there; then --set, --n-envs and --seed on top. Its
sections and defaults: agents.training.config (TrainConfig, RLlibConfig); an unknown key is
an error naming the closest valid one. The evaluation that picks the best model runs on the
validation seeds {VALIDATION_SEED}.. (eval.seed).

a run directory: config.yml (the exact config), model.safetensors + vecnormalize.safetensors,
best_model.safetensors, checkpoints/, evaluations.jsonl, baseline_eval.json (RLlib: checkpoint/,
progress.jsonl); agents.load(DIR) loads the policy. --resume of a run stopped before its first
checkpoint starts it from scratch with its config.yml.

exit status: 0 done; 1 a Tune trial failed; 2 bad input (one line on stderr); 130 stopped by
Ctrl-C/SIGTERM after a checkpoint (continue with --resume DIR)."""


def _rel(path: Path) -> str:
    try:
        return str(path.relative_to(Path.cwd()))
    except ValueError:
        return str(path)


def _int_at_least(low: int):
    def parse(text):
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
        if value < low:
            raise argparse.ArgumentTypeError(f"must be >= {low}, got {text!r}")
        return value

    parse.__name__ = f"integer >= {low}"
    return parse


def _int_in(low: int, high: int):
    def parse(text):
        value = _int_at_least(low)(text)
        if value > high:
            raise argparse.ArgumentTypeError(f"must be at most {high}, got {text!r}")
        return value

    parse.__name__ = f"integer in [{low}, {high}]"
    return parse


def threads_arg(text: str) -> int:
    """--threads: an integer from 1 to this machine's CPU count (more only spin; torch's
    OpenMP aborted the process at 100000)."""
    value = _int_at_least(1)(text)
    cpus = os.cpu_count() or 1
    if value > cpus:
        raise argparse.ArgumentTypeError(f"this machine has {cpus} CPUs: at most {cpus}, got {text!r}")
    return value


def _setting(text: str) -> tuple:
    key, sep, value = text.partition("=")
    if not sep or not key.strip():
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE (e.g. eval.episodes=4), got {text!r}")
    return key.strip(), parse_value(value)


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, through main's handler (exit status 2)
        from coopnav_env.names import option_hint

        raise ConfigError(option_hint(message, self._option_string_actions))


def build_parser(prog: str = "train.py") -> argparse.ArgumentParser:
    p = _Parser(
        prog=prog,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=_epilog(prog),
        description="Train a PPO beacon policy on a coopnav scenario: stable-baselines3 on this\n"
        "machine (default), or Ray RLlib (--backend rllib) for scale-out.",
    )
    job = p.add_argument_group("the run")
    job.add_argument(
        "--scenario", metavar="NAME", help="scenario to train on (required unless --resume; the names are listed below)"
    )
    job.add_argument(
        "--timesteps",
        metavar="N",
        type=_int_at_least(1),
        help="total environment steps (rows: beacons x environments; required unless --resume)",
    )
    job.add_argument("--out", metavar="DIR", help="run directory to create, absent or empty (required unless --resume)")
    job.add_argument(
        "--resume",
        metavar="DIR",
        help="continue the run in DIR from its last checkpoint, with its own config.yml and backend "
        "(then none of --scenario, --timesteps, --seed, --out, --config, --set, --n-envs, --tune)",
    )
    job.add_argument(
        "--plot",
        metavar="RUN",
        help="(re)draw RUN/learning_curve.png from the run's evaluations.jsonl and baseline_eval.json, "
        "and exit (train.py draws it when a run ends or stops)",
    )
    job.add_argument("--seed", metavar="N", type=int, help="seed of the run (default: the config's seed, 0)")
    job.add_argument(
        "--backend",
        choices=("sb3", "rllib"),
        help="sb3: stable-baselines3 PPO on one machine; rllib: Ray RLlib PPO "
        "(pip install -e '.[rllib]') (default: sb3; with --resume the run's)",
    )
    cfg = p.add_argument_group("the config")
    cfg.add_argument(
        "--config",
        metavar="FILE",
        help="config YAML (default: configs/ppo/<scenario>.yml, or configs/rllib/ for --backend rllib, "
        "else default.yml there)",
    )
    cfg.add_argument(
        "--set",
        metavar="KEY=VALUE",
        action="append",
        type=_setting,
        help="override one config entry, VALUE read as YAML (repeatable; e.g. eval.episodes=4, "
        "ppo.learning_rate=lin_1e-3, env.overrides.max_cycles=50)",
    )
    cfg.add_argument(
        "--n-envs",
        metavar="N",
        type=_int_at_least(1),
        help="environments in the batch: n_envs (rllib: env_runners.num_envs_per_env_runner) (default: the config's)",
    )
    run = p.add_argument_group("this process")
    run.add_argument("--device", default="cpu", help="torch device of the SB3 model (default: cpu)")
    run.add_argument(
        "--threads",
        metavar="N",
        type=threads_arg,
        default=1,
        help="torch threads (default: 1; PPO's small batches gain little from more, and a busy "
        "machine makes extra threads spin)",
    )
    run.add_argument(
        "--no-progress",
        action="store_true",
        help="no progress bar or progress lines (default: a bar on a terminal, a line per stage elsewhere; SB3 only)",
    )
    run.add_argument("--verbose", metavar="N", type=_int_in(0, 2), default=0, help="SB3's verbosity, 0-2 (default: 0)")
    run.add_argument(
        "--trust-pickle",
        action="store_true",
        help="accept pickle-based files, which can run code when loaded: an old run's .zip/.pkl "
        "checkpoints (--resume), an old init_from policy, an RLlib checkpoint (--resume of an "
        "rllib run); only for files you trust (default: refused; convert them once with "
        "coopnav-convert SRC --out NEW_DIR --trust-pickle)",
    )
    ray = p.add_argument_group("--backend rllib only")
    ray.add_argument(
        "--num-env-runners",
        metavar="N",
        type=_int_at_least(0),
        help="env runner processes (0: sample in this process) (default: the config's "
        "env_runners.num_env_runners; with --resume the run's)",
    )
    ray.add_argument(
        "--ray-address",
        metavar="ADDR",
        help="a running Ray cluster to join ('auto', or host:port) (default: start a local instance)",
    )
    ray.add_argument(
        "--tune",
        action="append",
        metavar="KEY=V1,V2",
        help="a Ray Tune grid (repeatable; KEY: seed or a PPOConfig.training keyword such as lr)",
    )
    return p


def main(argv: list[str] | None = None) -> int:
    """Parse ``argv`` (default ``sys.argv[1:]``), build the config and train; the exit status."""
    prog = Path(sys.argv[0]).name if argv is None and sys.argv and sys.argv[0] else "train.py"
    if prog in ("__main__.py", "-c", "cli.py"):
        prog = "train.py"
    from coopnav_env.failures import MACHINE_FAILURES, one_line
    from coopnav_env.progress import announce_after
    from coopnav_env.safe_load import UnsafeDataError

    from . import runlock

    try:
        args = build_parser(prog).parse_args(argv)
        if args.plot is not None:
            return run(args, argv)
        # silent if the checks are quick (a bad input stays one line); else says what is going on
        with announce_after(f"{prog}: reading the config and checking the scenario (loading numba)", 2.0):
            return run(args, argv)
    except (ConfigError, PolicyFormatError, UnsafeDataError) as err:
        print(f"{prog}: error: {' '.join(str(err).splitlines())}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except MACHINE_FAILURES as err:  # disk full, read-only, out of memory: one line
        print(f"{prog}: error: {one_line(err)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    finally:
        runlock.release_all()


def run(args: argparse.Namespace, argv: list[str] | None = None) -> int:
    """The parsed command line -> ``sb3`` or ``rllib`` ``train``/``resume``."""
    for name in ("out", "resume", "plot"):  # '' would be the working folder
        value = getattr(args, name)
        if value is not None and not value.strip():
            raise ConfigError(f"--{name} is empty: name a run folder")
    if args.plot is not None:
        from .curve import draw_learning_curve

        given = [f"--{n.replace('_', '-')}" for n in RUN_SETTINGS + ("resume",) if getattr(args, n) is not None]
        if given:  # they would be ignored: --plot only draws what the run wrote
            raise ConfigError(f"--plot draws a finished run's curve and takes no run options; drop {', '.join(given)}")
        read_run_record(Path(args.plot))
        path = draw_learning_curve(args.plot)
        if path is None:
            log = Path(args.plot) / "evaluations.jsonl"
            if log.is_file() and log.stat().st_size:
                raise ConfigError(f"{log} holds no readable validation line (cut or edited?): nothing to plot")
            raise ConfigError(f"{args.plot} has no validation yet (evaluations.jsonl): nothing to plot")
        print(f"wrote {path}")
        return 0
    if args.resume is not None:
        given = [f"--{n.replace('_', '-')}" for n in RUN_SETTINGS if getattr(args, n) is not None]
        if given:
            raise ConfigError(f"--resume continues a run with its own config.yml; drop {', '.join(given)}")
        out = Path(args.resume)
        from agents.safe_paths import check_tree

        from . import runlock

        read_run_record(out)  # a run folder (one line else), then: one trainer at a time, nothing read outside it
        from coopnav_env.records import check_writable

        try:  # a resumed run writes checkpoints there: refused now, not after the environments are built
            check_writable(out)
        except OSError as err:
            raise ConfigError(f"--resume {out}: {err}") from None
        runlock.hold(out)
        check_tree(out)
        backend = read_run_record(out)["args"].get("backend") or "sb3"
        if backend not in ("sb3", "rllib"):
            raise ConfigError(f"{out}/config.yml: unknown backend {backend!r}")
        if args.backend is not None and args.backend != backend:
            raise ConfigError(f"{out} is a --backend {backend} run; drop --backend {args.backend}")
        if backend == "rllib":
            return rllib.resume(
                out,
                num_env_runners=args.num_env_runners,
                ray_address=args.ray_address,
                threads=args.threads,
                trust_pickle=args.trust_pickle,
            )
        _sb3_only(args, f" ({out} is an sb3 run)")
        return sb3.resume(
            out,
            device=args.device,
            threads=args.threads,
            progress=not args.no_progress,
            verbose=args.verbose,
            trust_pickle=args.trust_pickle,
        )

    backend = args.backend or "sb3"
    if args.out is not None and Path(args.out).is_dir():  # one trainer per folder (a new one: when created)
        from . import runlock

        runlock.hold(args.out)
    if backend == "sb3":
        _sb3_only(args)
    missing = [f"--{n}" for n in ("scenario", "timesteps", "out") if getattr(args, n) is None]
    if missing:
        raise ConfigError(f"missing {', '.join(missing)} (or --resume RUN_DIR)")
    from coopnav_env.records import check_writable

    try:  # before the environments are built: a folder that cannot be written is refused at once
        check_writable(args.out)
    except OSError as err:
        raise ConfigError(f"--out {args.out}: {err}") from None
    if backend == "rllib":
        rllib.require_ray()
    path = hyperparameter_file(backend, args.scenario, args.config)
    try:  # a key twice with two values: which was meant?
        settings = unique_assignments(args.set or [], "--set")
    except ValueError as err:
        raise ConfigError(str(err)) from None
    if args.n_envs is not None:
        settings["n_envs" if backend == "sb3" else "env_runners.num_envs_per_env_runner"] = args.n_envs
    config = load_config(
        path, config_class(backend), settings, scenario=args.scenario, timesteps=args.timesteps, seed=args.seed
    )
    common = {"command": command_line(argv), "hyperparameter_file": path, "threads": args.threads}
    if backend == "rllib":
        from coopnav_env.progress import stage

        stage(f"train.py: Ray RLlib PPO on {args.scenario}, {args.timesteps:,} steps into {args.out}; starting Ray")
        return rllib.train(
            config,
            args.out,
            num_env_runners=args.num_env_runners,
            ray_address=args.ray_address,
            tune=rllib.parse_tune(args.tune or []),
            **common,
        )
    return sb3.train(
        config,
        args.out,
        device=args.device,
        progress=not args.no_progress,
        verbose=args.verbose,
        trust_pickle=args.trust_pickle,
        **common,
    )


def _sb3_only(args, why: str = ""):
    given = [f"--{n.replace('_', '-')}" for n in RLLIB_ONLY if getattr(args, n) is not None]
    if given:
        raise ConfigError(f"{', '.join(given)} only with --backend rllib{why}")
    check_device(args.device)


def check_device(device: str) -> None:
    """A ``ConfigError`` (one line) for a ``--device`` torch cannot parse, or a CUDA device on a
    machine without one (SB3 would fall back to the CPU without a word)."""
    import torch

    if device == "auto":  # SB3's own: CUDA if there is one, else the CPU
        return
    try:
        kind = torch.device(device).type
    except (RuntimeError, ValueError):
        raise ConfigError(f"--device {device}: not a torch device; use cpu, or cuda (cuda:0, ...) on a GPU") from None
    if kind == "cuda" and not torch.cuda.is_available():
        raise ConfigError(f"--device {device}: this machine has no CUDA device (torch.cuda.is_available() is False)")


if __name__ == "__main__":
    sys.exit(main())
