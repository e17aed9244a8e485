"""The reward: a weighted sum of named terms, declared once in a registry.

Every simulator puts its terms, unweighted, in ``StepResult.terms`` (name -> (B, N)
array, one value per beacon); ``weighted_reward`` turns them into the environment's
reward with the scenario's weights, and it is the only place that does. The
PettingZoo env, the SB3 VecEnv, the RLlib adapter and the evaluation all read the
reward or its terms from the step result.

**The registry.** A term is registered once (:func:`register_term`) with its name,
the scenario parameter that weighs it and the weight's sign, whether it is a penalty,
the networks and modes it applies to, its documentation line and, optionally, a
``compute(ctx)`` hook that computes it in Python from the step's arrays. Everything
else derives from the registry: ``TERM_WEIGHTS``, ``PENALTY_TERMS``, the simulators'
term tuples (``SURVEY_TERMS``, ``CHANNEL_TERMS``, ``MOVING_NETWORK_TERMS``,
``RIVER_NETWORK_TERMS``; read when accessed, so they follow the registry),
:func:`terms_for` (what a simulator asks), :func:`term_weights`, :func:`penalties`
and the documentation tables (:func:`markdown_table`, rendered into the docs by
``docs/hooks/generate.py``: ``<!-- generated: REWARD_TERMS -->``).

Two kinds of term share the registry:

* ``kind="env"``: the environment's reward terms, which the simulators return;
* ``kind="training"``: the training signals a trainer may use instead of the
  environment's reward (``CoopNavVecEnv(reward_terms={"error": 1.0, ...})``, train.py's
  YAML ``reward:``, the RLlib adapter): each a ``compute(ctx)`` over the step's
  ``StepResult`` (``ctx.result``) and the scenario's weights (``ctx.weights``),
  summed by :func:`training_reward` and validated by :func:`check_training_terms`
  (``<!-- generated: TRAINING_SIGNALS -->``).

A new term (say ``depth_limit``, weighed by a scenario field ``depth_limit_penalty``)::

    from coopnav_env.core.reward import register_term

    register_term("depth_limit", weight="depth_limit_penalty", penalty=True,
                  networks=("survey_beacons",),
                  doc="1 if a survey vehicle is deeper than ``max_depth_m``",
                  compute=lambda ctx: (ctx.state.s_pos[..., 2] > 50.0).any(-1)[:, None] * 1.0)
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Any

import numpy as np

from ..names import did_you_mean

KINDS = ("env", "training")
SURVEY_NETWORK, MOVING_NETWORK = "survey_beacons", "moving_lbl"  # ScenarioConfig.network


@dataclass(frozen=True)
class TermContext:
    """What a term's ``compute`` hook reads.

    For an environment term (kind "env", called by the simulator once per step after
    its own arrays): ``sim`` the simulator, ``config`` its scenario, ``state`` its
    ``SimState`` after the step, ``terms`` the terms computed so far (name -> (B, N)),
    ``arrays`` the step's other named arrays (the survey simulator: ``fused``,
    ``rejected``, ``lost`` (B, N, S) flags, ``transmit`` (B, N) or None, ``dist``
    (B, N, S) beacon-to-survey distances, ``info_gain`` (B,): the drop of the survey
    filters' log det over the cycle's acoustic updates).
    For a training signal (kind "training"): ``result`` the step's ``StepResult`` and
    ``weights`` the scenario's weights of its environment terms.
    """

    sim: Any = None
    config: Any = None
    state: Any = None
    terms: Mapping[str, np.ndarray] = field(default_factory=dict)
    arrays: Mapping[str, Any] = field(default_factory=dict)
    result: Any = None
    weights: Mapping[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class RewardTerm:
    """One registered term (see :func:`register_term` for the fields' meaning)."""

    name: str
    doc: str
    weight: str | None = None
    sign: float = -1.0
    penalty: bool = False
    networks: tuple = (SURVEY_NETWORK, MOVING_NETWORK)
    modes: Mapping[str, tuple] = field(default_factory=dict)
    compute: Callable[[TermContext], Any] | None = None
    kind: str = "env"

    def applies_to(self, config: Any, network: str | None = None) -> bool:
        """Whether a simulator of ``network`` (default ``config.network``) running
        ``config`` returns this term: the network is one of ``networks`` and every
        ``modes`` parameter has one of the listed values."""
        network = getattr(config, "network", None) if network is None else network
        return (
            self.kind == "env"
            and network in self.networks
            and all(getattr(config, k, None) in v for k, v in self.modes.items())
        )

    def weight_of(self, config: Any) -> float:
        """The scenario's weight: ``sign`` x the weight parameter's value (``sign`` alone
        when the term has no weight parameter)."""
        return self.sign * (1.0 if self.weight is None else float(getattr(config, self.weight)))

    def weight_text(self) -> str:
        """The weight as the docs show it: ``+1``, ``-``safety_penalty`````."""
        s, mag = ("-" if self.sign < 0 else "+"), abs(self.sign)
        if self.weight is None:
            return f"{s}{mag:g}"
        return f"{s}``{self.weight}``" if mag == 1.0 else f"{s}{mag:g} x ``{self.weight}``"

    def applies_text(self) -> str:
        """Where the term applies, as the docs show it."""
        if self.kind == "training":
            return "training signal"
        nets = {SURVEY_NETWORK: "survey network", MOVING_NETWORK: "moving network"}
        out = " and ".join(nets.get(n, n) for n in self.networks)
        for k, v in self.modes.items():
            out += f", ``{k}`` " + " or ".join(f'``"{x}"``' for x in v)
        return out


_TERMS: dict[str, RewardTerm] = {}


def register_term(
    name: str,
    *,
    doc: str,
    weight: str | None = None,
    sign: float | None = None,
    penalty: bool = False,
    networks: tuple = (SURVEY_NETWORK, MOVING_NETWORK),
    modes: Mapping[str, tuple] | None = None,
    compute: Callable[[TermContext], Any] | None = None,
    kind: str = "env",
) -> RewardTerm:
    """Register a reward term (or, ``kind="training"``, a training signal) and return it.

    ``weight``: the scenario parameter whose value weighs the term (None: weight 1);
    ``sign``: the weight's sign (default -1 with a weight parameter, a cost; +1 without);
    ``penalty``: counted by :func:`penalties` (the training signal ``penalties``);
    ``networks``: the ``ScenarioConfig.network`` values whose simulator returns it;
    ``modes``: scenario parameter -> the values it needs (``{"channel_mode": ("decide",)}``);
    ``doc``: one sentence for the docs' table (reST inline markup);
    ``compute(ctx: TermContext) -> (B, N) or broadcastable``: for terms that are not one of
    the simulator's own arrays (a kind "training" signal must have one).
    Terms keep their registration order: the weighted sum adds them in that order.
    """
    if not isinstance(name, str) or not name.isidentifier():
        raise ValueError(f"reward term name must be an identifier, got {name!r}")
    if name in _TERMS:
        raise ValueError(f"reward term {name!r} is registered twice")
    if kind not in KINDS:
        raise ValueError(f"reward term {name!r}: kind must be one of {', '.join(KINDS)}, got {kind!r}")
    if kind == "training" and compute is None:
        raise ValueError(f"training signal {name!r} needs a compute(ctx) hook")
    from ..scenarios.base import parameter_names

    params = set(parameter_names())
    for p in ([weight] if weight is not None else []) + list(modes or {}):
        if p not in params:
            raise ValueError(f"reward term {name!r}: {p!r} is not a scenario parameter (ScenarioConfig field)")
    if sign is None:
        sign = 1.0 if weight is None else -1.0
    term = RewardTerm(
        name=name,
        doc=doc,
        weight=weight,
        sign=float(sign),
        penalty=bool(penalty),
        networks=tuple(networks),
        modes=dict(modes or {}),
        compute=compute,
        kind=kind,
    )
    _TERMS[name] = term
    return term


def unregister_term(name: str) -> None:
    """Remove a registered term (tests, plug-ins that clean up after themselves)."""
    _TERMS.pop(name, None)


def get_term(name: str) -> RewardTerm:
    """The registered term ``name`` (``KeyError`` listing the valid ones)."""
    try:
        return _TERMS[name]
    except KeyError:
        hint = did_you_mean(name, _TERMS)
        raise KeyError(f"unknown reward term {name!r}{hint} registered: {', '.join(_TERMS)}") from None


def registered_terms(kind: str | None = "env") -> tuple[RewardTerm, ...]:
    """The registered terms of ``kind`` (None: all), in registration order."""
    return tuple(t for t in _TERMS.values() if kind is None or t.kind == kind)


def terms_for(config: Any, network: str | None = None) -> tuple[str, ...]:
    """The names of the environment terms a simulator returns for ``config``, in the
    order the weighted sum adds them. ``network``: the simulator's own network
    (``"survey_beacons"`` for ``core.sim``, ``"moving_lbl"`` for ``core.moving_network``),
    which it passes since it may run a config of the other network (default
    ``config.network``)."""
    return tuple(t.name for t in registered_terms("env") if t.applies_to(config, network))


def term_weights(config: Any, terms: Iterable[str]) -> dict[str, float]:
    """The scenario's weight of each term in ``terms``: name -> float."""
    return {t: _TERMS[t].weight_of(config) for t in terms}


def weighted_reward(terms: Mapping[str, np.ndarray], weights: Mapping[str, float]) -> np.ndarray:
    """sum_k weights[k] * terms[k], in ``weights``' order: (B, N)."""
    total: np.ndarray | None = None
    for name, w in weights.items():
        part = w * terms[name]
        total = part if total is None else total + part
    assert total is not None, "weighted_reward: no weights (a simulator has at least one term)"
    return total


def penalties(terms: Mapping[str, np.ndarray], weights: Mapping[str, float]) -> np.ndarray | float:
    """The weighted penalty terms (the registered penalties present in ``weights``) as a
    positive cost (B, N) (0.0 when none is present): what the training signal ``penalties`` subtracts."""
    out: np.ndarray | float = 0.0
    for t in registered_terms("env"):
        if t.penalty and t.name in weights:
            out = out - weights[t.name] * terms[t.name]
    return out


def has_hooks(names: Iterable[str]) -> bool:
    """Whether any of the terms ``names`` is computed by a ``compute`` hook (a simulator
    builds the hooks' ``TermContext`` only then: the built-in terms need none)."""
    return any(_TERMS[name].compute is not None for name in names)


def collect_terms(
    names: Iterable[str], arrays: Mapping[str, np.ndarray], ctx: TermContext, shape: tuple
) -> dict[str, np.ndarray]:
    """The step's terms by name, in ``names``' order: a registered term with a ``compute``
    hook is computed from ``ctx`` (with the terms so far, as floats of ``shape``);
    the others are the simulator's own ``arrays`` by name."""
    out: dict = {}
    for name in names:
        term = _TERMS[name]
        if term.compute is None:
            if name not in arrays:
                raise KeyError(f"reward term {name!r} has no compute hook and the simulator does not compute it")
            out[name] = arrays[name]
        else:
            value = term.compute(
                TermContext(sim=ctx.sim, config=ctx.config, state=ctx.state, terms=dict(out), arrays=ctx.arrays)
            )
            out[name] = np.broadcast_to(np.asarray(value, dtype=float), shape)
    return out


# ------------------------------------------------------------------------------------
# training signals (kind "training")


def training_signal_names() -> tuple[str, ...]:
    """The registered training signals' names (the valid keys of ``reward_terms``)."""
    return tuple(t.name for t in registered_terms("training"))


def check_training_terms(terms: Mapping[str, float] | None) -> dict[str, float] | None:
    """``{signal: weight}`` validated (None or {} -> None: the environment's reward)."""
    if not terms:
        return None
    if not isinstance(terms, dict):
        # ValueError, not TypeError: a config error, as before
        raise ValueError(f"reward terms must be a mapping term -> weight, got {terms!r}")
    valid = training_signal_names()
    out = {}
    for name, weight in terms.items():
        if name not in valid:
            raise ValueError(f"unknown reward term {name!r}{did_you_mean(name, valid)} valid terms: {', '.join(valid)}")
        try:
            w = float(weight)
        except (TypeError, ValueError):
            raise ValueError(f"reward term {name!r}: weight must be a number, got {weight!r}") from None
        if not np.isfinite(w):
            raise ValueError(f"reward term {name!r}: weight must be finite, got {weight!r}")
        out[name] = w
    return out


def training_reward(reward_terms: Mapping[str, float], res: Any, weights: Mapping[str, float]) -> np.ndarray:
    """The weighted sum of the training signals ``reward_terms`` ({name: weight}) for one
    batched step: ``res`` the core's StepResult, ``weights`` the scenario's weights of its
    reward terms (:func:`term_weights`). Returns (B, N)."""
    B, N = res.reward.shape
    total = np.zeros((B, N))
    ctx = TermContext(result=res, weights=weights, terms=res.terms)
    for name, w in reward_terms.items():
        compute = _TERMS[name].compute
        assert compute is not None, f"{name!r}: a training signal has a compute hook (register_term checks it)"
        total += w * compute(ctx)
    return total


# ------------------------------------------------------------------------------------
# the documentation tables and the derived names


def markdown_table(kind: str = "env") -> str:
    """The registered terms of ``kind`` as a Markdown table (the docs' generated table)."""

    def md(text: str) -> str:
        return text.replace("``", "`").replace("|", "\\|")

    if kind == "training":
        rows = ["| signal | value per beacon and step |", "|---|---|"]
        rows += [f"| `{t.name}` | {md(t.doc)} |" for t in registered_terms("training")]
    else:
        rows = ["| term | value per beacon and cycle | weight | penalty | returned by |", "|---|---|---|---|---|"]
        rows += [
            f"| `{t.name}` | {md(t.doc)} | {md(t.weight_text())} | {'yes' if t.penalty else 'no'} | "
            f"{md(t.applies_text())} |"
            for t in registered_terms(kind)
        ]
    return "\n".join(rows) + "\n"


# the names that used to be written out; each access reads the registry
_DEFAULT_MODES = {"channel_mode": "clock", "mission_frame": "frame"}
_DERIVED = {
    "SURVEY_TERMS": {"network": SURVEY_NETWORK},
    "CHANNEL_TERMS": {"network": SURVEY_NETWORK, "channel_mode": "decide"},  # the survey network, channel_mode="decide"
    "MOVING_NETWORK_TERMS": {"network": MOVING_NETWORK},
    "RIVER_NETWORK_TERMS": {"network": MOVING_NETWORK, "mission_frame": "world"},  # the moving network, world frame
}


def __getattr__(name: str) -> Any:
    if name in _DERIVED:
        return terms_for(SimpleNamespace(**{**_DEFAULT_MODES, **_DERIVED[name]}))
    if name == "TERM_WEIGHTS":  # term -> the scenario parameter that weighs it (None: weight +1)
        return {t.name: t.weight for t in registered_terms("env")}
    if name == "PENALTY_TERMS":
        return tuple(t.name for t in registered_terms("env") if t.penalty)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


# ------------------------------------------------------------------------------------
# the built-in terms. Registration order is the order of the weighted sum, so these keep
# the order the simulators have always added them in (bit-identical rewards).

register_term(
    "info_gain",
    doc="information the survey filters gained from this cycle's measurements: sum over "
    "survey vehicles of log det P_before - log det P_after of the horizontal position covariance (nats; "
    "shared by the team)",
)
register_term(
    "safety",
    weight="safety_penalty",
    penalty=True,
    doc="1 if the beacon is closer than ``safety_distance_m`` to a survey vehicle",
)
register_term(
    "geofence",
    weight="geofence_penalty",
    penalty=True,
    networks=(SURVEY_NETWORK,),
    doc="1 if the beacon is outside the geofence",
)
register_term(
    "baseline",
    weight="baseline_penalty",
    penalty=True,
    networks=(MOVING_NETWORK,),
    doc="1 if the boats' baseline is off ``baseline_target_m`` by more than ``baseline_tolerance_m``",
)
register_term(
    "approach",
    weight="approach_penalty",
    penalty=True,
    networks=(MOVING_NETWORK,),
    doc="1 if the vehicle is nearer the baseline than ``min_baseline_distance_m``",
)
register_term(
    "rotation",
    weight="rotation_penalty",
    penalty=True,
    networks=(MOVING_NETWORK,),
    doc="1 if the frame turned more than ``frame_rotation_tolerance_deg`` from its start (always 0 with "
    '``mission_frame="world"``: the frame must turn with the river)',
)
register_term(
    "contact",
    weight="contact_penalty",
    doc="1 if none of its ranges was fused this cycle (moving network: none of the vehicle's); not a "
    "penalty for the training signal ``penalties``",
)
register_term(
    "ping",
    weight="ping_penalty",
    penalty=True,
    networks=(SURVEY_NETWORK,),
    modes={"channel_mode": ("decide",)},
    doc="1 if the beacon transmitted a ping this cycle: the price of the channel and of the transmit "
    "energy (``core.channel``)",
)
register_term(
    "bank",
    weight="bank_penalty",
    penalty=True,
    networks=(MOVING_NETWORK,),
    modes={"mission_frame": ("world",)},
    doc="1 if the boat is farther than ``river_width_m`` / 2 from the river's centerline (a river survey)",
)

# the training signals (CoopNavVecEnv's and the RLlib adapter's reward_terms)
register_term(
    "env",
    kind="training",
    compute=lambda ctx: ctx.result.reward,
    doc="the environment's reward (information gain - penalties)",
)
register_term(
    "error",
    kind="training",
    compute=lambda ctx: -ctx.result.info["survey_error_m"].mean(-1)[:, None],
    doc="-survey_error_m: minus the true horizontal error after the cycle, averaged over the survey "
    "vehicles (privileged: the simulator's truth, used only as a training signal; the policy still acts "
    "on its observation). Summed over an episode it is -(steps x mean error), the evaluation score itself",
)

register_term(
    "log_error",
    kind="training",
    compute=lambda ctx: -np.log1p(ctx.result.info["survey_error_m"].mean(-1)[:, None] / 1.0),
    doc="-ln(1 + survey_error_m / 1 m): the error's signal with its tail bounded. With ``error`` a few "
    "episodes that lose the survey vehicle (hundreds of metres a step) outweigh the rest of the batch, "
    "whose actions then learn from those episodes' noise (the moving network at 10 s pings diverged, "
    "docs/training/marl.md#error-tail); here an error ten times larger costs about 2.3 more, not ten times",
)


def _std_signal(ctx: TermContext) -> np.ndarray:
    P = ctx.result.info["survey_cov_en_m2"]
    return -np.sqrt(np.maximum(P[..., 0, 0] + P[..., 1, 1], 0.0)).mean(-1)[:, None]


register_term(
    "std",
    kind="training",
    compute=_std_signal,
    doc="-sqrt(trace of the horizontal EKF covariance) after the cycle: the filter's own RMS error "
    "prediction (not privileged, less noisy)",
)
register_term(
    "logdet",
    kind="training",
    compute=lambda ctx: -0.5 * ctx.result.info["cov_logdet"].mean(-1)[:, None],
    doc="-0.5 log det of the horizontal EKF covariance after the cycle",
)
register_term(
    "penalties",
    kind="training",
    compute=lambda ctx: -penalties(ctx.result.terms, ctx.weights),
    doc="minus the beacon's weighted penalty terms of the step (the environment terms marked penalty: "
    "safety, geofence, ping and the moving network's baseline, approach, rotation, bank): the "
    "environment's penalties without its contact term",
)
register_term(
    "rejected",
    kind="training",
    compute=lambda ctx: -ctx.result.info["outliers_rejected"].sum(-1)[:, None],
    doc="-(ranges the survey filter's innovation gate rejected this cycle), summed over the survey "
    "vehicles: besides the multipath outliers the gate is there for, a rejected range is a filter that "
    "has drifted further than it believes (a lock-out, once every range is rejected)",
)
