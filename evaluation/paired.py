"""Paired statistics over common random numbers: episode ``i`` of every policy uses the
same seed, so the per-episode difference of two policies removes what the episode
itself contributes (its currents, biases and noise) and leaves what the policies do.

    from evaluation.paired import t_interval
    mean, lo, hi = t_interval(errors_a - errors_b)   # 95 % t interval of the mean difference
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike


def t_interval(x: ArrayLike, confidence: float = 0.95) -> tuple:
    """(mean, low, high): the ``confidence`` t interval of the mean of ``x`` (one value
    per episode). With one value the interval is that value."""
    from scipy import stats

    x = np.asarray(x, dtype=float)
    m = float(x.mean())
    if len(x) < 2:
        return m, m, m
    h = float(stats.t.ppf(0.5 + confidence / 2, len(x) - 1) * x.std(ddof=1) / np.sqrt(len(x)))
    return m, m - h, m + h
