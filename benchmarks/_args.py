"""The benchmark scripts' argument checks, one home for them: counts within their bounds,
seeds, scenario names and ``--set KEY=VALUE`` overrides, policies, task sets, comma lists
of numbers and the ``--overwrite`` flag, and the scripts' parser (``Parser``: an error is one
line, exit 2). Each check reports through ``parser.error``, naming the option and, where
there is one, the closest valid value; the scripts call them right after parsing, before
any run.

    from benchmarks import _args   # a script run directly: ``import _args`` (its own folder)
    p = _args.Parser(description=...)
    _args.count(p, args.episodes, "--episodes", low=2)
    config = _args.scenario_config(p, args.scenario, _args.overrides(p, args.set))
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Iterable
from typing import Any, NoReturn

from coopnav_env.names import OneLineParser
from evaluation.limits import MAX_BATCH_SIZE, MAX_EPISODES

# Bounds of the counts that are not episodes: far above what a measurement needs, low enough
# that a mistyped count is refused at once instead of running for days.
MAX_STEPS = 1_000_000  # timed steps or decisions of a timing script
MAX_BATCH = 262_144  # environments stepped at once (sim_profile --batch; 4,096 by default)
MAX_EVENTS = 1_000_000  # MLS sensor events (mls_speed, mls_tank, mls_analytic_vs_signal)
MAX_LAYER = 65_536  # units of one hidden layer (--net, --torchrl-net)
MAX_ENVS = 1_000_000  # environments of a training batch (--n-envs, --torchrl-n-envs)

# the bounds ``count`` takes by name: (value, where it is defined)
BOUNDS = {
    "MAX_EPISODES": (MAX_EPISODES, "evaluation.limits.MAX_EPISODES"),
    "MAX_BATCH_SIZE": (MAX_BATCH_SIZE, "evaluation.limits.MAX_BATCH_SIZE"),
    "MAX_STEPS": (MAX_STEPS, "benchmarks._args.MAX_STEPS"),
    "MAX_BATCH": (MAX_BATCH, "benchmarks._args.MAX_BATCH"),
    "MAX_EVENTS": (MAX_EVENTS, "benchmarks._args.MAX_EVENTS"),
    "MAX_LAYER": (MAX_LAYER, "benchmarks._args.MAX_LAYER"),
    "MAX_ENVS": (MAX_ENVS, "benchmarks._args.MAX_ENVS"),
}


class Parser(OneLineParser):
    """The scripts' parser, ``coopnav_env.names.OneLineParser``: an error is one line,
    ``<script>: error: <what was wrong>``, exit status 2, a mistyped option naming the one
    meant, as the project's other commands report."""


def _fail(parser: argparse.ArgumentParser, message: str) -> NoReturn:
    parser.error(" ".join(str(message).split()))  # one line, whatever the message held
    raise AssertionError("unreachable")  # parser.error exits


def first_line(err: BaseException) -> str:
    """``err``'s first line (its type's name if it says nothing)."""
    return (str(err).strip().splitlines() or [type(err).__name__])[0]


def add_overwrite(parser: argparse.ArgumentParser, what: str = "the output file") -> None:
    """``--overwrite``: replace ``what`` if it exists (refused without it: ``check_output_args``)."""
    parser.add_argument("--overwrite", action="store_true", help=f"replace {what} if it exists")


def outputs(parser: argparse.ArgumentParser, overwrite: bool, **files: Any) -> None:
    """``coopnav_env.records.check_output_args`` of the given file flags (``markdown=args.markdown``):
    an existing file is refused unless ``overwrite`` (the script's ``--overwrite``)."""
    from coopnav_env.records import check_output_args

    check_output_args(parser.error, overwrite=overwrite, **files)


def count(parser: argparse.ArgumentParser, value: int, option: str, low: int = 1, bound: str = "MAX_EPISODES") -> int:
    """``value`` if it is a whole number in [low, the bound], else one line naming ``option``,
    the range and the bound (``bound``: a name of ``BOUNDS``, e.g. ``evaluation.limits.MAX_EPISODES``)."""
    high, name = BOUNDS[bound]
    if isinstance(value, bool) or not isinstance(value, int):
        _fail(parser, f"{option} must be a whole number in [{low}, {high}], got {value!r}")
    if value < low:
        why = " (a 95 % interval needs two)" if low == 2 else ""
        _fail(parser, f"{option} must be at least {low}{why}, got {value}")
    if value > high:
        _fail(parser, f"{option} must be at most {high} ({name}), got {value}")
    return value


