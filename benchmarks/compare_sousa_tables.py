"""Our Table I/II (evaluate.py --sweep over depth x path for fim_a and fim_b) beside
Sousa, Ferreira & Cruz's, and the B - A differences against Table III's expectation.

    python evaluate.py --scenario sousa_asv --policies fim_a,fim_b --episodes 20 --seed 0 \\
        --sweep depth_m=1,5,20,50 --sweep survey_path=stationary,lawnmower,circle,spiral --out results/sousa_sweep
    python benchmarks/compare_sousa_tables.py results/sousa_sweep
"""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import numpy as np
from scipy import stats

try:
    from benchmarks import _args
except ImportError:  # run as a script: its own folder is on the path, not the checkout
    import _args  # type: ignore[no-redef]

depths = [1.0, 5.0, 20.0, 50.0]
paths = ["stationary", "lawnmower", "circle", "spiral"]
paper = {
    "fim_a": {
        1: [(0.810, 0.021), (0.689, 0.016), (0.575, 0.063), (1.970, 1.102)],
        5: [(1.720, 0.034), (1.362, 0.043), (1.255, 0.193), (2.016, 1.080)],
        20: [(1.820, 0.124), (1.482, 0.361), (1.488, 0.407), (2.530, 1.499)],
        50: [(1.78, 1.213), (2.309, 0.647), (2.135, 0.945), (3.542, 2.228)],
    },
    "fim_b": {
        1: [(0.690, 0.102), (0.659, 0.014), (0.537, 0.050), (4.309, 6.842)],
        5: [(1.730, 0.039), (1.415, 0.043), (1.170, 0.073), (4.933, 6.907)],
        20: [(1.817, 0.134), (1.479, 0.207), (5.637, 4.168), (5.041, 4.883)],
        50: [(1.568, 1.236), (2.150, 0.478), (5.074, 4.703), (5.375, 3.726)],
    },
}


def read_sweep(folder: Path) -> tuple[dict, list]:
    """The sweep's summary.json and episodes.csv; a ``ValueError`` (one line) if ``folder`` is
    not an ``evaluate.py --sweep`` result with fim_a and fim_b in every cell of the tables."""
    try:
        summary = json.loads((folder / "summary.json").read_text())
        with open(folder / "episodes.csv", newline="") as f:
            episodes = list(csv.DictReader(f))
    except FileNotFoundError as err:
        raise ValueError(f"{folder} is not an evaluate.py result folder: no {Path(err.filename).name}") from None
    except (OSError, json.JSONDecodeError, csv.Error) as err:
        raise ValueError(f"{folder}: cannot read its result files ({err})") from None
    cells = summary.get("cells") if isinstance(summary, dict) else None
    if not cells:
        raise ValueError(f"{folder} is not a --sweep result (its summary.json has no cells); run the sweep above")
    for d in depths:
        for p in paths:
            params = {"depth_m": d, "survey_path": p}
            found = next((c for c in cells if c.get("params") == params), None)
            missing = [pol for pol in ("fim_a", "fim_b") if found is None or pol not in found.get("policies", {})]
            if missing:
                raise ValueError(f"{folder}: the sweep has no {', '.join(missing)} at depth_m={d}, survey_path={p}")
    return summary, episodes


def main(argv: list[str] | None = None) -> int:
    parser = _args.Parser(description=(__doc__ or "").split("\n\n")[0])
    parser.add_argument("folder", help="the evaluate.py --sweep result folder (summary.json, episodes.csv)")
    args = parser.parse_args(argv)
    try:
        S, eps = read_sweep(Path(args.folder))
    except ValueError as err:
        print(f"compare_sousa_tables: {err}", file=sys.stderr)
        return 2

    def cell(d: float, p: str, pol: str) -> dict:
        return next(c for c in S["cells"] if c["params"] == {"depth_m": d, "survey_path": p})["policies"][pol]

    for pol, name in (("fim_a", "Table I (approach A)"), ("fim_b", "Table II (approach B)")):
        print(f"\n### {name}: ours mean / var  (paper mean / var)\n")
        print("| depth | " + " | ".join(paths) + " |")
        print("|---|---|---|---|---|")
        for d in depths:
            row = []
            for j, p in enumerate(paths):
                s = cell(d, p, pol)
                pm, pv = paper[pol][int(d)][j]
                row.append(f"{s['mean_error_m']:.3f} / {s['var_error_m2']:.3f} ({pm:.3f} / {pv:.3f})")
            print(f"| {int(d)} m | " + " | ".join(row) + " |")
    print("\n### B - A, paired per episode (mean and 95% t-interval, m); expectation of Table III; paper's sign\n")
    expect = {"stationary": "=", "lawnmower": "B<A", "circle": "B>A", "spiral": "B>A"}
    print("| depth | " + " | ".join(paths) + " |")
    print("|---|---|---|---|---|")
    for d in depths:
        row = []
        for j, p in enumerate(paths):
            cid = f"depth_m={d};survey_path={p}"
            a = {r["seed"]: float(r["mean_error_m"]) for r in eps if r["cell"] == cid and r["policy"] == "fim_a"}
            b = {r["seed"]: float(r["mean_error_m"]) for r in eps if r["cell"] == cid and r["policy"] == "fim_b"}
            diff = np.array([b[k] - a[k] for k in a])
            m = diff.mean()
            h = stats.t.ppf(0.975, len(diff) - 1) * diff.std(ddof=1) / np.sqrt(len(diff))
            sig = "B<A" if m + h < 0 else ("B>A" if m - h > 0 else "=")
            pdiff = paper["fim_b"][int(d)][j][0] - paper["fim_a"][int(d)][j][0]
            row.append(f"{m:+.3f} [{m - h:+.3f}, {m + h:+.3f}] {sig}; exp {expect[p]}; paper {pdiff:+.3f}")
        print(f"| {int(d)} m | " + " | ".join(row) + " |")
    print("\n### 50 m vs 1 m (ours)\n")
    for pol in ("fim_a", "fim_b"):
        shallow, deep = ([cell(d, p, pol) for p in paths] for d in (1.0, 50.0))
        verdicts = [
            "ok"
            if b["ci95_error_m"][0] > a["ci95_error_m"][1]
            else ("higher" if b["mean_error_m"] > a["mean_error_m"] else "NOT")
            for a, b in zip(shallow, deep)
        ]
        print(
            pol,
            [
                f"{p}: {a['mean_error_m']:.3f} -> {b['mean_error_m']:.3f} ({v})"
                for p, a, b, v in zip(paths, shallow, deep, verdicts)
            ],
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
