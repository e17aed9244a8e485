"""Evaluate policies on a coopnav scenario, headless, with common random numbers.

From Python:

    from evaluation import EvalConfig, run_evaluation
    summary = run_evaluation(EvalConfig(scenario="sousa_asv", policies=("fim_a", "fim_b", "static"),
                                        episodes=50, out="results/sousa"))
    summary["policies"]["fim_a"]["mean_error_m"]

From the command line (``coopnav-evaluate`` or ``python evaluate.py``, same options):

    coopnav-evaluate --scenario sousa_asv --policies fim_a,fim_b,ellipse,circle,static \\
        --episodes 50 --seed 0 --out results/sousa
    coopnav-evaluate --scenario sousa_asv --policies fim_a,fim_b --episodes 20 \\
        --sweep depth_m=1,5,20,50 --sweep survey_path=stationary,lawnmower,circle,spiral --out results/sweep

Episode ``i`` of every policy (and of every sweep cell) uses seed ``seed + i``; the
simulator's random numbers are counter-based per environment, so every policy sees
the same currents, sensor noise and range noise (common random numbers). Policies act
only on their observation vectors (see ``baselines``); a policy is a planner name
(``baselines.list_policies()``), ``ppo`` (the scenario's shipped PPO policy), a shipped
policy (``agents.list_policies()``) or a train.py run directory.

Outputs in ``out`` (each written to a temporary file and renamed into place, so an
interrupted run leaves no half-written file):

* ``episodes.csv``: one row per episode, policy and sweep cell
  (columns: ``evaluation.report.EPISODE_COLUMN_DOCS``);
* ``steps.csv``: one row per step of every episode (errors, ellipse axes), from which
  the summary's pooled statistics and the figures are computed
  (columns: ``evaluation.report.STEP_COLUMN_DOCS``);
* ``run.json``: the run's scenario, overrides, sweep, seed, episodes and policies,
  what each trained policy resolved to (``trained_policies``: the shipped policy and
  its files) and the versions that produced it (``versions``: git commit, packages);
* ``summary.json`` and ``summary.md``: per policy (and cell) the error statistics over
  all steps of all episodes (mean, median, p95, std, variance, a 95 % cluster-bootstrap
  interval of the mean over episodes), final error, return, ranges fused, outliers
  rejected, beacon distance (``evaluation.report.SUMMARY_COLUMN_DOCS``); a sweep adds
  the Table I/II layout (mean error / variance per cell) for each policy; summary.md
  ends with a "Columns" section defining every column with its unit;
* PNG figures (200 dpi): ``paths.png`` (both vehicles' paths in episode 0 per policy),
  ``error_vs_time.png`` (survey error against time, dead reckoning on its own panel
  below; Gao & Chitre Figs. 7 and 11), ``ellipse_axes.png`` (2-sigma ellipse semi-axes
  against time; Matos & Cruz Fig. 8), ``frame_errors.png`` for the moving network; a
  sweep draws ``sweep.png`` instead (``evaluation.figures``).

One run at a time owns ``out`` (a lock, ``evaluation.outdir``): a second run is refused,
and an earlier result there is kept unless ``overwrite`` (``--overwrite``) replaces it
or ``resume`` (``--resume``) continues it. ``resume`` checks the scenario, overrides,
sweep and seed against run.json, keeps every episode whose rows are complete in both
CSV files (the others are run again, said on stderr) and runs the missing ones; the run
then covers the earlier policies plus ``policies`` and the larger episode count. The
CSV floats are exact, so a resumed run's summary.json is byte-identical to an
uninterrupted run's. Bad input (an unknown policy, scenario or parameter, a bad value
or seed, a policy that cannot drive the scenario, an output directory in use or
holding another result) raises ``UsageError`` (on the command line: a one-line error
and exit status 2) before anything is written; a non-finite result raises
``EvaluationError`` naming the episode (exit status 1); Ctrl-C raises
``EvaluationInterrupted`` with the finished batches on disk (exit status 130, and the
command that resumes is printed).

Modules: ``config`` (EvalConfig, input checks), ``outdir`` (the output directory: lock,
earlier results), ``resume`` (what resume keeps), ``errors`` (UsageError), ``episodes``
(running episodes), ``parallel`` (batches side by side: ``--workers``), ``stats``
(statistics), ``report`` (columns, CSV, summary.md),
``figures``, ``run`` (the whole evaluation), ``cli`` (the command line). Importing this package is cheap:
the names below load their module on first use.
"""

from __future__ import annotations

import importlib

_EXPORTS = {
    "EvalConfig": "config",
    "UsageError": "config",
    "prepare": "config",
    "EvalResult": "run",
    "evaluate": "run",
    "run_evaluation": "run",
    "EvaluationError": "run",
    "EvaluationInterrupted": "run",
    "run_episodes": "episodes",
    "record_episode": "episodes",
    "make_policy": "episodes",
    "error_stats": "stats",
    "summarize": "stats",
    "EPISODE_COLUMNS": "report",
    "STEP_COLUMNS": "report",
    "EPISODE_COLUMN_DOCS": "report",
    "STEP_COLUMN_DOCS": "report",
    "SUMMARY_COLUMN_DOCS": "report",
    "main": "cli",
}
__all__ = sorted(_EXPORTS)


def __getattr__(name):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'evaluation' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
