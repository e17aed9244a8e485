"""A permutation-invariant encoder of the entity observation (``coopnav_env.entity_obs``):
one network for any team of up to five survey vehicles and three beacons.

    from agents.entity import EntityEncoder, EntityExtractor
    enc = EntityEncoder(encoder="attention", embed_dim=64)      # a plain torch module
    features = enc(x)                                           # x (B, ENTITY_DIM) -> (B, enc.features_dim)
    PPO("MlpPolicy", MixedTeamVecEnv(...),
        policy_kwargs={"features_extractor_class": EntityExtractor,
                       "features_extractor_kwargs": {"encoder": "deepsets"}})

The own features (the beacon's state and its role: kind and index) go through an MLP;
each survey vehicle and each other beacon through an MLP of its type (shared by every
entity of that type, so an entity's embedding does not depend on its slot). The set of
embeddings is then pooled, ignoring the padded slots (their mask is 0):

* ``deepsets`` (Zaheer et al. 2017, "Deep Sets"): the masked mean and the masked max
  over the survey vehicles and over the other beacons (zeros for an empty set);
  features = [own, mean_s, max_s, mean_b, max_b], 5 x ``embed_dim``;
* ``attention`` (Vaswani et al. 2017; entity attention as in Baker et al. 2020): the
  own embedding queries every entity (``heads`` heads, padded slots masked out of the
  softmax), plus the masked mean over the survey vehicles; features = [own,
  attended, mean_s], 3 x ``embed_dim``.

Either is invariant to the order of the survey vehicles and of the other beacons, and
to what the padded slots hold (tests/test_entity.py checks both to 1e-6). The
entities' kinds are in their features and the role in the own features, so two ASVs
of one team (sousa_ping) see different inputs.

``EntityExtractor`` is the SB3 ``BaseFeaturesExtractor`` around it; ``layout`` (saved
with a policy, ``EntityLayout.to_dict()``) must match the entity view this code builds,
or the policy is refused when it is loaded.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from torch import nn

from coopnav_env.entity_obs import LAYOUT, EntityLayout, entity_observation, team_problem
from coopnav_env.views import check_observation

from .policy import BatchPolicy

ENCODERS = ("deepsets", "attention")
MAX_EMBED_DIM = 1024
MAX_HEADS = 16

__all__ = [
    "ENCODERS",
    "EntityEncoder",
    "EntityExtractor",
    "EntityPolicy",
    "check_encoder_kwargs",
    "is_entity_model",
    "split_entities",
]


def check_encoder_kwargs(encoder: Any = "attention", embed_dim: Any = 64, heads: Any = 4, layout: Any = None) -> None:
    """Raise ``ValueError`` (one line naming the value) for settings the encoder cannot take."""
    if encoder not in ENCODERS:
        raise ValueError(f"encoder must be one of {', '.join(ENCODERS)}, got {encoder!r}")
    for name, value, high in (("embed_dim", embed_dim, MAX_EMBED_DIM), ("heads", heads, MAX_HEADS)):
        if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= high:
            raise ValueError(f"{name} must be an integer in [1, {high}], got {value!r}")
    if encoder == "attention" and embed_dim % heads:
        raise ValueError(f"embed_dim ({embed_dim}) must be a multiple of heads ({heads}) for attention")
    if layout is not None and dict(layout) != LAYOUT.to_dict():
        raise ValueError(
            f"the entity layout {dict(layout)} is not this code's ({LAYOUT.to_dict()}): a policy of another "
            "version of coopnav_env.entity_obs"
        )


def split_entities(x: torch.Tensor, layout: EntityLayout = LAYOUT) -> tuple:
    """(own, survey, survey_mask, beacons, beacon_mask) of flat entity observations
    x (B, flat_dim), as ``entity_obs.unflatten_entities`` (masks: value > 0.5)."""
    parts, i = [], 0
    for _, shape in layout.sections:
        n = 1
        for s in shape:
            n *= s
        parts.append(x[..., i : i + n].reshape(*x.shape[:-1], *shape))
        i += n
    own, survey, survey_mask, beacons, beacon_mask = parts
    return own, survey, survey_mask > 0.5, beacons, beacon_mask > 0.5


def _mlp(n_in: int, width: int) -> nn.Sequential:
    return nn.Sequential(nn.Linear(n_in, width), nn.ReLU(), nn.Linear(width, width), nn.ReLU())


def _masked_mean(e: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Mean of e (B, M, E) over the slots where mask (B, M) is True; zeros where none is."""
    m = mask.to(e.dtype).unsqueeze(-1)
    return (e * m).sum(-2) / m.sum(-2).clamp(min=1.0)


