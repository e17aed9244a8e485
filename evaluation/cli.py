"""The command line of the evaluation (``coopnav-evaluate``, and ``python evaluate.py``):
arguments -> ``EvalConfig`` -> ``evaluation.run.evaluate``; prints summary.md.

Bad input (an unknown policy, scenario or parameter, a bad value, an output path that
is a file) is one line on stderr and exit status 2, before anything is written.
"""

from __future__ import annotations

import argparse
import sys

from .config import EvalConfig, UsageError, parse_assignment, split_top_level

_DEFAULTS = EvalConfig()

EXAMPLES = """\
examples:
  %(prog)s --scenario sousa_asv --policies fim_a,fim_b,ellipse,circle,static --episodes 50 --out results/sousa
  %(prog)s --scenario sousa_asv --policies fim_a,fim_b --episodes 20 \\
      --sweep depth_m=1,5,20,50 --sweep survey_path=stationary,lawnmower,circle,spiral --out results/sweep
  %(prog)s --scenario gao_sea --policies ppo,ellipse --set max_cycles=200
"""


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        raise UsageError(message)

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
    return (f"scenarios: {', '.join(coopnav_env.list_scenarios())}\n"
            f"policies: planners {', '.join(list_policies())};\n"
            f"  ppo (the scenario's shipped PPO policy); a shipped policy ({shipped});\n"
            "  or a train.py run directory\n")


def build_parser(prog: str | None = None) -> argparse.ArgumentParser:
    """The argument parser (its ``error`` raises UsageError instead of exiting)."""
    p = _Parser(prog=prog, formatter_class=_Formatter,
                description="Evaluate coopnav policies on seeded episodes with common random numbers: episode i "
                            "of every policy (and sweep cell) uses seed SEED + i.\nWrites episodes.csv, "
                            "steps.csv, run.json, summary.json, summary.md and PNG figures to OUT.")
    p.add_argument("--scenario", default=_DEFAULTS.scenario, help="scenario name (listed below)")
    p.add_argument("--policies", default=None,
                   help="comma-separated policy names (listed below); default: every planner that can drive "
                        "the scenario's network")
    p.add_argument("--episodes", type=int, default=_DEFAULTS.episodes, help="episodes per policy (and per sweep cell)")
    p.add_argument("--seed", type=int, default=_DEFAULTS.seed, help="episode i uses seed SEED + i")
    p.add_argument("--out", default=_DEFAULTS.out, help="output directory (created)")
    p.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE",
                   help="set a scenario parameter for the whole run (repeatable)")
    p.add_argument("--sweep", dest="sweeps", action="append", default=[], metavar="KEY=V1,V2,...",
                   help="run the grid of these values (repeatable; the first key makes the table rows)")
    p.add_argument("--resume", action="store_true",
                   help="keep the episodes already in OUT (same scenario and --set) and run only the missing ones")
    p.add_argument("--batch-size", type=int, default=_DEFAULTS.batch_size, help="episodes simulated together")
    p.add_argument("--no-figures", action="store_true", help="write no PNG files")
    return p


def config_from_args(args) -> EvalConfig:
    """The ``EvalConfig`` of parsed arguments; raises UsageError."""
    sets = dict(parse_assignment(item, "--set") for item in args.sets)
    sweep = {}
    for item in args.sweeps:
        key, value = parse_assignment(item, "--sweep")
        if key in sweep:
            raise UsageError(f"--sweep {key} given twice")
        sweep[key] = split_top_level(value)
    return EvalConfig(scenario=args.scenario, policies=args.policies, episodes=args.episodes, seed=args.seed,
                      out=args.out, overrides=sets, sweep=sweep, resume=args.resume, batch_size=args.batch_size,
                      figures=not args.no_figures)


def main(argv=None, prog: str | None = None) -> int:
    """Run the command line; returns the exit status (0, or 2 for bad input)."""
    from .run import evaluate

    prog = prog or "coopnav-evaluate"
    try:
        result = evaluate(config_from_args(build_parser(prog).parse_args(argv)))
    except UsageError as err:
        print(f"{prog}: error: {err}", file=sys.stderr)
        return 2
    print(result.markdown)
    print(f"\nwrote {result.out}/: {', '.join(result.files)}")
    return 0
