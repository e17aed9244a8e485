"""The benchmark's task sets, as data (``evaluation.benchmark`` runs them).

A task is a name and scenario overrides (``make_config(scenario, **overrides)``); a
task set is a scenario, its tasks, the episode count every policy plays on every
task, and the planners the challengers are compared with. Episode ``i`` of every task
and policy is seeded ``coopnav_env.seeds.TEST_SEEDS[i]`` (common random numbers),
seeds the trainers refuse (``coopnav_env.seeds.refuse_test_seeds``).

* ``planners``: those of ``baselines.list_policies(network)`` other than the floors, and
  the set's ``extra_planners`` (a planner on another transmit schedule, ``"ellipse+clock"``);
  per task the one with the lowest mean error is the "best planner" a challenger has
  to beat;
* ``floors``: ``static`` and ``random``, reported for scale, never the best planner;
* ``references``: the set's ``oracle`` (``baselines.horizon``: the receding-horizon optimiser
  given the truth; ``"oracle+clock"`` on ``sousa_ping``), the ceiling of the headroom column,
  never the best planner;
* ``greedy_planners``: the planners other than ``NON_GREEDY`` (``horizon``): the best of
  them is the floor of the headroom, best greedy minus oracle.

Changing a task set changes the benchmark: bump ``BENCHMARK_VERSION`` (results.json
and results.md carry it, so that results of different versions are not compared).
"""

from __future__ import annotations

import dataclasses
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

from coopnav_env.scenarios.matos import PAPER_SETTINGS, RIVER_PAPER_SETTINGS

if TYPE_CHECKING:
    from coopnav_env.scenarios import ScenarioConfig

# 2: the gao_team and matos_river task sets; 3: the receding-horizon planner `horizon` among the planners,
# the Matos scenarios on the project's channel (outliers and losses) with the paper's channel as named tasks,
# and issue 21's physics under every task; 4: the reference `oracle` runs on every task it can drive and each
# task set reports the headroom (best greedy planner minus oracle) and the fraction of it each challenger closes,
# and the results carry each policy's cost per decision (issue 22); 5: the oracle plans from the survey filters'
# estimates and errors (eq. H4 of baselines/horizon.py), not from the true positions with the filters' covariances;
# 6: the moving network's task sets gain `horizon` and the `oracle` for the boats (baselines/boat_horizon.py), so
# every task set has a headroom row (the survey task sets run the same policies as in 5, with the same results),
# and a task's headroom is measured only where its paired interval lies above 0 (benchmark_stats.headroom_task)
# (the shift task sets shifts_<scenario> were added under 6: new sets, the eight others unchanged);
# 7: sousa_ping's planners also transmit on the clock schedule (ellipse+clock, fim_a+clock, horizon+clock),
# the better fixed schedule on the sonar link, and its oracle transmits on it (oracle+clock); the other
# task sets are unchanged (their v6 results stand)
BENCHMARK_VERSION = 7
EPISODES = 50  # per task and policy: the benchmark's count
FLOORS = ("static", "random")
REFERENCES = ("oracle",)  # given the truth: never a task's best planner (issue 22's headroom reference)
NON_GREEDY = ("horizon",)  # planners that look beyond the next ping: not among the "best greedy planner"'s candidates

__all__ = [
    "BENCHMARK_VERSION",
    "EPISODES",
    "FLOORS",
    "NON_GREEDY",
    "REFERENCES",
    "TASK_SETS",
    "Task",
    "TaskSet",
    "get_task_set",
    "list_task_sets",
]


@dataclasses.dataclass(frozen=True)
class Task:
    """One benchmark task: a name (unique in its set) and scenario overrides."""

    name: str
    overrides: MappingProxyType
    about: str = ""

    def config(self, scenario: str, **extra: Any) -> ScenarioConfig:
        """The task's ``ScenarioConfig`` (``extra``: more overrides on top, e.g. ``--set``)."""
        from coopnav_env import make_config

        return make_config(scenario, **{**self.overrides, **extra})


