"""Reading YAML and JSON that may come from a stranger: bounded before it is parsed.

A run folder someone sends you holds ``config.yml``, ``run.json``, safetensors headers
and the like. ``yaml.safe_load`` runs no code, but it still expands aliases (a
"billion laughs" bomb of a few hundred bytes takes minutes and gigabytes), recurses
once per nesting level (a 20,000-deep list is a ``RecursionError`` traceback), and
reads any size; ``json.loads`` recurses too. Here every document is checked first:

* at most ``MAX_BYTES`` (1 MiB by default) of UTF-8 text;
* YAML: no anchors or aliases, no tags beyond YAML's own (``!!python/...`` and the
  like are refused even though the safe loader would refuse them later, with a
  traceback), at most ``MAX_DEPTH`` nested collections and ``MAX_NODES`` nodes,
  checked on the parser's event stream, which does not recurse;
* JSON: at most ``MAX_DEPTH`` nested brackets (a scan outside strings), then
  ``json.loads``; NaN/Infinity are accepted as Python's json does.

Every refusal is an ``UnsafeDataError`` (a ``ValueError``) of one line naming the
file and what is wrong, raised in well under a second.

    from coopnav_env.safe_load import read_yaml, loads_json
    record = read_yaml("runs/x/config.yml")        # None if the file does not exist
"""

from __future__ import annotations

import json
import os
from typing import Any

MAX_BYTES = 1 << 20  # 1 MiB: the largest config.yml / run.json the project writes is a few kB
MAX_DEPTH = 64
MAX_NODES = 200_000

__all__ = [
    "MAX_BYTES",
    "MAX_DEPTH",
    "MAX_NODES",
    "UnsafeDataError",
    "loads_json",
    "loads_yaml",
    "parse_value_text",
    "read_json",
    "read_text",
    "read_yaml",
]


class UnsafeDataError(ValueError):
    """A YAML or JSON document refused before (or while) parsing it: one line."""


def _decode(data, where: str, max_bytes: int) -> str:
    if isinstance(data, str):
        if len(data) > max_bytes:
            raise UnsafeDataError(f"{where} is larger than {max_bytes} bytes: refused")
        text = data
    else:
        if len(data) > max_bytes:
            raise UnsafeDataError(f"{where} is larger than {max_bytes} bytes: refused")
        try:
            text = bytes(data).decode("utf-8")
        except UnicodeDecodeError as err:
            raise UnsafeDataError(f"{where} is not UTF-8 text (byte {err.start}): refused") from None
    if "\0" in text:
        raise UnsafeDataError(f"{where} holds NUL bytes (not a text file): refused")
    return text


def read_text(path: str | os.PathLike[str], max_bytes: int = MAX_BYTES, what: str | None = None) -> str | None:
    """The UTF-8 text of ``path`` (None if it does not exist), at most ``max_bytes``
    (checked before reading all of it); an ``UnsafeDataError`` else."""
    where = what or str(path)
    try:
        with open(path, "rb") as f:
            data = f.read(max_bytes + 1)
    except FileNotFoundError:
        return None
    except IsADirectoryError:
        raise UnsafeDataError(f"{where} is a directory, not a file") from None
    except OSError as err:
        raise UnsafeDataError(f"cannot read {where}: {err.strerror or err}") from None
    return _decode(data, where, max_bytes)


# --------------------------------------------------------------------------------------
# YAML

_STANDARD_TAG = "tag:yaml.org,2002:"
_SAFE_TAGS = {
    _STANDARD_TAG + t
    for t in (
        "null",
        "bool",
        "int",
        "float",
        "str",
        "seq",
        "map",
        "binary",
        "timestamp",
        "set",
        "omap",
        "pairs",
        "merge",
    )
}


