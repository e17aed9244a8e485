"""The beacon AUV's carried covariance, isotropic against full (eq. N1): what each does to
the beacon's own consistency and to the survey filter that fuses its ranges.

    python benchmarks/beacon_covariance.py --runs 100 --seed 900000 --cases 2

For each case of ``benchmarks/nees_per_cycle.py`` chosen (``--cases``, its numbers) and
each ``beacon_covariance`` (``"isotropic"``, ``"full"``), ``--runs`` episodes run as one
batch (seeds ``--seed`` + i; the same seeds for both, so the two columns share their
draws), the case's planner driving every beacon. Reported, over every run-cycle of the
first survey vehicle and the first beacon AUV:

* the beacon's own horizontal NEES e_b^T Sigma^-1 e_b against the covariance it carries
  (2 when consistent), and the same against m I2 (its mean is 2 for any Sigma of trace 2m:
  the mean cannot tell the two apart); the share of cycles without a GPS fix in which Sigma
  shrinks along some axis (Sigma_k+1 - Sigma_k not positive semi-definite), which the survey's consider
  states, a random walk for a DVL beacon (eq. C7, phi = 1), take for independent growth;
* the survey filter's horizontal NEES mean and its 99.9 % exceedances (x nominal);
* the survey's mean horizontal error |e_s|, its root mean square (what the filter
  minimizes), the share of run-cycles beyond 100 m, the 90th percentile of its episode
  means and its worst, and |e_s - e_b| ("survey error - beacon error"): its error relative
  to the beacon's own, the part ranges see (a range measures the survey's position relative
  to the beacon's true one). No cell holds a "|": the table is markdown.
"""

from __future__ import annotations

import sys

import numpy as np
from scipy.stats import chi2

try:
    from benchmarks import _args
except ImportError:  # run as a script: its own folder is on the path, not the checkout
    import _args  # type: ignore[no-redef]

COVARIANCES = ("isotropic", "full")
P999 = float(chi2.ppf(0.999, 2))


def _cases_module():
    """``benchmarks/nees_per_cycle.py``: its cases and its planner loop (a sibling when this
    runs as a script, the package's module under ``python -m``)."""
    try:
        from benchmarks import nees_per_cycle
    except ImportError:  # run as a script: its own folder is on the path, not the checkout
        import nees_per_cycle  # type: ignore[no-redef]
    return nees_per_cycle


def _nees(e: np.ndarray, S: np.ndarray) -> np.ndarray:
    return np.einsum("bi,bi->b", e, np.linalg.solve(S, e[..., None])[..., 0])


def covariance_figures(scenario: str, planner: str, overrides: dict, runs: int, seed: int) -> dict:
    """One case with one ``beacon_covariance`` (in ``overrides``): the figures above."""
    policy_steps = _cases_module().policy_steps
    own_full, own_iso, survey, err, rel, per_run, shrinks = [], [], [], [], [], [], []
    prev = None
    for cfg, sim, _res, live in policy_steps(scenario, planner, overrides, runs, seed):
        st = sim.state
        j = list(cfg.beacon_kinds).index("beacon_auv")
        eb = st.b_nav_err[:, j, :2]
        m, dev = st.b_nav_var_m2[:, j], st.b_nav_dev_m2[:, j]
        Sb = np.empty((len(m), 2, 2))
        Sb[:, 0, 0], Sb[:, 1, 1], Sb[:, 0, 1] = m + dev.real, m - dev.real, dev.imag
        Sb[:, 1, 0] = Sb[:, 0, 1]
        if prev is not None:  # a random walk's covariance only grows: Sigma_k+1 - Sigma_k >= 0
            lam = np.linalg.eigvalsh(Sb - prev)[:, 0]
            fixing = st.b_surfacings[:, j] > 0  # a GPS fix resets Sigma: eq. C8's business, not the walk's
            shrinks.append((lam < -1e-9 * np.abs(Sb).max(axis=(1, 2)))[live & ~fixing])
        prev = Sb
        es = st.s_est[:, 0, :2] - st.s_pos[:, 0, :2]
        own_full.append(_nees(eb, Sb)[live])
        own_iso.append(((eb * eb).sum(1) / m)[live])
        survey.append(_nees(es, st.s_P[:, 0, :2, :2])[live])
        err.append(np.linalg.norm(es, axis=1)[live])
        rel.append(np.linalg.norm(es - eb, axis=1)[live])
        per_run.append(np.where(live, np.linalg.norm(es, axis=1), np.nan))
    cat = np.concatenate
    ep_mean = np.nanmean(np.array(per_run), axis=0)
    s, r = cat(survey), cat(rel)
    return {
        "beacon NEES": float(cat(own_full).mean()),
        "beacon NEES vs m I2": float(cat(own_iso).mean()),
        # None (n/a) where every cycle had a GPS fix (gao_lawnmower surfaces every cycle): no walk to judge
        "cycles its Sigma shrinks along some axis": float(sh.mean()) if (sh := cat(shrinks or [[]])).size else None,
        "survey NEES": float(s.mean()),
        "survey > 99.9 % (x nominal)": float(np.mean(s > P999) / 0.001),
        "survey error mean (m)": float(cat(err).mean()),
        "survey error rms (m)": float(np.sqrt(np.mean(cat(err) ** 2))),
        "run-cycles survey error > 100 m": float(np.mean(cat(err) > 100.0)),
        "survey episode mean p90 (m)": float(np.percentile(ep_mean, 90)),
        "survey error worst (m)": float(cat(err).max()),
        "survey error - beacon error, mean (m)": float(r.mean()),
        "run-cycles survey error - beacon error > 20 m": float(np.mean(r > 20.0)),
    }


