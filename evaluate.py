#!/usr/bin/env python
"""Evaluate policies on a coopnav scenario, headless, with common random numbers.

    python evaluate.py --scenario sousa_asv --policies fim_a,fim_b,ellipse,circle,static \\
        --episodes 50 --seed 0 --out results/sousa
    python evaluate.py --scenario sousa_asv --policies fim_a,fim_b --episodes 20 \\
        --sweep depth_m=1,5,20,50 --sweep survey_path=stationary,lawnmower,circle,spiral --out results/sweep

Episode ``i`` of every policy (and of every sweep cell) uses seed ``--seed + i``;
the simulator's random numbers are counter-based per environment, so every policy
sees the same currents, sensor noise and range noise (common random numbers).
Policies act only on their observation vectors (see ``baselines``).

Outputs in ``--out`` (each written to a temporary file and renamed into place, so
an interrupted run leaves no half-written file):

* ``episodes.csv``: one row per episode, policy and sweep cell;
* ``steps.csv``: one row per step of every episode (errors, ellipse axes), from
  which the summary's pooled statistics and the figures are computed;
* ``summary.json`` and ``summary.md``: per policy (and cell) the error statistics
  over all steps of all episodes (mean, median, p95, std, variance, a 95 %
  cluster-bootstrap interval of the mean over episodes), final error, return,
  ranges fused, outliers rejected, beacon distance; a sweep adds the Table I/II
  layout (mean error / variance per cell) for each policy;
* PNG figures: ``paths.png`` (both vehicles' paths in episode 0 per policy),
  ``error_vs_time.png`` (survey error against time, dead reckoning beside it;
  Gao & Chitre Figs. 7 and 11), ``ellipse_axes.png`` (2-sigma ellipse semi-axes
  against time; Matos & Cruz Fig. 8); a sweep draws ``sweep.png`` instead.

``--resume`` keeps the episodes already in ``episodes.csv``/``steps.csv`` (same
scenario and ``--set`` overrides) and runs only the missing ones. Bad input (an
unknown policy, scenario or parameter, a bad value, an output path that is a
file) is a one-line error and exit status 2 before any work.
"""

from __future__ import annotations

import argparse
import ast
import csv
import dataclasses
import io
import json
import os
import sys
import tempfile

import numpy as np

EPISODE_COLUMNS = ["cell", "policy", "episode", "seed", "steps", "duration_s", "mean_error_m", "final_error_m",
                   "max_error_m", "mean_dr_error_m", "final_dr_error_m", "return", "ranges_fused",
                   "outliers_rejected", "packets_lost", "beacon_distance_m", "safety_violations",
                   "geofence_violations"]
STEP_COLUMNS = ["cell", "policy", "episode", "seed", "step", "t_s", "survey_error_m", "dr_error_m",
                "ellipse_major_m", "ellipse_minor_m", "reward", "beacon_distance_m", "error_x_m", "error_y_m"]
# error_x_m, error_y_m: signed errors in the moving frame (network="moving_lbl" only; blank otherwise)