@dataclasses.dataclass(frozen=True)
class TaskSet:
    """A named set of tasks on one scenario, ``episodes`` per task and policy."""

    name: str
    scenario: str
    tasks: tuple
    episodes: int = EPISODES
    about: str = ""
    # planners beyond the network's registered ones: a motion planner on another transmit
    # schedule ("ellipse+clock") where the channel is shared (channel_mode="decide")
    extra_planners: tuple = ()
    # the reference given the truth (REFERENCES' oracle, or it on another transmit schedule)
    oracle: str = "oracle"

    @property
    def config(self) -> ScenarioConfig:
        """The scenario's config (the tasks' overrides aside)."""
        from coopnav_env import make_config

        return make_config(self.scenario)

    @property
    def network(self) -> str:
        return self.config.network

    @property
    def planners(self) -> list:
        """The planners compared against: those that drive the network, minus the floors and
        the references that are given the truth (``REFERENCES``)."""
        from baselines import list_policies, motion_name

        network = list_policies(config=self.config)
        registered = [p for p in network if p not in FLOORS and motion_name(p) not in REFERENCES]
        return registered + [p for p in self.extra_planners if p not in registered]

    @property
    def greedy_planners(self) -> list:
        """The planners that look one ping ahead or are geometric (``planners`` minus ``NON_GREEDY``,
        whatever their transmit schedule)."""
        from baselines import motion_name

        return [p for p in self.planners if motion_name(p) not in NON_GREEDY]

    @property
    def references(self) -> list:
        """The reference (``oracle``: ``REFERENCES``' planner, perhaps on another transmit schedule) if it
        drives the network: run on every task, never the best planner."""
        from baselines import list_policies, motion_name

        return [self.oracle] if motion_name(self.oracle) in list_policies(config=self.config) else []

    @property
    def floors(self) -> list:
        from baselines import list_policies

        return [p for p in FLOORS if p in list_policies(config=self.config)]

    def task(self, name: str) -> Task:
        for t in self.tasks:
            if t.name == name:
                return t
        raise KeyError(name)


# on the sonar link two staggered pings share a slot without colliding, so the clock schedule
# (every slot, twice TDMA's pings) is a fixed schedule to beat: ellipse+clock 1.126 m against
# ellipse on TDMA 1.364 m (docs/training/marl.md#levers-sousa-ping, seeds 700000-700029)
_CLOCK_PLANNERS = ("ellipse+clock", "fim_a+clock", "horizon+clock")


def _task(name: str, about: str = "", **overrides) -> Task:
    return Task(name, MappingProxyType(dict(overrides)), about)


def _sousa_grid() -> tuple:
    """Sousa et al. Tables I-II: depth x survey path, 16 cells."""
    return tuple(
        _task(f"{path}_{depth:g}m", f"survey_path={path}, depth_m={depth:g}", depth_m=float(depth), survey_path=path)
        for depth in (1, 5, 20, 50)
        for path in ("stationary", "lawnmower", "circle", "spiral")
    )


