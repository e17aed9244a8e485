"""What an evaluation is asked to do: ``EvalConfig`` (one set of defaults), the parsing
of ``KEY=VALUE`` parameters, and ``prepare``, which checks every input and builds the
run plan before any work is done.

    from evaluation import EvalConfig
    config = EvalConfig(scenario="sousa_asv", policies=("fim_a", "fim_b"), episodes=20,
                        sweep={"depth_m": (1, 5, 20, 50)}, out="results/sweep")

Scenario parameters (``overrides``, ``sweep``) may be given typed (``{"max_cycles": 20}``)
or as the command line's text (``{"max_cycles": "20"}``); both parse to the same values.
Bad input raises ``UsageError`` (a ``ValueError``) with a one-line message; an unknown
``EvalConfig`` field raises ``TypeError`` naming the closest valid one.
"""

from __future__ import annotations

import ast
import dataclasses
import inspect
import numbers
import os
import sys
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from coopnav_env.names import closest
from coopnav_env.records import plain
from coopnav_env.seeds import EVALUATE_SEED, MAX_SEED, check_seed

from .errors import UsageError  # defined there (every module raises it), used and re-exported here

if TYPE_CHECKING:
    from coopnav_env.scenarios import ScenarioConfig


def _check_field_names(cls):
    """Make unknown keyword arguments of a dataclass an error naming the closest field."""
    init = cls.__init__
    names = [f.name for f in dataclasses.fields(cls)]

    def __init__(self, *args, **kwargs):
        unknown = [k for k in kwargs if k not in names]
        if unknown:
            hints = ", ".join(
                repr(k) + "".join(f" (did you mean {c!r}?)" for c in [closest(k, names)] if c) for k in unknown
            )
            raise TypeError(f"unknown {cls.__name__} field(s) {hints}; valid fields: {', '.join(names)}")
        init(self, *args, **kwargs)

    __init__.__doc__ = init.__doc__
    __init__.__signature__ = inspect.signature(init)  # type: ignore[attr-defined]  # read by inspect.signature
    cls.__init__ = __init__
    return cls


