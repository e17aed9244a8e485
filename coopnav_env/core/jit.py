"""Compiling a kernel twice: once for small batches, once threaded for large ones.

Every batched kernel is one Python function compiled twice with numba, serial
(``njit(cache=True)``) for the PettingZoo env and small batches, threaded
(``parallel=True``, its ``prange`` loops over the batch run on every core) for the
trainer's large batches. Numba's on-disk cache names its files after the function's
module, qualified name and first line, and keys its entries by signature and
bytecode, not by the compile options (numba issue #6845): two dispatchers built from
the same function share one cache entry, so whichever compiled first was loaded for
both, and a large batch ran single-threaded (or a batch of one paid for threads).
``parallel_twin`` compiles a copy of the function under its own qualified name,
``<name>_parallel``, which gets cache files of its own.
"""

from __future__ import annotations

import types
from collections.abc import Callable
from typing import Any

from numba import njit


def parallel_twin(fn: Callable[..., Any]) -> Any:
    """``njit(cache=True, parallel=True)`` of a copy of ``fn`` named ``<qualname>_parallel``
    (same code, globals, defaults and closure), so its numba cache files are its own."""
    twin = types.FunctionType(fn.__code__, fn.__globals__, fn.__name__, fn.__defaults__, fn.__closure__)
    twin.__qualname__ = fn.__qualname__ + "_parallel"
    twin.__module__ = fn.__module__
    twin.__doc__ = fn.__doc__
    return njit(cache=True, parallel=True)(twin)