_SETS: tuple[TaskSet, ...] = (
    TaskSet(
        "sousa_grid",
        "sousa_asv",
        _sousa_grid(),
        about="one ASV helping an ROV: the 16 cells of Sousa et al.'s Tables I-II (depth x survey path)",
    ),
    TaskSet(
        "gao_lawnmower",
        "gao_lawnmower",
        (
            _task("lake", "the lake trial as published"),
            _task("deep_20m", "the survey at 20 m instead of 3 m", depth_m=20.0),
            _task("current_0.3", "a 0.3 m/s current instead of 0.05", current_speed_mps=0.3),
            _task("spiral", "a descending spiral instead of the lawnmower", survey_path="spiral"),
            _task("two_beacons", "team: two beacon AUVs", beacon_kinds=("beacon_auv", "beacon_auv")),
            _task("two_surveys", "team: two survey AUVs, one beacon", n_survey=2),
        ),
        about="Gao & Chitre's lake trial and variations (depth, current, path, team)",
    ),
    TaskSet(
        "gao_sea",
        "gao_sea",
        (
            _task("sea", "the sea trial as published (0.3 m/s current)"),
            _task("calm", "a 0.05 m/s current", current_speed_mps=0.05, current_speed_spread_mps=0.03),
            _task("current_0.6", "a 0.6 m/s current", current_speed_mps=0.6),
            _task("deep_30m", "the survey at 30 m instead of 5 m", depth_m=30.0),
            _task("two_beacons", "team: two beacon AUVs", beacon_kinds=("beacon_auv", "beacon_auv")),
        ),
        about="Gao & Chitre's sea trial and variations (current, depth, team)",
    ),
    TaskSet(
        "gao_team",
        "gao_team",
        (
            _task("team", "an ASV and a beacon AUV help two survey AUVs 60 m apart, as configured"),
            _task("calm", "a 0.05 m/s current", current_speed_mps=0.05, current_speed_spread_mps=0.03),
            _task("current_0.5", "a 0.5 m/s current", current_speed_mps=0.5),
            _task("deep_30m", "the surveys at 30 m instead of 5 m", depth_m=30.0),
            _task("apart_120m", "the two surveys 120 m apart instead of 60", survey_spacing_m=120.0),
        ),
        about="cooperation: an ASV and a beacon AUV (different kinds) help two survey AUVs; the planners run "
        "per beacon",
    ),
    TaskSet(
        "swarm_mls",
        "swarm_mls",
        (
            _task("swarm3", "three survey AUVs with MLS ranging, as configured"),
            _task("current_0.3", "a 0.3 m/s current instead of 0.05", current_speed_mps=0.3),
            _task("swarm2", "team: two survey AUVs", n_survey=2),
            _task("swarm5", "team: five survey AUVs", n_survey=5),
            _task("two_beacons", "team: two beacon AUVs", beacon_kinds=("beacon_auv", "beacon_auv")),
        ),
        about="Kottege & Zimmer's MLS swarm and variations (current, team size)",
    ),
    TaskSet(
        "sousa_ping",
        "sousa_ping",
        (
            _task("lawnmower_5m", "two ASVs share the channel: lawnmower at 5 m", survey_path="lawnmower", depth_m=5.0),
            _task("lawnmower_20m", "lawnmower at 20 m", survey_path="lawnmower", depth_m=20.0),
            _task("circle_5m", "circle at 5 m", survey_path="circle", depth_m=5.0),
            _task("circle_20m", "circle at 20 m", survey_path="circle", depth_m=20.0),
        ),
        about="when to ping: two ASVs decide motion and transmission on one half-duplex channel; the planners "
        "transmit on a TDMA schedule, and ellipse, fim_a and horizon also on the clock (both ASVs every slot, "
        "staggered); the oracle on the clock",
        extra_planners=_CLOCK_PLANNERS,
        oracle="oracle+clock",
    ),
    TaskSet(
        "matos_moving_lbl",
        "matos_moving_lbl",
        (
            _task("channel", "the moving baseline on the project's channel: 3 % outliers, losses 5-50 %"),
            _task("paper", "Matos & Cruz's moving baseline as published: white range noise only", **PAPER_SETTINGS),
            _task("current_0.3", "a 0.3 m/s current instead of 0.05", current_speed_mps=0.3),
            _task("short_baseline", "a 50 m baseline instead of 100", baseline_target_m=50.0),
            _task("frame_north", "the frame oriented north (0 deg) instead of east", frame_orientation_deg=0.0),
            _task("noisy_ranges", "3 m range noise instead of 1.4", range_noise_std_m=3.0),
        ),
        about="Matos & Cruz's moving long baseline (two boats) and variations",
    ),
    TaskSet(
        "matos_river",
        "matos_river",
        (
            _task("river", "down the 1.6 km winding river, as configured (3 % outliers, losses 5-50 %)"),
            _task(
                "river_paper_channel",
                "the river with the paper's channel and filter: white range noise only",
                **RIVER_PAPER_SETTINGS,
            ),
            _task("current_0.5", "a 0.5 m/s river current instead of 0.3", current_speed_mps=0.5),
            _task("narrow_120m", "a 120 m wide river instead of 150", river_width_m=120.0),
            _task("short_baseline", "a 60 m baseline instead of 100", baseline_target_m=60.0),
            _task("noisy_ranges", "3 m range noise instead of 1.4", range_noise_std_m=3.0),
        ),
        about="the moving network with the vehicle's mission in the world, down a winding river: the boats "
        "must escort it",
    ),
)