class UsageError(Exception):
    """Bad input: reported as one line, exit status 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        raise UsageError(message)


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="evaluate.py", description="Evaluate coopnav policies on seeded episodes.")
    p.add_argument("--scenario", default="gao_lawnmower", help="scenario name (coopnav_env.list_scenarios())")
    p.add_argument("--policies", default=None,
                   help="comma-separated policy names (default: every baseline that can drive the scenario, "
                        "baselines.list_policies(network))")
    p.add_argument("--episodes", type=int, default=10, help="episodes per policy (and per sweep cell)")
    p.add_argument("--seed", type=int, default=0, help="episode i uses seed SEED + i")
    p.add_argument("--out", default="results/eval", help="output directory")
    p.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario parameter for the whole run (repeatable)")
    p.add_argument("--sweep", dest="sweeps", action="append", default=[], metavar="KEY=V1,V2,...",
                   help="run the grid of these values (repeatable; the first key makes the rows)")
    p.add_argument("--resume", action="store_true", help="skip the episodes already in episodes.csv")
    p.add_argument("--batch-size", type=int, default=25, help="episodes simulated together")
    p.add_argument("--no-figures", action="store_true", help="write no PNG files")
    return p


# ------------------------------------------------------------------------------------
# input parsing and validation (all before any work)

def split_top_level(text: str) -> list:
    """Split on commas that are not inside brackets: '1,(2,3)' -> ['1', '(2,3)']."""
    out, depth, cur = [], 0, []
    for ch in text:
        if ch in "([{":
            depth += 1
        elif ch in ")]}":
            depth -= 1
        if ch == "," and depth == 0:
            out.append("".join(cur))
            cur = []
        else:
            cur.append(ch)
    out.append("".join(cur))
    return [s.strip() for s in out]


def _to_tuple(v):
    return tuple(_to_tuple(x) for x in v) if isinstance(v, (list, tuple)) else v


def parse_value(key: str, text: str):
    """Parse ``text`` as the type of scenario parameter ``key``."""
    from coopnav_env.scenarios import ScenarioConfig
    from coopnav_env.scenarios.base import check_overrides

    check_overrides({key: None})
    default = {f.name: f.default for f in dataclasses.fields(ScenarioConfig)}[key]
    text = text.strip()
    if text == "":
        raise UsageError(f"empty value for {key}")
    try:
        if isinstance(default, bool):
            low = text.lower()
            if low not in ("true", "false", "1", "0", "yes", "no"):
                raise ValueError
            return low in ("true", "1", "yes")
        if isinstance(default, int):
            v = float(text)
            if not v.is_integer():
                raise ValueError
            return int(v)
        if isinstance(default, float):
            return float(text)
        if isinstance(default, tuple):
            v = ast.literal_eval(text)
            if not isinstance(v, (list, tuple)):
                v = (v,)
            if default and not isinstance(default[0], (tuple, list)) and len(v) != len(default):
                raise UsageError(f"{key} takes {len(default)} values, got {len(v)}")
            return _to_tuple(v)
        return text
    except (ValueError, SyntaxError):
        raise UsageError(f"bad value {text!r} for {key} (a {type(default).__name__})") from None


def parse_assignment(item: str, option: str):
    if "=" not in item:
        raise UsageError(f"{option} expects KEY=VALUE, got {item!r}")
    key, value = item.split("=", 1)
    return key.strip(), value


def cell_id(cell: dict) -> str:
    return ";".join(f"{k}={v}" for k, v in cell.items())


def prepare(args) -> dict:
    """Validate every input and build the run plan; raises UsageError."""
    import coopnav_env
    from baselines import list_policies

    scenarios = coopnav_env.list_scenarios()
    if args.scenario not in scenarios:
        raise UsageError(f"unknown scenario {args.scenario!r}; valid scenarios: {', '.join(scenarios)}")
    if args.policies is None:  # every planner that drives this scenario's network
        args.policies = ",".join(list_policies(coopnav_env.make_config(args.scenario).network))
    policies = [p.strip() for p in args.policies.split(",") if p.strip()]
    if not policies:
        raise UsageError("no policy given")
    valid = list_policies()
    for p in policies:
        if p not in valid:
            try:  # a trained policy: "ppo" (the scenario's shipped one), a shipped name, or a run directory
                import agents

                agents.resolve(p, args.scenario)
            except Exception as err:  # noqa: BLE001 - any failure to find it is a usage error
                raise UsageError(f"unknown policy {p!r} ({err}); valid: {', '.join(valid)}, ppo, a shipped policy "
                                 f"({', '.join(agents.list_policies()) or 'none shipped'}) or a train.py run "
                                 "directory") from None
    if len(set(policies)) != len(policies):
        raise UsageError("a policy is listed twice")
    if args.episodes < 1:
        raise UsageError(f"--episodes must be >= 1, got {args.episodes}")
    if args.seed < 0:
        raise UsageError(f"--seed must be >= 0, got {args.seed}")
    if args.batch_size < 1:
        raise UsageError(f"--batch-size must be >= 1, got {args.batch_size}")
    try:
        overrides = {}
        for item in args.sets:
            key, value = parse_assignment(item, "--set")
            overrides[key] = parse_value(key, value)
        sweep = {}
        for item in args.sweeps:
            key, value = parse_assignment(item, "--sweep")
            if key in sweep:
                raise UsageError(f"--sweep {key} given twice")
            if key in overrides:
                raise UsageError(f"{key} is both --set and --sweep")
            values = [parse_value(key, v) for v in split_top_level(value)]
            if len(set(map(repr, values))) != len(values):
                raise UsageError(f"--sweep {key} repeats a value")
            sweep[key] = values
        cells = [{}]
        for key, values in sweep.items():
            cells = [dict(c, **{key: v}) for c in cells for v in values]
        configs = {}
        for cell in cells:
            configs[cell_id(cell)] = coopnav_env.make_config(args.scenario, **overrides, **cell)
    except ValueError as err:  # unknown parameter or invalid value, from the scenario's checks
        raise UsageError(str(err).splitlines()[0]) from None
    out = args.out
    if os.path.exists(out) and not os.path.isdir(out):
        raise UsageError(f"output path {out!r} is a file, not a directory")
    parent = os.path.dirname(os.path.abspath(out))
    while parent and not os.path.exists(parent):
        parent = os.path.dirname(parent)
    if parent and not os.path.isdir(parent):
        raise UsageError(f"output path {out!r} is under a file ({parent!r})")
    run_info = {"scenario": args.scenario, "overrides": {k: _jsonable(v) for k, v in overrides.items()},
                "sweep": {k: [_jsonable(v) for v in vs] for k, vs in sweep.items()}, "seed": args.seed,
                "episodes": args.episodes, "policies": policies}
    if args.resume:
        old = _read_json(os.path.join(out, "run.json"))
        if old is not None and (old.get("scenario") != run_info["scenario"]
                                or old.get("overrides") != run_info["overrides"]):
            raise UsageError(f"cannot resume: {out!r} holds a run of {old.get('scenario')!r} with overrides "
                             f"{old.get('overrides')}, not {args.scenario!r} with {run_info['overrides']}")
    return {"policies": policies, "cells": cells, "configs": configs, "sweep": sweep, "overrides": overrides,
            "run_info": run_info}


def _jsonable(v):
    return list(map(_jsonable, v)) if isinstance(v, tuple) else v


def _read_json(path):
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError):
        return None


# ------------------------------------------------------------------------------------
# atomic output

def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write_bytes(path: str, data: bytes):
    """Write ``data`` to a temporary file beside ``path`` and rename it into place."""
    d = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(dir=d, prefix="." + os.path.basename(path) + ".", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def atomic_write_text(path: str, text: str):
    atomic_write_bytes(path, text.encode("utf-8"))


def csv_text(columns, rows) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=columns, extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: _fmt(r.get(k, "")) for k in columns})
    return buf.getvalue()


def _fmt(v):
    if isinstance(v, (float, np.floating)):
        return f"{float(v):.6g}"
    return v


def read_csv(path):
    try:
        with open(path, newline="") as f:
            return list(csv.DictReader(f))
    except OSError:
        return []


# ------------------------------------------------------------------------------------
# running episodes

def make_policy(name: str, config, seed, agent: int):
    """A planner from baselines/ by name, else a trained policy through agents/ (same interface)."""
    import baselines

    if name in baselines.list_policies():
        return baselines.make_policy(name, config, seed=seed, agent=agent)
    import agents

    return agents.make_policy(name, config, seed=seed, agent=agent)


def run_episodes(config, policy_name: str, seeds, progress=None):
    """Run ``policy_name`` (one instance per beacon and episode) on episodes ``seeds``
    as one batch. Returns (episode rows, step rows) without cell/policy columns."""
    from coopnav_env.core.information import error_ellipse
    from coopnav_env.core import make_simulator

    seeds = [int(s) for s in seeds]
    B, N = len(seeds), config.n_beacons
    sim = make_simulator(config, batch_size=B)
    obs = sim.reset(seeds)
    policies = [[make_policy(policy_name, config, seed=(s, j), agent=j) for j in range(N)] for s in seeds]
    T = config.ping_interval_s
    done = np.zeros(B, dtype=bool)
    hist = {k: [] for k in ("alive", "err", "dr", "major", "minor", "reward", "dist", "fused", "rejected", "lost",
                             "unsafe", "outside", "ex", "ey")}
    frame = config.network == "moving_lbl"
    fe0, fn0, fe1, fn1 = config.geofence_m
    actions = np.zeros((B, N, 2))
    while not done.all():
        for b in np.flatnonzero(~done):
            for j in range(N):
                actions[b, j] = policies[b][j].act(obs[b, j])
        actions[done] = 0.0
        res = sim.step(actions)
        obs = res.obs
        st = sim.state
        major, minor, _ = error_ellipse(st.s_P)
        dist = np.linalg.norm(st.s_pos[:, None, :, :] - st.b_pos[:, :, None, :], axis=-1)  # (B,N,S)
        bx, by = st.b_pos[..., 0], st.b_pos[..., 1]
        hist["alive"].append(~done)
        hist["err"].append(res.info["survey_error_m"].mean(-1))
        hist["dr"].append(res.info["dr_error_m"].mean(-1))
        hist["major"].append(major.mean(-1))
        hist["minor"].append(minor.mean(-1))
        hist["reward"].append(res.reward.mean(-1))
        hist["dist"].append(dist.mean((-1, -2)))
        hist["fused"].append(res.info["ranges_fused"].sum(-1))
        hist["rejected"].append(res.info["outliers_rejected"].sum(-1))
        hist["lost"].append(res.info["packets_lost"].sum(-1))
        hist["unsafe"].append((dist < config.safety_distance_m).any((-1, -2)))
        hist["outside"].append(((bx < fe0) | (bx > fe1) | (by < fn0) | (by > fn1)).any(-1) & (not frame))
        if frame:
            hist["ex"].append(res.info["error_x_m"][:, 0])
            hist["ey"].append(res.info["error_y_m"][:, 0])
        ended = (res.terminated | res.truncated) & ~done
        done |= ended
        if progress is not None and ended.any():
            progress(int(ended.sum()))
    H = {k: np.array(v) for k, v in hist.items()}  # (steps, B)
    episodes, steps = [], []
    for b, seed in enumerate(seeds):
        n = int(H["alive"][:, b].sum())
        err, dr = H["err"][:n, b], H["dr"][:n, b]
        episodes.append({
            "seed": seed, "steps": n, "duration_s": n * T, "mean_error_m": float(err.mean()),
            "final_error_m": float(err[-1]), "max_error_m": float(err.max()), "mean_dr_error_m": float(dr.mean()),
            "final_dr_error_m": float(dr[-1]), "return": float(H["reward"][:n, b].sum()),
            "ranges_fused": int(H["fused"][:n, b].sum()), "outliers_rejected": int(H["rejected"][:n, b].sum()),
            "packets_lost": int(H["lost"][:n, b].sum()), "beacon_distance_m": float(H["dist"][:n, b].mean()),
            "safety_violations": int(H["unsafe"][:n, b].sum()), "geofence_violations": int(H["outside"][:n, b].sum()),
        })
        for k in range(n):
            steps.append({"seed": seed, "step": k + 1, "t_s": (k + 1) * T, "survey_error_m": float(err[k]),
                          "dr_error_m": float(dr[k]), "ellipse_major_m": float(H["major"][k, b]),
                          "ellipse_minor_m": float(H["minor"][k, b]), "reward": float(H["reward"][k, b]),
                          "beacon_distance_m": float(H["dist"][k, b])})
            if frame:
                steps[-1].update(error_x_m=float(H["ex"][k, b]), error_y_m=float(H["ey"][k, b]))
    return episodes, steps


def record_episode(config, policy_name: str, seed: int):
    """Re-run one episode and keep every snapshot (for the path figure)."""
    from coopnav_env.core import make_simulator
    from coopnav_env.render import EpisodeRecorder

    sim = make_simulator(config, batch_size=1)
    obs = sim.reset([seed])
    N = config.n_beacons
    policies = [make_policy(policy_name, config, seed=(seed, j), agent=j) for j in range(N)]
    rec = EpisodeRecorder(config)
    rec.record(sim.state, 0)
    while True:
        a = np.stack([policies[j].act(obs[0, j]) for j in range(N)])[None]
        res = sim.step(a)
        obs = res.obs
        rec.record(sim.state, 0)
        if res.terminated[0] or res.truncated[0]:
            return rec


# ------------------------------------------------------------------------------------
# statistics

def error_stats(step_rows, episode_rows, n_boot: int = 2000) -> dict:
    err = np.array([float(r["survey_error_m"]) for r in step_rows])
    by_ep = {}
    for r in step_rows:
        by_ep.setdefault(int(r["seed"]), []).append(float(r["survey_error_m"]))
    sums = np.array([np.sum(v) for v in by_ep.values()])
    counts = np.array([len(v) for v in by_ep.values()])
    mean = float(err.mean())
    if len(sums) > 1:  # cluster bootstrap over episodes of the pooled (ratio) mean
        rng = np.random.default_rng(12345)
        idx = rng.integers(0, len(sums), size=(n_boot, len(sums)))
        boot = sums[idx].sum(1) / counts[idx].sum(1)
        ci = [float(np.percentile(boot, 2.5)), float(np.percentile(boot, 97.5))]
    else:
        ci = [mean, mean]

    def ep_mean(key):
        return float(np.mean([float(r[key]) for r in episode_rows]))

    return {
        "episodes": len(episode_rows), "steps": int(err.size),
        "mean_error_m": mean, "median_error_m": float(np.median(err)), "p95_error_m": float(np.percentile(err, 95)),
        "std_error_m": float(err.std()), "var_error_m2": float(err.var()), "ci95_error_m": ci,
        "final_error_m": ep_mean("final_error_m"), "mean_dr_error_m": ep_mean("mean_dr_error_m"),
        "mean_return": ep_mean("return"), "ranges_fused": ep_mean("ranges_fused"),
        "outliers_rejected": ep_mean("outliers_rejected"), "beacon_distance_m": ep_mean("beacon_distance_m"),
        **frame_error_stats(step_rows),
    }


def frame_error_stats(step_rows) -> dict:
    """Moving-frame error statistics (Matos & Cruz sec. VIII): the standard deviation
    of the x and y errors over all steps; empty for scenarios without them."""
    ex = [float(r["error_x_m"]) for r in step_rows if r.get("error_x_m", "") != ""]
    ey = [float(r["error_y_m"]) for r in step_rows if r.get("error_y_m", "") != ""]
    if not ex:
        return {}
    return {"error_x_std_m": float(np.std(ex)), "error_y_std_m": float(np.std(ey)),
            "error_x_mean_m": float(np.mean(ex)), "error_y_mean_m": float(np.mean(ey))}


def summarize(plan, ep_rows, step_rows, args) -> dict:
    policies, cells = plan["policies"], plan["cells"]
    cell_stats = []
    for cell in cells:
        cid = cell_id(cell)
        per = {}
        for p in policies:
            eps = [r for r in ep_rows if r["cell"] == cid and r["policy"] == p]
            sts = [r for r in step_rows if r["cell"] == cid and r["policy"] == p]
            if eps and sts:
                per[p] = error_stats(sts, eps)
        cell_stats.append({"params": {k: _jsonable(v) for k, v in cell.items()}, "policies": per})
    summary = {"scenario": args.scenario, "episodes": args.episodes, "seed": args.seed,
               "overrides": plan["run_info"]["overrides"]}
    if plan["sweep"]:
        summary["sweep"] = plan["run_info"]["sweep"]
        summary["cells"] = cell_stats
        pooled = {}
        for p in policies:
            eps = [r for r in ep_rows if r["policy"] == p and r["cell"] in {cell_id(c) for c in cells}]
            sts = [r for r in step_rows if r["policy"] == p and r["cell"] in {cell_id(c) for c in cells}]
            if eps and sts:
                pooled[p] = error_stats(sts, eps)
        summary["policies"] = pooled  # pooled over every cell of the grid
    else:
        summary["policies"] = cell_stats[0]["policies"]
    return summary


def markdown(summary: dict, plan) -> str:
    lines = [f"# Evaluation: {summary['scenario']}", ""]
    ov = summary.get("overrides") or {}
    lines.append(f"{summary['episodes']} episodes per policy{' and cell' if plan['sweep'] else ''}, seeds "
                 f"{summary['seed']}..{summary['seed'] + summary['episodes'] - 1} (common random numbers)"
                 + (f"; overrides: {', '.join(f'{k}={v}' for k, v in ov.items())}" if ov else "") + ".")
    lines.append("Error: `survey_error_m` (true horizontal error of the EKF estimate) over all steps of all "
                 "episodes; the 95 % interval of the mean is a bootstrap over episodes.")
    lines.append("")
    title = "pooled over the grid" if plan["sweep"] else "per policy"
    lines += [f"## Summary ({title})", "", policy_table(summary["policies"]), ""]
    if plan["sweep"]:
        keys = list(plan["sweep"])
        row_key, col_keys = keys[0], keys[1:]
        col_cells = [{}]
        for k in col_keys:
            col_cells = [dict(c, **{k: v}) for c in col_cells for v in plan["sweep"][k]]
        for p in plan["policies"]:
            lines += [f"## {p}: mean error (m) / variance (m^2)", ""]
            head = [row_key] + [", ".join(f"{v}" for v in c.values()) or "value" for c in col_cells]
            lines.append("| " + " | ".join(head) + " |")
            lines.append("|" + "---|" * len(head))
            for rv in plan["sweep"][row_key]:
                row = [f"{rv}"]
                for cc in col_cells:
                    params = {row_key: _jsonable(rv), **{k: _jsonable(v) for k, v in cc.items()}}
                    st = _find_cell(summary, params, p)
                    row.append("-" if st is None else f"{st['mean_error_m']:.3f} / {st['var_error_m2']:.3f}")
                lines.append("| " + " | ".join(row) + " |")
            lines.append("")
    return "\n".join(lines)


def _find_cell(summary, params, policy):
    for c in summary.get("cells", []):
        if all(c["params"].get(k) == v for k, v in params.items()):
            return c["policies"].get(policy)
    return None


def policy_table(stats: dict) -> str:
    head = ["policy", "mean (m)", "median", "p95", "std", "95% CI of mean", "final", "DR mean", "return",
            "ranges fused", "outliers rej.", "beacon dist. (m)"]
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for p, s in stats.items():
        out.append("| " + " | ".join([
            p, f"{s['mean_error_m']:.3f}", f"{s['median_error_m']:.3f}", f"{s['p95_error_m']:.3f}",
            f"{s['std_error_m']:.3f}", f"[{s['ci95_error_m'][0]:.3f}, {s['ci95_error_m'][1]:.3f}]",
            f"{s['final_error_m']:.3f}", f"{s['mean_dr_error_m']:.3f}", f"{s['mean_return']:.2f}",
            f"{s['ranges_fused']:.1f}", f"{s['outliers_rejected']:.1f}", f"{s['beacon_distance_m']:.1f}"]) + " |")
    if any("error_x_std_m" in s for s in stats.values()):
        out += ["", "Moving-frame errors (Matos & Cruz sec. VIII reports std 0.25 m in x, 0.86 m in y):", "",
                "| policy | x error std (m) | y error std (m) | x mean | y mean |", "|---|---|---|---|---|"]
        for p, s in stats.items():
            if "error_x_std_m" in s:
                out.append(f"| {p} | {s['error_x_std_m']:.3f} | {s['error_y_std_m']:.3f} | "
                           f"{s['error_x_mean_m']:+.3f} | {s['error_y_mean_m']:+.3f} |")
    return "\n".join(out)


# ------------------------------------------------------------------------------------
# figures (matplotlib imported here only, Agg canvas, no pyplot)

def _save_figure(fig, path):
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    atomic_write_bytes(path, buf.getvalue())


def _time_series(step_rows, policy, key):
    by_t = {}
    for r in step_rows:
        if r["policy"] == policy:
            by_t.setdefault(float(r["t_s"]), []).append(float(r[key]))
    if not by_t:
        return (np.array([]),) * 4
    most = max(len(v) for v in by_t.values())
    t = np.array([x for x in sorted(by_t) if len(by_t[x]) >= 0.5 * most])  # drop thin tails of long episodes
    vals = [np.array(by_t[x]) for x in t]
    return t, np.array([v.mean() for v in vals]), np.array([np.percentile(v, 25) for v in vals]), \
        np.array([np.percentile(v, 75) for v in vals])


def draw_figures(out, plan, ep_rows, step_rows, args):
    from matplotlib.figure import Figure

    policies = plan["policies"]
    config = plan["configs"][cell_id(plan["cells"][0])]
    colors = {p: f"C{i}" for i, p in enumerate(policies)}
    written = []
    # paths of both vehicles, episode 0 of each policy
    n = len(policies)
    cols = min(n, 3)
    rows = (n + cols - 1) // cols
    fig = Figure(figsize=(4.6 * cols, 4.2 * rows))
    for i, p in enumerate(policies):
        rec = record_episode(config, p, args.seed)
        t, true, dr, est, P, beacons = rec.arrays()
        ax = fig.add_subplot(rows, cols, i + 1)
        for s in range(true.shape[1]):
            wp = rec.waypoints[s, :rec.n_waypoints[s]]
            ax.plot(wp[:, 0], wp[:, 1], color="0.75", lw=1, ls=":", label="planned" if s == 0 else None)
            ax.plot(true[:, s, 0], true[:, s, 1], color="k", lw=1.3, label="survey (true)" if s == 0 else None)
            ax.plot(est[:, s, 0], est[:, s, 1], color="tab:blue", lw=0.9, label="survey (EKF)" if s == 0 else None)
            ax.plot(dr[:, s, 0], dr[:, s, 1], color="tab:red", lw=0.9, ls="--", label="dead reckoning" if s == 0 else None)
        for j in range(beacons.shape[1]):
            ax.plot(beacons[:, j, 0], beacons[:, j, 1], color="tab:green", lw=1, label="beacon" if j == 0 else None)
            ax.plot(beacons[0, j, 0], beacons[0, j, 1], "o", color="tab:green", ms=4)
        ax.set_title(f"{p} (seed {args.seed})", fontsize=9)
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(True, lw=0.3)
        ax.tick_params(labelsize=7)
        if i == 0:
            ax.legend(fontsize=6, loc="best")
    fig.suptitle(f"{config.name}: paths of both vehicles (east/north, m)", fontsize=10)
    fig.tight_layout()
    _save_figure(fig, os.path.join(out, "paths.png"))
    written.append("paths.png")

    # survey error against time, dead reckoning beside it
    fig = Figure(figsize=(7.5, 4.5))
    ax = fig.add_subplot(1, 1, 1)
    dr_all = {}
    for p in policies:
        t, m, lo, hi = _time_series(step_rows, p, "survey_error_m")
        if t.size == 0:
            continue
        ax.plot(t, m, color=colors[p], label=p)
        ax.fill_between(t, lo, hi, color=colors[p], alpha=0.12, lw=0)
        for r in step_rows:
            if r["policy"] == p:
                dr_all.setdefault(float(r["t_s"]), []).append(float(r["dr_error_m"]))
    if dr_all:
        most = max(len(v) for v in dr_all.values())
        td = np.array([x for x in sorted(dr_all) if len(dr_all[x]) >= 0.5 * most])
        ax.plot(td, [np.mean(dr_all[x]) for x in td], color="k", ls="--", label="dead reckoning")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("horizontal error (m)")
    ax.set_title(f"{config.name}: survey error, mean over episodes (band: quartiles)", fontsize=10)
    ax.grid(True, lw=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    _save_figure(fig, os.path.join(out, "error_vs_time.png"))
    written.append("error_vs_time.png")

    # ellipse axes against time
    fig = Figure(figsize=(7.5, 4.5))
    ax = fig.add_subplot(1, 1, 1)
    for p in policies:
        t, m, _, _ = _time_series(step_rows, p, "ellipse_major_m")
        t2, m2, _, _ = _time_series(step_rows, p, "ellipse_minor_m")
        if t.size == 0:
            continue
        ax.plot(t, m, color=colors[p], label=f"{p} major")
        ax.plot(t2, m2, color=colors[p], ls=":", label=f"{p} minor")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("2-sigma semi-axis (m)")
    ax.set_title(f"{config.name}: EKF uncertainty-ellipse axes, mean over episodes", fontsize=10)
    ax.grid(True, lw=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    _save_figure(fig, os.path.join(out, "ellipse_axes.png"))
    written.append("ellipse_axes.png")
    if config.network == "moving_lbl":
        written.append(draw_frame_errors(out, policies, step_rows, args, config))
    return written


def draw_frame_errors(out, policies, step_rows, args, config):
    """Matos & Cruz Figs. 6-8 for the first episode of each policy: the x and y errors
    in the moving frame and the filter's ellipse axes against time."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.5, 7.5))
    axes = [fig.add_subplot(3, 1, i + 1) for i in range(3)]
    for i, p in enumerate(policies):
        rows = [r for r in step_rows if r["policy"] == p and int(r["seed"]) == args.seed and r["cell"] == step_rows[0]["cell"]]
        if not rows:
            continue
        t = np.array([float(r["t_s"]) for r in rows])
        for ax, key in zip(axes[:2], ("error_x_m", "error_y_m")):
            v = np.array([float(r[key]) for r in rows])
            ax.plot(t, v, color=f"C{i}", lw=0.8, label=f"{p} (std {v.std():.2f} m)")
        # the step rows' ellipse columns: 2-sigma semi-axes, plotted as they are
        axes[2].plot(t, [float(r["ellipse_major_m"]) for r in rows], color=f"C{i}", lw=0.9, label=f"{p} major")
        axes[2].plot(t, [float(r["ellipse_minor_m"]) for r in rows], color=f"C{i}", lw=0.9, ls=":", label=f"{p} minor")
    for ax, label in zip(axes, ("x error (m)", "y error (m)", "2-sigma semi-axes (m)")):
        ax.set_ylabel(label)
        ax.grid(True, lw=0.3)
        ax.legend(fontsize=7)
    axes[2].set_xlabel("time (s)")
    fig.suptitle(f"{config.name}, seed {args.seed}: moving-frame errors (cf. Matos & Cruz Figs. 6-8)", fontsize=10)
    fig.tight_layout()
    _save_figure(fig, os.path.join(out, "frame_errors.png"))
    return "frame_errors.png"


