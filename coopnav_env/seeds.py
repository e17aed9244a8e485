"""Where episode seeds come from: one home for the seed ranges every tool uses.

Episode ``i`` of an evaluation is seeded ``first + i``. The simulator's random
numbers are counter-based per seed, so every policy evaluated on the same seeds
meets the same currents, sensor errors and range noise (common random numbers).

* ``EVALUATE_SEED`` (0): the default first seed of ``evaluate.py``.
* ``VALIDATION_SEED`` (500_000): the default first seed of the trainers' periodic
  evaluation (``eval.seed`` in the YAML), which picks the best model; results that
  are reported should come from other seeds than the ones a model was chosen on.
"""

EVALUATE_SEED = 0
VALIDATION_SEED = 500_000
MAX_SEED = 2**63 - 1 - 2**40  # room for episode offsets (VecEnv: seed + env + k * stride) below int64's limit
