"""Where episode seeds come from: one home for the seed ranges every tool uses.

Episode ``i`` of an evaluation is seeded ``first + i``. The simulator's random
numbers are counter-based per seed, so every policy evaluated on the same seeds
meets the same currents, sensor errors and range noise (common random numbers).

* ``EVALUATE_SEED`` (0): the default first seed of ``evaluate.py``.
* ``MAX_SEED``: seeds are integers in [0, 2**62 - 1] (``check_seed``).
* ``VALIDATION_SEED`` (500_000): the default first seed of the trainers' periodic
  evaluation (``eval.seed`` in the YAML), which picks the best model; results that
  are reported should come from other seeds than the ones a model was chosen on.
"""

EVALUATE_SEED = 0
VALIDATION_SEED = 500_000
MAX_SEED = 2**62 - 1  # room for episode offsets (VecEnv: seed + env + k * stride) below int64's limit


def check_seed(seed, what: str = "seed") -> int:
    """``seed`` as a Python int if it is an integer in [0, MAX_SEED], else a one-line
    ``ValueError`` naming ``what``. Every view, the trainers and the evaluation take
    their seeds through this, so they accept and refuse the same values."""
    import numbers

    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral):
        raise ValueError(f"{what} must be an integer in [0, {MAX_SEED}], got {seed!r}")
    if not 0 <= int(seed) <= MAX_SEED:
        raise ValueError(f"{what} must be in [0, {MAX_SEED}] (2**62 - 1), got {seed!r}")
    return int(seed)
