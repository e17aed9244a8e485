"""Validation-selected checkpoints for BenchMARL runs (``python -m agents.training.marl
--eval-every-steps N``), as the batched loop and ``train.py`` keep theirs.

BenchMARL evaluates its policy on its own test environment and keeps its last weights; a
run's last weights are not its best. ``ValidationCallback`` plays the policy, every ``N``
env-steps and at the end, on the validation seeds (``coopnav_env.seeds.VALIDATION_SEED``
onwards: never the benchmark's test seeds) **through the path the benchmark scores**: it
saves the weights as a run folder (``policy.safetensors`` and ``run.json``), loads that folder
with ``agents.benchmarl_policy`` (one policy per beacon, as ``evaluate.py`` does) and plays it
with ``agents.training.scoring.episode_mean_error``, where the batched loop's validation plays
too. The number it keeps is what ``evaluate.py --policies <out>/best`` gives on those seeds
(a test checks it): the mean over the episodes of each episode's mean survey error (m). The training's random
streams (torch's, numpy's and Python's global generators) are left as they were: a run with
validation trains exactly as the same run without.

When a validation is the lowest so far, the folder is copied to ``best/`` (weights first,
``run.json`` last, each written atomically; ``run.json`` adds ``validation_error_m``,
``validation_seeds`` and ``frames``). ``agents.load("<out>/best", ...)`` and ``evaluate.py``
take it like any BenchMARL run.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import TYPE_CHECKING, Any

from benchmarl.experiment.callback import Callback

if TYPE_CHECKING:
    from coopnav_env.scenarios import ScenarioConfig

__all__ = ["ValidationCallback", "save_weights"]


def save_weights(experiment: Any, path: Path) -> None:
    """The experiment's policy weights as safetensors (data, not a pickle), written atomically."""
    import torch
    from safetensors.torch import save

    from coopnav_env.records import atomic_write_bytes

    state = {
        k: v.detach().cpu().contiguous().clone()
        for k, v in experiment.policy.state_dict().items()
        if isinstance(v, torch.Tensor)  # TensorDict modules also keep shapes there
    }
    atomic_write_bytes(path, save(state))


class ValidationCallback(Callback):
    """Every ``every_steps`` env-steps (checked after each training step of the last agent
    group) and at ``finish``, score the policy on ``episodes`` validation episodes seeded
    ``seed + i`` of ``config`` and keep the best weights in ``best`` (see the module).

    ``record``: the run's fields that ``agents.benchmarl_policy.load`` reads besides the
    policy's own (``task``, ``task_config``); ``algorithm``, ``model``: the run's names.
    ``history`` holds one ``{"frames", "validation_error_m"}`` per validation."""

    def __init__(
        self,
        every_steps: int,
        episodes: int,
        seed: int,
        config: ScenarioConfig,
        record: dict,
        algorithm: str,
        model: str,
        scratch: Path,
        best: Path,
    ) -> None:
        super().__init__()
        if every_steps < 1 or episodes < 1:
            raise ValueError(f"every_steps and episodes must be >= 1, got {every_steps} and {episodes}")
        self.every_steps, self.episodes, self.seed = int(every_steps), int(episodes), int(seed)
        self.config, self.record, self.algorithm, self.model = config, dict(record), algorithm, model
        self.scratch, self.best = Path(scratch), Path(best)
        self.next_at = self.every_steps
        self.history: list[dict] = []
        self.best_row: dict | None = None
        self.seconds = 0.0  # wall seconds spent validating (the run's env-steps/s leaves them out)
        self._env: Any = None  # the validation episodes' environment, built at the first validation

    def __getstate__(self) -> dict:  # BenchMARL pickles its callbacks with the experiment
        return {**self.__dict__, "_env": None}

    @property
    def seeds(self) -> list[int]:
        return [self.seed + i for i in range(self.episodes)]

    def on_train_end(self, training_td: Any, group: str) -> None:
        if group != list(self.experiment.group_map)[-1]:
            return
        frames = int(self.experiment.total_frames)
        if frames >= self.next_at:
            self.validate(frames)
            self.next_at = (frames // self.every_steps + 1) * self.every_steps

    def finish(self) -> dict | None:
        """Validate the last weights unless the last validation saw them; the best row."""
        frames = int(self.experiment.total_frames)
        if not self.history or self.history[-1]["frames"] != frames:
            self.validate(frames)
        shutil.rmtree(self.scratch, ignore_errors=True)
        return self.best_row

    def validate(self, frames: int) -> float:
        """Score the current weights (see the module); copy them to ``best`` if lowest."""
        import random
        import time

        import numpy as np
        import torch

        t0 = time.perf_counter()
        # rebuilding the actor draws initial weights from torch's global generator: keep the
        # training's random streams as they were, so a run with validation trains as one without
        py_state, np_state = random.getstate(), np.random.get_state()  # noqa: NPY002 - BenchMARL seeds it
        try:
            with torch.random.fork_rng(devices=[]):
                return self._validate(frames)
        finally:
            random.setstate(py_state)
            np.random.set_state(np_state)  # noqa: NPY002
            self.seconds += time.perf_counter() - t0

    def _validate(self, frames: int) -> float:
        import numpy as np

        from agents.benchmarl_policy import RUN_RECORD, WEIGHTS, forget, load, policy_record
        from coopnav_env.records import atomic_write_bytes, atomic_write_text
        from coopnav_env.torchrl_env import CoopNavTorchEnv

        from .scoring import episode_mean_error

        self.scratch.mkdir(parents=True, exist_ok=True)
        save_weights(self.experiment, self.scratch / WEIGHTS)
        record = {**policy_record(self.experiment, self.algorithm, self.model), **self.record, "frames": frames}
        atomic_write_text(self.scratch / RUN_RECORD, json.dumps(record, indent=2, default=str))
        if self._env is None:  # built once: each validation re-seeds it
            self._env = CoopNavTorchEnv(self.config, n_envs=self.episodes, seed=self.seed, infos=True)
        try:  # the saved folder, loaded as evaluate.py loads it: one policy (its own memory) per beacon
            policies = [load(self.scratch, scenario=self.config, agent=j) for j in range(self.config.n_beacons)]

            def act(obs: Any, first: Any) -> Any:
                rows = obs.numpy()
                return np.stack([p.act_batch(rows[:, j]) for j, p in enumerate(policies)], 1)

            error = episode_mean_error(self._env, act, self.seed)
        finally:
            forget(self.scratch)  # one cached actor per validation would pile up
        row = {"frames": frames, "validation_error_m": error}
        self.history.append(row)
        if self.best_row is None or error < self.best_row["validation_error_m"]:
            self.best_row = row
            self.best.mkdir(parents=True, exist_ok=True)
            atomic_write_bytes(self.best / WEIGHTS, (self.scratch / WEIGHTS).read_bytes())
            best_record = {
                **record,
                "validation_error_m": error,
                "validation_seeds": [self.seeds[0], self.seeds[-1]],
            }
            atomic_write_text(self.best / RUN_RECORD, json.dumps(best_record, indent=2, default=str))
        return error
