"""Where a batched PPO run starts (``--init-from``): the actor of an SB3 policy (flat or
entity), of a shipped policy or of a run of the loop itself, as the loop's tensors, the first
layer widened to the run's window of observations (``widen_to_history``) and a loop run's
hidden layers to the run's ``--net`` (``widen_layers``)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from agents.batched_policy import WEIGHTS, is_batched_path

from .loop_config import ENTITY


def load_sb3_actor(
    source: str,
    scenario: str,
    net: Sequence[int],
    obs_dim: int,
    action_dim: int,
    reward_terms: dict[str, float] | None = None,
    history: int = 1,
    entity: dict[str, Any] | None = None,
    role_slots: int = 0,
) -> dict:
    """The actor of a train.py run, a run of this loop or a shipped policy (``agents.resolve``:
    a name such as ``ppo_gao_team``, ``ppo`` for the scenario's, or a run folder) as this
    loop's tensors:
    ``{"actor": state_dict of mlp(obs_dim, net, action_dim), "log_std", "obs_mean",
    "obs_var", "obs_count", "ret_var", "ret_count"}``. SB3's flat ``MlpPolicy`` with tanh
    (``mlp_extractor.policy_net`` then ``action_net``) is the same function as ``mlp``'s
    Linear-tanh stack, and VecNormalize's scaling is ``RunningNorm``'s, so the loop starts
    where that policy stands. The return's statistics (``ret_var``, ``ret_count``) come only
    when the run trains on the reward that policy was trained on (``reward_terms`` against its
    config.yml's ``reward``; None and {} both the environment's): another reward has another
    scale. With ``history`` > 1 the first layer is widened to the window with zeros
    (``widen_to_history``): the actor starts as the policy was; with ``role_slots`` a role input
    of that size is added after the window, its weights zero (``add_role``). With ``entity`` (the run's
    encoder settings) the policy must be an SB3 entity policy with that encoder: its
    ``pi_features_extractor`` becomes ``entity_net``'s ``encoder``, its MLP the ``head``
    (``{"actor": state_dict of entity_net(...)}``; no observation statistics, since the
    entity features are not normalized). A loop run's actor is read from its folder
    (``_load_loop_actor``). A ``ValueError`` (one line) names what does not fit."""
    import torch

    from agents import resolve
    from agents.formats import read_model, read_vecnormalize, safe_yaml

    model, stats, config_file = resolve(source, scenario)
    if Path(str(model)).name == WEIGHTS and is_batched_path(Path(str(model)).parent):
        return _load_loop_actor(source, Path(str(model)).parent, net, obs_dim, action_dim, history, entity, role_slots)
    if Path(str(model)).suffix != ".safetensors":
        raise ValueError(f"--init-from {source}: {model} is not an SB3 model file (a flat MlpPolicy run or policy)")
    spec, state, _ = read_model(model)
    kwargs = spec.get("policy_kwargs") or {}
    if spec.get("policy") != "MlpPolicy" or kwargs.get("activation_fn", "tanh") != "tanh":
        raise ValueError(
            f"--init-from {source}: {spec.get('policy')} with {kwargs.get('activation_fn')}; "
            "only SB3's MlpPolicy with tanh maps onto this loop's actor"
        )
    extractor = kwargs.get("features_extractor_class")
    if (extractor == "EntityExtractor") != (entity is not None):
        raise ValueError(
            f"--init-from {source}: an entity policy (EntityExtractor): add --entity"
            if extractor == "EntityExtractor"
            else f"--init-from {source}: a flat policy ({extractor or 'no features extractor'}); --entity needs an "
            "entity policy (ppo_gao_sea, ppo_gao_lawnmower, ...)"
        )
    if entity is not None:
        from agents.entity import check_encoder_kwargs

        fe_kwargs = dict(kwargs.get("features_extractor_kwargs") or {})
        check_encoder_kwargs(**fe_kwargs)  # its layout is this code's entity view
        own = {k: v for k, v in fe_kwargs.items() if k != "layout"}
        if {**ENTITY, **own} != entity:
            raise ValueError(f"--init-from {source}: its encoder is {own}, the run's {entity}")
    widths = [int(state[f"mlp_extractor.policy_net.{2 * i}.weight"].shape[0]) for i in range(len(net))]
    if tuple(widths) != tuple(net) or f"mlp_extractor.policy_net.{2 * len(net)}.weight" in state:
        arch = kwargs.get("net_arch")
        raise ValueError(f"--init-from {source}: its actor is {arch}, the loop's --net {','.join(map(str, net))}")
    n_in = int(state["mlp_extractor.policy_net.0.weight"].shape[1])
    if entity is not None:  # the MLP reads the encoder's features; the policy reads entity observations
        n_in = int((spec.get("observation_space") or {}).get("shape", [-1])[0])
    n_out = int(state["action_net.weight"].shape[0])
    if (n_in, n_out) != (obs_dim, action_dim):
        raise ValueError(
            f"--init-from {source}: observations {n_in} and actions {n_out}, the environment's {obs_dim} and "
            f"{action_dim} (a policy of another scenario or observation?)"
        )
    head = "head." if entity is not None else ""  # entity_net's MLP is its module "head"
    actor = {}
    for i in range(len(net)):
        for part in ("weight", "bias"):
            actor[f"{head}{2 * i}.{part}"] = state[f"mlp_extractor.policy_net.{2 * i}.{part}"]
    for part in ("weight", "bias"):
        actor[f"{head}{2 * len(net)}.{part}"] = state[f"action_net.{part}"]
    actor[f"{head}0.weight"] = add_role(widen_to_history(actor[f"{head}0.weight"], history), role_slots)
    if entity is not None:  # SB3 shares one extractor between actor and critic; the actor's copy
        prefix = next(
            p for p in ("pi_features_extractor.net.", "features_extractor.net.") if any(k.startswith(p) for k in state)
        )
        actor.update({"encoder." + k[len(prefix) :]: v for k, v in state.items() if k.startswith(prefix)})
    out: dict[str, Any] = {"actor": actor, "log_std": state["log_std"]}
    if stats is not None:
        vn = read_vecnormalize(stats)
        if entity is None:
            out.update(
                obs_mean=torch.as_tensor(vn["obs_mean"], dtype=torch.float64),
                obs_var=torch.as_tensor(vn["obs_var"], dtype=torch.float64),
                obs_count=vn["obs_count"],
            )
        trained_on = None
        if config_file is not None and Path(config_file).is_file():
            hyper = (safe_yaml(config_file) or {}).get("hyperparameters") or {}
            trained_on = {k: float(v) for k, v in (hyper.get("reward") or {}).items()}
        if trained_on is not None and trained_on == dict(reward_terms or {}):
            out.update(
                ret_var=torch.as_tensor(vn["ret_var"], dtype=torch.float64).reshape(()), ret_count=vn["ret_count"]
            )
    return out


def widen_to_history(weight: Any, history: int, own: int = 1) -> Any:
    """A first layer's weight (H, own x O), for a window of ``own`` observations, widened to a
    window of ``history`` (H, history x O), newest first: the columns it had are kept and the
    older observations' are zeros, so the widened actor is the same function of the
    observations it read and learns what the older ones are worth. With ``history`` equal to
    ``own`` the weight is returned as it is."""
    import torch

    if not 1 <= own <= history:
        raise ValueError(f"a window of {own} observations cannot be widened to {history}")
    n_out, n_in = weight.shape
    if history == own:
        return weight
    wide = torch.zeros((n_out, n_in // own * history), dtype=weight.dtype)
    wide[:, :n_in] = weight
    return wide


def add_role(weight: Any, slots: int, role: Any = None) -> Any:
    """A first layer's weight (H, F) followed by the columns of a role input of ``slots``
    (``agents.batched_policy.role_input``): ``role`` (H, slots), a run's own, or zeros, so the
    actor is the same function of what it read and learns what its beacon's index is worth.
    With ``slots`` 0 the weight itself."""
    import torch

    if not slots:
        return weight
    if role is None:
        role = torch.zeros((weight.shape[0], slots), dtype=weight.dtype)
    return torch.cat([weight, role], dim=1)


def widen_layers(actor: dict, own: Sequence[int], net: Sequence[int], prefix: str = "", seed: int = 0) -> dict:
    """A Linear-tanh stack's weights (``mlp``'s keys ``{prefix}0.weight``, ``{prefix}2.weight``,
    ...) with hidden layers ``own`` widened to ``net`` (as wide or wider, the same depth) by
    Net2WiderNet (Chen, Goodfellow & Shlens 2016): each new unit copies a unit of its layer,
    drawn at random, incoming weights and bias, and the copies of a unit share its outgoing
    weights in random parts that sum to one, so the wider stack is the same function. The
    shares differ, so the copies' gradients differ in size and they part once trained (equal
    halves would keep them equal forever)."""
    import torch

    if len(own) != len(net) or any(n < o for o, n in zip(own, net)):
        raise ValueError(f"layers {list(own)} cannot be widened to {list(net)} (the same depth, each as wide or wider)")
    gen = torch.Generator().manual_seed(seed)
    out = dict(actor)
    for i, (h_old, h_new) in enumerate(zip(own, net)):
        if h_new == h_old:
            continue
        src = torch.cat([torch.arange(h_old), torch.randint(h_old, (h_new - h_old,), generator=gen)])
        weight, bias, after = (out[f"{prefix}{k}"] for k in (f"{2 * i}.weight", f"{2 * i}.bias", f"{2 * i + 2}.weight"))
        parts = torch.rand(h_new, generator=gen, dtype=torch.float64) + 0.5  # each copy's part, before scaling
        totals = torch.zeros(h_old, dtype=torch.float64).index_add_(0, src, parts)
        share = (parts / totals[src]).to(after.dtype)  # a unit's copies: parts summing to one
        out[f"{prefix}{2 * i}.weight"] = weight[src].clone()
        out[f"{prefix}{2 * i}.bias"] = bias[src].clone()
        out[f"{prefix}{2 * i + 2}.weight"] = after[:, src] * share
    return out


def _load_loop_actor(
    source: str,
    directory: Path,
    net: Sequence[int],
    obs_dim: int,
    action_dim: int,
    history: int,
    entity: dict[str, Any] | None = None,
    role_slots: int = 0,
) -> dict:
    """``load_sb3_actor``'s tensors from a run of this loop (``actor.safetensors``,
    ``run.json``): its actor (widened to ``history`` if its own window is shorter), log std and
    observation scaling with its count (runs saved before the count was kept: their
    env-steps), so the scaling moves as slowly as it did. Its return's scale is not kept by a
    run, so it starts anew."""
    import torch
    from safetensors.torch import load_file

    from agents.formats import safe_json

    record = safe_json(directory / "run.json")
    run = record.get("config") or {}
    own = [int(h) for h in run.get("net") or ()]
    wider = len(own) == len(net) and all(n >= o for o, n in zip(own, net)) and entity is None
    if tuple(own) != tuple(net) and not wider:
        raise ValueError(
            f"--init-from {source}: its actor is {own}, the loop's --net {','.join(map(str, net))} "
            f"(a flat actor can be widened: {len(own)} layers, each at least as wide)"
        )
    if (int(record.get("obs_dim", -1)), int(record.get("action_dim", -1))) != (obs_dim, action_dim):
        raise ValueError(
            f"--init-from {source}: observations {record.get('obs_dim')} and actions {record.get('action_dim')}, "
            f"the environment's {obs_dim} and {action_dim} (a policy of another scenario or observation?)"
        )
    if run.get("entity") != entity:
        raise ValueError(f"--init-from {source}: its entity encoder is {run.get('entity')}, the run's {entity}")
    own_history = int(run.get("history", 1))
    if own_history > history:
        raise ValueError(
            f"--init-from {source}: its window is {own_history} observations, the run's --history {history} "
            f"(give --history {own_history} or more: a window widens, it does not narrow)"
        )
    own_role = int(record.get("role_slots", 0))
    if own_role and own_role != role_slots:
        raise ValueError(
            f"--init-from {source}: its role input is for {own_role} beacons, the run's "
            + (f"for {role_slots}" if role_slots else "none (give --role)")
        )
    weights = load_file(str(directory / WEIGHTS))
    actor = {k[len("actor.") :]: v for k, v in weights.items() if k.startswith("actor.")}
    first = "head.0.weight" if entity is not None else "0.weight"
    window, role = actor[first], None
    if own_role:  # the window's columns widen; the role's are kept after them
        window, role = window[:, :-own_role], window[:, -own_role:]
    actor[first] = add_role(widen_to_history(window, history, own_history), role_slots, role)
    if tuple(own) != tuple(net):  # a wider actor, the same function (Net2WiderNet)
        actor = widen_layers(actor, own, net)
    out: dict[str, Any] = {"actor": actor, "log_std": weights["log_std"]}
    if "obs_mean" in weights:
        out.update(
            obs_mean=weights["obs_mean"].to(torch.float64),
            obs_var=weights["obs_var"].to(torch.float64),
            obs_count=float(weights["obs_count"][0]) if "obs_count" in weights else float(record.get("steps", 1)),
        )
    return out
