"""The evaluation's error for bad input, in a module of its own so that every module of
the package (``config``, ``outdir``) can raise it without importing the others."""


class UsageError(ValueError):
    """Bad input: reported as one line (exit status 2 from the command line), before any work."""