def _masked_max(e: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Max of e (B, M, E) over the slots where mask (B, M) is True; zeros where none is."""
    if e.shape[-2] == 0:
        return e.new_zeros(e.shape[:-2] + e.shape[-1:])
    filled = e.masked_fill(~mask.unsqueeze(-1), float("-inf")).amax(-2)
    return torch.where(mask.any(-1, keepdim=True), filled, torch.zeros_like(filled))


class EntityEncoder(nn.Module):
    """Flat entity observations (B, ``layout.flat_dim``) -> features (B, ``features_dim``).
    See the module docstring for ``encoder`` ("deepsets" | "attention"), ``embed_dim``
    and ``heads`` (attention only)."""

    def __init__(
        self, encoder: str = "attention", embed_dim: int = 64, heads: int = 4, layout: dict | None = None
    ) -> None:
        super().__init__()
        check_encoder_kwargs(encoder, embed_dim, heads, layout)
        self.layout = LAYOUT
        self.encoder, self.embed_dim, self.heads = encoder, int(embed_dim), int(heads)
        E = self.embed_dim
        self.own_net = _mlp(LAYOUT.own_dim, E)
        self.survey_net = _mlp(LAYOUT.survey_dim, E)
        self.beacon_net = _mlp(LAYOUT.beacon_dim, E)
        if encoder == "attention":
            self.query = nn.Linear(E, E)
            self.key = nn.Linear(E, E)
            self.value = nn.Linear(E, E)
            self.out = nn.Linear(E, E)
            self.features_dim = 3 * E
        else:
            self.features_dim = 5 * E

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        own, survey, survey_mask, beacons, beacon_mask = split_entities(x, self.layout)
        # only the slots some row of the batch fills: a slot padded in every row adds nothing to
        # any pooled value (masked out below), so it is not embedded (a mixed-team training batch
        # of one- and two-survey teams embeds 2 of the 5 survey slots)
        survey, survey_mask = _filled_slots(survey, survey_mask)
        beacons, beacon_mask = _filled_slots(beacons, beacon_mask)
        o = self.own_net(own)
        s = self.survey_net(survey)
        b = self.beacon_net(beacons)
        if self.encoder == "deepsets":
            pooled = [_masked_mean(s, survey_mask), _masked_max(s, survey_mask)]
            pooled += [_masked_mean(b, beacon_mask), _masked_max(b, beacon_mask)]
            return torch.cat([o, *pooled], -1)
        entities = torch.cat([s, b], -2)  # (B, M, E): every entity, survey vehicles first
        valid = torch.cat([survey_mask, beacon_mask], -1)
        # a row with no valid entity cannot happen (n_survey >= 1); guard the softmax anyway
        valid = valid | ~valid.any(-1, keepdim=True)
        return torch.cat([o, self._attend(o, entities, valid), _masked_mean(s, survey_mask)], -1)

    def _attend(self, own: torch.Tensor, entities: torch.Tensor, valid: torch.Tensor) -> torch.Tensor:
        """Multi-head attention of one query (the own embedding, (B, E)) over the entities
        (B, M, E), padded slots (valid False) out of the softmax (Vaswani et al. 2017, eq. 1:
        softmax(q k^T / sqrt(d)) v per head, then the output projection). The M entities are
        few: the products are summed over the head's d channels one entity at a time (a batched
        matrix product of 1 x d by d x M matrices costs several times more on the CPU)."""
        B, M, E = entities.shape
        H = self.heads
        d = E // H
        q = self.query(own).reshape(B, H, d)
        keys = self.key(entities).reshape(B, M, H, d).unbind(1)  # M of (B, H, d)
        values = self.value(entities).reshape(B, M, H, d).unbind(1)
        scores = torch.stack([(q * k).sum(-1) for k in keys], -1) / d**0.5  # (B, H, M)
        scores = scores.masked_fill(~valid.unsqueeze(1), float("-inf"))
        weights = torch.softmax(scores, -1).unbind(-1)  # M of (B, H)
        attended = sum(w.unsqueeze(-1) * v for w, v in zip(weights, values))  # (B, H, d)
        return self.out(attended.reshape(B, E))


def _filled_slots(entities: torch.Tensor, mask: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The slots (axis -2 of ``entities``, -1 of ``mask``) that at least one row fills: the
    pooled features do not depend on the others (their mask is 0 in every row). Keeps one slot
    where none is filled, so the shapes stay non-empty."""
    filled = mask.reshape(-1, mask.shape[-1]).any(0)
    if bool(filled.all()):
        return entities, mask
    if not bool(filled.any()):
        filled = torch.zeros_like(filled)
        filled[:1] = True
    return entities[..., filled, :], mask[..., filled]