@_check_field_names
@dataclass(frozen=True)
class EvalConfig:
    """One evaluation: which policies, on which scenario, how many seeded episodes, where.

    * ``scenario``: a name of ``coopnav_env.list_scenarios()``;
    * ``policies``: names, as a tuple or one comma-separated string: planners
      (``baselines.list_policies()``), ``"ppo"`` (the scenario's shipped PPO policy), a
      shipped policy (``agents.list_policies()``) or a train.py run directory; None:
      every planner that can drive the scenario's network;
    * ``episodes``: episodes per policy (and per sweep cell); episode ``i`` uses seed
      ``seed + i`` for every policy (common random numbers); None: 10, or with
      ``resume`` the earlier run's;
    * ``seed``: the first episode's seed (``coopnav_env.seeds.EVALUATE_SEED``); the
      last, ``seed + episodes - 1``, must not exceed ``coopnav_env.seeds.MAX_SEED``
      (``coopnav_env.seeds.check_seed``);
    * ``out``: the output directory (created; one run at a time: a second writer is
      refused, and an earlier result is kept unless ``resume`` or ``overwrite``);
    * ``overrides``: scenario parameters set for the whole run (``--set KEY=VALUE``);
    * ``sweep``: parameter -> values (a sequence, or the command line's text
      ``"V1,V2"``), run as a grid (``--sweep KEY=V1,V2``; the first key makes the rows
      of the tables);
    * ``resume``: keep the episodes already in ``out`` (same scenario, overrides, sweep
      and seed; every kept episode complete in both CSV files) and run the missing ones;
      the run then covers the earlier run's policies plus ``policies`` (None: the
      earlier ones) and the larger of the two episode counts;
    * ``overwrite``: replace an earlier result in ``out``;
    * ``batch_size``: episodes simulated together;
    * ``workers``: processes running batches side by side (``evaluation.parallel``; 0:
      every core); the results are the same to the bit for any count;
    * ``figures``: write the PNG figures;
    * ``progress``: a progress bar on stderr (None: a bar when stderr is a terminal, one line per batch
      elsewhere; False: nothing).
    """

    scenario: str = "gao_lawnmower"
    policies: tuple | None = None
    episodes: int | None = 10
    seed: int = EVALUATE_SEED
    out: str = "results/eval"
    overrides: Mapping[str, Any] = field(default_factory=dict)
    sweep: Mapping[str, tuple] = field(default_factory=dict)
    resume: bool = False
    overwrite: bool = False
    batch_size: int = 25
    workers: int = 1
    figures: bool = True
    progress: bool | None = None
    trust_pickle: bool = False  # accept pickle-based trained policies (they can run code): --trust-pickle

    def __post_init__(self):
        policies = self.policies
        if isinstance(policies, str):
            policies = [p.strip() for p in policies.split(",") if p.strip()]
        if policies is not None:
            object.__setattr__(self, "policies", tuple(str(p) for p in policies))
        object.__setattr__(self, "out", os.fspath(self.out))
        object.__setattr__(self, "overrides", dict(self.overrides))
        object.__setattr__(
            self,
            "sweep",
            {k: tuple(split_top_level(v) if isinstance(v, str) else v) for k, v in dict(self.sweep).items()},
        )
        from .limits import MAX_CELLS

        n_cells = 1
        for values in self.sweep.values():  # bounded work: checked before any value is parsed
            n_cells *= max(len(values), 1)
            if n_cells > MAX_CELLS:
                raise UsageError(f"the --sweep grid has more than {MAX_CELLS} cells: refused")
        for name in ("episodes", "batch_size"):
            value = getattr(self, name)
            if value is None and name == "episodes":
                continue
            if isinstance(value, bool) or not isinstance(value, numbers.Integral):
                raise UsageError(f"{name} (--{name.replace('_', '-')}) must be an integer, got {value!r}")
            object.__setattr__(self, name, int(value))
            if int(value) < 1:
                raise UsageError(f"--{name.replace('_', '-')} must be >= 1, got {value}")
            from .limits import MAX_BATCH_SIZE, MAX_EPISODES

            high = MAX_EPISODES if name == "episodes" else MAX_BATCH_SIZE
            if int(value) > high:  # bounded work, before anything runs
                raise UsageError(f"--{name.replace('_', '-')} must be <= {high}, got {value}")
        from .parallel import check_workers

        try:
            object.__setattr__(self, "workers", check_workers(self.workers))
        except ValueError as err:
            raise UsageError(str(err)) from None
        try:  # the seed range every tool shares
            object.__setattr__(self, "seed", check_seed(self.seed, "--seed"))
        except ValueError as err:
            raise UsageError(str(err)) from None
        if self.resume and self.overwrite:
            raise UsageError(
                "--resume keeps the episodes in the output directory, --overwrite replaces them: give one of them"
            )

    def replace(self, **changes: Any) -> EvalConfig:
        """A copy with ``changes`` (unknown names are an error)."""
        return dataclasses.replace(self, **changes)


# ------------------------------------------------------------------------------------
# scenario parameters: text or typed values -> the parameter's type


def split_top_level(text: str) -> list:
    """Split on commas that are not inside brackets: '1,(2,3)' -> ['1', '(2,3)']."""
    out: list[str] = []
    cur: list[str] = []
    depth = 0
    for ch in text:
        if ch in "([{":
            depth += 1
        elif ch in ")]}":
            depth -= 1
        if ch == "," and depth == 0:
            out.append("".join(cur))
            cur = []
        else:
            cur.append(ch)
    out.append("".join(cur))
    return [s.strip() for s in out]


def _to_tuple(v):
    return tuple(_to_tuple(x) for x in v) if isinstance(v, (list, tuple)) else v


