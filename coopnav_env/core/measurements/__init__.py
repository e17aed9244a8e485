"""Measurement models of the survey vehicles' acoustic sensors: a registry, one module each.

A scenario's ``acoustic_sensor`` names one registered sensor; the survey simulator
builds it once (``build(sim)``) and calls its ``fuse(draws, out)`` every cycle after
the filters' prediction. Each model is a small compiled kernel over the batch built
from the shared pieces in ``core.navigation`` (the chi-square gate and the Joseph
update with the model's own residual, as filterpy's ``update(..., residual=...)``).

* ``modem``: acoustic-modem ranges, one-way or two-way travel time (Gao & Chitre;
  Sousa et al.), with lock-out recovery;
* ``mls``: Kottege & Zimmer's MLS array: range and bearing from one sender per
  cycle (the sensor's analytic mode, ``core.mls``).

A new sensor is one module with ``build(sim) -> object with fuse(draws, out) and
heard_mask(cycle)`` plus one :func:`register_sensor` call (in the module itself, or
here for a built-in sensor, whose module is then imported only when it is used)::

    from coopnav_env.core.measurements import register_sensor

    register_sensor("depth_only", build=lambda sim: DepthOnly(sim),
                    draws=[("depth_only_n", "normal", lambda S, N, K: (S,))],
                    networks=("survey_beacons",), doc="no ranges; a depth sensor alone")

``draws`` are the sensor's own random numbers per cycle, ``(purpose, "normal" |
"uniform", shape_fn(S, N, K))``, appended after the simulator's shared ones in its
``rng.DrawLayout`` (so they never shift the others' numbers), and read in ``fuse``
as ``draws[purpose]`` (B, *shape). The scenario's validation reads the registry
(:func:`check_sensor`): the name must be registered, the network one of the sensor's
``networks``, and the sensor's own ``validate(config)`` hook, if any, must pass.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

DrawSpec = tuple  # (purpose, "normal" | "uniform", shape_fn(S, N, K) -> tuple)


class FusionOutputs(NamedTuple):
    """What a cycle's acoustic fusion reports, for the infos and the reward: flags per
    (B, N, S) fused / rejected by the gate / lost, and per (B, S) NaN readings and
    filter restarts. A named record, so the fusion kernels take it as one argument and
    write its arrays in place."""

    fused: np.ndarray
    rejected: np.ndarray
    lost: np.ndarray
    nan_count: np.ndarray
    restarts: np.ndarray


@dataclass(frozen=True)
class Sensor:
    """One registered sensor (see :func:`register_sensor`)."""

    name: str
    build: Callable[[Any], Any] | str
    draws: tuple = ()
    networks: tuple = ("survey_beacons",)
    validate: Callable[[Any], None] | None = None
    doc: str = ""
    arrival: Callable[[Any, Any], np.ndarray] | None = None  # (config, distance_m) -> P(a ping is received)
    reach: Callable[[Any], float] | None = None  # config -> the farthest a ping is received, m
    range_variance: Callable[..., np.ndarray] | None = None  # (config, distance_m, beacon_var_m2, depth_m) -> R, m^2

    def make(self, sim: Any) -> Any:
        """The sensor's model for simulator ``sim`` (a module path's ``build`` imported now)."""
        build = importlib.import_module(self.build).build if isinstance(self.build, str) else self.build
        return build(sim)


_SENSORS: dict[str, Sensor] = {}


def register_sensor(
    name: str,
    build: Callable[[Any], Any] | str,
    *,
    draws: Sequence[tuple] = (),
    networks: tuple = ("survey_beacons",),
    validate: Callable[[Any], None] | None = None,
    doc: str = "",
    arrival: Callable[[Any, Any], np.ndarray] | None = None,
    reach: Callable[[Any], float] | None = None,
    range_variance: Callable[..., np.ndarray] | None = None,
) -> Sensor:
    """Register the sensor ``name`` (a scenario's ``acoustic_sensor``) and return it.

    ``build``: ``build(sim)`` -> the model, or a module path whose ``build`` it is;
    ``draws``: its random numbers per cycle, ``(purpose, kind, shape_fn(S, N, K))``;
    ``networks``: the ``ScenarioConfig.network`` values it works with;
    ``validate(config)``: raises ``ValueError`` on a scenario the sensor cannot simulate;
    ``arrival(config, distance_m)``: the probability that a ping over that distance is
    received, ``reach(config)``: the farthest one is, and ``range_variance(config,
    distance_m, beacon_var_m2, depth_m)``: the variance R (m^2) the survey filter gives
    such a range (what the planners model; default: the modem's loss curve,
    ``max_range_m`` and R).
    """
    if not isinstance(name, str) or not name:
        raise ValueError(f"sensor name must be a non-empty string, got {name!r}")
    if name in _SENSORS:
        raise ValueError(f"acoustic sensor {name!r} is registered twice")
    for spec in draws:
        if len(spec) != 3 or spec[1] not in ("normal", "uniform") or not callable(spec[2]):
            raise ValueError(
                f"sensor {name!r}: a draw is (purpose, 'normal' | 'uniform', shape_fn(S, N, K)), got {spec!r}"
            )
    sensor = Sensor(name, build, tuple(draws), tuple(networks), validate, doc, arrival, reach, range_variance)
    _SENSORS[name] = sensor
    return sensor


def unregister_sensor(name: str) -> None:
    """Remove a registered sensor (tests, plug-ins that clean up after themselves)."""
    _SENSORS.pop(name, None)


def sensor_names() -> tuple[str, ...]:
    """The registered sensors' names: the valid values of ``acoustic_sensor``."""
    return tuple(_SENSORS)


def get_sensor(name: str) -> Sensor:
    """The registered sensor ``name`` (``ValueError`` listing the valid ones)."""
    if name not in _SENSORS:
        raise ValueError(f"unknown acoustic_sensor {name!r}; valid: {', '.join(_SENSORS)}")
    return _SENSORS[name]


def check_sensor(config: Any) -> None:
    """The scenario's sensor checks: registered, on one of its networks, its own hook."""
    sensor = get_sensor(config.acoustic_sensor)
    if config.network not in sensor.networks:
        raise ValueError(f"acoustic_sensor={sensor.name!r} needs network={' or '.join(map(repr, sensor.networks))}")
    if sensor.validate is not None:
        sensor.validate(config)


def _modem_arrival(config: Any, distance_m: Any) -> np.ndarray:
    """The modem's: on the shared channel's sonar link (``channel_mode="decide"``,
    ``link_model="sonar"``, where the modem's own range loss is off) the link's
    probability that the ping is decoded (``link_budget.ping_success_probability``: SNR from
    the source level, spreading and absorption, the band's noise); otherwise 1 - the
    loss probability, ``packet_loss_near`` to ``packet_loss_far`` over ``max_range_m``."""
    from .. import acoustics

    c = config
    from ..link_budget import on_sonar_link, ping_success_probability

    if on_sonar_link(c):
        return ping_success_probability(c, distance_m)
    return 1.0 - acoustics.packet_loss_probability(distance_m, c.packet_loss_near, c.packet_loss_far, c.max_range_m)


def arrival_probability(config: Any, distance_m: Any) -> np.ndarray:
    """The probability that a ping over ``distance_m`` reaches a survey vehicle with the
    scenario's ``acoustic_sensor`` (its ``arrival`` hook; the modem's loss curve by default)."""
    arrival = get_sensor(config.acoustic_sensor).arrival or _modem_arrival
    return np.asarray(arrival(config, distance_m), float)


def reach_m(config: Any) -> float:
    """The farthest a ping reaches a survey vehicle with the scenario's sensor (its
    ``reach`` hook; ``max_range_m`` by default)."""
    reach = get_sensor(config.acoustic_sensor).reach
    return float(reach(config) if reach is not None else config.max_range_m)


def _modem_range_variance(config: Any, distance_m: Any, beacon_var_m2: Any, depth_m: float) -> np.ndarray:
    """The survey filter's R of a modem range (``acoustics.modem_range_variance``, the
    formula its kernel calls): the ranging noise, the beacon's own position variance, and
    the sound speed's uncertainty as a scale error that grows with the distance, at
    mid-depth ``depth_m`` (the filter's: halfway between the two vehicles)."""
    from .. import acoustics

    c = config
    rel = acoustics.sound_speed_rel_std(c.water_temperature_c, c.salinity_psu, c.temperature_uncertainty_c, depth_m)
    two_way = c.ranging_mode == "twtt"
    return acoustics.modem_range_variance(c.range_noise_std_m, two_way, beacon_var_m2, distance_m, rel)


def range_variance_m2(config: Any, distance_m: Any, beacon_var_m2: Any, depth_m: float) -> np.ndarray:
    """The variance R (m^2) the survey filter gives a range over ``distance_m`` from a
    beacon whose own position variance per axis is ``beacon_var_m2``, with the
    scenario's ``acoustic_sensor`` (its ``range_variance`` hook; the modem's R by
    default). What the planners weigh a candidate position's range by: the same R as the
    filter that fuses it (docs/baselines/horizon.md#range-variance)."""
    hook = get_sensor(config.acoustic_sensor).range_variance or _modem_range_variance
    return np.asarray(hook(config, np.asarray(distance_m, float), beacon_var_m2, float(depth_m)), float)


def _mls_range_variance(config: Any, distance_m: Any, beacon_var_m2: Any, depth_m: float) -> np.ndarray:
    """The MLS array's, as the planners model it: ``range_noise_std_m`` squared plus the
    beacon's variance at every distance. (The array's own range variance follows the
    signal-to-noise ratio of each reception, ``mls_array``; the planners do not model it.)"""
    return config.range_noise_std_m**2 + np.asarray(beacon_var_m2, float) + np.zeros(np.shape(distance_m))


def _mls_arrival(config: Any, distance_m: Any) -> np.ndarray:
    """The MLS array's window: it hears every sender within ``mls_max_range_m`` and none
    farther (its minimum range, 0.4 m, lies inside every scenario's safety distance)."""
    return (np.asarray(distance_m, float) <= config.mls_max_range_m).astype(float)


def draw_layout(name: str, S: int, N: int, K: int) -> list[tuple[str, str, tuple]]:
    """The sensor's entries of the simulator's ``rng.DrawLayout``: (purpose, kind, shape)."""
    return [(purpose, kind, tuple(shape_fn(S, N, K))) for purpose, kind, shape_fn in get_sensor(name).draws]


def build(name: str, sim: Any) -> Any:
    """The measurement model ``name`` for simulator ``sim``."""
    return get_sensor(name).make(sim)


# the built-in sensors (their modules are imported when a simulator builds them). The
# modem's random numbers are the simulator's shared acoustic_n / acoustic_u (the channel
# reads them too); the MLS array's 13 normals and a compass reading come after them.
register_sensor(
    "modem",
    "coopnav_env.core.measurements.modem",
    networks=("survey_beacons", "moving_lbl"),
    doc="acoustic-modem ranges, one-way or two-way travel time, with lock-out recovery",
)
register_sensor(
    "mls",
    "coopnav_env.core.measurements.mls_array",
    draws=[("mls_n", "normal", lambda S, N, K: (S, 14))],
    doc="Kottege & Zimmer's MLS array: range and bearing from one sender per cycle",
    arrival=_mls_arrival,
    reach=lambda config: float(config.mls_max_range_m),
    range_variance=_mls_range_variance,
)