def _check_yaml_events(text: str, where: str, max_depth: int, max_nodes: int):
    import yaml

    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    depth = nodes = 0
    # per open collection: [a mapping?, its next node is a key?, the keys seen]
    stack: list[list] = []
    try:
        for event in yaml.parse(text, Loader=loader):
            if isinstance(event, yaml.AliasEvent):
                raise UnsafeDataError(f"{where}: YAML aliases (*{event.anchor}) are not accepted: refused")
            if isinstance(event, yaml.NodeEvent) and stack and stack[-1][0]:
                if stack[-1][1] and isinstance(event, yaml.ScalarEvent):
                    # a key given twice: yaml keeps the last silently; which was meant?
                    if event.value in stack[-1][2]:
                        line = event.start_mark.line + 1 if event.start_mark is not None else "?"
                        raise UnsafeDataError(f"{where}: key {event.value!r} given twice (line {line}): keep one")
                    stack[-1][2].add(event.value)
                stack[-1][1] = not stack[-1][1]
            if isinstance(event, yaml.CollectionStartEvent):
                stack.append([isinstance(event, yaml.MappingStartEvent), True, set()])
            elif isinstance(event, yaml.CollectionEndEvent):
                stack.pop()
            if isinstance(event, (yaml.ScalarEvent, yaml.SequenceStartEvent, yaml.MappingStartEvent)):
                if event.anchor is not None:
                    raise UnsafeDataError(f"{where}: YAML anchors (&{event.anchor}) are not accepted: refused")
                tag = event.tag
                if tag is not None and tag not in ("!", "?") and tag not in _SAFE_TAGS:
                    raise UnsafeDataError(f"{where}: YAML tag {tag!r} is not accepted (plain data only): refused")
                nodes += 1
                if nodes > max_nodes:
                    raise UnsafeDataError(f"{where} holds more than {max_nodes} YAML nodes: refused")
            if isinstance(event, (yaml.SequenceStartEvent, yaml.MappingStartEvent)):
                depth += 1
                if depth > max_depth:
                    raise UnsafeDataError(f"{where} nests deeper than {max_depth} levels: refused")
            elif isinstance(event, (yaml.SequenceEndEvent, yaml.MappingEndEvent)):
                depth -= 1
    except yaml.YAMLError as err:
        raise UnsafeDataError(f"{where}: not YAML: {' '.join(str(err).split())[:300]}") from None


def loads_yaml(
    text: str | bytes,
    where: str = "YAML text",
    max_bytes: int = MAX_BYTES,
    max_depth: int = MAX_DEPTH,
    max_nodes: int = MAX_NODES,
) -> Any:
    """``yaml.safe_load(text)`` after the checks of the module docstring (``text``:
    str or bytes)."""
    import yaml

    text = _decode(text, where, max_bytes)
    _check_yaml_events(text, where, max_depth, max_nodes)
    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    try:
        return yaml.load(text, Loader=loader)
    except yaml.YAMLError as err:
        raise UnsafeDataError(f"{where}: not YAML: {' '.join(str(err).split())[:300]}") from None
    except (RecursionError, MemoryError, OverflowError, ValueError, TypeError) as err:
        raise UnsafeDataError(f"{where}: cannot be read ({type(err).__name__}): refused") from None


def read_yaml(path: str | os.PathLike[str], max_bytes: int = MAX_BYTES, max_depth: int = MAX_DEPTH) -> Any:
    """``loads_yaml`` of a file (None if it does not exist)."""
    text = read_text(path, max_bytes)
    return None if text is None else loads_yaml(text, str(path), max_bytes, max_depth)


def parse_value_text(text: str) -> Any:
    """A value written on a command line: '3e-4' -> 0.0003, '2' -> 2, '[64, 64]' -> [64, 64],
    'true' -> True, 'null' -> None, 'tanh' -> 'tanh' (numbers first, then bounded YAML,
    else the text itself). ``UnsafeDataError`` for YAML this module refuses. The one parser
    of training overrides (``agents.training.config.parse_value``) and planner settings
    (``baselines.split_spec``)."""
    text = str(text).strip()
    for cast in (int, float):
        try:
            return cast(text)
        except ValueError:
            pass
    try:
        return loads_yaml(text, f"value {text[:40]!r}", max_bytes=64 << 10)  # no aliases, bounded
    except UnsafeDataError as err:
        if ": not YAML:" in str(err):
            return text
        raise


# --------------------------------------------------------------------------------------
# JSON


def _json_depth_ok(text: str, max_depth: int) -> bool:
    depth = 0
    in_string = escaped = False
    for ch in text:
        if in_string:
            if escaped:
                escaped = False
            elif ch == "\\":
                escaped = True
            elif ch == '"':
                in_string = False
        elif ch == '"':
            in_string = True
        elif ch in "[{":
            depth += 1
            if depth > max_depth:
                return False
        elif ch in "]}":
            depth -= 1
    return True


def loads_json(
    text: str | bytes, where: str = "JSON text", max_bytes: int = MAX_BYTES, max_depth: int = MAX_DEPTH
) -> Any:
    """``json.loads(text)`` after the size and depth checks (``text``: str or bytes)."""
    text = _decode(text, where, max_bytes)
    if text.count("[") + text.count("{") > max_depth and not _json_depth_ok(text, max_depth):
        raise UnsafeDataError(f"{where} nests deeper than {max_depth} levels: refused")
    try:
        return json.loads(text)
    except ValueError as err:
        raise UnsafeDataError(f"{where}: not JSON: {str(err).splitlines()[0]}") from None
    except (RecursionError, MemoryError, OverflowError) as err:
        raise UnsafeDataError(f"{where}: cannot be read ({type(err).__name__}): refused") from None


def read_json(path: str | os.PathLike[str], max_bytes: int = MAX_BYTES, max_depth: int = MAX_DEPTH) -> Any:
    """``loads_json`` of a file (None if it does not exist)."""
    text = read_text(path, max_bytes)
    return None if text is None else loads_json(text, os.fspath(path), max_bytes, max_depth)
