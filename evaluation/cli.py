"""The command line of the evaluation (``coopnav-evaluate``, and ``python evaluate.py``):
arguments -> ``EvalConfig`` -> ``evaluation.run.evaluate``; prints summary.md.

Exit status: 0 done; 2 bad input (an unknown policy, scenario or parameter, a bad value or
seed, a policy that cannot drive the scenario, an output directory in use by another run,
holding another result, or not matching --resume): one line on stderr, nothing written;
1 a result that cannot be summarized (a non-finite value, the episode named); 130
interrupted (Ctrl-C, SIGTERM): what was finished stays in OUT and the command that
resumes it is printed. Progress and messages go to stderr, summary.md to stdout.
"""

from __future__ import annotations

import argparse
import shlex
import signal
import sys
from collections.abc import Sequence
from typing import Any

from coopnav_env.failures import MACHINE_FAILURES, one_line

from .config import EvalConfig, UsageError, parse_assignment, parse_assignments, split_top_level
from .errors import UsageParser
from .parallel import add_workers_argument

_DEFAULTS = EvalConfig()

EXAMPLES = """\
examples:
  %(prog)s --scenario sousa_asv --policies fim_a,fim_b,ellipse,circle,static --episodes 50 --out results/sousa
  %(prog)s --scenario sousa_asv --policies fim_a,fim_b --episodes 20 \\
      --sweep depth_m=1,5,20,50 --sweep survey_path=stationary,lawnmower,circle,spiral --out results/sweep
  %(prog)s --scenario gao_sea --policies ppo,ellipse --set max_cycles=200
"""


class _Parser(UsageParser):
    def format_help(self):
        self.epilog = _choices_text() + "\n" + EXAMPLES  # computed only when help is asked for
        return super().format_help()


class _Formatter(argparse.ArgumentDefaultsHelpFormatter, argparse.RawDescriptionHelpFormatter):
    """Defaults shown (those that say something), description and epilog kept as written."""

    def _get_help_string(self, action):
        if action.default is None or action.default is False or action.default == []:
            return action.help
        return super()._get_help_string(action)


def _choices_text() -> str:
    import agents
    import coopnav_env
    from baselines import list_policies

    shipped = ", ".join(agents.list_policies()) or "none shipped"
    return (
        f"scenarios: {', '.join(coopnav_env.list_scenarios())}\n"
        f"policies: planners {', '.join(list_policies())};\n"
        f"  ppo (the scenario's shipped PPO policy); a shipped policy ({shipped});\n"
        "  or a train.py run directory\n"
    )


def build_parser(prog: str | None = None) -> argparse.ArgumentParser:
    """The argument parser (its ``error`` raises UsageError instead of exiting)."""
    p = _Parser(
        prog=prog,
        formatter_class=_Formatter,
        description="Evaluate coopnav policies on seeded episodes with common random numbers: episode i "
        "of every policy (and sweep cell) uses seed SEED + i.\nWrites episodes.csv, "
        "steps.csv, run.json, summary.json, summary.md and PNG figures to OUT.",
    )
    p.add_argument("--scenario", default=_DEFAULTS.scenario, help="scenario name (listed below)")
    p.add_argument(
        "--policies",
        default=None,
        help="comma-separated policy names (listed below), a planner with settings as "
        "NAME:KEY=VALUE[:KEY=VALUE] (ellipse:range_model=filter, horizon:horizon=8); default: every "
        "planner that can drive the scenario's network",
    )
    p.add_argument(
        "--episodes",
        type=int,
        default=None,
        help=f"episodes per policy (and per sweep cell); default {_DEFAULTS.episodes}, with --resume the run's",
    )
    p.add_argument("--seed", type=int, default=_DEFAULTS.seed, help="episode i uses seed SEED + i")
    p.add_argument(
        "--out",
        default=_DEFAULTS.out,
        help="output directory (created; one run at a time; an earlier result there needs --resume or --overwrite)",
    )
    p.add_argument(
        "--set",
        dest="sets",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="set a scenario parameter for the whole run (repeatable)",
    )
    p.add_argument(
        "--sweep",
        dest="sweeps",
        action="append",
        default=[],
        metavar="KEY=V1,V2,...",
        help="run the grid of these values (repeatable; the first key makes the table rows)",
    )
    p.add_argument(
        "--resume",
        action="store_true",
        help="keep the complete episodes already in OUT (same --scenario, --seed, --set and --sweep) and "
        "run the missing ones; the run covers OUT's policies plus --policies, and the larger "
        "--episodes",
    )
    p.add_argument("--overwrite", action="store_true", help="replace the result already in OUT")
    p.add_argument("--batch-size", type=int, default=_DEFAULTS.batch_size, help="episodes simulated together")
    add_workers_argument(p, "batches")
    p.add_argument("--no-figures", action="store_true", help="write no PNG files")
    p.add_argument(
        "--trust-pickle",
        action="store_true",
        help="accept trained policies in pickle-based formats (an old SB3 .zip/.pkl run, an RLlib "
        "checkpoint), which can run code when loaded; only for files you trust (or convert them "
        "once: python -m agents.convert SRC --out NEW_DIR --trust-pickle)",
    )
    return p


