"""Counter-based random numbers for the batched core.

Every random number is a hash of (environment key, stream, counter, index):
env ``b`` seeded with ``s`` draws the same numbers whether it runs alone (the
PettingZoo view, batch of one) or as row ``b`` of a batch of 1024, and a draw
never shifts the draws after it. That second property gives evaluations common
random numbers for free: two policies on the same seed see the same currents,
the same compass noise and the same range noise at the same cycle, whatever
else they did. (A stateful ``np.random.Generator`` per environment would need a
Python loop over the batch; one generator for the batch would tie the numbers
of one environment to the size of its batch.)

The hash is SplitMix64's finalizer (Steele, Lea & Flood 2014); normals come from
the inverse normal CDF of 53-bit uniforms.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
from numpy.typing import ArrayLike
from scipy.special import ndtri

_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_S30, _S27, _S31, _S11 = np.uint64(30), np.uint64(27), np.uint64(31), np.uint64(11)
_C_COUNTER = np.uint64(0xABC98388FB8FAC03)
_C_INDEX = np.uint64(0x8CB92BA72F3D8DD7)
_TWO_M53 = 1.0 / 9007199254740992.0


def _mix(z: np.ndarray) -> np.ndarray:
    """SplitMix64 finalizer on a uint64 array (wraps modulo 2**64, in place)."""
    z ^= z >> _S30
    z *= _M1
    z ^= z >> _S27
    z *= _M2
    z ^= z >> _S31
    return z


def env_keys(seeds: ArrayLike) -> np.ndarray:
    """One 64-bit key per environment from integer seeds."""
    s = np.asarray(seeds, dtype=np.int64).astype(np.uint64)
    return _mix(s * _GOLDEN + _GOLDEN)


def uniform(keys: np.ndarray, stream: int, counter: np.ndarray, shape: tuple) -> np.ndarray:
    """Uniform numbers in (0, 1), shape (B, *shape).

    keys: (B,) uint64 environment keys; stream: a small integer naming what the
    numbers are for; counter: (B,) integer, e.g. the cycle number.
    """
    n = int(np.prod(shape)) if shape else 1
    stream_bits = np.uint64((int(stream) * 0xD1B54A32D192ED03) & 0xFFFFFFFFFFFFFFFF)
    base = keys ^ stream_bits ^ (np.asarray(counter).astype(np.uint64) * _C_COUNTER)
    z = base[:, None] ^ (np.arange(1, n + 1, dtype=np.uint64) * _C_INDEX)[None, :]
    z = _mix(_mix(z))
    u = ((z >> _S11).astype(np.float64) + 0.5) * _TWO_M53
    return u.reshape((keys.shape[0],) + tuple(shape))


def to_normal(u: np.ndarray) -> np.ndarray:
    """Standard normal numbers from uniforms in (0, 1) (inverse normal CDF)."""
    return ndtri(u)


def normal(keys: np.ndarray, stream: int, counter: np.ndarray, shape: tuple) -> np.ndarray:
    """Standard normal numbers, shape (B, *shape)."""
    return to_normal(uniform(keys, stream, counter, shape))


# stream names: one per purpose, so that adding a draw never changes another
STREAM_EPISODE = 1  # per-episode randomization (current, biases, start geometry)
STREAM_CYCLE = 2  # everything drawn in a cycle (laid out by purpose in Simulator)


class DrawLayout:
    """Every random number of one cycle from one hash call, laid out by purpose.

    ``layout`` is a list of (name, "normal" | "uniform", shape); a new purpose goes
    at the end so that the others keep their numbers. ``draw(keys, counter)``
    returns name -> (B, *shape).
    """

    def __init__(
        self, layout: Iterable[tuple[str, str, tuple[int, ...]]], batch_size: int, stream: int = STREAM_CYCLE
    ) -> None:
        self.layout, self.stream = list(layout), int(stream)
        self.slices, start = [], 0
        for name, kind, shape in self.layout:
            if kind not in ("normal", "uniform"):
                raise ValueError(f"draw kind must be 'normal' or 'uniform', got {kind!r}")
            size = int(np.prod(shape))
            self.slices.append((name, kind == "normal", slice(start, start + size), (int(batch_size),) + tuple(shape)))
            start += size
        self.size = start

    def draw(self, keys: np.ndarray, counter: np.ndarray) -> dict:
        u = uniform(keys, self.stream, counter, (self.size,))
        out = {}
        for name, normal_, cols, shape in self.slices:
            block = u[:, cols].reshape(shape)
            out[name] = to_normal(block) if normal_ else block
        return out
