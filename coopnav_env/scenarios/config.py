"""``ScenarioConfig``: a scenario's parameters, in the sections that apply to it.

A config is a frozen dataclass with two top-level fields (``name``, ``network``) and
one field per section (``sections.py``). A section that does not apply to the
scenario is ``None`` (the moving network's for ``network="survey_beacons"``, the
channel's for ``channel_mode="clock"``, ...; the table is ``SECTIONS``), so
``print(config)`` shows only what the scenario uses.

Every parameter name is unique across sections, so the flat forms keep working:
``ScenarioConfig(name="x", ping_interval_s=10.0)``, ``config.replace(ping_interval_s=10.0)``,
``dataclasses.replace(config, ping_interval_s=10.0)`` and ``config.ping_interval_s``;
the dotted form ``config.replace(**{"timing.ping_interval_s": 10.0})`` names the section
too. Setting a parameter of a section that does not apply is a ``ValueError`` that
says which setting enables it.
"""

from __future__ import annotations

import dataclasses
import numbers
from dataclasses import dataclass
from typing import Any, NamedTuple

from ..names import closest
from . import sections as S
from . import sections_beacons as BS
from . import sections_link as L
from . import sections_moving as M
from .params import check
from .validate import validate


class SectionSpec(NamedTuple):
    """A section of ``ScenarioConfig``: its attribute, class, and when it applies
    (every ``(switch, value)`` of ``requires`` holds; ``()``: always)."""

    attr: str
    cls: type
    requires: tuple = ()


SURVEY = (("network", "survey_beacons"),)
MOVING = (("network", "moving_lbl"),)
SECTIONS = (
    SectionSpec("timing", S.Timing),
    SectionSpec("roster", S.Roster),
    SectionSpec("path", S.SurveyPath),
    SectionSpec("vehicle", S.SurveyVehicle),
    SectionSpec("sensors", S.SurveySensors),
    SectionSpec("ekf", S.SurveyEKF),
    SectionSpec("beacon_auv", BS.BeaconAUV, SURVEY),
    SectionSpec("asv", BS.ASV, SURVEY),
    SectionSpec("beacon_start", BS.BeaconStart, SURVEY),
    SectionSpec("acoustics", S.Acoustics),
    SectionSpec("modem", L.Modem),
    SectionSpec("mls", L.MLSSensor, (("acoustic_sensor", "mls"),)),
    SectionSpec("channel", L.Channel, (("channel_mode", "decide"),)),
    SectionSpec("current", S.Current),
    SectionSpec("reward", S.Reward),
    SectionSpec("boat", M.Boat, MOVING),
    SectionSpec("moving", M.MovingNetwork, MOVING),
    SectionSpec("river", M.River, MOVING + (("mission_frame", "world"),)),
    SectionSpec("randomization", S.Randomization, SURVEY),
    SectionSpec("observation", S.Observation),
)
SECTION_BY_ATTR = {s.attr: s for s in SECTIONS}
TOP_LEVEL = ("name", "network")
CONSIDER_PING_EXTRA_BITS = 20  # Pbb 24 bits + fix counter 4 bits - the 8-bit variance (consider-fusion.md)
FULL_COVARIANCE_EXTRA_BITS = 16  # white fusion with beacon_covariance="full": Pbb 24 bits - the 8-bit variance
# the consider states with beacon_covariance="full": the error model's state, 7 numbers of 8 bits (eq. N2: D, s,
# G, the time without lock, the walk's variance), from which the survey computes Pbb, in place of the 24-bit Pbb
FULL_MODEL_EXTRA_BITS = 7 * 8 - 24
# parameter name -> the attribute of its section, and its field
OWNER = {f.name: s.attr for s in SECTIONS for f in dataclasses.fields(s.cls)}
FIELD = {f.name: f for s in SECTIONS for f in dataclasses.fields(s.cls)}
assert len(OWNER) == sum(len(dataclasses.fields(s.cls)) for s in SECTIONS), "parameter names must be unique"
DEFAULTS = {"name": "custom", "network": "survey_beacons", **{n: f.default for n, f in FIELD.items()}}


