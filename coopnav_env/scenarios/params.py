"""Declaring scenario parameters: ``param(...)`` and the ``Section`` base class.

Every parameter is a field of a frozen section dataclass (``sections.py``) declared
with ``param(default, unit=..., low=..., high=..., doc=..., source=...)``. The
metadata it stores is the one description of the parameter: ``Section``'s
``__post_init__`` checks types, finiteness and ranges from it, ``bounds()`` is the
table of ranges, and ``docs/hooks/generate.py`` renders the parameter reference
from it.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from typing import Any

from ..names import did_you_mean

COORDINATE_LIMIT_M = 1e6  # |east|, |north| of origins and waypoints


def param(
    default: Any,
    *,
    doc: str,
    unit: str = "-",
    low: float | None = None,
    high: float | None = None,
    open_low: bool = False,
    choices: tuple | None = None,
    source: str = "",
) -> Any:
    """A parameter field: its default and its metadata.

    Args:
        default: the value when a scenario does not set it (an int, float, str, bool or tuple)
        doc: what it means (one sentence or two; the reference page shows it)
        unit: its physical unit ("-" when dimensionless)
        low, high: the allowed range of a number, inclusive
        open_low: the range excludes ``low`` (``(low, high]``)
        choices: the allowed values of a string
        source: where the default comes from (a paper, ``reference-values.md``, "[U]" for
            an assumption); empty when ``doc`` says it
    """
    if isinstance(default, (int, float)) and not isinstance(default, bool):
        assert low is not None and high is not None, "a number parameter needs low and high"
    meta = {
        "unit": unit,
        "low": low,
        "high": high,
        "open_low": open_low,
        "choices": choices,
        "doc": doc,
        "source": source,
    }
    return dataclasses.field(default=default, metadata=meta)


def kind_of(field: dataclasses.Field) -> type:
    """The type of a parameter: the type of its default (bool, int, float, str or tuple)."""
    return type(field.default)


def range_text(field: dataclasses.Field) -> str:
    """``[low, high]`` or ``(low, high]`` of a number parameter; "" otherwise."""
    m = field.metadata
    if m.get("low") is None:
        return ""
    return f"{'(' if m['open_low'] else '['}{m['low']:g}, {m['high']:g}]"


def in_range(field: dataclasses.Field, value: float) -> bool:
    m = field.metadata
    return (value > m["low"] if m["open_low"] else value >= m["low"]) and value <= m["high"]


def shown(v: Any, limit: int = 40) -> str:
    """``repr(v)`` cut to ``limit`` characters (a 400-digit number stays one short line)."""
    text = repr(v)
    return text if len(text) <= limit else f"{text[: limit - 12]}... ({len(text)} chars)"


def check(cond: bool, message: str) -> None:
    """Raise ``ValueError(message)`` unless ``cond``."""
    if not cond:
        raise ValueError(message)


def finite(x: Any) -> bool:
    try:
        return math.isfinite(float(x))
    except (TypeError, ValueError, OverflowError):
        return False


def real(v: Any) -> bool:
    """A finite real number that is not a bool."""
    return isinstance(v, numbers.Real) and not isinstance(v, bool) and finite(v)


def check_coordinates(name: str, values: Any, n: int) -> None:
    check(
        isinstance(values, tuple) and len(values) == n, f"scenario parameter {name} must be {n} numbers, got {values!r}"
    )
    for v in values:
        check(
            real(v) and abs(v) <= COORDINATE_LIMIT_M,
            f"scenario parameter {name} must hold finite numbers within +-{COORDINATE_LIMIT_M:g} m, got {values!r}",
        )


def check_field(field: dataclasses.Field, v: Any) -> None:
    """Type, finiteness, range (numbers) and choices (strings) of one parameter's value."""
    name, kind = field.name, kind_of(field)
    if kind is int:
        check(
            isinstance(v, numbers.Integral) and not isinstance(v, bool),
            f"scenario parameter {name} must be an integer, got {shown(v)}",
        )
    elif kind is float:
        check(
            isinstance(v, numbers.Real) and not isinstance(v, bool),
            f"scenario parameter {name} must be a number, got {shown(v)}",
        )
        check(finite(v), f"scenario parameter {name} must be finite, got {shown(v)}")
    elif kind is str:
        check(isinstance(v, str), f"scenario parameter {name} must be a string, got {shown(v)}")
        choices = field.metadata.get("choices")
        if choices:
            check(v in choices, f"unknown {name} {v!r}{did_you_mean(v, choices)} valid: {', '.join(choices)}")
    elif kind is bool:
        check(isinstance(v, bool), f"scenario parameter {name} must be True or False, got {shown(v)}")
    elif kind is tuple:
        check(isinstance(v, tuple), f"scenario parameter {name} must be a tuple (or list), got {shown(v)}")
    if kind in (int, float):
        check(in_range(field, v), f"scenario parameter {name} must be in {range_text(field)}, got {shown(v)}")


def coerce(field: dataclasses.Field, v: Any) -> Any:
    """numpy scalars (sweeps, YAML) become plain ints and floats, lists (YAML, JSON) tuples;
    anything else is left for ``check_field`` to refuse."""
    kind = kind_of(field)
    if kind is int and isinstance(v, numbers.Integral) and not isinstance(v, bool):
        return int(v)
    if kind is float and isinstance(v, numbers.Real) and not isinstance(v, bool):
        try:
            return float(v)
        except OverflowError:  # an int beyond a float (10**400): check_field refuses it as not finite
            return v
    if kind is tuple and isinstance(v, list):
        return tuple(tuple(x) if isinstance(x, list) else x for x in v)
    return v


@dataclasses.dataclass(frozen=True)
class Section:
    """A group of parameters. Subclasses are frozen dataclasses of ``param`` fields;
    ``check()`` holds the checks that concern the section's fields only."""

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            object.__setattr__(self, f.name, coerce(f, getattr(self, f.name)))
        for f in dataclasses.fields(self):
            check_field(f, getattr(self, f.name))
        self.check()

    def check(self) -> None:
        """Checks between this section's fields (after each field's own)."""


def section(cls: type) -> type:
    """``@section``: a frozen dataclass of parameters."""
    return dataclasses.dataclass(frozen=True)(cls)
