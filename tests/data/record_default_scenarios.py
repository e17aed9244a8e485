"""Record 20-step episodes of the existing scenarios through the batched core.

``tests/test_channel.py`` replays the same episodes and compares them with
``default_scenarios.npz`` bit for bit (np.array_equal): the acoustic channel of
``channel_mode="decide"`` must leave the fixed-clock scenarios untouched. The
arrays were recorded with the code before the channel existed (run this file to
re-record: ``python tests/data/record_default_scenarios.py``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

SCENARIOS = ("gao_lawnmower", "gao_sea", "sousa_asv", "swarm_mls")
RUNS = ((1, (7,)), (3, (11, 12, 13)))  # (batch size, seeds)
STEPS = 20
PATH = Path(__file__).with_name("default_scenarios.npz")


def record(scenario: str, batch: int, seeds) -> dict:
    import coopnav_env
    from coopnav_env.core import make_simulator

    config = coopnav_env.make_config(scenario)
    sim = make_simulator(config, batch)
    steps = {"obs0": sim.reset(list(seeds))}
    rng = np.random.default_rng(1234)
    for _ in range(STEPS):
        res = sim.step(rng.uniform(-1.0, 1.0, (batch, config.n_beacons, 2)))
        row = {"obs": res.obs, "reward": res.reward, "terminated": res.terminated, "truncated": res.truncated}
        row.update({f"info.{k}": v for k, v in res.info.items()})
        row.update({f"term.{k}": np.asarray(v) for k, v in res.terms.items()})
        row.update({f"beacon.{k}": v for k, v in res.beacon_info.items()})
        for k, v in row.items():
            steps.setdefault(k, []).append(v)
    # one array per quantity, steps along the first axis
    return {k: np.asarray(v) if k == "obs0" else np.stack(v) for k, v in steps.items()}


def record_all() -> dict:
    arrays = {}
    for scenario in SCENARIOS:
        for batch, seeds in RUNS:
            for k, v in record(scenario, batch, seeds).items():
                arrays[f"{scenario}/B{batch}/{k}"] = v
    return arrays


if __name__ == "__main__":
    np.savez_compressed(PATH, **record_all())
    print(PATH, PATH.stat().st_size, "bytes")