def _requires_text(spec: SectionSpec) -> str:
    return " and ".join(f"{k}={v!r}" for k, v in spec.requires)


@dataclass(frozen=True, init=False, repr=False)
class ScenarioConfig:
    """Every parameter of a coopnav scenario, in sections (``None``: does not apply).

    Construct it with flat keywords (``ScenarioConfig(name="x", ping_interval_s=10.0)``),
    dotted ones (``**{"timing.ping_interval_s": 10.0}``), section objects
    (``timing=Timing(...)``) or mappings (``timing={"ping_interval_s": 10.0}``, as YAML
    gives them); parameters not given keep their defaults. Units and ranges
    are in each field's metadata (``sections.py``; the reference page lists them).
    """

    name: str = "custom"  # the scenario's name (make_config sets it)
    network: str = "survey_beacons"  # which simulator: "survey_beacons" or "moving_lbl"
    timing: S.Timing | None = None
    roster: S.Roster | None = None
    path: S.SurveyPath | None = None
    vehicle: S.SurveyVehicle | None = None
    sensors: S.SurveySensors | None = None
    ekf: S.SurveyEKF | None = None
    beacon_auv: BS.BeaconAUV | None = None
    asv: BS.ASV | None = None
    beacon_start: BS.BeaconStart | None = None
    acoustics: S.Acoustics | None = None
    modem: L.Modem | None = None
    mls: L.MLSSensor | None = None
    channel: L.Channel | None = None
    current: S.Current | None = None
    reward: S.Reward | None = None
    boat: M.Boat | None = None
    moving: M.MovingNetwork | None = None
    river: M.River | None = None
    randomization: S.Randomization | None = None
    observation: S.Observation | None = None

    def __init__(self, name: str = "custom", network: str = "survey_beacons", **params: Any) -> None:
        check_overrides(params)
        values: dict[str, Any] = {}
        explicit: dict[str, Any] = {}
        for key, v in params.items():  # sections first: flat and dotted keywords override them
            if key in SECTION_BY_ATTR and not isinstance(v, dict) and v is not None:
                check(
                    isinstance(v, SECTION_BY_ATTR[key].cls),
                    f"scenario section {key} must be a {SECTION_BY_ATTR[key].cls.__name__}, got {v!r}",
                )
                values.update((f.name, getattr(v, f.name)) for f in dataclasses.fields(v))
        for key, v in params.items():
            if key not in SECTION_BY_ATTR:
                explicit[flat_name(key)] = v
            elif isinstance(v, dict):  # a section as a mapping (YAML): {"timing": {"ping_interval_s": 10}}
                explicit.update((flat_name(f"{key}.{k}"), x) for k, x in v.items())
        values.update(explicit)
        object.__setattr__(self, "name", name)
        object.__setattr__(self, "network", network)
        check(isinstance(name, str), f"scenario parameter name must be a string, got {name!r}")
        check(
            isinstance(network, str) and network in S.NETWORKS,
            f"unknown network {network!r}; valid networks: {', '.join(S.NETWORKS)}",
        )
        switch = {"network": network, **values}
        for spec in SECTIONS:
            if all(switch.get(k, DEFAULTS[k]) == v for k, v in spec.requires):
                names = [f.name for f in dataclasses.fields(spec.cls)]
                part = spec.cls(**{n: values[n] for n in names if n in values})
                for n in names:  # flat reads as fast as before: the values are in the instance's dict too
                    object.__setattr__(self, n, getattr(part, n))
            else:
                for key in explicit:
                    check(
                        OWNER[key] != spec.attr,
                        f"scenario parameter {key} belongs to section {spec.attr!r}, which applies only with "
                        f"{_requires_text(spec)}; this scenario has "
                        + ", ".join(f"{k}={switch.get(k, DEFAULTS[k])!r}" for k, _ in spec.requires),
                    )
                part = None
            object.__setattr__(self, spec.attr, part)
        validate(self)

    # flat reads: config.ping_interval_s is config.timing.ping_interval_s (stored flat as well
    # by __init__); only a parameter of an absent section gets here ------------------
    def __getattr__(self, key: str) -> Any:
        if key.startswith("_") or key not in OWNER:  # (pickle and copy look up dunders on a bare object)
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {key!r}")
        part = self.__dict__.get(OWNER[key])
        if part is None:
            spec = SECTION_BY_ATTR[OWNER[key]]
            raise AttributeError(
                f"scenario {self.__dict__.get('name')!r} has no parameter {key}: its section "
                f"{spec.attr!r} applies only with {_requires_text(spec)}"
            )
        return getattr(part, key)

    def __repr__(self) -> str:
        parts = [f"name={self.name!r}", f"network={self.network!r}"]
        parts += [f"{s.attr}={getattr(self, s.attr)!r}" for s in SECTIONS if getattr(self, s.attr) is not None]
        return f"{type(self).__name__}({', '.join(parts)})"

    def applies(self, key: str) -> bool:
        """Whether parameter ``key`` (flat or dotted) is part of this scenario."""
        key = flat_name(key)
        return key in TOP_LEVEL or getattr(self, OWNER[key]) is not None

    def sections(self) -> dict:
        """{section attribute: section} of the sections that apply."""
        return {s.attr: getattr(self, s.attr) for s in SECTIONS if getattr(self, s.attr) is not None}

    def to_flat_dict(self, all_parameters: bool = False) -> dict:
        """{parameter: value}, flat (as run.json stores it): the parameters that apply or,
        with ``all_parameters``, every parameter (the defaults where a section is absent)."""
        out: dict[str, Any] = {"name": self.name, "network": self.network}
        for spec in SECTIONS:
            part = getattr(self, spec.attr)
            for f in dataclasses.fields(spec.cls):
                if part is not None:
                    out[f.name] = getattr(part, f.name)
                elif all_parameters:
                    out[f.name] = f.default
        return out

    def replace(self, **overrides: Any) -> ScenarioConfig:
        """A copy with ``overrides`` (flat or dotted parameter names, or sections). On the
        moving network, an override of ``depth_m`` without ``waypoints_m`` moves the
        mission's waypoints to that depth (``_mission_depth``)."""
        return dataclasses.replace(self, **_mission_depth(self, check_overrides(overrides)))

    # derived quantities, computed in one place --------------------------------------
    @property
    def n_beacons(self) -> int:
        return len(self.beacon_kinds)

    @property
    def substeps_per_cycle(self) -> int:
        timing = self.timing
        assert timing is not None, "every scenario has a timing section"
        return timing.substeps_per_cycle

    @property
    def geofence_m(self) -> tuple:
        """(east_min, north_min, east_max, north_max) of the geofence."""
        e0, n0 = self.survey_origin_m
        w, h = self.survey_area_m
        m = self.geofence_margin_m
        return (e0 - m, n0 - m, e0 + w + m, n0 + h + m)

    @property
    def position_scale_m(self) -> float:
        """Length that normalizes positions in observations."""
        w, h = self.survey_area_m
        return float(max(w, h) / 2 + self.geofence_margin_m)

    def max_speed_mps(self, kind: str) -> float:
        """A beacon's maximum speed through the water by its kind (``BEACON_KINDS``):
        the one place that maps a kind to its speed parameter."""
        speeds = {"beacon_auv": "beacon_auv_max_speed_mps", "asv": "asv_max_speed_mps", "boat": "boat_max_speed_mps"}
        if kind not in speeds:
            raise ValueError(f"unknown beacon kind {kind!r}; valid: {', '.join(speeds)}")
        return float(getattr(self, speeds[kind]))

    @property
    def ping_bits(self) -> int:
        """A beacon's ping on the channel, bits: ``ping_packet_bits``, plus the consider
        states' fields with ``beacon_error_fusion="schmidt"`` (its Pbb in 24 bits and a
        4-bit GPS fix counter, replacing the 8-bit variance: +20; consider-fusion.md), with a
        beacon AUV's ``beacon_covariance="full"`` its error model's state in place of Pbb
        (eq. N2, +32 more); without them, its 2x2 covariance (the 24-bit Pbb replacing the
        8-bit variance, +16)."""
        full = "beacon_auv" in self.beacon_kinds and self.beacon_covariance == "full"
        if self.beacon_error_fusion == "schmidt":
            extra = CONSIDER_PING_EXTRA_BITS + (FULL_MODEL_EXTRA_BITS if full else 0)
        elif full:
            extra = FULL_COVARIANCE_EXTRA_BITS
        else:
            extra = 0
        return int(self.ping_packet_bits) + extra

    @property
    def beacon_max_speeds_mps(self) -> tuple:
        """The maximum speed of each beacon, in ``beacon_kinds`` order."""
        return tuple(self.max_speed_mps(k) for k in self.beacon_kinds)


