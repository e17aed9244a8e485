"""The tank experiment of Kottege & Zimmer (Acoustics '08, section 3), simulated.

    python benchmarks/mls_tank.py                   # table beside the paper's Table 1
    python benchmarks/mls_tank.py --json            # one JSON object
    python benchmarks/mls_tank.py --mode analytic --seed 3 --estimator paper

Setup (paper): hydrophone base d = 0.3 m, projector spacing l = 0.5 m, f_s = 96 kHz,
5 Hz updates, the sender fixed at 1.00 m with a relative heading of 150 deg when the
azimuth is 0, the observer rotated in place so that the azimuth sweeps
-90 -> 0 -> +90 deg (the relative heading then sweeps 60 -> 150 -> 240 deg). Ground
truth is the geometry (the gantry's role), unfolded. Statistics are the paper's
(eqs. 15-19): mean error, standard deviation (1/m) and average deviation.

What the paper does not give, and what we assume (stated, not fitted to Table 1):

* sweep rate 3 deg/s, i.e. 301 events at 5 Hz over 60 s (--events);
* MLS of order 10 (1023 chips at 96 kHz) in a 4-40 kHz transducer pass band;
* in-band SNR per sample of 20 dB at 1 m (--snr-db): a modest figure for a small
  projector in a quiet tank; the errors here are dominated by the sub-sample
  interpolation and the geometry, not by noise, down to about 0 dB;
* one reflection, the tank's surface, above both rigs at 0.5 m depth, with
  coefficient -0.9 (a near pressure-release surface); the 4.2 m tank's corrugated
  walls and its bottom are farther and arrive after the direct paths' peaks
  (--no-reflection to leave it out);
* fresh tap water at 20 degC (Mackenzie at 0 psu: 1481.7 m/s), known to the receiver;
* perfect synchronisation of the TOAs (sender and observer on one clock in the tank).
"""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Sequence
from typing import Any

import numpy as np

from coopnav_env.core.mls import (
    MLSConfig,
    MLSSensor,
    PeakTracker,
    Reflection,
    error_statistics,
    geometric_truth,
    wrap_angle_rad,
)

try:
    from benchmarks import _args
except ImportError:  # run as a script: its own folder is on the path, not the checkout
    import _args  # type: ignore[no-redef]

PAPER_TABLE_1 = {
    "azimuth_mean_deg": 0.00,
    "azimuth_std_deg": 2.39,
    "azimuth_avgdev_deg": 1.83,
    "range_mean_mm": 0.64,
    "range_std_mm": 6.77,
    "range_avgdev_mm": 3.65,
    "heading_mean_deg": 0.62,
    "heading_std_deg": 7.59,
    "heading_avgdev_deg": 5.40,
}
HEADLINE = {  # the paper's headline bounds (absolute values of the means; average deviation)
    "azimuth_mean_deg": 0.3,
    "azimuth_avgdev_deg": 2.0,
    "range_mean_mm": 10.0,
    "heading_mean_deg": 5.0,
}

RANGE_M = 1.00
HEADING_AT_ZERO_DEG = 150.0
UPDATE_HZ = 5.0


def tank_config(snr_db: float = 20.0, reflection: bool = True, estimator: str = "exact", **overrides: Any) -> MLSConfig:
    """The sensor as set up in the tank (see the module docstring for the assumptions)."""
    kw = dict(
        hydrophone_base_m=0.3,
        projector_spacing_m=0.5,
        sample_rate_hz=96_000.0,
        snr_db_at_1m=snr_db,
        water_temperature_c=20.0,
        salinity_psu=0.0,
        depth_m=0.5,
        max_range_m=3.0,
        estimator=estimator,
        reflection=Reflection(kind="surface", coefficient=-0.9) if reflection else None,
    )
    kw.update(overrides)
    return MLSConfig(**kw)


