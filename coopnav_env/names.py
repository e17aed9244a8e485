"""'Did you mean' for mistyped names (scenarios, policies, task sets, tasks).

raise ValueError(f"unknown policy {name!r}{did_you_mean(name, valid)} valid: ...")
# unknown policy 'fim_c'; did you mean 'fim_a'? valid: ...
"""

from __future__ import annotations

import argparse
import difflib
from collections.abc import Iterable
from typing import NoReturn

__all__ = ["OneLineParser", "closest", "did_you_mean", "option_hint", "unique_assignments"]


def closest(name: object, valid: Iterable[object]) -> str | None:
    """The one of ``valid`` a user most likely meant by ``name``: the same name in another case
    (``GAO_SEA``, ``PPO``), else the closest spelling (``difflib.get_close_matches``, compared
    in lower case), else None."""
    options = [str(v) for v in valid]
    text = str(name)
    same = [v for v in options if v.lower() == text.lower()]
    if same:
        return same[0]
    lowered = {v.lower(): v for v in options}
    close = difflib.get_close_matches(text.lower(), list(lowered), n=1, cutoff=0.6)
    return lowered[close[0]] if close else None


def did_you_mean(name: object, valid: Iterable[object]) -> str:
    """``"; did you mean 'x'?"`` with ``closest(name, valid)``, or ``";"`` when none is close:
    the house style ``unknown policy 'fim_c'; did you mean 'fim_a'? valid: ...``."""
    close = closest(name, valid)
    return f"; did you mean {close!r}?" if close else ";"


def option_hint(message: str, option_strings: Iterable[str]) -> str:
    """argparse's ``unrecognized arguments: --outdir x`` with the option meant, if one is close:
    ``unrecognized arguments: --outdir x; did you mean --out?`` (each front end's one-line
    parser error). Other messages are returned as they are."""
    prefix = "unrecognized arguments: "
    if not message.startswith(prefix):
        return message
    valid = [o[2:] for o in option_strings if o.startswith("--") and o != "--help"]
    hints = []  # (the option meant, the one given)
    for word in message[len(prefix) :].split():
        flag = word.split("=", 1)[0]
        close = closest(flag[2:], valid) if flag.startswith("--") else None  # compared without the dashes
        if close and f"--{close}" != flag:
            hints.append((f"--{close}", flag))
    if not hints:
        return message
    if len(hints) == 1:
        return f"{message}; did you mean {hints[0][0]}?"
    return f"{message}; did you mean {', '.join(f'{meant} for {given}' for meant, given in hints)}?"


class OneLineParser(argparse.ArgumentParser):
    """``argparse.ArgumentParser`` whose errors are one line, ``<prog>: error: <what was
    wrong>``, with exit status 2 and no usage block above it (``--help`` gives that), a
    mistyped option naming the one meant (``option_hint``): the parser of the commands that
    exit on their own (``coopnav-warmup``, the scripts in ``benchmarks/``). The front ends
    that report through a handler of their own raise instead (``evaluation.errors.UsageParser``,
    ``train.py``'s)."""

    def error(self, message: str) -> NoReturn:
        line = " ".join(option_hint(message, self._option_string_actions).split())
        self.exit(2, f"{self.prog}: error: {line}\n")


def unique_assignments(pairs: Iterable[tuple[str, object]], option: str) -> dict:
    """``(key, value)`` pairs of a repeatable ``KEY=VALUE`` option (``--set``) as a dict. A key
    given twice with different values is a ``ValueError`` of one line: which was meant? (The
    same value twice is harmless.) One rule for ``evaluate``, the benchmark and ``train.py``,
    which otherwise each took the last silently."""
    out: dict = {}
    for key, value in pairs:
        if key in out and out[key] != value:
            raise ValueError(f"{option} {key} given twice, as {out[key]!r} and {value!r}: keep one")
        out[key] = value
    return out