def flat_name(key: str) -> str:
    """``"timing.ping_interval_s"`` -> ``"ping_interval_s"`` (checking the section);
    a flat name is returned as it is."""
    if "." not in key:
        return key
    sec, _, name = key.partition(".")
    if OWNER.get(name) != sec:
        if name in OWNER:
            hint = f"; {name} is in section {OWNER[name]!r}"
        elif sec in SECTION_BY_ATTR:
            close = closest(name, [f.name for f in dataclasses.fields(SECTION_BY_ATTR[sec].cls)])
            hint = f" (did you mean '{sec}.{close}'?)" if close else f"; section {sec!r} has no parameter {name!r}"
        else:
            close = closest(sec, list(SECTION_BY_ATTR))
            hint = f"; no section {sec!r}" + (f" (did you mean {close!r}?)" if close else "")
        raise ValueError(f"unknown scenario parameter {key!r}{hint}")
    return name


def parameter_names() -> list:
    """Every parameter's flat name, section by section (``name`` and ``network`` first)."""
    return list(DEFAULTS)


def default_of(key: str) -> Any:
    """A parameter's default (flat or dotted name)."""
    check_overrides({key: None})
    return DEFAULTS[flat_name(key)]


def section_of(key: str) -> str | None:
    """The section attribute of a parameter (``None`` for ``name`` and ``network``)."""
    return OWNER.get(flat_name(key))


