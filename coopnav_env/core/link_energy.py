"""The modem's electrical side for ``core.link`` (which re-exports all of it): the
power a source level costs and the energy of a packet sent or received (Urick 1983's
source level of a 1 W source; the efficiency and receive power are [U] as in
``PowerModel``). Split from ``link`` to keep each module of the core readable in one
sitting (``tests/test_kernel_shape.py``)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import vectorize
from numpy.typing import ArrayLike

# Urick 1983: a 1 W omnidirectional acoustic source gives 170.8 dB re 1 uPa at 1 m
# (intensity 1 W / (4 pi m^2) over rho c = 1.5e6 rayl; 10 log10 of (p / 1 uPa)^2).
SL_ONE_WATT_DB = 170.8


class PowerModel(NamedTuple):
    """Electrical side of the modem.

    - ``efficiency`` 0.25 [U]: acoustic over electrical power of amplifier and
      transducer.
    - ``receive_power_w`` 0.3 [U] and ``idle_power_w`` 0.08 [U]: the modem's draw while
      receiving and while listening idle (not in a primary source here).
    """

    efficiency: float = 0.25
    receive_power_w: float = 0.3
    idle_power_w: float = 0.08


DEFAULT_POWER = PowerModel()


# ------------------------------------------------------------------------- energy


@vectorize(["float64(float64, float64)"], cache=True)
def acoustic_power_w(source_level_db: float, transmit_directivity_index_db: float) -> float:
    """Radiated acoustic power (W) for a source level: SL = 170.8 + 10 log10(P) + DI
    (Urick 1983), so P = 10^((SL - 170.8 - DI) / 10); DI the *transmitting* transducer's,
    which SL includes (the receiver's is ``link.LinkParams.receive_directivity_index_db``)."""
    return 10.0 ** ((source_level_db - SL_ONE_WATT_DB - transmit_directivity_index_db) / 10.0)


def electrical_power_w(
    source_level_db: ArrayLike, power: PowerModel = DEFAULT_POWER, transmit_directivity_index_db: float = 0.0
) -> np.ndarray:
    """Electrical power while transmitting (W): acoustic power / efficiency."""
    return acoustic_power_w(np.asarray(source_level_db, float), transmit_directivity_index_db) / power.efficiency


def source_level_from_power_db(
    electrical_power_w: ArrayLike, power: PowerModel = DEFAULT_POWER, transmit_directivity_index_db: float = 0.0
) -> np.ndarray:
    """The source level a modem drawing ``electrical_power_w`` while transmitting
    radiates: SL = 170.8 + 10 log10(efficiency x P_electrical) + DI (dB re 1 uPa at
    1 m; Urick 1983). The inverse of ``electrical_power_w``."""
    p_ac = np.asarray(electrical_power_w, float) * power.efficiency
    return SL_ONE_WATT_DB + 10.0 * np.log10(p_ac) + transmit_directivity_index_db


def transmit_energy_j(
    source_level_db: ArrayLike,
    duration_s: ArrayLike,
    power: PowerModel = DEFAULT_POWER,
    transmit_directivity_index_db: float = 0.0,
) -> np.ndarray:
    """Electrical energy of a transmission (J): electrical power x duration."""
    return electrical_power_w(source_level_db, power, transmit_directivity_index_db) * np.asarray(duration_s, float)


def receive_energy_j(duration_s: ArrayLike, power: PowerModel = DEFAULT_POWER) -> np.ndarray:
    """Energy spent receiving for ``duration_s`` (J): receive power x duration."""
    return power.receive_power_w * np.asarray(duration_s, float)
