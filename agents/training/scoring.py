"""The trainers' evaluation on fixed validation seeds (both backends score alike).

    cells = eval_cells(scenario_config, {"depth_m": [1.0, 50.0]})
    result = evaluate(act, cells, episodes=16, seed=VALIDATION_SEED)   # act(obs, venv) -> actions
    result["survey_error_m"], result["per_cell"]

The deterministic policy runs one episode in each of ``episodes`` environments seeded
``seed + e`` in every cell (common random numbers across cells and policies), scored
by the mean of ``survey_error_m`` over every step of every episode of every cell (the
evaluation's ``mean_error_m``; lower is better). The default first seed is
``coopnav_env.seeds.VALIDATION_SEED``: the seeds the best model is chosen on, not the
ones results are reported on.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np

from coopnav_env.records import atomic_write_text, read_json, strict_json

RANDOMIZATION_OFF = {"randomize_survey_path": (), "randomize_depth_m": (), "randomize_noise_scale": ()}

__all__ = ["RANDOMIZATION_OFF", "baseline_actor", "baselines_on_eval_seeds", "eval_cells", "evaluate"]


def eval_cells(scenario_config: Any, cells: dict | None = None) -> list:
    """[(label, ScenarioConfig)] the evaluation runs: every combination of ``cells``
    ({parameter: [values]}) as a fixed scenario, or without cells the training
    scenario (label "all"); the per-episode randomization is off in every cell (the
    scenario's own survey_path, depth_m and noise levels unless the cell sets them)."""
    base = scenario_config.replace(**{k: v for k, v in RANDOMIZATION_OFF.items() if scenario_config.applies(k)})
    if not cells:
        return [("all", base)]
    if not isinstance(cells, dict):
        raise ValueError(f"eval.cells must map parameters to lists of values, got {cells!r}")
    combos: list[dict] = [{}]
    for name, values in cells.items():
        if not isinstance(values, (list, tuple)) or not values:
            raise ValueError(f"eval.cells entry {name!r} must be a non-empty list of values")
        combos = [dict(c, **{name: v}) for c in combos for v in values]
    return [(";".join(f"{k}={v}" for k, v in combo.items()), base.replace(**combo)) for combo in combos]


def evaluate(act: Callable[[Any, Any], np.ndarray], cells: list, episodes: int, seed: int) -> dict:
    """Run ``act(obs (rows, D), venv) -> actions (rows, 2)`` for one episode in each of
    ``episodes`` environments seeded ``seed + e`` in every cell of ``cells``
    ([(label, ScenarioConfig)], see ``eval_cells``). Score: survey_error_m (the
    info's mean over survey vehicles) averaged over every step of every episode of
    every cell; ``per_cell`` the same per cell."""
    from coopnav_env.vector import CoopNavVecEnv

    per_cell, per_episode, total, count = {}, [], 0.0, 0
    for label, config in cells:
        venv = CoopNavVecEnv(config, n_envs=episodes, seed=seed)
        N = venv.n_beacons
        obs = venv.reset()
        running = np.ones(episodes, dtype=bool)
        err_sum = np.zeros(episodes)
        steps = np.zeros(episodes)
        while running.any():
            obs, _, done, infos = venv.step(act(obs, venv))
            err = np.array([infos[e * N]["survey_error_m"] for e in range(episodes)])
            err_sum += np.where(running, err, 0.0)
            steps += running
            running &= ~done[::N]
        per_cell[label] = float(err_sum.sum() / steps.sum())
        per_episode.extend((err_sum / steps).round(4).tolist())
        total += err_sum.sum()
        count += steps.sum()
    return {
        "survey_error_m": float(total / count),
        "episodes": episodes * len(cells),
        "survey_error_m_per_episode": per_episode,
        "per_cell": per_cell,
    }


def baseline_actor(name: str) -> Callable[[np.ndarray, Any], np.ndarray]:
    """A batch actor from one baselines policy per row (reset at the first step of a
    new evaluation environment)."""
    from baselines import make_policy

    policies: dict[Any, Any] = {}  # "venv": the environment they were made for; row -> policy

    def act(obs, venv):
        if policies.get("venv") is not venv:
            policies.clear()
            policies["venv"] = venv
            for row in range(venv.num_envs):
                e, j = divmod(row, venv.n_beacons)
                policies[row] = make_policy(name, venv.config, seed=int(venv.episode_seeds[e]), agent=j)
        return np.stack([policies[row].act(obs[row]) for row in range(venv.num_envs)])

    return act


def baselines_on_eval_seeds(out: Path, cells: list, names: Iterable[str], episodes: int, seed: int) -> dict:
    """The planners ``names`` scored on the evaluation seeds, once per run: read from
    and written (atomically) to ``out/baseline_eval.json``; name -> {survey_error_m, per_cell}.
    Nothing is scored with ``episodes`` 0 (what the file holds is returned)."""
    scores = read_json(Path(out) / "baseline_eval.json") or {}
    if episodes <= 0:
        return scores
    for name in names or []:
        if name in scores:
            continue
        try:
            result = evaluate(baseline_actor(name), cells, episodes, seed)
        except ImportError as err:  # the baselines package is not there
            print(f"baseline {name} not evaluated: {err}", file=sys.stderr)
            continue
        scores[name] = {"survey_error_m": result["survey_error_m"], "per_cell": result["per_cell"]}
    atomic_write_text(Path(out) / "baseline_eval.json", strict_json(scores, indent=None))
    return scores
