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

__all__ = [
    "RANDOMIZATION_OFF",
    "baseline_actor",
    "baselines_on_eval_seeds",
    "episode_mean_error",
    "eval_cells",
    "evaluate",
]


def episode_mean_error(env: Any, act: Callable[[Any, Any], Any], seed: int) -> float:
    """Play one episode in each row of ``env`` (a ``coopnav_env.torchrl_env.CoopNavTorchEnv``,
    re-seeded so that row e plays episode ``seed + e``) with ``act(obs, first) -> actions``:
    obs (E, N, O) the group's observations, first (E,) True where the step is an episode's
    first, actions (E, N, A) (clipped to [-1, 1] here). Returns the mean over the rows of
    each episode's mean survey error (m): what ``evaluation.episodes.run_episodes`` gives the
    same policy on those seeds (to float32 rounding: this acts on every row in one batch).
    The batched loop's and BenchMARL's validations play here."""
    import torch

    from coopnav_env.torchrl_env import GROUP

    E = env.n_envs
    env.set_seed(seed)  # the same episodes at every call
    td = env.reset()
    alive = torch.ones(E, dtype=torch.bool)
    total = torch.zeros(E, dtype=torch.float64)
    steps = torch.zeros(E, dtype=torch.float64)
    first = torch.ones(E, dtype=torch.bool)
    with torch.no_grad():
        while alive.any():
            td.set((GROUP, "action"), torch.as_tensor(act(td.get((GROUP, "observation")), first)).clamp(-1.0, 1.0))
            td, td_next = env.step_and_maybe_reset(td)
            nxt = td.get("next")
            total += torch.where(alive, nxt.get(("info", "survey_error_m")).double(), 0.0)
            steps += alive.double()
            first = nxt.get("done").squeeze(-1).bool()
            alive &= ~first
            td = td_next
    return float((total / steps).mean())


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