class EntityExtractor(BaseFeaturesExtractor):
    """``EntityEncoder`` as an SB3 features extractor (``policy_kwargs``'
    ``features_extractor_class``; its ``features_extractor_kwargs`` are the encoder's)."""

    def __init__(
        self,
        observation_space: Any,
        encoder: str = "attention",
        embed_dim: int = 64,
        heads: int = 4,
        layout: dict | None = None,
    ) -> None:
        if tuple(observation_space.shape) != (LAYOUT.flat_dim,):
            raise ValueError(
                f"EntityExtractor reads entity observations ({LAYOUT.flat_dim},), got shape "
                f"{tuple(observation_space.shape)}: use the entity view (coopnav_env.entity_views)"
            )
        net = EntityEncoder(encoder, embed_dim, heads, layout)
        super().__init__(observation_space, net.features_dim)
        self.net = net

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        return self.net(observations)


def is_entity_model(model: Any) -> bool:
    """Whether a loaded SB3 model (``agents.LoadedModel`` or a PPO) reads entity observations."""
    return isinstance(getattr(model.policy, "features_extractor", None), EntityExtractor)


class EntityPolicy(BatchPolicy):
    """A trained entity policy (``base``: the ``agents.PPOPolicy`` of its network, which
    reads entity observations) bound to ``config`` (a ScenarioConfig; None: unbound) and
    beacon ``agent``: ``act`` takes that beacon's flat observation of ``config``.
    ``for_config(config, agent)`` binds it to another team; ``act_rows`` acts for rows
    of several beacons (a ``CoopNavVecEnv``'s, with ``entity_obs.row_agents``)."""

    def __init__(self, base: Any, config: Any = None, agent: int = 0, name: str | None = None) -> None:
        self.base = base
        self.name = name or base.name
        self.run_config = base.run_config
        self.agent = int(agent)
        # an SB3 network (agents.PPOPolicy) or a batched_ppo run's (agents.batched_policy)
        dim = getattr(base, "action_dim", None)
        self.action_dim = int(dim) if dim is not None else int(base.model.action_space.shape[0])
        self.config = None
        self.obs_dim = 0
        if config is not None:
            problem = self.config_problem(config)
            if problem is not None:
                raise ValueError(f"policy {self.name!r} {problem}")
            from coopnav_env.obs_layout import obs_dim

            self.config, self.obs_dim = config, int(obs_dim(config))
            if not 0 <= self.agent < config.n_beacons:
                raise ValueError(f"agent {agent} is not a beacon of {config.name!r} (0-{config.n_beacons - 1})")

    def config_problem(self, config: Any) -> str | None:
        """Why it cannot drive ``config``: a team the entity view does not read
        (``entity_obs.team_problem``), or another action size; None: it can."""
        problem = team_problem(config)
        if problem is not None:
            return f"(an entity policy) cannot read it: {problem}"
        from coopnav_env.views import action_dim

        if action_dim(config) != self.action_dim:
            return (
                f"(an entity policy) acts with {self.action_dim} numbers; scenario {config.name!r} takes "
                f"{action_dim(config)} (channel_mode)"
            )
        return None

    def for_config(self, config: Any, agent: int = 0) -> EntityPolicy:
        """The same network bound to ``config`` and beacon ``agent`` (a network with memory,
        a batched_ppo run's window, gets a memory of its own)."""
        fork = getattr(self.base, "fork", None)
        return EntityPolicy(fork() if fork is not None else self.base, config, agent, self.name)

    def reset(self, seed: int | None = None) -> None:
        """Clears the network's memory, if it has one (SB3's networks have none)."""
        self.base.reset(seed)

    def act_rows(self, obs: np.ndarray, agents: Any) -> np.ndarray:
        """Actions (M, action_dim) for flat observations (M, D) of the bound scenario, row i
        being beacon ``agents[i]``."""
        if self.config is None:
            raise ValueError(f"entity policy {self.name!r} is not bound to a scenario: use for_config(config, agent)")
        obs = check_observation(obs, self.obs_dim, batch=True)  # shape and finite, one line
        return self.base.act_batch(entity_observation(obs, self.config, np.asarray(agents, dtype=np.int64)))

    def act(self, obs: np.ndarray) -> np.ndarray:
        if self.config is None:
            raise ValueError(f"entity policy {self.name!r} is not bound to a scenario: use for_config(config, agent)")
        return super().act(obs)

    def act_batch(self, obs: np.ndarray) -> np.ndarray:
        obs = np.asarray(obs)
        return self.act_rows(obs, np.full(obs.shape[:1], self.agent))

    def __repr__(self):
        scen = self.config.name if self.config is not None else "unbound"
        return f"EntityPolicy({self.name!r}, scenario={scen!r}, agent={self.agent})"
