"""Bounds on what a file's header or a config may ask to allocate, checked before
anything is built: a safetensors header saying ``net_arch: [2000000000]`` would
otherwise allocate a 150 GB layer, ``n_envs: 1e7`` ten million simulators.

``check_net_arch(value, where)`` and ``check_space_size(shape, where)`` raise
``LimitError`` (a ``ValueError``; ``agents.formats`` re-raises it as
``PolicyFormatError``) with one line naming the field. The
limits are far above what the project trains (64-256 units, 2-3 layers, observations
of a few hundred numbers)."""

from __future__ import annotations

import math
import numbers
from typing import Any


class LimitError(ValueError):
    """A size refused (callers re-raise it as ``agents.PolicyFormatError``)."""


MAX_LAYER_WIDTH = 8192
MAX_LAYERS = 32
MAX_OBS_SIZE = 100_000  # numbers in one observation or action
MAX_PARAMETERS = 50_000_000  # weights of one network (200 MB of float32)

__all__ = [
    "MAX_LAYERS",
    "MAX_LAYER_WIDTH",
    "MAX_OBS_SIZE",
    "MAX_PARAMETERS",
    "LimitError",
    "check_net_arch",
    "check_network",
    "check_space_size",
]


def _width(value: Any, where: str) -> int:
    v: Any = value  # numbers.Real narrows to an ABC that typeshed gives no int()/<= support
    if isinstance(v, bool) or not isinstance(value, numbers.Real) or not math.isfinite(v) or int(v) != v:
        raise LimitError(f"{where}: layer width {v!r} is not an integer: refused")
    if not 1 <= v <= MAX_LAYER_WIDTH:
        raise LimitError(f"{where}: layer width {v!r} is outside [1, {MAX_LAYER_WIDTH}]: refused")
    return int(v)


def _layers(v, where: str) -> list:
    if not isinstance(v, (list, tuple)):
        raise LimitError(f"{where}: expected a list of layer widths, got {type(v).__name__}: refused")
    if len(v) > MAX_LAYERS:
        raise LimitError(f"{where}: {len(v)} layers, more than {MAX_LAYERS}: refused")
    return [_width(x, where) for x in v]


def check_net_arch(value: Any, where: str = "net_arch") -> list:
    """The hidden-layer widths of an SB3 ``net_arch`` (a list, or {pi: [..], vf: [..]}),
    each checked; returns the list of all the widths' lists."""
    if value is None:
        return []
    if isinstance(value, dict):
        extra = set(value) - {"pi", "vf"}
        if extra:
            raise LimitError(f"{where}: unknown keys {sorted(extra)} (pi, vf): refused")
        return [_layers(value.get(k, []), f"{where}.{k}") for k in ("pi", "vf")]
    return [_layers(value, where)]


def check_space_size(shape: Any, where: str = "space") -> int:
    """The number of elements of a Box ``shape``; refused above ``MAX_OBS_SIZE``."""
    if not isinstance(shape, (list, tuple)) or len(shape) > 8:
        raise LimitError(f"{where}: bad shape {shape!r}: refused")
    n = 1
    for s in shape:
        if isinstance(s, bool) or not isinstance(s, numbers.Integral) or not 0 <= int(s) <= MAX_OBS_SIZE:
            raise LimitError(f"{where}: bad dimension {s!r} in shape {shape!r}: refused")
        n *= int(s)
        if n > MAX_OBS_SIZE:
            raise LimitError(f"{where}: shape {shape!r} holds more than {MAX_OBS_SIZE} numbers: refused")
    return n


def check_network(obs_size: int, act_size: int, layer_lists: list, where: str) -> None:
    """Refuse a network whose weights would exceed ``MAX_PARAMETERS``."""
    total = 0
    for widths in layer_lists or [[]]:
        prev = obs_size
        for w in widths:
            total += prev * w + w
            prev = w
        total += prev * max(act_size, 1) + prev
    if total > MAX_PARAMETERS:
        raise LimitError(f"{where}: the network would have about {total} weights, more than {MAX_PARAMETERS}: refused")
