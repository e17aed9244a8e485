"""The moving acoustic network of Matos & Cruz: one AUV navigating in the frame of
two beacon boats, batched (``network = "moving_lbl"``).

One step is one positioning cycle of ``ping_interval_s``:

1. the boats' actions become ground-velocity commands (the same rate-limited
   kernel as every beacon, ``substeps.integrate_beacons``), which the boats follow
   imperfectly (``disturb_boats``): a Gauss-Markov surge and course fluctuation
   each, and the part of the river current their ground-speed control leaves;
2. the vehicle is integrated in sub-steps: line-of-sight guidance (Fig. 5) on its
   filter's frame estimate, heading reference psi + phi_hat steered on the compass,
   true motion = water speed x heading + current; the filter predicts with the
   measured water speed (propeller encoder) and compass heading (section VII);
3. the three-interval exchange of section V runs in time between the moving
   vehicles (``core.lbl.exchange_of``); the filter fuses d1 as it arrives, then d2
   and l together (their noises are correlated, see ``filter``), and restarts from
   the fix after a gate lockout (``recovery``);
4. the boats, which hear S1, S2 and S4 too, track the vehicle externally
   (``core.lbl.track_fix_of``): that, their GPS and each other's position over the
   radio is all they observe;
5. reward: the information the vehicle's filter gained this cycle (log det of its
   (x, y) covariance before minus after), shared by the boats, minus penalties: a
   boat within ``safety_distance_m`` of the vehicle; the baseline off its target
   by more than ``baseline_tolerance_m``; the vehicle nearer the baseline than
   ``min_baseline_distance_m``; the frame turned more than
   ``frame_rotation_tolerance_deg`` from its start (the filter models phi as
   constant: a turning frame makes it confidently wrong, which the information
   term alone would reward); no range fused this cycle.

**A mission in the world** (``mission_frame="world"``, scenario ``matos_river``): the
paper gives the vehicle its mission in the moving frame (section VI), so where the
boats go hardly matters to it. With ``"world"`` the mission's waypoints are (east,
north, depth) along a river (``core.river``), and at the start of every cycle they
are re-expressed in the frame the boats' GPS gives (B1's GPS position and the bearing
of B2's from it, which the boats telemeter to the vehicle with the exchange; the
vehicle has no other world reference): the vehicle still navigates in the frame with
the moving-frame EKF, but where it must go in the frame now depends on where the
boats are, and boats that stay behind lose it. The river's current is spatially
varying: its mean speed along the local downstream direction of the centerline (at
each boat and at the vehicle, held over the cycle) plus the usual Gauss-Markov part.
Reward: the ``bank`` term (a boat farther than ``river_width_m`` / 2 from the
centerline) is added and the ``rotation`` term is 0, since the frame must turn with
the river. The boats also observe the river (``RIVER_OBS_FIELDS``).

The package holds one named step per module, each a short compiled function (its
records: ``state``):

* ``state``: ``FrameState`` and the named records the kernels pass;
* ``initial``: an episode's start;
* ``vehicle``: steps 1-2, the boats' disturbance and the vehicle's sub-steps
  (``integrate_vehicle``);
* ``exchange``: the exchange's physics around ``lbl.exchange_of``;
* ``filter``: the moving-frame EKF's range updates (prediction:
  ``navigation.frame_predict``, in the sub-steps);
* ``recovery``: the restart from the fix after gate lockout;
* ``tracking``: the boats' tracker;
* ``terms``: the reward's terms and the infos;
* ``cycle``: steps 3-5 composed into one kernel over the batch (``cycle``, and
  ``cycle_parallel`` for large batches);
* ``observe``: the boats' observation and their commands;
* ``simulator``: ``MovingNetworkSimulator``.

Steps 1-2 and 3-5 are compiled kernels written once over the batch
(``integrate_vehicle``, ``cycle``; the observation ``observe_boats``), so a batch of
one costs tens of microseconds; only what numpy computes differently from the C
library (arctan2, log) is left to numpy around them.

It implements the simulator contract (``core.contract.BatchedSimulator``) as
``core.sim.Simulator`` does, so every view, the trainers and the evaluation run it
unchanged.
"""

from __future__ import annotations

from ..dynamics import boat_noise_step, disturb_boats
from .cycle import cycle, cycle_parallel
from .filter import EXCHANGE_COVARIANCE, exchange_covariance_m2
from .observe import (
    command_velocity,
    frame_waypoints,
    gps_frame_of,
    observe_boats,
    observe_boats_parallel,
    observe_river,
)
from .simulator import MovingNetworkSimulator
from .state import (
    CYCLE_COUNTS,
    CYCLE_OUT,
    FRAME_INFO_KEYS,
    OBS_DIM,
    OBS_FIELDS,
    REINIT_AFTER_CYCLES,
    RIVER_LEAD_BASELINES,
    RIVER_OBS_DIM,
    RIVER_OBS_FIELDS,
    RIVER_STATE_DIM,
    TRACKER_ALPHA,
    TRACKER_BETA,
    Boats,
    CycleDraws,
    CycleParams,
    Filter,
    FrameState,
    ObserveParams,
    Tracker,
    Vehicle,
    VehicleParams,
    obs_dim_of,
    obs_fields,
)
from .vehicle import integrate_vehicle

__all__ = [
    "CYCLE_COUNTS",
    "CYCLE_OUT",
    "EXCHANGE_COVARIANCE",
    "FRAME_INFO_KEYS",
    "OBS_DIM",
    "OBS_FIELDS",
    "REINIT_AFTER_CYCLES",
    "RIVER_LEAD_BASELINES",
    "RIVER_OBS_DIM",
    "RIVER_OBS_FIELDS",
    "RIVER_STATE_DIM",
    "TRACKER_ALPHA",
    "TRACKER_BETA",
    "Boats",
    "CycleDraws",
    "CycleParams",
    "Filter",
    "FrameState",
    "MovingNetworkSimulator",
    "ObserveParams",
    "Tracker",
    "Vehicle",
    "VehicleParams",
    "boat_noise_step",
    "command_velocity",
    "cycle",
    "cycle_parallel",
    "disturb_boats",
    "exchange_covariance_m2",
    "frame_waypoints",
    "gps_frame_of",
    "integrate_vehicle",
    "obs_dim_of",
    "obs_fields",
    "observe_boats",
    "observe_boats_parallel",
    "observe_river",
]
