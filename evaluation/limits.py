"""Bounds on the work an evaluation may be asked for, checked before anything runs:
``--episodes 10**12``, a 10^6-cell ``--sweep`` or a run.json saying
``episodes: 1e12`` would otherwise run (or allocate) for ever. Far above what a
study needs (the benchmark runs 200 episodes of a few dozen cells)."""

MAX_EPISODES = 1_000_000  # per policy and cell
MAX_BATCH_SIZE = 10_000
MAX_CELLS = 10_000  # cells of a --sweep grid
MAX_POLICIES = 100
MAX_TOTAL_EPISODES = 10_000_000  # cells x policies x episodes