def seeds(parser: argparse.ArgumentParser, first: int, n: int = 1, option: str = "--seed") -> list[int]:
    """The seeds ``first`` .. ``first + n - 1``, every one a valid seed
    (``coopnav_env.seeds.check_seed``), else one line naming ``option``."""
    from coopnav_env.seeds import check_seed

    try:
        check_seed(first, option)
        if n > 1:
            check_seed(first + n - 1, f"{option} + the count - 1 (the last seed, {first + n - 1})")
    except ValueError as err:
        _fail(parser, str(err))
    return list(range(first, first + n))


def number(parser: argparse.ArgumentParser, value: float, option: str, low: float, high: float = math.inf) -> float:
    """``value`` if it is a finite number in [low, high] (NaN and infinities refused), else one line."""
    if not (math.isfinite(value) and low <= value <= high):
        span = f" at least {low:g}" if high == math.inf else f" in [{low:g}, {high:g}]"
        _fail(parser, f"{option} must be a finite number{'' if low == -math.inf else span}, got {value!r}")
    return value


def int_list(parser: argparse.ArgumentParser, text: str, option: str, low: int = 1, high: int = MAX_LAYER) -> list[int]:
    """``"128,128"`` -> [128, 128]: whole numbers in [low, high] separated by commas, else one line."""
    try:
        values = [int(v) for v in text.split(",")]
    except ValueError:
        _fail(parser, f"{option} takes whole numbers separated by commas (e.g. 128,128), got {text!r}")
    bad = [v for v in values if not low <= v <= high]
    if bad:
        _fail(parser, f"{option}: each number must be in [{low}, {high}], got {bad[0]} in {text!r}")
    return values


def unknown_parameter(key: str) -> str | None:
    """None if ``key`` is a scenario parameter, else one line naming the closest (not the list
    of some two hundred that ``check_overrides`` gives)."""
    from coopnav_env.names import did_you_mean
    from coopnav_env.scenarios import ScenarioConfig

    valid = ScenarioConfig().to_flat_dict(all_parameters=True)
    if key in valid:
        return None
    return f"unknown scenario parameter {key!r}{did_you_mean(key, valid)} see docs/reference/parameters.md"


def scenario_overrides(items: Iterable[str], option: str = "--set") -> dict[str, Any]:
    """``--set KEY=VALUE`` items as scenario overrides, parsed as evaluate.py parses its own
    (``evaluation.config.parse_assignments`` and ``coerce_value``: the parameter's type; a key
    given twice with two values refused), an unknown key named with the closest one; a
    ``ValueError`` of one line. For the scripts that report errors themselves; the others
    call ``overrides``."""
    from coopnav_env.scenarios.base import check_overrides
    from evaluation.config import coerce_value, parse_assignments

    texts = parse_assignments(items, option)
    for key in texts:
        if (problem := unknown_parameter(key)) is not None:
            raise ValueError(f"{option}: {problem}")
    check_overrides(dict.fromkeys(texts))
    return {key: coerce_value(key, text) for key, text in texts.items()}


def overrides(parser: argparse.ArgumentParser, items: Iterable[str], option: str = "--set") -> dict[str, Any]:
    """``scenario_overrides`` reported through ``parser.error`` (one line, exit 2)."""
    try:
        return scenario_overrides(items, option)
    except ValueError as err:
        _fail(parser, f"{option}: {first_line(err)}" if not str(err).startswith(option) else first_line(err))


def scenario_config(
    parser: argparse.ArgumentParser, name: str, extra: dict | None = None, option: str = "--scenario"
) -> Any:
    """``coopnav_env.make_config(name, **extra)``: an unknown scenario named with the closest
    one, a value the scenario refuses named as ``--set``'s."""
    import coopnav_env
    from coopnav_env.names import did_you_mean

    valid = coopnav_env.list_scenarios()
    if name not in valid:
        _fail(parser, f"{option}: unknown scenario {name!r}{did_you_mean(name, valid)} valid: {', '.join(valid)}")
    try:
        return coopnav_env.make_config(name, **(extra or {}))
    except (ValueError, TypeError) as err:
        _fail(parser, f"--set on {name}: {first_line(err)}")


