"""What the views over the batched core share: spaces, action checking, infos."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from gymnasium import spaces
from numpy.typing import ArrayLike

if TYPE_CHECKING:
    from .core.contract import BatchedSimulator
    from .scenarios import ScenarioConfig

OBS_BOUND = 10.0


def action_dim(sim_or_config: BatchedSimulator | ScenarioConfig | None = None) -> int:
    """Components of a beacon's action, as the scenario's channel model declares them
    (``core.channel`` registry): 2 (the motion), 3 with ``channel_mode="decide"`` (the
    motion, then the transmit decision: transmit this slot when it is > 0)."""
    if sim_or_config is None:
        return 2
    from .core.channel import channel_model

    config = getattr(sim_or_config, "config", sim_or_config)
    return channel_model(getattr(config, "channel_mode", "clock")).action_dim


def action_space(sim: BatchedSimulator | ScenarioConfig | None = None) -> spaces.Box:
    """Every beacon's action: numbers in [-1, 1], two for the motion (see the scenario's
    action_mode) and, with ``channel_mode="decide"``, a third: transmit when > 0."""
    return spaces.Box(-1.0, 1.0, shape=(action_dim(sim),), dtype=np.float32)


def observation_space(sim: BatchedSimulator) -> spaces.Box:
    return spaces.Box(-OBS_BOUND, OBS_BOUND, shape=(sim.obs_dim,), dtype=np.float32)


def state_space(sim: BatchedSimulator) -> spaces.Box:
    return spaces.Box(-OBS_BOUND, OBS_BOUND, shape=(sim.state_dim,), dtype=np.float32)


def check_observation(obs: ArrayLike, dim: int, batch: bool = False) -> np.ndarray:
    """An observation (``batch``: observations (M, dim)) as a float64 array, or a one-line
    ``ValueError`` for a wrong shape or a NaN/infinite value: a policy given one would
    answer with a NaN action, or fail deep inside its network. The environments never give
    one; a user's edited or hand-built observation can."""
    try:
        complex_ = np.iscomplexobj(obs)
        o = None if complex_ else np.asarray(obs, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"observation is not numeric: {obs!r:.80}") from None
    if o is None:
        raise ValueError("observation must be real, got a complex array")
    fits = (o.ndim == 2 and o.shape[1] == dim) if batch else o.shape == (dim,)
    if not fits:
        shape = f"(M, {dim})" if batch else f"({dim},)"
        raise ValueError(f"observation{'s' if batch else ''} must have shape {shape}, got {o.shape}")
    bad = np.argwhere(~np.isfinite(o))
    if bad.size:
        where = ", ".join(str(tuple(int(k) for k in i)) if batch else str(int(i[0])) for i in bad[:5])
        more = ", ..." if len(bad) > 5 else ""
        what = "(row, entry)" if batch else "entries"
        raise ValueError(f"observation must be finite, got {len(bad)} NaN or infinite value(s) ({what} {where}{more})")
    return o


def check_action(agent: str, action: ArrayLike, dim: int = 2) -> np.ndarray:
    """One agent's action as a float array of shape (dim,), clipped to [-1, 1].

    Raises ValueError naming the agent for a wrong shape or a NaN/infinite value;
    finite out-of-range values are clipped, as users of Box spaces expect. With
    ``dim=3`` (``channel_mode="decide"``) a two-component action (the motion alone)
    is accepted too and means "transmit every slot", the fixed clock.
    """
    try:
        if np.iscomplexobj(action):  # numpy would drop the imaginary part with only a warning
            raise ValueError(f"action for {agent} must be real, got {action!r}")
        a = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError) as err:
        if "must be real" in str(err):
            raise
        raise ValueError(f"action for {agent} is not numeric: {action!r}") from err
    if a.shape != (dim,) and not (dim == 3 and a.shape == (2,)):
        raise ValueError(f"action for {agent} must have shape ({dim},), got shape {a.shape}")
    if not np.isfinite(a).all():
        raise ValueError(f"action for {agent} must be finite, got {a.tolist()}")
    if a.shape != (dim,):
        a = np.append(a, 1.0)  # the motion alone: transmit, as the fixed clock does
    return np.minimum(np.maximum(a, -1.0), 1.0)


def agent_infos(info: dict, row: int, beacon_info: dict | None = None, agent: int = 0) -> dict:
    """The infos of beacon ``agent`` in environment ``row`` of a step: for each scalar
    info the mean over survey vehicles (sums for counts, any for range_ok) plus the
    per-vehicle list; the vector infos (``survey_error_en_m`` (S, 2),
    ``survey_cov_en_m2`` (S, 2, 2)) as nested lists per survey vehicle; then the beacon's own
    (``beacon_error_m``)."""
    out = {}
    for key in info:
        if info[key].ndim > 2:  # a vector per survey vehicle
            out[key] = info[key][row].tolist()
            continue
        values = info[key][row].tolist()
        if key == "range_ok":
            out[key] = any(values)
        elif isinstance(values[0], float):
            out[key] = sum(values) / len(values)
        else:
            out[key] = int(sum(values))
        out[key + "_per_vehicle"] = values
    for key, v in (beacon_info or {}).items():
        out[key] = float(v[row, agent])
    return out