def _cell(value: float | None) -> str:
    """A table cell: the figure, or n/a where nothing was there to measure (never nan)."""
    return "n/a (a GPS fix every cycle)" if value is None else f"{value:.3f}"


def main(argv: list[str] | None = None) -> int:
    CASES = _cases_module().CASES
    ap = _args.Parser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=100, help="episodes per case and covariance (one batch)")
    ap.add_argument("--seed", type=int, default=900_000, help="run i uses seed SEED + i")
    ap.add_argument("--cases", default="2", help="comma-separated case numbers of nees_per_cycle.py")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE", help="a scenario override")
    ap.add_argument("--markdown", help="also write the table here")
    ap.add_argument("--overwrite", action="store_true", help="replace the --markdown file if it exists")
    args = ap.parse_args(argv)
    problem = _cases_module().check_run_args(args.runs, args.seed, args.markdown, args.overwrite)
    if problem is not None:
        print(problem, file=sys.stderr)
        return 2
    try:
        chosen = [int(i) for i in args.cases.split(",")]
        if any(not 0 <= i < len(CASES) for i in chosen):
            raise ValueError
    except ValueError:
        print(f"--cases must be numbers in [0, {len(CASES) - 1}], got {args.cases!r}", file=sys.stderr)
        return 2
    try:
        extra = _cases_module().parse_sets(args.set)
    except ValueError as err:
        print(err, file=sys.stderr)
        return 2
    if "beacon_covariance" in extra:
        print("--set beacon_covariance: it is what this script compares (both columns run)", file=sys.stderr)
        return 2
    import coopnav_env

    lines = []
    for i in chosen:
        label, scenario, planner, overrides = CASES[i]
        try:
            cfg = coopnav_env.make_config(scenario, **{**overrides, **extra})
        except ValueError as err:  # a --set the scenario refuses: its one line
            print(err, file=sys.stderr)
            return 2
        if "beacon_auv" not in cfg.beacon_kinds:
            print(f"case {i} ({label}) has no beacon AUV: nothing to compare", file=sys.stderr)
            return 2
        figs = {
            cov: covariance_figures(
                scenario, planner, {**overrides, **extra, "beacon_covariance": cov}, args.runs, args.seed
            )
            for cov in COVARIANCES
        }
        title = f"{label} ({planner}, {args.runs} runs, seeds {args.seed}-, set {extra or '-'})"
        lines += [f"**{title}**", "", "| figure | isotropic | full |", "|---|---|---|"]
        for key in figs["isotropic"]:
            iso, full = (figs[cov][key] for cov in COVARIANCES)
            lines.append(f"| {key} | {_cell(iso)} | {_cell(full)} |")
        lines.append("")
    text = "\n".join(lines)
    print(text)
    if args.markdown:
        from coopnav_env.records import atomic_write_text

        atomic_write_text(args.markdown, text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
