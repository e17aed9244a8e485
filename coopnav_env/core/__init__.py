"""The batched simulator core: arrays in, arrays out; no PettingZoo, no plotting."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ._cache import clear_stale_kernels

if TYPE_CHECKING:
    from ..scenarios import ScenarioConfig
    from .contract import BatchedSimulator

clear_stale_kernels()  # numba's cache does not follow edits across modules (see _cache.py)


def make_simulator(config: ScenarioConfig, batch_size: int = 1) -> BatchedSimulator:
    """The simulator that reads ``config``: ``config.network`` chooses between the
    survey/beacon network (``sim.Simulator``) and the moving LBL network
    (``moving_network.MovingNetworkSimulator``). Both implement
    ``contract.BatchedSimulator``."""
    if config.network == "moving_lbl":
        from .moving_network import MovingNetworkSimulator

        return MovingNetworkSimulator(config, batch_size)
    from .sim import Simulator

    return Simulator(config, batch_size)
