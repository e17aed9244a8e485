"""The evaluation's error for bad input, in a module of its own so that every module of
the package (``config``, ``outdir``) can raise it without importing the others, and the
front ends' parser that reports through it."""

import argparse
from typing import NoReturn


class UsageError(ValueError):
    """Bad input: reported as one line (exit status 2 from the command line), before any work."""


class UsageParser(argparse.ArgumentParser):
    """``argparse.ArgumentParser`` whose errors are a ``UsageError`` (one line through the front
    end's handler, exit status 2), a mistyped option naming the one meant
    (``coopnav_env.names.option_hint``): ``evaluate.py``'s and the benchmark's."""

    def error(self, message: str) -> NoReturn:
        from coopnav_env.names import option_hint

        raise UsageError(option_hint(message, self._option_string_actions))