def policy(parser: argparse.ArgumentParser, name: str, config: Any, seed: int, option: str) -> None:
    """Refuse policy ``name`` if it cannot drive ``config`` (``evaluation.episodes.check_policy``:
    it loads and answers one observation), naming the closest policy name."""
    from evaluation.episodes import check_policy

    try:
        check_policy(name, config, seed)
    except KeyboardInterrupt:
        raise
    except Exception as err:  # a policy that cannot act here is bad input (as evaluate.py's check)
        import agents
        from baselines import list_policies
        from coopnav_env.names import did_you_mean

        hint = did_you_mean(name, list_policies() + ["ppo"] + list(agents.list_policies())).rstrip(";")
        _fail(parser, f"{option} {name!r} cannot drive {config.name}: {first_line(err)}{hint}")


def planner(parser: argparse.ArgumentParser, name: str, config: Any, seed: int, option: str) -> None:
    """Refuse ``name`` unless it is a baselines planner (a spec ``NAME:KEY=VALUE,...`` or
    ``MOTION+SCHEDULE`` of one) that can drive ``config`` (``policy``), naming the closest
    planner: for the scripts whose runs ``baselines.make_policy`` drives."""
    import baselines
    from coopnav_env.names import did_you_mean

    if not baselines.is_planner(name):
        motion, valid = baselines.motion_name(name), baselines.list_policies(config.network)
        _fail(parser, f"{option}: {motion!r} is not a planner{did_you_mean(motion, valid)} valid: {', '.join(valid)}")
    policy(parser, name, config, seed, option)


def task_set(parser: argparse.ArgumentParser, name: str, option: str = "--tasks") -> Any:
    """The benchmark task set ``name`` (``evaluation.tasks.get_task_set``), else one line
    naming the closest."""
    from evaluation.tasks import get_task_set

    try:
        return get_task_set(name)
    except KeyError as err:
        _fail(parser, f"{option}: {err.args[0] if err.args else name}")


def names(parser: argparse.ArgumentParser, text: str, option: str) -> list[str]:
    """The comma-separated names of ``text``; an empty list (``''``, ``','``) is refused."""
    out = [s.strip() for s in text.split(",") if s.strip()]
    if not out:
        _fail(parser, f"{option} names nothing (got {text!r}): give at least one")
    return out


def _is_number(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def episode_errors_problem(errors: Any, where: str, n: int | None = None) -> str | None:
    """Why a list of per-episode errors cannot be summarized (None if it can): not a list
    of at least two finite numbers, or not ``n`` of them (the other policies' count)."""
    if not isinstance(errors, list) or not all(_is_number(x) for x in errors):
        bad = next((x for x in errors if not _is_number(x)), errors) if isinstance(errors, list) else errors
        return f"{where} holds {bad!r:.40}, not finite numbers"
    if len(errors) < 2:
        return f"{where} holds {len(errors)} episode(s); an interval needs two"
    if n is not None and len(errors) != n:
        return f"{where} holds {len(errors)} episodes, the others {n}: not paired"
    return None


def benchmark_results_problem(results: Any) -> str | None:
    """Why a benchmark ``results.json``'s content cannot be summarized again (None if it can):
    its task sets, tasks and policies, each policy's ``mean_error_m`` a finite number and its
    ``episode_mean_error_m`` finite numbers, the same count for every policy of a task."""
    if not isinstance(results, dict) or not isinstance(results.get("task_sets"), dict):
        return "no task_sets"
    for set_name, ts in results["task_sets"].items():
        tasks = ts.get("tasks") if isinstance(ts, dict) else None
        if not isinstance(tasks, dict):
            return f"task set {set_name!r} has no tasks"
        n = None  # episode i of every task and policy of a set has the same seed: one count
        for task_name, task in tasks.items():
            policies = task.get("policies") if isinstance(task, dict) else None
            if not isinstance(policies, dict):
                return f"{set_name}/{task_name} has no policies"
            for label, entry in policies.items():
                if not isinstance(entry, dict) or "mean_error_m" not in entry:
                    continue  # n/a: the policy cannot drive the task
                where = f"{set_name}/{task_name}/{label}"
                if not _is_number(entry["mean_error_m"]):
                    return f"{where} mean_error_m is {entry['mean_error_m']!r:.40}, not a finite number"
                errors = entry.get("episode_mean_error_m")
                problem = episode_errors_problem(errors, f"{where} episode_mean_error_m", n)
                if problem is not None:
                    return problem
                n = len(errors)
    return None