def config_from_args(args: argparse.Namespace) -> EvalConfig:
    """The ``EvalConfig`` of parsed arguments; raises UsageError."""
    sets: dict[str, Any] = parse_assignments(args.sets, "--set")
    sweep: dict[str, Any] = {}
    for item in args.sweeps:
        key, value = parse_assignment(item, "--sweep")
        if key in sweep:
            raise UsageError(f"--sweep {key} given twice")
        sweep[key] = split_top_level(value)
    return EvalConfig(
        scenario=args.scenario,
        policies=args.policies,
        episodes=args.episodes,
        seed=args.seed,
        out=args.out,
        overrides=sets,
        sweep=sweep,
        resume=args.resume,
        overwrite=args.overwrite,
        batch_size=args.batch_size,
        workers=args.workers,
        figures=not args.no_figures,
        trust_pickle=args.trust_pickle,
    )


def resume_command(argv: Sequence[str], prog: str) -> str:
    """The command that resumes the run of ``argv``: the same arguments, without
    --overwrite, with --resume."""
    args = [a for a in argv if not (len(a) > 4 and a.startswith("--ov") and "--overwrite".startswith(a))]
    if not any(len(a) > 4 and a.startswith("--re") and "--resume".startswith(a) for a in args):
        args.append("--resume")
    front = ["python", "evaluate.py"] if prog == "evaluate.py" else [prog]
    return shlex.join(front + args)


def _terminate(signum, frame):
    raise KeyboardInterrupt(f"signal {signum}")


def main(argv: Sequence[str] | None = None, prog: str | None = None) -> int:
    """Run the command line; returns the exit status (0; 2 bad input; 1 a result that
    cannot be summarized; 130 interrupted)."""
    from .run import EvaluationError, EvaluationInterrupted, evaluate

    prog = prog or "coopnav-evaluate"
    argv = list(sys.argv[1:] if argv is None else argv)
    try:  # SIGTERM stops the run like Ctrl-C: finished batches stay, the resume command is printed
        previous_handler = signal.signal(signal.SIGTERM, _terminate)
    except ValueError:  # not the main thread
        previous_handler = None
    try:
        try:
            config = config_from_args(build_parser(prog).parse_args(argv))
            result = evaluate(config, command=shlex.join([prog] + argv))
        except UsageError as err:
            print(f"{prog}: error: {err}", file=sys.stderr)
            return 2
        except EvaluationError as err:
            print(f"{prog}: error: {err}", file=sys.stderr)
            return 1
        except EvaluationInterrupted as err:
            print(f"{prog}: {err}; resume with: {resume_command(argv, prog)}", file=sys.stderr)
            return 130
        except KeyboardInterrupt:
            print(f"{prog}: interrupted before any episode ran; nothing was written", file=sys.stderr)
            return 130
        except MACHINE_FAILURES as err:  # disk full, read-only, out of memory: one line, the lock released
            print(f"{prog}: error: {one_line(err)}", file=sys.stderr)
            return 2
    finally:
        if previous_handler is not None:
            signal.signal(signal.SIGTERM, previous_handler)
    print(result.markdown)
    print(f"\nwrote {result.out}/: {', '.join(result.files)}")
    return 0
