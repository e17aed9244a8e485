"""Where episode seeds come from: one home for the seed ranges every tool uses.

Episode ``i`` of an evaluation is seeded ``first + i``. The simulator's random
numbers are counter-based per seed, so every policy evaluated on the same seeds
meets the same currents, sensor errors and range noise (common random numbers).

* ``EVALUATE_SEED`` (0): the default first seed of ``evaluate.py``.
* ``MAX_SEED``: seeds are integers in [0, 2**62 - 1] (``check_seed``).
* ``VALIDATION_SEED`` (500_000): the default first seed of the trainers' periodic
  evaluation (``eval.seed`` in the YAML), which picks the best model; results that
  are reported should come from other seeds than the ones a model was chosen on.
* ``TEST_SEEDS``: the benchmark's test seeds (``evaluation.benchmark``), the top
  2**20 seeds [2**62 - 2**20, 2**62 - 1]. Training never draws them: the trainers
  take training and validation seeds only below ``TRAINING_SEED_LIMIT`` (2**61) and
  refuse a config that reaches above it (``refuse_test_seeds``); the arithmetic is
  below.
"""

from typing import Any

EVALUATE_SEED = 0
VALIDATION_SEED = 500_000
MAX_SEED = 2**62 - 1  # room for episode offsets (VecEnv: seed + env + k * stride) below int64's limit


def check_seed(seed: Any, what: str = "seed") -> int:
    """``seed`` as a Python int if it is an integer in [0, MAX_SEED], else a one-line
    ``ValueError`` naming ``what``. Every view, the trainers and the evaluation take
    their seeds through this, so they accept and refuse the same values."""
    import numbers

    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral):
        raise ValueError(f"{what} must be an integer in [0, {MAX_SEED}], got {seed!r}")
    if not 0 <= int(seed) <= MAX_SEED:
        raise ValueError(f"{what} must be in [0, {MAX_SEED}] (2**62 - 1), got {seed!r}")
    return int(seed)


# ----------------------------------------------------------------------------------
# the benchmark's test seeds, which training never draws
#
# A training run seeded s plays episode k (k = 0, 1, ...) of its environment copy c
# with seed s + c + k * SEED_STRIDE, SEED_STRIDE = 1_000_003 (coopnav_env.vector:
# SB3's VecEnv, c = the env index; coopnav_env.rllib_env: c = the copy's index over
# all env runners); a resumed run takes a fresh seed below 2**31
# (agents.training.common.resume_seed); validation plays eval.seed + e for
# e < eval.episodes, one episode each (k = 0). The trainers refuse a seed, or an
# eval.seed range, reaching TRAINING_SEED_LIMIT = 2**61 (refuse_test_seeds,
# agents.training.common.prepare_job), and the test seeds start at
# TEST_SEED = 2**62 - 2**20. For any accepted s < 2**61, any copy c < 2**31 and any
# episode k < 2**41 (2.2e12 episodes of ONE copy, each at least one step: some 10**4
# times the longest run ever trained here), the largest seed drawn is below
#
#     2**61 + 2**31 + 2**41 * 1_000_003 = 4_504_872_863_982_944_256
#   < 2**62 - 2**20                   = 4_611_686_018_426_339_328 = TEST_SEED
#
# with a margin of 1.07e17: no training or validation episode is a test episode
# (tests/test_benchmark.py checks the inequality). From a seed in the first billion,
# as every shipped config's, a copy would need k > 4.6e12 episodes. A nearer range
# would not do: 9e9, for instance, is reached from seed 0 by episode k = 9000 of a
# copy, which a long run plays.
# ----------------------------------------------------------------------------------
TRAINING_SEED_LIMIT = 2**61  # training and validation seeds are below this (the trainers refuse the rest)
TEST_SEED_COUNT = 2**20
TEST_SEED = MAX_SEED + 1 - TEST_SEED_COUNT  # 2**62 - 2**20 = 4_611_686_018_426_339_328: the first test seed
TEST_SEEDS = range(TEST_SEED, MAX_SEED + 1)  # the benchmark's episodes are TEST_SEEDS[offset + i]
TRAINING_EPISODE_BOUND = 2**41  # episodes of one environment copy within which the arithmetic above holds
TRAINING_COPY_BOUND = 2**31  # environment copies (index c) within which it holds
# coopnav_env.vector.SEED_STRIDE, restated (this module imports nothing of the package);
# tests/test_benchmark.py checks that the two agree
TRAINING_SEED_STRIDE = 1_000_003


def is_test_seed(seed: Any) -> bool:
    """Whether ``seed`` is one of the benchmark's test seeds (``TEST_SEEDS``)."""
    return int(seed) in TEST_SEEDS


def refuse_test_seeds(first: Any, count: int = 1, what: str = "seed") -> None:
    """Refuse the seeds ``first`` .. ``first + count - 1`` of a training job (its seed,
    or its validation range) with a one-line ``ValueError`` naming ``what`` if any of
    them is at or above ``TRAINING_SEED_LIMIT``: above it lie the test seeds and the
    gap below them that keeps every later training episode (``s + c + k *
    SEED_STRIDE``) away from them (see the arithmetic above)."""
    first, count = int(first), max(int(count), 1)
    last = first + count - 1
    if last >= TRAINING_SEED_LIMIT:
        span = f"{what} {first}" if count == 1 else f"{what} {first} with {count} episodes (seeds up to {last})"
        raise ValueError(
            f"{span} reaches the benchmark's reserved seeds [2**61, 2**62), where its test seeds are: "
            f"training and validation seeds must stay below {TRAINING_SEED_LIMIT} "
            f"(coopnav_env.seeds.TRAINING_SEED_LIMIT)"
        )


def max_training_seed(seed: int, copies: int, episodes: int) -> int:
    """The largest seed a training run seeded ``seed`` draws in its first ``episodes``
    episodes of each of ``copies`` environment copies: ``seed + (copies - 1) +
    (episodes - 1) * SEED_STRIDE``."""
    return int(seed) + int(copies) - 1 + (int(episodes) - 1) * TRAINING_SEED_STRIDE


class EpisodeSeeds:
    """The training views' episode seeds (one home for the schedule above): episode k
    (0, 1, ...) of environment e is seeded ``base + e + k * TRAINING_SEED_STRIDE``.
    ``current[e]`` is the seed of environment e's current episode (-1 before its first)."""

    def __init__(self, n_envs: int) -> None:
        import numpy as np

        self.base = 0
        self.started = np.zeros(n_envs, dtype=np.int64)  # episodes started per environment
        self.current = np.full(n_envs, -1, dtype=np.int64)

    def restart(self, seed: int | None) -> int:
        """Count episodes from 0 again with base ``seed`` (None: a random one); returns the base."""
        import numpy as np

        if seed is None:
            seed = int(np.random.SeedSequence().generate_state(1, dtype=np.uint32)[0] >> 1)
        self.base = check_seed(seed)
        self.started[:] = 0
        return self.base

    def next(self, envs: Any) -> Any:
        """The seeds of the next episodes of environments ``envs`` (int array), counted."""
        seeds = self.base + envs + self.started[envs] * TRAINING_SEED_STRIDE
        self.started[envs] += 1
        self.current[envs] = seeds
        return seeds