def _default(key: str):
    from coopnav_env.scenarios.base import default_of

    return default_of(key)


def parse_value(key: str, text: str) -> Any:
    """Parse ``text`` as the type of scenario parameter ``key``."""
    default = _default(key)
    text = text.strip()
    if text == "":
        raise UsageError(f"empty value for {key}")
    value = _parse(key, text, default)
    if default and isinstance(default, tuple) and isinstance(default[0], (int, float)) and len(value) != len(default):
        raise UsageError(f"{key} takes {len(default)} values, got {len(value)}")  # a point or an area
    return value


def _parse(key: str, text: str, default):
    try:
        if isinstance(default, bool):
            low = text.lower()
            if low not in ("true", "false", "1", "0", "yes", "no"):
                raise ValueError
            return low in ("true", "1", "yes")
        if isinstance(default, int):
            v = float(text)
            if not v.is_integer():  # NaN and infinities (1e400, 10**400 written out) included
                raise ValueError
            return int(v)
        if isinstance(default, float):
            return float(text)
        if isinstance(default, tuple):
            names = tuple(w.strip().strip("'\"") for w in text.strip("()[]").split(","))
            if default and isinstance(default[0], str):  # names: beacon_kinds=asv,beacon_auv (quotes optional)
                if not all(names):
                    raise ValueError
                return names
            try:
                literal = ast.literal_eval(text)
            except (ValueError, SyntaxError):
                if default or not all(names):  # numbers expected
                    raise
                return names  # randomize_survey_path=lawnmower,spiral
            if not isinstance(literal, (list, tuple)):
                literal = (literal,)
            return _to_tuple(literal)
        return text
    except (ValueError, SyntaxError):
        raise UsageError(f"bad value {text!r} for {key} (a {type(default).__name__})") from None


def coerce_value(key: str, value: Any) -> Any:
    """A parameter value as the command line would give it: text is parsed
    (``parse_value``), numbers take the parameter's type (1 -> 1.0 for a float
    parameter, so cells and tables read the same), lists become tuples."""
    if isinstance(value, str):
        return parse_value(key, value)
    default = _default(key)
    if isinstance(default, float) and isinstance(value, int) and not isinstance(value, bool):
        try:
            return float(value)
        except OverflowError:
            raise UsageError(f"bad value for {key}: {value!r:.40} is out of range") from None
    if isinstance(default, int) and not isinstance(default, bool) and isinstance(value, float) and value.is_integer():
        return int(value)
    return _to_tuple(value)


def parse_assignment(item: str, option: str) -> tuple[str, Any]:
    """``"KEY=VALUE"`` -> (key, value text)."""
    if "=" not in item:
        raise UsageError(f"{option} expects KEY=VALUE, got {item!r}")
    key, value = item.split("=", 1)
    return key.strip(), value


def parse_assignments(items: Iterable[str], option: str) -> dict[str, str]:
    """Repeated ``KEY=VALUE`` items -> {key: value text}; a key given twice with different
    values is a UsageError (``coopnav_env.names.unique_assignments``)."""
    from coopnav_env.names import unique_assignments

    try:
        return unique_assignments((parse_assignment(item, option) for item in items), option)
    except ValueError as err:
        raise UsageError(str(err)) from None


def cell_id(cell: dict) -> str:
    """The ``cell`` column of a sweep cell ("" without a sweep)."""
    return ";".join(f"{k}={v}" for k, v in cell.items())


def sweep_layout(sweep: dict) -> tuple[str, list, list]:
    """The table layout of a sweep: (row key, its values, the column cells: dicts of the
    other keys' values, in grid order)."""
    keys = list(sweep)
    col_cells: list[dict] = [{}]
    for k in keys[1:]:
        col_cells = [dict(c, **{k: v}) for c in col_cells for v in sweep[k]]
    return keys[0], list(sweep[keys[0]]), col_cells


# ------------------------------------------------------------------------------------
# the plan: every check before any work


