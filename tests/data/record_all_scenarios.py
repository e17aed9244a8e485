"""Record short episodes of every registered scenario through the batched core.

The refactor guard: ``tests/test_recorded.py`` replays the same episodes and compares
them with ``all_scenarios.npz``. On the machine that recorded them the arrays must be
equal bit for bit (``COOPNAV_BITWISE=1``); on another machine numpy's and numba's
vectorized ``sin``/``cos``/``exp`` may take another SIMD path (AVX2 against AVX-512)
and differ by an ulp or two, so by default each array is compared within a relative
tolerance of ``RTOL`` of its own scale (docs/reliability.md#reproducibility).

Every scenario runs with its defaults and with two overrides that switch on the
branches its defaults leave off (outliers, losses, surfacing, randomization), batch
sizes 1 and 3, ``STEPS`` cycles of actions drawn from a fixed generator (for the
moving network, 3x as many: its cycles are 2 s). Re-record with
``python tests/data/record_all_scenarios.py`` only when a change is meant to move
the physics, and say so in the commit.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

RUNS = ((1, (7,)), (3, (11, 12, 13)))  # (batch size, seeds)
STEPS = 20
RTOL = 1e-9  # relative to each array's largest magnitude (see the module docstring)
PATH = Path(__file__).with_name("all_scenarios.npz")
# variants that reach branches the defaults leave off; (name, overrides)
VARIANTS = {
    "matos_moving_lbl": {"outlier_probability": 0.05, "packet_loss_near": 0.05, "packet_loss_far": 0.5},
    "matos_river": {"outlier_probability": 0.05, "packet_loss_near": 0.05, "packet_loss_far": 0.5},
    "gao_sea": {"beacon_surface_every_s": 200.0, "randomize_noise_scale": (0.5, 2.0)},
    "sousa_asv": {
        "randomize_survey_path": ("lawnmower", "spiral"),
        "randomize_depth_m": (5.0, 20.0),
        "ranging_mode": "twtt",
        "sensor_nan_probability": 0.05,
    },
}


def scenarios() -> list:
    from coopnav_env.scenarios.base import list_scenarios

    return list_scenarios()


def record(scenario: str, batch: int, seeds, overrides=None) -> dict:
    import coopnav_env
    from coopnav_env.core import make_simulator

    config = coopnav_env.make_config(scenario, **(overrides or {}))
    sim = make_simulator(config, batch)
    steps = {"obs0": sim.reset(list(seeds))}
    rng = np.random.default_rng(1234)
    n_act = 3 if config.channel_mode == "decide" else 2
    n_steps = STEPS * (3 if config.network == "moving_lbl" else 1)
    for _ in range(n_steps):
        res = sim.step(rng.uniform(-1.0, 1.0, (batch, config.n_beacons, n_act)))
        row = {"obs": res.obs, "reward": res.reward, "terminated": res.terminated, "truncated": res.truncated}
        row.update({f"info.{k}": v for k, v in res.info.items()})
        row.update({f"term.{k}": np.asarray(v) for k, v in res.terms.items()})
        row.update({f"beacon.{k}": v for k, v in res.beacon_info.items()})
        row["state"] = sim.global_state()
        for k, v in row.items():
            steps.setdefault(k, []).append(np.array(v))
    return {k: np.asarray(v) if k == "obs0" else np.stack(v) for k, v in steps.items()}


def record_all() -> dict:
    arrays = {}
    for scenario in scenarios():
        for tag, overrides in (("default", None), ("variant", VARIANTS.get(scenario))):
            if tag == "variant" and overrides is None:
                continue
            for batch, seeds in RUNS:
                for k, v in record(scenario, batch, seeds, overrides).items():
                    arrays[f"{scenario}/{tag}/B{batch}/{k}"] = v
    return arrays


if __name__ == "__main__":
    np.savez_compressed(PATH, **record_all())
    print(PATH, PATH.stat().st_size, "bytes")
