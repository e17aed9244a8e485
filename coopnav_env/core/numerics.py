"""Small compiled arithmetic that the kernels share: a fused multiply-add, and the
order in which numpy computed a few operations that the moving network used to do
in numpy (its matrix products and solves went through OpenBLAS, |z| and z / x of
complex numbers through numpy's own loops).

Why the order matters: the moving network's kernels replaced numpy code whose
outputs are recorded (episodes, tests, figures), and one unit in the last place
of the filter's state grows to visible differences in the float32 observations
within a few hundred cycles. Spelling out the same arithmetic keeps those outputs
bit-for-bit what they were on the machine they were recorded on (x86-64 with
AVX-512: OpenBLAS's SkylakeX kernels, numpy's AVX-512 loops). They were checked
against numpy there on every shape the project uses; the formulas are exact in
exact arithmetic whatever order a machine prefers. Transcendental functions whose
numpy versions differ from the C library's (arctan2, log, exp under AVX-512) stay
in numpy in the callers.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numba import njit, types
from numba.extending import intrinsic


@intrinsic
def fma(typingctx: Any, a: Any, b: Any, c: Any) -> tuple[Any, Callable[..., Any]]:
    """a * b + c rounded once (LLVM's fma; one instruction on x86-64 with FMA3)."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        return builder.fma(*args)

    return sig, codegen


@njit(cache=True)
def complex_abs(z: complex) -> float:
    """numpy's |z| of a complex128 (its AVX-512 loop): hi * sqrt(1 + (lo/hi)^2)."""
    x, y = abs(z.real), abs(z.imag)
    hi, lo = max(x, y), min(x, y)
    if hi == 0.0:
        return 0.0
    r = lo / hi
    return hi * np.sqrt(fma(r, r, 1.0))


@njit(cache=True)
def complex_div_real(z: complex, d: float) -> complex:
    """numpy's z / d for a complex z and a real d > 0 (Smith's division by d + 0j)."""
    rat = 0.0 / d
    scl = 1.0 / (d + 0.0 * rat)
    return complex((z.real + z.imag * rat) * scl, (z.imag - z.real * rat) * scl)


# --- matrix products and solves of small dense matrices ----------------------------------
@njit(cache=True)
def matmul(A: np.ndarray, B: np.ndarray, out: np.ndarray) -> None:
    """out = A @ B; every element a dot product accumulated in order with fused
    multiply-adds (as BLAS's small-matrix kernels do). A (p, q), B (q, r); transposes
    are passed as views (``matmul(A, B.T, out)``), which keeps the same order."""
    for i in range(A.shape[0]):
        for j in range(B.shape[1]):
            s = 0.0
            for k in range(A.shape[1]):
                s = fma(A[i, k], B[k, j], s)
            out[i, j] = s


@njit(cache=True)
def vecmat(h: np.ndarray, P: np.ndarray, out: np.ndarray) -> None:
    """out = h @ P for a row vector h (n,) and P (n, n), in the order of BLAS's
    matrix-vector kernel (numpy sends a row vector times a matrix to gemv): outputs
    in blocks of four sum the products in blocks of four columns (second product
    first), then a pair, then a single column; the remaining outputs in order."""
    n = h.shape[0]
    rows4 = n - n % 4
    for j in range(n):
        y = 0.0
        if j < rows4:
            k = 0
            while k + 4 <= n:
                t = h[k + 1] * P[k + 1, j]
                t = fma(h[k], P[k, j], t)
                t = fma(h[k + 2], P[k + 2, j], t)
                t = fma(h[k + 3], P[k + 3, j], t)
                y = y + t
                k += 4
            if n - k >= 2:
                y = y + fma(h[k], P[k, j], h[k + 1] * P[k + 1, j])
                k += 2
            if n - k == 1:
                y = y + h[k] * P[k, j]
        else:
            for k in range(n):
                y = fma(h[k], P[k, j], y)
        out[j] = y


@njit(cache=True)
def lu_solve(S: np.ndarray, Bm: np.ndarray, X: np.ndarray, lu: np.ndarray, piv: np.ndarray) -> bool:
    """X = S^-1 Bm by LU with partial pivoting (LAPACK's gesv as OpenBLAS computes
    it: the column below a pivot scaled by the pivot's reciprocal; back substitution
    divides for one right-hand side and multiplies by reciprocals for several).
    S (m, m), Bm and X (m, r); lu (m, m) and piv (m,) int64 are work arrays.
    Returns False (X undefined) for a singular S."""
    m, r = S.shape[0], Bm.shape[1]
    lu[:, :] = S
    for k in range(m):
        p = k
        for i in range(k + 1, m):
            if abs(lu[i, k]) > abs(lu[p, k]):
                p = i
        piv[k] = p
        if lu[p, k] == 0.0:
            return False
        if p != k:
            for j in range(m):
                lu[k, j], lu[p, j] = lu[p, j], lu[k, j]
        inv = 1.0 / lu[k, k]
        for i in range(k + 1, m):
            lu[i, k] *= inv
        for i in range(k + 1, m):
            for j in range(k + 1, m):
                lu[i, j] = lu[i, j] - lu[i, k] * lu[k, j]
    X[:, :] = Bm
    for k in range(m):
        p = piv[k]
        if p != k:
            for j in range(r):
                X[k, j], X[p, j] = X[p, j], X[k, j]
    for j in range(r):
        for i in range(m):  # L (unit lower) forward
            s = X[i, j]
            for k in range(i):
                s = fma(-lu[i, k], X[k, j], s)
            X[i, j] = s
        for i in range(m - 1, -1, -1):  # U backward
            s = X[i, j]
            for k in range(i + 1, m):
                s = fma(-lu[i, k], X[k, j], s)
            X[i, j] = s / lu[i, i] if r == 1 else s * (1.0 / lu[i, i])
    return True