@dataclass
class Plan:
    """A checked evaluation: the policies, the grid's cells and their scenario configs,
    what each trained policy resolved to, and the record written to run.json."""

    config: EvalConfig
    policies: list
    cells: list
    configs: dict  # cell_id -> ScenarioConfig
    sweep: dict  # key -> parsed values
    overrides: dict  # key -> parsed value
    trained: dict  # trained policy name -> what it resolved to (see resolve_trained)
    run_info: dict
    episodes: int = 0  # episodes per policy and cell (with resume: the larger of the run's and the config's)
    previous: dict | None = None  # run.json of the earlier run in ``out`` that resume extends
    out_state: tuple = ()  # what ``out`` held when checked (``outdir.snapshot``)

    @property
    def seeds(self) -> list:
        """The episodes' seeds: seed + i."""
        return [self.config.seed + i for i in range(self.episodes)]

    def first_config(self) -> ScenarioConfig:
        """The scenario config of the first cell (the figures' episode)."""
        return self.configs[cell_id(self.cells[0])]


def _relative(path) -> str:
    from coopnav_env.records import PROJECT_ROOT

    path = os.path.abspath(os.fspath(path))
    try:
        rel = os.path.relpath(path, PROJECT_ROOT)
    except ValueError:
        return path
    return path if rel.startswith("..") else rel


def resolve_trained(name: str, scenario: str, trust_pickle: bool = False) -> dict:
    """What a trained policy name resolved to (``agents.resolve``): the shipped policy's
    name (None for a run directory) and its files, relative to the repository.
    ``trust_pickle`` trusts its pickle-based files for the rest of the process."""
    import agents

    model, stats, config = agents.resolve(name, scenario, trust_pickle=trust_pickle)
    shipped = None
    try:
        shipped = os.path.relpath(os.path.abspath(model), agents.POLICY_DIR).split(os.sep)[0]
    except ValueError:
        pass
    if shipped is not None and (shipped.startswith("..") or shipped not in agents.list_policies()):
        shipped = None
    return {
        "shipped": shipped,
        "model": _relative(model),
        "vecnormalize": None if stats is None else _relative(stats),
        "config": None if config is None else _relative(config),
    }


def _check_output(out: str):
    if os.path.exists(out) and not os.path.isdir(out):
        raise UsageError(f"output path {out!r} is a file, not a directory")
    parent = os.path.dirname(os.path.abspath(out))
    while parent and not os.path.exists(parent) and os.path.dirname(parent) != parent:
        parent = os.path.dirname(parent)
    if parent and not os.path.isdir(parent):
        raise UsageError(f"output path {out!r} is under a file ({parent!r})")
    from coopnav_env.records import check_writable

    try:  # before the policies are checked (which can compile the simulator for a minute)
        check_writable(out)
    except OSError as err:
        raise UsageError(f"--out {out}: {err}") from None


def _ppo_scenarios() -> list:
    """The scenarios whose "ppo" resolves to a shipped policy."""
    import agents
    import coopnav_env

    out = []
    for name in coopnav_env.list_scenarios():
        try:
            agents.resolve("ppo", name)
        except Exception:  # no shipped policy for it
            continue
        out.append(name)
    return out


def _unknown_policy(p: str, scenario: str, err: Exception, valid: list) -> UsageError:
    import agents

    if p == "ppo":
        return UsageError(
            f"scenario {scenario!r} has no shipped policy, so 'ppo' names nothing; scenarios with "
            f"one: {', '.join(_ppo_scenarios()) or 'none'} (or give a train.py run directory)"
        )
    from coopnav_env.names import did_you_mean

    # why loading failed, where the name looks like a path (a run folder or a model file);
    # a bare name is simply not one of the names listed
    looks_like_path = "/" in p or "\\" in p or Path(p).suffix != "" or Path(p).exists()
    first = f" ({_first_line(err)})" if looks_like_path else ""
    hint = did_you_mean(p, list(valid) + ["ppo"] + list(agents.list_policies()))
    return UsageError(
        f"unknown policy {p!r}{first}{hint} valid: {', '.join(valid)}, ppo, a shipped policy "
        f"({', '.join(agents.list_policies()) or 'none shipped'}) or a train.py run directory"
    )