def sweep_poses(n_events: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sender and observer poses of the sweep: the sender fixed at (1, 0) m with world
    heading 150 deg, the observer at the origin rotated so the azimuth goes -90 -> +90 deg."""
    az = np.radians(np.linspace(-90.0, 90.0, n_events))
    observer_heading = -az  # rotating the observer by -az puts the sender at az
    sender_pos = np.array([RANGE_M, 0.0])
    sender_heading = math.radians(HEADING_AT_ZERO_DEG)
    return sender_pos, sender_heading, observer_heading


def run_sweep(
    n_events: int = 301,
    seed: int = 0,
    mode: str = "signal",
    snr_db: float = 20.0,
    reflection: bool = True,
    estimator: str = "exact",
) -> dict:
    """Run the sweep; returns a dict of the errors (rad, m) and the truth azimuths (rad)."""
    sensor = MLSSensor(tank_config(snr_db, reflection, estimator))
    sender_pos, sender_heading, obs_heading = sweep_poses(n_events)
    rng = np.random.default_rng(seed)
    obs_pos = np.zeros(2)
    true_az, true_r, true_hd = geometric_truth(sender_pos, sender_heading, obs_pos, obs_heading)
    if mode == "signal":
        tracker = PeakTracker()  # one link, tracked over the sweep
        az = np.empty(n_events)
        rr = np.empty(n_events)
        hd = np.empty(n_events)
        for k in range(n_events):
            m = sensor.measure_signal(sender_pos, sender_heading, obs_pos, obs_heading[k], rng, tracker)
            az[k], rr[k], hd[k] = m.azimuth_rad, m.range_m, m.heading_rad
    elif mode == "analytic":
        m = sensor.measure_analytic(
            np.broadcast_to(sender_pos, (n_events, 2)),
            np.full(n_events, sender_heading),
            np.zeros((n_events, 2)),
            obs_heading,
            rng=rng,
        )
        az, rr, hd = m.azimuth_rad, m.range_m, m.heading_rad
    else:
        raise ValueError(f"mode must be 'signal' or 'analytic', got {mode!r}")
    return {
        "true_azimuth_rad": true_az,
        "azimuth_err_rad": wrap_angle_rad(az - true_az),
        "range_err_m": rr - true_r,
        "heading_err_rad": wrap_angle_rad(hd - true_hd),
        "sound_speed_mps": sensor.sound_speed_true_mps,
    }


def statistics(errs: dict) -> dict:
    """The paper's statistics (eqs. 15-19) in the units of Table 1, plus the largest
    errors near the ends of the sweep (|azimuth| >= 80 deg) and elsewhere."""
    out = {}
    for key, scale, unit in (
        ("azimuth", 180.0 / math.pi, "deg"),
        ("range", 1e3, "mm"),
        ("heading", 180.0 / math.pi, "deg"),
    ):
        e = errs[f"{key}_err_rad" if key != "range" else "range_err_m"] * scale
        mu, sigma, avgdev = error_statistics(e)
        out[f"{key}_mean_{unit}"] = float(mu)
        out[f"{key}_std_{unit}"] = float(sigma)
        out[f"{key}_avgdev_{unit}"] = float(avgdev)
        near = np.abs(np.degrees(errs["true_azimuth_rad"])) >= 80.0
        out[f"{key}_maxabs_near_90_{unit}"] = float(np.max(np.abs(e[near])))
        out[f"{key}_maxabs_within_80_{unit}"] = float(np.max(np.abs(e[~near])))
    return out


def headline_checks(stats: dict) -> dict:
    return {
        "azimuth_mean_under_0.3_deg": abs(stats["azimuth_mean_deg"]) < HEADLINE["azimuth_mean_deg"],
        "azimuth_avgdev_under_2.0_deg": stats["azimuth_avgdev_deg"] < HEADLINE["azimuth_avgdev_deg"],
        "range_mean_under_10_mm": abs(stats["range_mean_mm"]) < HEADLINE["range_mean_mm"],
        "heading_mean_under_5_deg": abs(stats["heading_mean_deg"]) < HEADLINE["heading_mean_deg"],
    }


def _parse(argv=None):
    ap = _args.Parser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--mode", choices=("signal", "analytic"), default="signal")
    ap.add_argument("--events", type=int, default=301, help="events in the sweep (5 Hz; default 301 = 60 s)")
    ap.add_argument("--snr-db", type=float, default=20.0, help="in-band SNR per sample at 1 m (dB)")
    ap.add_argument("--no-reflection", action="store_true", help="leave out the surface reflection")
    ap.add_argument(
        "--estimator",
        choices=("exact", "paper"),
        default="exact",
        help="exact: near-field sub-azimuths and midpoint azimuth; paper: eqs. (2)-(5) as printed",
    )
    args = ap.parse_args(argv)
    _args.count(ap, args.events, "--events", low=3, bound="MAX_EVENTS")
    _args.seeds(ap, args.seed)
    _args.number(ap, args.snr_db, "--snr-db", low=-math.inf)
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = _parse(argv)
    errs = run_sweep(args.events, args.seed, args.mode, args.snr_db, not args.no_reflection, args.estimator)
    stats = statistics(errs)
    checks = headline_checks(stats)
    if args.json:
        out = dict(stats)
        out.update(
            {
                "mode": args.mode,
                "seed": args.seed,
                "events": args.events,
                "snr_db_at_1m": args.snr_db,
                "reflection": "none" if args.no_reflection else "surface, 0.5 m depth, coefficient -0.9",
                "estimator": args.estimator,
                "sound_speed_mps": errs["sound_speed_mps"],
                "paper_table_1": PAPER_TABLE_1,
                "headline_checks": checks,
                "headline_met": all(checks.values()),
            }
        )
        print(json.dumps(out, sort_keys=False))
        return 0 if all(checks.values()) else 1
    print(
        f"MLS tank sweep: {args.events} events, mode {args.mode}, seed {args.seed}, SNR {args.snr_db:g} dB at 1 m, "
        f"{'no reflection' if args.no_reflection else 'surface reflection'}, estimator {args.estimator}, "
        f"c = {errs['sound_speed_mps']:.1f} m/s"
    )
    print()
    print(f"{'statistic (eqs. 15-19)':34s} {'ours':>9s} {'paper':>9s}")
    for key, label in (
        ("azimuth_mean_deg", "azimuth mean error (deg)"),
        ("azimuth_std_deg", "azimuth std (deg)"),
        ("azimuth_avgdev_deg", "azimuth average deviation (deg)"),
        ("range_mean_mm", "range mean error (mm)"),
        ("range_std_mm", "range std (mm)"),
        ("range_avgdev_mm", "range average deviation (mm)"),
        ("heading_mean_deg", "heading mean error (deg)"),
        ("heading_std_deg", "heading std (deg)"),
        ("heading_avgdev_deg", "heading average deviation (deg)"),
    ):
        print(f"{label:34s} {stats[key]:9.2f} {PAPER_TABLE_1[key]:9.2f}")
    print()
    print(
        f"largest |error| at |azimuth| >= 80 deg: azimuth {stats['azimuth_maxabs_near_90_deg']:.2f} deg, "
        f"range {stats['range_maxabs_near_90_mm']:.2f} mm, heading {stats['heading_maxabs_near_90_deg']:.2f} deg"
    )
    print(
        f"largest |error| at |azimuth| <  80 deg: azimuth {stats['azimuth_maxabs_within_80_deg']:.2f} deg, "
        f"range {stats['range_maxabs_within_80_mm']:.2f} mm, heading {stats['heading_maxabs_within_80_deg']:.2f} deg"
    )
    print()
    for name, ok in checks.items():
        print(f"{name:32s} {'met' if ok else 'NOT met'}")
    return 0 if all(checks.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