def draw_sweep_figure(out, plan, summary):
    from matplotlib.figure import Figure

    keys = list(plan["sweep"])
    row_key = keys[0]
    col_cells = [{}]
    for k in keys[1:]:
        col_cells = [dict(c, **{k: v}) for c in col_cells for v in plan["sweep"][k]]
    xs = plan["sweep"][row_key]
    numeric = all(isinstance(x, (int, float)) for x in xs)
    n = len(plan["policies"])
    fig = Figure(figsize=(5.0 * n, 4.0))
    first = None
    for i, p in enumerate(plan["policies"]):
        ax = fig.add_subplot(1, n, i + 1, sharey=first)  # one error scale for every policy
        first = first or ax
        for cc in col_cells:
            ys = []
            for x in xs:
                st = _find_cell(summary, {row_key: _jsonable(x), **{k: _jsonable(v) for k, v in cc.items()}}, p)
                ys.append(np.nan if st is None else st["mean_error_m"])
            xv = xs if numeric else list(range(len(xs)))
            ax.plot(xv, ys, "o-", label=", ".join(str(v) for v in cc.values()) or p)
        if not numeric:
            ax.set_xticks(range(len(xs)))
            ax.set_xticklabels([str(x) for x in xs])
        ax.set_xlabel(row_key)
        ax.set_ylabel("mean survey error (m)")
        ax.set_title(p)
        ax.grid(True, lw=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    _save_figure(fig, os.path.join(out, "sweep.png"))
    return ["sweep.png"]


# ------------------------------------------------------------------------------------

def main(argv=None) -> int:
    try:
        args = build_parser().parse_args(argv)
        plan = prepare(args)
        os.makedirs(args.out, exist_ok=True)
    except UsageError as err:
        print(f"evaluate.py: error: {err}", file=sys.stderr)
        return 2
    except OSError as err:
        print(f"evaluate.py: error: cannot create output directory {args.out!r}: {err.strerror}", file=sys.stderr)
        return 2
    out = args.out
    ep_path, st_path = os.path.join(out, "episodes.csv"), os.path.join(out, "steps.csv")
    ep_rows, step_rows = [], []
    if args.resume:
        ep_rows, step_rows = read_csv(ep_path), read_csv(st_path)
        have_steps = {(r["cell"], r["policy"], r["seed"]) for r in step_rows}
        ep_rows = [r for r in ep_rows if (r["cell"], r["policy"], r["seed"]) in have_steps]
        have_eps = {(r["cell"], r["policy"], r["seed"]) for r in ep_rows}
        step_rows = [r for r in step_rows if (r["cell"], r["policy"], r["seed"]) in have_eps]
    atomic_write_text(os.path.join(out, "run.json"), json.dumps(plan["run_info"], indent=2) + "\n")
    done = {(r["cell"], r["policy"], str(r["seed"])) for r in ep_rows}
    sweep_keys = list(plan["sweep"])
    ep_columns = EPISODE_COLUMNS[:1] + sweep_keys + EPISODE_COLUMNS[1:]
    seeds_all = [args.seed + i for i in range(args.episodes)]
    todo = []
    for cell in plan["cells"]:
        cid = cell_id(cell)
        for p in plan["policies"]:
            missing = [(i, s) for i, s in enumerate(seeds_all) if (cid, p, str(s)) not in done]
            for k in range(0, len(missing), args.batch_size):
                todo.append((cell, p, missing[k:k + args.batch_size]))
    total = sum(len(m) for _, _, m in todo)
    bar = None
    if total and sys.stderr.isatty():
        try:
            from tqdm import tqdm

            bar = tqdm(total=total, unit="episode", file=sys.stderr, dynamic_ncols=True)
        except ImportError:
            bar = None
    skipped = len(plan["cells"]) * len(plan["policies"]) * args.episodes - total
    if skipped and args.resume:
        print(f"resuming: {skipped} episode(s) already done, {total} to run", file=sys.stderr)
    try:
        for cell, p, chunk in todo:
            cid = cell_id(cell)
            if bar is not None:
                bar.set_description(f"{p} {cid}".strip()[:40])
            eps, sts = run_episodes(plan["configs"][cid], p, [s for _, s in chunk],
                                    progress=bar.update if bar is not None else None)
            index = {s: i for i, s in chunk}
            for r in eps:
                r.update({"cell": cid, "policy": p, "episode": index[r["seed"]], **{k: cell[k] for k in cell}})
            for r in sts:
                r.update({"cell": cid, "policy": p, "episode": index[r["seed"]]})
            ep_rows.extend(eps)
            step_rows.extend(sts)
            atomic_write_text(st_path, csv_text(STEP_COLUMNS, step_rows))
            atomic_write_text(ep_path, csv_text(ep_columns, ep_rows))
    finally:
        if bar is not None:
            bar.close()
    if not todo:  # rewrite in the current column layout anyway
        atomic_write_text(st_path, csv_text(STEP_COLUMNS, step_rows))
        atomic_write_text(ep_path, csv_text(ep_columns, ep_rows))
    summary = summarize(plan, ep_rows, step_rows, args)
    atomic_write_text(os.path.join(out, "summary.json"), json.dumps(summary, indent=2) + "\n")
    md = markdown(summary, plan)
    atomic_write_text(os.path.join(out, "summary.md"), md + "\n")
    if not args.no_figures:
        if plan["sweep"]:
            draw_sweep_figure(out, plan, summary)
        else:
            draw_figures(out, plan, ep_rows, step_rows, args)
    print(md)
    print(f"\nwrote {out}/: summary.json, summary.md, episodes.csv, steps.csv"
          + ("" if args.no_figures else (", sweep.png" if plan["sweep"] else
                                         ", paths.png, error_vs_time.png, ellipse_axes.png")))
    return 0


if __name__ == "__main__":
    sys.exit(main())