# Issue 23's shifts: what a user will try on any scenario. Each scenario gets a task set
# "shifts_<scenario>" of these, minus the ones equal to its own settings; a policy that loses
# the survey vehicle on one where a planner keeps it is a defect, not a tie.
_SHIFTS = (
    ("still", "no current", {"current_speed_mps": 0.0, "current_speed_spread_mps": 0.0}),
    ("current_0.5", "a 0.5 m/s current", {"current_speed_mps": 0.5}),
    # the fixed-clock channel's range loss (5 % near, 50 % at the range limit by default)
    (
        "lossy",
        "a lossier channel: 20 % of the packets lost near, 80 % at the range limit",
        {"packet_loss_near": 0.2, "packet_loss_far": 0.8},
    ),
    ("ping_10s", "a ping every 10 s", {"ping_interval_s": 10.0}),
    ("shallow_1m", "the survey at 1 m", {"depth_m": 1.0}),
    ("deep_50m", "the survey at 50 m", {"depth_m": 50.0}),
)
# the shared channel (channel_mode="decide", sousa_ping) has no range-loss parameter (the sonar link
# sets its losses) and cannot fit its exchange in a 10 s slot: a weaker link and a slower clock instead
_DECIDE_SHIFTS = {
    # a loud sea alone loses nothing at sousa_ping's few hundred metres with a 185 dB modem
    # (3 tuning episodes: 0 of 180 packets); with a 130 dB source about a third are lost
    "lossy": (
        "weak_link",
        "a weak source (130 dB instead of 185) in a loud sea (15 m/s wind, heavy shipping)",
        {"source_level_db": 130.0, "noise_wind_mps": 15.0, "noise_shipping": 1.0},
    ),
    "ping_10s": ("ping_30s", "a slot every 30 s (10 s cannot hold the exchange)", {"ping_interval_s": 30.0}),
}


# the MLS array (acoustic_sensor="mls", swarm_mls) ignores the modem's packet loss (2 tuning
# episodes: the same 1 loss in 357 with lossy's settings): a weaker signal instead
_MLS_SHIFTS = {
    "lossy": (
        "weak_signal",
        "the MLS signal 10 dB weaker (20 dB SNR at 1 m instead of 30)",
        {"mls_snr_db_at_1m": 20.0},
    ),
}


def _shift_set(origin: TaskSet) -> TaskSet:
    """The shifts of ``origin``'s scenario, compared with ``origin``'s planners and oracle."""
    from coopnav_env import make_config

    scenario = origin.scenario
    base = make_config(scenario)
    tasks = []
    for name, about, overrides in _SHIFTS:
        if base.channel_mode == "decide" and name in _DECIDE_SHIFTS:
            name, about, overrides = _DECIDE_SHIFTS[name]
        elif base.acoustic_sensor == "mls" and name in _MLS_SHIFTS:
            name, about, overrides = _MLS_SHIFTS[name]
        if all(getattr(base, k) == v for k, v in overrides.items()):
            continue  # the scenario's own setting: no shift
        tasks.append(_task(name, about, **overrides))
    return TaskSet(
        f"shifts_{scenario}",
        scenario,
        tuple(tasks),
        about=f"issue 23's shifts on {scenario}: currents 0-0.5 m/s, a lossier channel, another ping interval, "
        "shallower and deeper water",
        extra_planners=origin.extra_planners,
        oracle=origin.oracle,
    )


_FIRST_SET = {s.scenario: s for s in reversed(_SETS)}  # each scenario's first task set
_SETS = _SETS + tuple(_shift_set(_FIRST_SET[scenario]) for scenario in dict.fromkeys(s.scenario for s in _SETS))

TASK_SETS = MappingProxyType({s.name: s for s in _SETS})


def list_task_sets() -> list:
    """The task sets' names."""
    return list(TASK_SETS)


def get_task_set(name: str) -> TaskSet:
    """The task set ``name`` (a ``KeyError`` naming the valid ones else)."""
    try:
        return TASK_SETS[name]
    except KeyError:
        from coopnav_env.names import did_you_mean

        raise KeyError(
            f"unknown task set {name!r}{did_you_mean(name, TASK_SETS)} valid: {', '.join(TASK_SETS)}"
        ) from None
