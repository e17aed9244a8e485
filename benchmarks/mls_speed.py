"""Time to process one MLS sending event at signal level, on one core.

    python benchmarks/mls_speed.py                  # 200 events, readable
    python benchmarks/mls_speed.py --events 500 --json

An event is two chirps (bow, stern) on two hydrophones: four channels of nfft
samples. *Processing* (``MLSSensor.process``, the sensor's own work) is: one batched
real FFT of the four channels, four matched filters against the precomputed replica
spectrum and two channel cross-correlations (two batched inverse FFTs), six tracked
peak searches, one cubic spline over the six peaks (scipy CubicSpline with a
(2K+1) x 6 right-hand side) with closed-form stationary points, and eqs. (1)-(10).
*Synthesis* (``MLSSensor.synthesize``, the simulator's work: phase shifts, noise,
band pass) is timed separately, and the sum. Poses vary from event to event over
0.5-5 m and all azimuths; the peak tracker is carried along one link. Threads are
limited to one before numpy is imported. Target: processing under 5 ms per event.
This is a script, not a test: nothing is timed under pytest.
"""

from __future__ import annotations

import os
from collections.abc import Sequence

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import json  # noqa: E402
import math  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from coopnav_env.core.mls import MLSConfig, MLSSensor, PeakTracker, Reflection  # noqa: E402

try:
    from benchmarks import _args
except ImportError:  # run as a script: its own folder is on the path, not the checkout
    import _args  # type: ignore[no-redef]

TARGET_MS = 5.0


def main(argv: Sequence[str] | None = None) -> int:
    ap = _args.Parser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--events", type=int, default=200)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    _args.count(ap, args.events, "--events", low=10, bound="MAX_EVENTS")
    _args.seeds(ap, args.seed)
    try:
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})  # one core
    except (AttributeError, OSError):
        pass
    sensor = MLSSensor(MLSConfig(reflection=Reflection("surface", -0.9)))
    rng = np.random.default_rng(args.seed)
    tracker = PeakTracker()
    # warm-up (imports, FFT plans)
    for _ in range(10):
        ch = sensor.synthesize(np.array([2.0, 0.5]), 1.0, np.zeros(2), 0.0, rng)
        sensor.process(ch, tracker)
    tracker.reset()
    t_syn, t_proc = [], []
    for _ in range(args.events):
        r = rng.uniform(0.5, 5.0)
        az = rng.uniform(-math.pi, math.pi)
        sp = np.array([r * math.cos(az), r * math.sin(az)])
        hd = rng.uniform(-math.pi, math.pi)
        t0 = time.perf_counter()
        ch = sensor.synthesize(sp, hd, np.zeros(2), 0.0, rng)
        t1 = time.perf_counter()
        sensor.process(ch, tracker)
        t2 = time.perf_counter()
        t_syn.append(t1 - t0)
        t_proc.append(t2 - t1)
    t_syn = np.array(t_syn) * 1e3
    t_proc = np.array(t_proc) * 1e3
    tot = t_syn + t_proc
    res = {
        "events": args.events,
        "nfft": sensor.nfft,
        "mls_chips": sensor.n_chips,
        "process_median_ms": float(np.median(t_proc)),
        "process_p90_ms": float(np.percentile(t_proc, 90)),
        "synthesize_median_ms": float(np.median(t_syn)),
        "synthesize_p90_ms": float(np.percentile(t_syn, 90)),
        "total_median_ms": float(np.median(tot)),
        "total_p90_ms": float(np.percentile(tot, 90)),
        "target_ms": TARGET_MS,
        "met": bool(np.median(t_proc) < TARGET_MS),
        "machine": platform.machine(),
        "python": platform.python_version(),
        "loadavg": os.getloadavg() if hasattr(os, "getloadavg") else None,
    }
    if args.json:
        print(json.dumps(res))
        return 0
    print(
        f"MLS event ({sensor.n_chips} chips, 2 chirps x 2 hydrophones, nfft {sensor.nfft}), "
        f"{args.events} events, one core"
    )
    print(f"{'':12s} {'median ms':>10s} {'p90 ms':>10s}")
    for name, t in (("process", t_proc), ("synthesize", t_syn), ("total", tot)):
        print(f"{name:12s} {np.median(t):10.3f} {np.percentile(t, 90):10.3f}")
    print(
        f"processing under {TARGET_MS:g} ms per event: {'met' if res['met'] else 'NOT met'} "
        f"(load average {res['loadavg'][0]:.2f})"
        if res["loadavg"]
        else ""
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