def _first_line(err: BaseException) -> str:
    return (str(err).strip().splitlines() or [type(err).__name__])[0]


def check_policies(plan: Plan) -> None:
    """Check that every policy of ``plan`` loads and drives every cell's scenario: one
    observation of the first episode per beacon, each answered by a finite (2,) action.
    Raises UsageError naming the policy (and the model, for a trained one)."""
    from .episodes import check_policy

    seen = set()
    for cell in plan.cells:
        cid = cell_id(cell)
        scenario_config = plan.configs[cid]
        key = repr(scenario_config)
        if key in seen:
            continue
        seen.add(key)
        where = plan.config.scenario + (f" ({cid})" if cid else "")
        for p in plan.policies:
            try:
                check_policy(p, scenario_config, plan.config.seed)
            except KeyboardInterrupt:
                raise
            except Exception as err:  # a policy that cannot act here is bad input
                if p in plan.trained:
                    model = plan.trained[p]["model"]
                    raise UsageError(f"policy {p!r} (model {model}) cannot drive {where}: {_first_line(err)}") from None
                raise UsageError(f"policy {p!r} cannot drive {where}: {_first_line(err)}") from None


def _out_of_range(scenario: str, overrides: Mapping, sweep: Mapping, err: Exception) -> str:
    """One line naming the --set/--sweep parameter whose value the scenario cannot take."""
    import coopnav_env

    for key, values in [(k, [v]) for k, v in overrides.items()] + list(sweep.items()):
        for v in values:
            try:
                coopnav_env.make_config(scenario, **{key: coerce_value(key, v)})
            except (ArithmeticError, TypeError, ValueError):
                return f"bad value for {key}: {str(v)[:40]!r} is out of range ({type(err).__name__})"
    return (
        f"a --set/--sweep value is out of range ({type(err).__name__}: {str(err).splitlines()[0] if str(err) else ''})"
    )


