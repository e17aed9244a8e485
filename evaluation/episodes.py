"""Running episodes: one policy on a batch of seeded episodes of one scenario config,
giving the rows of ``episodes.csv`` and ``steps.csv`` (``run_episodes``), and one
episode re-run with every position kept, for the path figure (``record_episode``).

    from coopnav_env import make_config
    from evaluation.episodes import run_episodes
    episodes, steps = run_episodes(make_config("gao_lawnmower", max_cycles=50), "fim_a", range(4))

A policy is a planner of ``baselines`` or a trained policy of ``agents`` (same
interface); one instance acts for each beacon of each episode, on that beacon's
observation only. Everything the evaluation reads of a step comes through
``_step_measurements``.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from coopnav_env.scenarios import ScenarioConfig


def make_policy(name: str, config: ScenarioConfig, seed: int | tuple[int, int] | None, agent: int) -> Any:
    """A planner from baselines/ by name (``motion+schedule`` on the shared channel:
    ``baselines.make_policy``), else a trained policy through agents/ (same interface)."""
    import baselines

    if baselines.is_planner(name):
        return baselines.make_policy(name, config, seed=seed, agent=agent)
    import agents

    return agents.make_policy(name, config, seed=seed, agent=agent)


def check_policy(name: str, config: ScenarioConfig, seed: int) -> None:
    """Check that ``name`` loads and drives ``config``'s scenario: the policy is asked
    whether it takes the scenario (a trained policy's ``config_problem``: its observation
    size, or for an entity policy the team it can read; loading one asks it too), then a
    simulator of one episode (``seed``) is reset and one policy per beacon answers its
    first observation with a finite action of the scenario's shape
    (``views.action_dim``: 2, or 3 with a transmit decision). Raises what the policy
    raises, or ValueError with the policy's reason (the benchmark's ``n/a``)."""
    from coopnav_env.core import make_simulator
    from coopnav_env.views import action_dim

    sim = make_simulator(config, batch_size=1)
    obs = sim.reset([int(seed)])
    dim = action_dim(sim)
    for j in range(config.n_beacons):
        policy = make_policy(name, config, seed=(int(seed), j), agent=j)
        problem = getattr(policy, "config_problem", None)
        if callable(problem) and (why := problem(config)) is not None:
            raise ValueError(f"policy {name!r} {why}")
        action = np.asarray(policy.act(obs[0, j]), dtype=float)
        if action.shape != (dim,) or not np.isfinite(action).all():
            raise ValueError(f"beacon_{j}'s action is {action!r}, not {dim} finite numbers")


def _step_measurements(sim, res, config, step_rows: bool = True) -> dict:
    """What the evaluation reads of the batch after a step (``res``, the step's result)
    or after a reset (``res`` None: only the positions), from the step result and
    ``sim.snapshot()`` (``coopnav_env.core.contract``). ``step_rows=False``: without what
    only the step rows use (the ellipse's axes, the frame's signed error). Arrays over the batch:

    * (B,): ``survey_error_m``, ``dr_error_m``, ``ellipse_major_m``, ``ellipse_minor_m``
      (means over survey vehicles), ``reward`` (mean over beacons), ``ranges_fused``,
      ``outliers_rejected``, ``packets_lost`` (sums over survey vehicles),
      ``beacon_distance_m`` (mean over beacon-survey pairs), ``safety_violation`` (a
      pair closer than ``safety_distance_m``: the reward's ``safety`` term), ``geofence_violation``
      (a beacon outside ``geofence_m``: its ``geofence`` term; the moving network has none), and for
      ``network="moving_lbl"``
      ``error_x_m``, ``error_y_m`` (the first survey vehicle's signed error in the frame);
    * positions: ``t_s`` (B,), ``survey_true_m``, ``survey_est_m``, ``survey_dr_m``
      (B, S, 3), ``beacon_true_m`` (B, N, 3), ``waypoints_m`` (B, S, W, 3) and
      ``n_waypoints`` (B, S), copies.
    """
    from coopnav_env.core.information import error_ellipse

    snap = sim.snapshot()
    frame = config.network == "moving_lbl"
    out = {
        "t_s": np.asarray(snap.t_s, dtype=float),
        "survey_true_m": snap.survey_true_m,
        "survey_est_m": snap.survey_est_m,
        "survey_dr_m": snap.survey_dr_m,
        "beacon_true_m": snap.beacon_true_m,
        "waypoints_m": snap.waypoints_m,
        "n_waypoints": snap.n_waypoints,
    }
    if res is None:
        return out
    dist = np.linalg.norm(snap.survey_true_m[:, None, :, :] - snap.beacon_true_m[:, :, None, :], axis=-1)  # (B,N,S)
    no_term = np.zeros(res.reward.shape)
    out.update(
        {
            "survey_error_m": res.info["survey_error_m"].mean(-1),
            "dr_error_m": res.info["dr_error_m"].mean(-1),
            "reward": res.reward.mean(-1),
            "beacon_distance_m": dist.mean((-1, -2)),
            "ranges_fused": res.info["ranges_fused"].sum(-1),
            "outliers_rejected": res.info["outliers_rejected"].sum(-1),
            "packets_lost": res.info["packets_lost"].sum(-1),
            # the reward's own indicator terms (core.reward): a beacon too close, a beacon outside the fence
            "safety_violation": res.terms["safety"].any(-1),
            "geofence_violation": res.terms.get("geofence", no_term).any(-1),
            **_channel_use(res, config),
        }
    )
    if not step_rows:
        return out
    major, minor, _ = error_ellipse(res.info["survey_cov_en_m2"])
    out["ellipse_major_m"], out["ellipse_minor_m"] = major.mean(-1), minor.mean(-1)
    if frame:
        out["error_x_m"] = res.info["error_x_m"][:, 0]
        out["error_y_m"] = res.info["error_y_m"][:, 0]
    return out


def _channel_use(res, config) -> dict:
    """Pings, collisions and transmit energy of the step, summed over beacons (B,). With
    ``channel_mode="decide"`` the simulator reports them (``core/channel.py``); on the
    fixed clock every beacon pings once per cycle, nothing collides (the clock does not
    simulate the channel), and each ping costs the scenario's modem energy."""
    if "pings" in res.beacon_info:
        return {k: res.beacon_info[k].sum(-1) for k in ("pings", "collisions", "energy_J")}
    from coopnav_env.core.channel import ping_energy_j

    pings = np.full(res.reward.shape[0], float(config.n_beacons))
    joules = ping_energy_j(config)
    return {"pings": pings, "collisions": np.zeros_like(pings), "energy_J": pings * joules}


_PER_EPISODE = (  # summed or averaged into the episode rows
    "survey_error_m",
    "dr_error_m",
    "reward",
    "beacon_distance_m",
    "ranges_fused",
    "outliers_rejected",
    "packets_lost",
    "safety_violation",
    "geofence_violation",
    "pings",
    "collisions",
    "energy_J",
)
_STEP_ONLY = ("ellipse_major_m", "ellipse_minor_m")  # read by the step rows alone


def run_episodes(
    config: ScenarioConfig,
    policy_name: str,
    seeds: Sequence[int],
    progress: Callable[[float], object] | None = None,
    act_seconds: list | None = None,
    keep_steps: bool = True,
) -> tuple[list[dict], list[dict]]:
    """Run ``policy_name`` (one instance per beacon and episode) on episodes ``seeds``
    as one batch. Returns (episode rows, step rows) without the cell/policy/episode
    columns (see ``evaluation.report.EPISODE_COLUMN_DOCS``). ``progress(n)`` is called
    after every step with the episodes' worth of work done in it (fractions: the steps
    taken over ``max_cycles``, so a bar moves while a batch runs; the calls add up to
    ``len(seeds)`` exactly when the last episode ends). ``act_seconds``: a list that
    receives the CPU seconds of every ``act`` call (the calling thread's clock,
    ``time.thread_time_ns``: one beacon's decision on one core, what other processes on
    the machine do not inflate; a privileged policy's ``observe_truth`` not included).
    ``keep_steps=False``: no step rows (an empty list), for callers that keep the episodes'
    alone (a cell of the benchmark: 60-240 rows an episode not built)."""
    from baselines import tell_truth
    from coopnav_env.core import make_simulator

    seeds = [int(s) for s in seeds]
    B, N = len(seeds), config.n_beacons
    sim = make_simulator(config, batch_size=B)
    obs = sim.reset(seeds)
    policies = [[make_policy(policy_name, config, seed=(s, j), agent=j) for j in range(N)] for s in seeds]
    T = config.ping_interval_s
    frame = config.network == "moving_lbl"
    step_only = _STEP_ONLY + (("error_x_m", "error_y_m") if frame else ())
    keys = _PER_EPISODE + (step_only if keep_steps else ())
    done = np.zeros(B, dtype=bool)
    hist: dict[str, list] = {k: [] for k in ("alive",) + keys}
    from coopnav_env.views import action_dim

    actions = np.zeros((B, N, action_dim(sim)))
    credited, k_step, horizon = 0.0, 0, max(int(getattr(config, "max_cycles", 1)), 1)
    while not done.all():
        live = np.flatnonzero(~done).tolist()
        tell_truth(policies, sim, live)  # the truth, for reference policies (baselines' oracle)
        for b in live:
            for j in range(N):
                if act_seconds is None:
                    actions[b, j] = policies[b][j].act(obs[b, j])
                else:
                    t0 = time.thread_time_ns()
                    actions[b, j] = policies[b][j].act(obs[b, j])
                    act_seconds.append((time.thread_time_ns() - t0) * 1e-9)
        actions[done] = 0.0
        res = sim.step(actions)
        obs = res.obs
        m = _step_measurements(sim, res, config, step_rows=keep_steps)
        hist["alive"].append(~done)
        for k in keys:
            hist[k].append(m[k])
        ended = (res.terminated | res.truncated) & ~done
        done |= ended
        k_step += 1
        if progress is not None:  # ended episodes count whole, running ones by their share of max_cycles
            target = float(B) if done.all() else min(done.sum() + (~done).sum() * min(k_step / horizon, 0.99), B)
            if target > credited:
                progress(target - credited)
                credited = target
    H = {k: np.array(v) for k, v in hist.items()}  # (steps, B)
    episodes, steps = [], []
    for b, seed in enumerate(seeds):
        n = int(H["alive"][:, b].sum())
        err, dr = H["survey_error_m"][:n, b], H["dr_error_m"][:n, b]

        def total(k: str) -> int:
            return int(H[k][:n, b].sum())  # noqa: B023 - called only in this iteration, below

        episodes.append(
            {
                "seed": seed,
                "steps": n,
                "duration_s": n * T,
                "mean_error_m": float(err.mean()),
                "final_error_m": float(err[-1]),
                "max_error_m": float(err.max()),
                "mean_dr_error_m": float(dr.mean()),
                "final_dr_error_m": float(dr[-1]),
                "return": float(H["reward"][:n, b].sum()),
                "ranges_fused": total("ranges_fused"),
                "outliers_rejected": total("outliers_rejected"),
                "packets_lost": total("packets_lost"),
                "beacon_distance_m": float(H["beacon_distance_m"][:n, b].mean()),
                "safety_violations": total("safety_violation"),
                "geofence_violations": total("geofence_violation"),
                "pings": total("pings"),
                "collisions": total("collisions"),
                "energy_J": float(H["energy_J"][:n, b].sum()),
            }
        )
        for i in range(n if keep_steps else 0):
            steps.append(
                {
                    "seed": seed,
                    "step": i + 1,
                    "t_s": (i + 1) * T,
                    "survey_error_m": float(err[i]),
                    "dr_error_m": float(dr[i]),
                    "ellipse_major_m": float(H["ellipse_major_m"][i, b]),
                    "ellipse_minor_m": float(H["ellipse_minor_m"][i, b]),
                    "reward": float(H["reward"][i, b]),
                    "beacon_distance_m": float(H["beacon_distance_m"][i, b]),
                }
            )
            if frame:
                steps[-1].update(error_x_m=float(H["error_x_m"][i, b]), error_y_m=float(H["error_y_m"][i, b]))
    return episodes, steps


def record_episode(config: ScenarioConfig, policy_name: str, seed: int) -> dict:
    """Re-run one episode and keep every position (for the path figure): ``t_s`` (T,),
    ``survey_true_m``, ``survey_est_m``, ``survey_dr_m`` (T, S, 3), ``beacon_true_m``
    (T, N, 3), from the start (row 0) to the end; ``waypoints_m`` (S, W, 3) and
    ``n_waypoints`` (S,) as at the end."""
    from coopnav_env.core import make_simulator

    sim = make_simulator(config, batch_size=1)
    obs = sim.reset([seed])
    N = config.n_beacons
    policies = [make_policy(policy_name, config, seed=(seed, j), agent=j) for j in range(N)]
    snaps = [_step_measurements(sim, None, config)]
    while True:
        a = np.stack([policies[j].act(obs[0, j]) for j in range(N)])[None]
        res = sim.step(a)
        obs = res.obs
        snaps.append(_step_measurements(sim, res, config))
        if res.terminated[0] or res.truncated[0]:
            break
    track = {
        k: np.array([s[k][0] for s in snaps])
        for k in ("t_s", "survey_true_m", "survey_est_m", "survey_dr_m", "beacon_true_m")
    }
    track["waypoints_m"], track["n_waypoints"] = snaps[-1]["waypoints_m"][0], snaps[-1]["n_waypoints"][0]
    return track