def bounds() -> dict:
    """{parameter: (low, high, open_low)} of every number parameter (from the metadata)."""
    return {
        n: (f.metadata["low"], f.metadata["high"], f.metadata["open_low"])
        for n, f in FIELD.items()
        if f.metadata.get("low") is not None
    }


def _mission_depth(config: ScenarioConfig, overrides: dict) -> dict:
    """The moving network's vehicle holds one depth, ``depth_m``: the depth its waypoints
    carry (``validate``) and the one the boats' external tracking assumes. An override of
    ``depth_m`` alone (the shift sets' ``deep_50m``, a training team's ``{depth_m: 50}``)
    therefore moves the waypoints' depth column with it; before, the vehicle stayed at its
    waypoints' 2 m while the tracking placed it as if at 50 m, never got a fix, and the
    boats lost it. Other overrides pass unchanged."""
    named = {flat_name(k): k for k in overrides if k not in SECTION_BY_ATTR}
    if "depth_m" not in named or "waypoints_m" in named:
        return overrides
    depth = overrides[named["depth_m"]]
    network = overrides.get("network", config.network)
    if network != "moving_lbl" or isinstance(depth, bool) or not isinstance(depth, numbers.Real):
        return overrides  # (a bad depth_m is refused by its own check)
    moved = tuple((w[0], w[1], float(depth)) for w in config.waypoints_m)
    return {**overrides, "waypoints_m": moved}


def check_overrides(overrides: dict) -> dict:
    """Refuse unknown parameter names, naming the valid ones (and the closest)."""
    valid = parameter_names()
    unknown = []
    for k in overrides:
        if k in SECTION_BY_ATTR:
            continue
        if "." in k:
            flat_name(k)
        elif k not in DEFAULTS:
            unknown.append(k)
    if unknown:
        hints = []
        for k in unknown:
            close = closest(k, valid)
            hints.append(f"{k!r}" + (f" (did you mean {close!r}?)" if close else ""))
        raise ValueError(f"unknown scenario parameter(s) {', '.join(hints)}; valid parameters: {', '.join(valid)}")
    return overrides