def prepare(config: EvalConfig) -> Plan:
    """Check every input of ``config`` and build the run plan; raises UsageError.
    Writes nothing. Checks the output directory too (``outdir.check_existing``): an
    earlier result there needs ``resume`` or ``overwrite``, and ``resume`` the same
    scenario, overrides, sweep and seed; and that every policy loads and can drive
    every cell's scenario (``check_policies``)."""
    import coopnav_env
    from baselines import is_planner, list_policies

    from . import outdir

    scenarios = coopnav_env.list_scenarios()
    if config.scenario not in scenarios:
        from coopnav_env.names import did_you_mean

        raise UsageError(
            f"unknown scenario {config.scenario!r}{did_you_mean(config.scenario, scenarios)} "
            f"valid scenarios: {', '.join(scenarios)}"
        )
    _check_output(config.out)
    outdir.check_not_in_use(config.out)
    foreign = outdir.other_result(config.out)
    if foreign is not None:
        raise UsageError(f"{config.out!r} holds {foreign}; use another --out")
    out_state = outdir.snapshot(config.out)
    if config.resume and not os.path.exists(config.out):
        # said, not refused: the resume command a run prints must work even when the run was
        # killed before its folder was made; a mistyped folder is then seen at once
        print(f"resuming: {config.out!r} does not exist: nothing to keep, the run starts afresh", file=sys.stderr)
    previous = outdir.read_previous(config.out) if config.resume else None
    given = None if config.policies is None else list(config.policies)
    if given is not None:
        if not given:
            raise UsageError("no policy given")
        if len(set(given)) != len(given):
            raise UsageError("a policy is listed twice")
    if previous is not None:  # resume extends the earlier run: its policies, then the new ones
        policies = list(previous["policies"]) + [p for p in given or [] if p not in previous["policies"]]
        episodes = previous["episodes"] if config.episodes is None else max(previous["episodes"], config.episodes)
    else:
        if given is None:  # every planner that drives this scenario
            given = list_policies(config=coopnav_env.make_config(config.scenario))
        policies = given
        episodes = 10 if config.episodes is None else config.episodes
    if not policies:
        raise UsageError("no policy given")
    from . import limits

    if len(policies) > limits.MAX_POLICIES:
        raise UsageError(f"{len(policies)} policies, more than {limits.MAX_POLICIES}: refused")
    n_cells = 1
    for raw in config.sweep.values():
        n_cells *= max(len(raw), 1)
        if n_cells > limits.MAX_CELLS:
            raise UsageError(f"the --sweep grid has more than {limits.MAX_CELLS} cells: refused")
    if n_cells * len(policies) * episodes > limits.MAX_TOTAL_EPISODES:
        raise UsageError(
            f"{n_cells} cell(s) x {len(policies)} policies x {episodes} episodes is more than "
            f"{limits.MAX_TOTAL_EPISODES} episodes: refused"
        )
    last_seed = config.seed + episodes - 1
    if last_seed > MAX_SEED:
        raise UsageError(
            f"--seed {config.seed} with {episodes} episodes reaches seed {last_seed}, above the largest "
            f"valid seed {MAX_SEED} (coopnav_env.seeds.MAX_SEED)"
        )
    valid = list_policies()
    trained = {}
    for p in policies:
        if p not in valid and not is_planner(p):  # is_planner: "ellipse:range_model=filter", "fim_a+clock"
            try:  # a trained policy: "ppo" (the scenario's shipped one), a shipped name, or a run directory
                trained[p] = resolve_trained(p, config.scenario, config.trust_pickle)
            except ValueError as err:  # found but refused (agents.PolicyFormatError): pickle, normalization, ...
                import agents

                if not isinstance(err, agents.PolicyFormatError):
                    raise _unknown_policy(p, config.scenario, err, valid) from None
                raise UsageError(f"policy {p!r}: {_first_line(err)}") from None
            except Exception as err:  # any failure to find it is a usage error
                raise _unknown_policy(p, config.scenario, err, valid) from None
    try:
        overrides = {k: coerce_value(k, v) for k, v in config.overrides.items()}
        sweep = {}
        for key, raw in config.sweep.items():
            if key in overrides:
                raise UsageError(f"{key} is both --set and --sweep")
            values = [coerce_value(key, v) for v in raw]
            if not values:
                raise UsageError(f"--sweep {key} has no value")
            if len(set(map(repr, values))) != len(values):
                raise UsageError(f"--sweep {key} repeats a value")
            sweep[key] = values
        cells: list[dict] = [{}]
        for key, values in sweep.items():
            cells = [dict(c, **{key: v}) for c in cells for v in values]
        configs = {cell_id(cell): coopnav_env.make_config(config.scenario, **overrides, **cell) for cell in cells}
    except UsageError:
        raise
    except ValueError as err:  # unknown parameter or invalid value, from the scenario's checks
        raise UsageError(str(err).splitlines()[0]) from None
    except (OverflowError, ZeroDivisionError, TypeError) as err:  # a value the scenario's checks let through
        raise UsageError(_out_of_range(config.scenario, overrides, config.sweep, err)) from None
    run_info = {
        "scenario": config.scenario,
        "overrides": plain(overrides),
        "sweep": plain(sweep),
        "seed": config.seed,
        "episodes": episodes,
        "policies": policies,
    }
    outdir.check_existing(config, run_info, previous, trained)
    plan = Plan(
        config=config,
        policies=policies,
        cells=cells,
        configs=configs,
        sweep=sweep,
        overrides=overrides,
        trained=trained,
        run_info=run_info,
        episodes=episodes,
        previous=previous,
        out_state=out_state,
    )
    check_policies(plan)
    return plan
