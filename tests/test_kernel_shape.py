"""The core's shape: short functions with few parameters, modules of readable length.

Kernels pass named records (numba NamedTuples or structured arrays), not long
positional lists (ARCHITECTURE.md); this walks ``coopnav_env/core/`` with ``ast`` and
holds every function (methods and nested functions included) to at most
``MAX_FUNCTION_LINES`` lines (``def`` to its last line, decorators excluded) and
``MAX_PARAMETERS`` parameters (positional and keyword-only, ``self``/``cls``
excluded), and every module to at most ``MAX_MODULE_LINES`` lines.
"""

from __future__ import annotations

import ast
from pathlib import Path

CORE = Path(__file__).resolve().parents[1] / "coopnav_env" / "core"
MAX_FUNCTION_LINES = 80
MAX_PARAMETERS = 12
MAX_MODULE_LINES = 600

# known offenders, "module.qualified_name" (relative to core/, without .py): being
# refactored on branch kernels; the lead empties this set after the merge
PENDING: set[str] = set()  # the kernels branch fixed the last offenders; keep it empty


def _functions(node: ast.AST, prefix: str = ""):
    """(qualified name, node) of every function under ``node``, nested ones included."""
    for child in ast.iter_child_nodes(node):
        if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
            yield prefix + child.name, child
            yield from _functions(child, prefix + child.name + ".")
        elif isinstance(child, ast.ClassDef):
            yield from _functions(child, prefix + child.name + ".")
        else:
            yield from _functions(child, prefix)


def _n_parameters(fn: ast.FunctionDef) -> int:
    names = [a.arg for a in fn.args.posonlyargs + fn.args.args + fn.args.kwonlyargs]
    if names and names[0] in ("self", "cls"):
        names = names[1:]
    return len(names)


def _modules():
    for path in sorted(CORE.rglob("*.py")):
        yield path.relative_to(CORE).with_suffix("").as_posix(), path


def offenders() -> dict:
    """{"module.function": (lines, parameters)} of the functions over a limit."""
    out = {}
    for module, path in _modules():
        for name, fn in _functions(ast.parse(path.read_text(), filename=str(path))):
            lines = fn.end_lineno - fn.lineno + 1
            n = _n_parameters(fn)
            if lines > MAX_FUNCTION_LINES or n > MAX_PARAMETERS:
                out[f"{module}.{name}"] = (lines, n)
    return out


def test_functions_are_short_and_take_few_parameters():
    bad = {k: v for k, v in offenders().items() if k not in PENDING}
    assert not bad, (
        f"over {MAX_FUNCTION_LINES} lines or {MAX_PARAMETERS} parameters "
        f"((lines, parameters) each; pass a named record): {bad}"
    )


def test_pending_offenders_are_still_offenders():
    """An entry of ``PENDING`` that was fixed (or renamed) must leave the set."""
    stale = PENDING - set(offenders())
    assert not stale, f"fixed or gone, remove from PENDING: {sorted(stale)}"


def test_modules_are_of_readable_length():
    long = {m: n for m, path in _modules() if (n := len(path.read_text().splitlines())) > MAX_MODULE_LINES}
    assert not long, f"modules over {MAX_MODULE_LINES} lines: {long}"


def test_the_walk_sees_the_core():
    names = {name for _, path in _modules() for name, _ in _functions(ast.parse(path.read_text()))}
    assert {"MovingNetworkSimulator.step", "exchange_of", "joseph_update_vector"} <= names


# The large state records: numba counts a reference to each of their arrays at every call
# of a helper (SurveyView 19, ConsiderView 16, ModemCycle 9), which was 70 % of the
# simulator's time when the modem's per-ping helpers took them (docs/performance.md#refcounts)
LARGE_RECORDS = {"sv", "cv", "cyc"}
# helpers that take one anyway, on a rare path: a beacon's fix counter changed, a range was rejected
RARE_PATH_HELPERS = {"measurements/modem._heard_fix_count", "measurements/modem._count_rejection"}


def _inlined(fn: ast.FunctionDef) -> bool:
    """Whether ``fn`` is decorated ``njit(..., inline="always")``: a per-element helper."""
    for d in fn.decorator_list:
        if isinstance(d, ast.Call) and any(
            k.arg == "inline" and isinstance(k.value, ast.Constant) and k.value.value == "always" for k in d.keywords
        ):
            return True
    return False


def large_record_helpers() -> set[str]:
    """The inlined helpers of ``core/`` that take a large state record as a parameter."""
    out = set()
    for module, path in _modules():
        for name, fn in _functions(ast.parse(path.read_text(), filename=str(path))):
            params = {a.arg for a in fn.args.posonlyargs + fn.args.args + fn.args.kwonlyargs}
            if _inlined(fn) and params & LARGE_RECORDS:
                out.add(f"{module}.{name}")
    return out


def test_per_element_helpers_take_rows_not_large_records():
    found = large_record_helpers()
    assert found >= {"measurements/modem._count_rejection"}, "the scan no longer sees the modem's helpers"
    bad = found - RARE_PATH_HELPERS
    assert not bad, (
        f"inlined helpers taking {sorted(LARGE_RECORDS)}: {sorted(bad)}; pass the rows and scalars they read "
        "(docs/performance.md#refcounts), or add a helper that runs on a rare path to RARE_PATH_HELPERS"
    )
