"""Runs of ``agents.training.batched_ppo`` as coopnav policies:
``agents.load("runs/sousa_asv_batched", scenario="sousa_asv")``.

A run folder holds ``run.json`` (``"trainer": "batched_ppo"``, its settings, the sizes of
the observation and the action) and ``actor.safetensors`` (the actor MLP's weights and
the log standard deviation: data, not a pickle). The policy acts deterministically (the
Gaussian's mean, clipped to [-1, 1]); the beacons share the network, so it drives any number
of beacons of a scenario whose observation and action sizes are the run's. A run trained
with ``--history K`` has memory: the policy keeps a window of the last K observations of
each row it is given, so it wants one object per beacon and episode (``agents.make_policy``
gives one), the same rows at each step, and ``reset()`` at an episode's start. Acting needs
torch only (not torchrl). A run trained with ``--role`` reads its beacon's index too
(``role_input``): it is bound to the beacon ``load``'s ``agent`` names, as a window is to
one beacon. The network (``mlp``) is defined here and the trainer builds its
actor from it, so loading a policy never imports the trainer.

A run trained with ``--entity`` reads entity observations (``coopnav_env.entity_obs``)
through ``entity_net``: ``agents.entity``'s permutation-invariant encoder, then the MLP. It
loads as an ``agents.entity.EntityPolicy`` bound to a team and a beacon (its role input),
so it drives any team the entity view reads (1-5 survey vehicles, 1-3 beacons), as the SB3
entity policies do.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from coopnav_env.views import check_observation

from .formats import PolicyFormatError
from .policy import BatchPolicy

if TYPE_CHECKING:
    from coopnav_env.scenarios import ScenarioConfig

RUN_RECORD = "run.json"
WEIGHTS = "actor.safetensors"
TRAINER = "batched_ppo"  # agents.training.batched_ppo.TRAINER

__all__ = ["BatchedPPOPolicy", "entity_net", "is_batched_path", "load", "make_policy", "push_window", "role_input"]


def _record(directory: Path) -> dict | None:
    from .formats import safe_json

    try:
        record = safe_json(directory / RUN_RECORD)
    except (OSError, ValueError):
        return None
    return record if isinstance(record, dict) and record.get("trainer") == TRAINER else None


def _tanh_module() -> Any:
    """tanh as 2 sigmoid(2x) - 1 (the same function; float32 results within 2e-7 of
    ``torch.tanh``), with the derivative 1 - y^2 from the output. On this machine's CPU
    torch's tanh costs 15 ms on a 32,768 x 128 batch and its sigmoid 2 ms, and the
    activations were a third of the update."""
    import torch
    from torch import nn

    class _Tanh(torch.autograd.Function):
        @staticmethod
        def forward(ctx: Any, x: Any) -> Any:
            y = torch.sigmoid(x * 2.0).mul_(2.0).sub_(1.0)
            ctx.save_for_backward(y)
            return y

        @staticmethod
        def backward(ctx: Any, grad: Any) -> Any:
            (y,) = ctx.saved_tensors
            return grad * (1.0 - y * y)

    class Tanh(nn.Module):
        def forward(self, x: Any) -> Any:
            return _Tanh.apply(x)

    return Tanh()


def mlp(n_in: int, net: Sequence[int], n_out: int, out_gain: float) -> Any:
    """Linear-tanh layers with orthogonal initialisation (gain sqrt 2, the output ``out_gain``)."""
    import torch
    from torch import nn

    layers: list[nn.Module] = []
    for h in net:
        layer = nn.Linear(n_in, h)
        nn.init.orthogonal_(layer.weight, math.sqrt(2))
        nn.init.zeros_(layer.bias)
        layers += [layer, _tanh_module()]
        n_in = h
    out = nn.Linear(n_in, n_out)
    nn.init.orthogonal_(out.weight, out_gain)
    nn.init.zeros_(out.bias)
    return nn.Sequential(*layers, out).to(torch.float32)


def entity_net(entity: dict, net: Sequence[int], n_out: int, out_gain: float, history: int = 1) -> Any:
    """The entity encoder (``agents.entity.EntityEncoder(**entity)``) applied to each of the
    ``history`` entity observations of a window (..., history x ENTITY_DIM), newest first,
    and ``mlp`` on their features side by side (..., history x features): with ``history`` 1
    SB3's ``EntityExtractor`` then ``mlp_extractor`` then the output layer, so an SB3 entity
    policy's weights map onto it (``agents.training.batched_ppo.load_sb3_actor``). Modules
    ``encoder`` and ``head``."""
    from torch import nn

    from coopnav_env.entity_obs import ENTITY_DIM

    from .entity import EntityEncoder

    class EntityNet(nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.encoder = EntityEncoder(**entity)
            self.head = mlp(self.encoder.features_dim * history, net, n_out, out_gain)

        def forward(self, x: Any) -> Any:
            lead = x.shape[:-1]
            features = self.encoder(x.reshape(-1, ENTITY_DIM))  # every window slot of every row
            return self.head(features.reshape(*lead, history * self.encoder.features_dim))

    return EntityNet()


def push_window(window: Any, obs: Any, first: Any) -> Any:
    """The window (..., K, O) of the last K observations, newest first, after ``obs``
    (..., O): shifted by one with ``obs`` in front; where ``first`` (the leading axis: an
    episode's first step) every slot holds ``obs``, so no episode sees another's
    observations. A new tensor. Training (``agents.training.batched_ppo``, windows (B, N, K,
    O)) and acting (``BatchedPPOPolicy``, (M, K, O)) share it."""
    import torch

    out = torch.cat([obs.unsqueeze(-2), window[..., :-1, :]], dim=-2)
    if first.any():
        fresh = obs[first].unsqueeze(-2)
        out[first] = fresh.expand(*fresh.shape[:-2], window.shape[-2], fresh.shape[-1])
    return out


def role_input(x: Any, slots: int, beacon: int | None = None) -> Any:
    """The actor's input ``x`` with its beacon's role after it: a one-hot of the beacon's index
    among ``slots`` (agent identity, for beacons a shared network must tell apart). With
    ``beacon`` None, ``x`` is (..., n, F), one row per beacon of a team of n <= ``slots``
    (training: beacon j gets one-hot j); else ``x`` is (..., F), rows of that one beacon
    (acting). A new tensor (..., F + slots). Training (``agents.training.batched_ppo``) and
    acting share it."""
    import torch

    if beacon is None:
        onehot = torch.eye(slots, dtype=x.dtype)[: x.shape[-2]]
    else:
        onehot = torch.zeros(slots, dtype=x.dtype)
        onehot[beacon] = 1.0
    return torch.cat([x, onehot.expand(*x.shape[:-1], slots)], dim=-1)


def is_batched_path(path: Any) -> bool:
    """Whether ``path`` is a batched_ppo run folder (no import of torch)."""
    directory = Path(str(path))
    if not (directory.is_dir() and (directory / RUN_RECORD).is_file() and (directory / WEIGHTS).is_file()):
        return False
    return _record(directory) is not None


class BatchedPPOPolicy(BatchPolicy):
    """The actor of a batched_ppo run (see the module docstring)."""

    def __init__(self, directory: Path, record: dict, config: ScenarioConfig | None) -> None:
        import torch
        from safetensors.torch import load_file

        self.name = directory.name
        self.record = record
        self.run_config = record
        self.config = config
        try:
            self.obs_dim = int(record["obs_dim"])
            self.action_dim = int(record["action_dim"])
            net = [int(h) for h in record["config"]["net"]]
            self.history = int(record["config"].get("history", 1))  # runs before the option: 1
            self.entity = record["config"].get("entity")  # None: flat observations
            self.role_slots = int(record.get("role_slots", 0))  # 0: no role input (runs before --role too)
        except (KeyError, TypeError, ValueError, AttributeError):
            raise PolicyFormatError(f"{directory / RUN_RECORD} lacks obs_dim, action_dim or config.net") from None
        if self.history < 1:
            raise PolicyFormatError(f"{directory / RUN_RECORD}: config.history must be >= 1, got {self.history}")
        if not 0 <= self.role_slots <= 64 or (self.role_slots and self.entity is not None):
            raise PolicyFormatError(f"{directory / RUN_RECORD}: role_slots must be in 0..64 (0 with entity)")
        self.agent = 0  # the beacon whose role this object plays (load's agent; with role_slots)
        if self.entity is not None:  # reads entity observations (bound to a team by EntityPolicy)
            try:
                self.actor = entity_net(dict(self.entity), net, self.action_dim, 0.01, self.history)
            except (TypeError, ValueError) as err:
                raise PolicyFormatError(f"{directory / RUN_RECORD}: config.entity {self.entity!r}: {err}") from None
            self.config = None
        else:
            self.actor = mlp(self.obs_dim * self.history + self.role_slots, net, self.action_dim, 0.01)
        weights = load_file(str(directory / WEIGHTS))
        state = {k[len("actor.") :]: v for k, v in weights.items() if k.startswith("actor.")}
        try:
            self.actor.load_state_dict(state)
        except RuntimeError as err:
            first = str(err).strip().splitlines()[0]
            raise PolicyFormatError(f"{directory / WEIGHTS} does not fit the run's network {net}: {first}") from None
        self.actor.eval()
        self._torch = torch
        self.obs_mean = weights.get("obs_mean")  # None: trained on raw observations
        self.obs_std = None if self.obs_mean is None else torch.sqrt(weights["obs_var"] + 1e-8)
        if self.obs_mean is not None and self.obs_mean.shape != (self.obs_dim,):
            raise PolicyFormatError(f"{directory / WEIGHTS}: obs_mean has shape {tuple(self.obs_mean.shape)}")

        self._window: Any = None  # with history > 1: the last observations of each row (M, K, O)

    def fork(self) -> BatchedPPOPolicy:
        """The same network with a memory of its own (for another beacon or episode)."""
        import copy

        other = copy.copy(self)
        other._window = None
        return other

    def reset(self, seed: int | None = None) -> None:
        """Clear the memory (with ``history`` > 1 the next step is an episode's first: its
        observation fills the window, as in training's ``push_window``)."""
        self._window = None

    def act_batch(self, obs: np.ndarray) -> np.ndarray:
        obs = check_observation(obs, self.obs_dim, batch=True)  # shape and finite, one line
        torch = self._torch
        x = torch.as_tensor(obs, dtype=torch.float32)
        if self.obs_mean is not None:  # as training scaled them (agents.training.batched_ppo.RunningNorm)
            x = ((x - self.obs_mean) / self.obs_std).clamp(-10.0, 10.0)
        if self.history > 1:  # the window, newest first (an episode's first step fills it)
            w = self._window
            first = w is None or w.shape[0] != x.shape[0]
            if first:
                w = torch.zeros((x.shape[0], self.history, x.shape[1]))
            self._window = w = push_window(w, x, torch.full((x.shape[0],), first))
            x = w.reshape(x.shape[0], -1)
        if self.role_slots:  # its beacon's index, as training gave it (role_input)
            x = role_input(x, self.role_slots, self.agent)
        with torch.no_grad():
            mean = self.actor(x).numpy()
        return np.clip(mean, -1.0, 1.0).astype(np.float32)

    def config_problem(self, config: Any) -> str | None:
        from coopnav_env.views import action_dim

        if self.entity is not None:  # the entity form has one size for every team
            from agents.entity import EntityPolicy

            return EntityPolicy(self).config_problem(config)
        problem = super().config_problem(config)
        if problem is None and action_dim(config) != self.action_dim:
            return f"takes actions of size {self.action_dim}; scenario {config.name!r} has {action_dim(config)}"
        return problem

    def __repr__(self) -> str:
        memory = f", history={self.history}" if self.history > 1 else ""
        entity = f", entity={self.entity.get('encoder')}" if self.entity is not None else ""
        role = f", role={self.agent} of {self.role_slots}" if self.role_slots else ""
        return f"BatchedPPOPolicy({self.name!r}, critic={self.record['config'].get('critic')}{memory}{entity}{role})"


def load(path: str | Path, scenario: Any = None, agent: int = 0) -> BatchPolicy:
    """The policy of the run at ``path``, bound to ``scenario`` (a name, a ScenarioConfig or
    an env; default: the scenario it trained on, with its parameters). One line
    (``ValueError``) if it cannot drive it. A run of entity observations is an
    ``agents.entity.EntityPolicy`` for beacon ``agent`` of that team; any other run ignores
    ``agent`` unless it was trained with a role input (``--role``: ``agent`` is then the
    beacon's index it is given), else the beacons share the network and its input has no role."""
    from coopnav_env.scenarios import make_config, resolve_config

    directory = Path(str(path))
    record = _record(directory)
    if record is None:
        raise PolicyFormatError(f"{directory} is not a batched_ppo run (run.json with trainer: batched_ppo)")
    if scenario is None:
        run = record.get("config") or {}
        config = make_config(str(run.get("scenario")), **dict(run.get("overrides") or {}))
    else:
        config = resolve_config(scenario)
    policy = BatchedPPOPolicy(directory, record, config)
    problem = policy.config_problem(config)
    if problem:
        raise ValueError(f"{directory}: {problem}")
    if policy.entity is not None:
        from .entity import EntityPolicy

        return EntityPolicy(policy, config, agent)
    if policy.role_slots:
        if not 0 <= agent < config.n_beacons:
            raise ValueError(f"agent must be a beacon index in 0..{config.n_beacons - 1}, got {agent}")
        policy.agent = int(agent)
    return policy


def make_policy(path: str | Path, scenario: Any = None, agent: int = 0) -> BatchPolicy:
    """``agents.make_policy`` for a run folder: a fresh object (its own memory) for beacon
    ``agent`` of ``scenario``."""
    return load(path, scenario, agent)
