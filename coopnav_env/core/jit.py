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

The threaded twins are switched off (``THREADED_MIN_BATCH = None``, ``threaded``):
numba 0.68's parfor lowering loses writes made through a record's arrays inside a
``prange`` loop when the callee is inlined (``inline="always"``, as the record helpers
are: ``kernel_records``), and other twins (the modem's fusion, the message exchange)
dropped their writes even without it; the moving network's twin does not compile
(``AttributeError: 'str' object has no attribute 'loc'`` in
``_create_gufunc_for_parfor_body``). From 256 environments on, every threaded twin ran:
the survey vehicles did not move, no range was fused and no episode ended, silently.
``tests/test_batch_rows.py`` checks a batch of 300 row by row against batches of one;
re-enable threads only with it passing. The smallest reproduction, numba 0.68.1::

    class V(NamedTuple):
        a: np.ndarray
    @njit(inline="always")
    def inner(v, i):
        v.a[i, 0] += 1.0
    @njit(parallel=True)
    def f(v, n):
        for i in prange(n):
            inner(v, i)
    v = V(np.zeros((4, 2))); f(v, 4)  # v.a[:, 0] stays 0; without parallel=True it is 1
"""

from __future__ import annotations

import types
from collections.abc import Callable
from typing import Any

from numba import njit

THREADED_MIN_BATCH: int | None = None  # the batch size from which the twins run; None: never (above)


def threaded(batch_size: int) -> bool:
    """Whether a batch of ``batch_size`` environments runs the threaded twins."""
    return THREADED_MIN_BATCH is not None and batch_size >= THREADED_MIN_BATCH


def parallel_twin(fn: Callable[..., Any]) -> Any:
    """``njit(cache=True, parallel=True)`` of a copy of ``fn`` named ``<qualname>_parallel``
    (same code, globals, defaults and closure), so its numba cache files are its own."""
    twin = types.FunctionType(fn.__code__, fn.__globals__, fn.__name__, fn.__defaults__, fn.__closure__)
    twin.__qualname__ = fn.__qualname__ + "_parallel"
    twin.__module__ = fn.__module__
    twin.__doc__ = fn.__doc__
    return njit(cache=True, parallel=True)(twin)
