"""The declared contracts between the parts: the simulator protocol, the reward as a
weighted sum of named terms, reset infos equal to step infos, and an import graph
without cycles that points one way (core <- views <- planners <- agents <- evaluation)."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

import coopnav_env
from coopnav_env.core import make_simulator
from coopnav_env.core.contract import BatchedSimulator, Snapshot, StepResult
from coopnav_env.core.reward import TERM_WEIGHTS, weighted_reward
from coopnav_env.views import action_dim

ROOT = Path(__file__).resolve().parent.parent
SCENARIOS = coopnav_env.list_scenarios()


def _run(name, B=3, steps=6, **overrides):
    config = coopnav_env.make_config(name, **overrides)
    sim = make_simulator(config, B)
    sim.reset(np.arange(B) + 40)
    rng = np.random.default_rng(0)
    dim = action_dim(sim)  # 3 where the scenario has a transmit decision (channel_mode="decide")
    results = [sim.step(rng.uniform(-1, 1, (B, config.n_beacons, dim))) for _ in range(steps)]
    return config, sim, results


@pytest.mark.parametrize("name", SCENARIOS)
def test_every_scenario_runs_through_the_protocol(name):
    config, sim, results = _run(name)
    assert isinstance(sim, BatchedSimulator)
    B, N, S = sim.batch_size, sim.N, sim.S
    assert (config.n_beacons, config.n_survey if config.network != "moving_lbl" else 1) == (N, S)
    for res in results:
        assert isinstance(res, StepResult)
        assert res.obs.shape == (B, N, sim.obs_dim) and res.obs.dtype == np.float32
        assert res.reward.shape == (B, N)
        assert res.terminated.shape == res.truncated.shape == (B,)
        assert tuple(res.info) == tuple(sim.info_keys)
        assert all(v.shape[:2] == (B, S) for v in res.info.values())
        assert res.info["survey_error_en_m"].shape == (B, S, 2)
        np.testing.assert_allclose(
            np.linalg.norm(res.info["survey_error_en_m"], axis=-1), res.info["survey_error_m"], rtol=1e-9, atol=1e-12
        )
        assert tuple(res.beacon_info) == tuple(sim.beacon_info_keys)
        assert all(v.shape == (B, N) and np.all(v >= 0) for v in res.beacon_info.values())
        assert tuple(res.terms) == tuple(sim.reward_terms)
        assert all(np.shape(v) == (B, N) and np.all(np.isfinite(v)) for v in res.terms.values())
        assert res.info["survey_cov_en_m2"].shape == (B, S, 2, 2)
        # the reward is the weighted sum of the terms, with the scenario's weights
        np.testing.assert_allclose(res.reward, weighted_reward(res.terms, sim.reward_weights), rtol=0, atol=1e-12)
        for term, w in sim.reward_weights.items():
            param = TERM_WEIGHTS[term]
            assert w == (1.0 if param is None else -getattr(config, param))
        # the indicators are indicators; the covariance is symmetric positive definite
        for term in set(sim.reward_terms) - {"info_gain"}:
            assert set(np.unique(res.terms[term])) <= {0.0, 1.0}
        P = res.info["survey_cov_en_m2"]
        np.testing.assert_allclose(P, np.swapaxes(P, -1, -2), atol=1e-9)
        assert np.all(np.linalg.eigvalsh(P) > 0)
    assert np.array_equal(sim.global_state().shape, (B, sim.state_dim))
    snap = sim.snapshot()
    assert isinstance(snap, Snapshot)
    assert snap.survey_true_m.shape == snap.survey_est_m.shape == snap.survey_dr_m.shape == (B, S, 3)
    assert snap.beacon_true_m.shape == snap.beacon_est_m.shape == (B, N, 3)
    assert snap.waypoints_m.shape[:2] == (B, S) and snap.n_waypoints.shape == (B, S)
    # the snapshot agrees with the step's infos: error of the estimate, and (rotated into
    # east/north for the moving network) the same ellipse
    err = np.linalg.norm(snap.survey_est_m[..., :2] - snap.survey_true_m[..., :2], axis=-1)
    np.testing.assert_allclose(err, results[-1].info["survey_error_m"], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(
        np.linalg.eigvalsh(snap.survey_cov_en_m2), np.linalg.eigvalsh(results[-1].info["survey_cov_en_m2"]), rtol=1e-9
    )


@pytest.mark.parametrize("name", SCENARIOS)
def test_reset_info_has_the_step_keys_and_the_state_values(name):
    config = coopnav_env.make_config(name)
    sim = make_simulator(config, 2)
    with pytest.raises(RuntimeError, match="before reset"):
        sim.reset_info()
    sim.reset([5, 6])
    info = sim.reset_info()
    assert tuple(info) == tuple(sim.info_keys)
    assert all(v.shape[:2] == (2, sim.S) for v in info.values())
    assert not info["range_ok"].any() and not info["ranges_fused"].any()
    snap = sim.snapshot()
    err = np.linalg.norm(snap.survey_est_m[..., :2] - snap.survey_true_m[..., :2], axis=-1)
    np.testing.assert_allclose(info["survey_error_m"], err, rtol=1e-9, atol=1e-12)
    assert np.all(info["survey_error_m"] > 0)  # the start estimate is drawn with its prior's error


@pytest.mark.parametrize("name", SCENARIOS)
def test_reset_infos_equal_step_infos_for_every_agent(name):
    env = coopnav_env.parallel_env(name, max_cycles=3)
    _, reset_infos = env.reset(seed=1)
    _, _, _, _, step_infos = env.step({a: env.action_space(a).sample() for a in env.agents})
    assert set(reset_infos) == set(step_infos) == set(env.possible_agents)
    for agent in env.possible_agents:
        assert set(reset_infos[agent]) == set(step_infos[agent])
        assert "survey_error_m" in reset_infos[agent]


def test_vecenv_reset_infos_have_the_step_keys():
    from coopnav_env.vector import CoopNavVecEnv

    venv = CoopNavVecEnv("gao_sea", n_envs=2, seed=0)
    venv.reset()
    _, _, _, infos = venv.step(np.zeros((venv.num_envs, 2)))
    assert len(venv.reset_infos) == venv.num_envs
    for r, s in zip(venv.reset_infos, infos):
        assert set(r) == set(s)


def test_survey_reward_terms_by_hand():
    """The survey network's terms against the snapshot's positions: 'too close' is a
    3-D distance under safety_distance_m, 'outside' a beacon beyond the fence."""
    config = coopnav_env.make_config(
        "gao_lawnmower", safety_penalty=2.0, geofence_penalty=3.0, contact_penalty=0.5, safety_distance_m=30.0
    )
    sim = make_simulator(config, 1)
    sim.reset([3])
    st = sim.state
    st.b_pos[0, 0, :2] = st.s_pos[0, 0, :2]  # on top of the survey vehicle: it moves ~20 m in a cycle
    res = sim.step(np.zeros((1, 1, 2)))
    snap = sim.snapshot()
    dist = np.linalg.norm(snap.beacon_true_m[0, 0] - snap.survey_true_m[0, 0])
    assert dist < 30.0 and res.terms["safety"][0, 0] == 1.0
    expected = (
        res.terms["info_gain"] - 2.0 * res.terms["safety"] - 3.0 * res.terms["geofence"] - 0.5 * res.terms["contact"]
    )
    np.testing.assert_allclose(res.reward, expected, atol=1e-12)
    st.b_pos[0, 0, :2] = np.array(config.geofence_m[2:]) + 500.0
    res = sim.step(np.zeros((1, 1, 2)))
    assert res.terms["geofence"][0, 0] == 1.0 and res.terms["safety"][0, 0] == 0.0
    assert res.reward[0, 0] == pytest.approx(res.terms["info_gain"][0, 0] - 3.0 - 0.5 * res.terms["contact"][0, 0])


# --------------------------------------------------------------------------------------
# the import graph of the installed packages

PACKAGES = ("coopnav_env", "baselines", "agents", "evaluation")
LAYER = {"coopnav_env": 0, "baselines": 1, "agents": 2, "evaluation": 3}


def _modules() -> dict:
    """module name -> path, for every .py file of the packages."""
    out = {}
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = path
    return out


def _imports(name: str, path: Path, modules: dict) -> set:
    """The package modules that ``name`` imports anywhere in its file (lazy imports
    inside functions included: they are edges too)."""
    is_pkg = path.name == "__init__.py"
    package = name if is_pkg else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            # "from pkg import mod" imports the module; "from pkg import name" the package
            targets = [f"{mod}.{a.name}" if f"{mod}.{a.name}" in modules else mod for a in node.names]
        else:
            continue
        for t in targets:
            while t and t not in modules:
                t = t.rpartition(".")[0]
            if t and t != name:
                found.add(t)
    return found


def _graph():
    modules = _modules()
    return {name: _imports(name, path, modules) for name, path in modules.items()}


def test_layers_import_one_way():
    wrong = []
    for mod, targets in _graph().items():
        for t in targets:
            if LAYER[t.split(".")[0]] > LAYER[mod.split(".")[0]]:
                wrong.append(f"{mod} -> {t}")
    assert not wrong, "imports against the layers: " + ", ".join(sorted(wrong))


def test_no_import_cycles():
    """Tarjan's strongly connected components over module -> module edges; a package
    importing its own submodules (``__init__`` re-exports) is not a cycle when the
    submodule does not import it back."""
    graph = _graph()
    index, low, stack, on, cycles = {}, {}, [], set(), []

    def visit(v, counter=[0]):  # noqa: B006 - a counter shared by the recursion
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                cycles.append(sorted(comp))

    for v in graph:
        if v not in index:
            visit(v)
    assert not cycles, f"import cycles: {cycles}"


def test_no_import_path_edits_in_tests_or_benchmarks():
    needle = "sys." + "path"  # spelled so that grep finds no edit here either
    offenders = [
        str(p.relative_to(ROOT))
        for d in ("tests", "benchmarks")
        for p in (ROOT / d).rglob("*.py")
        if needle in p.read_text()
    ]
    assert not offenders, offenders


def test_evaluation_reads_no_simulator_internals():
    """The evaluation reads the step result and the snapshot, not ``sim.state``."""
    offenders = [
        str(p.relative_to(ROOT))
        for p in (ROOT / "evaluation").rglob("*.py")
        if ".state." in p.read_text() or "sim.state" in p.read_text()
    ]
    assert not offenders, offenders


@pytest.mark.parametrize("name", ["gao_sea", "sousa_asv", "matos_moving_lbl"])
def test_infos_let_anyone_check_the_filter(name):
    """Every agent's infos carry the survey vehicles' true error vectors and the filters'
    2x2 covariances, and the beacon's own true navigation error."""
    env = coopnav_env.parallel_env(name, max_cycles=5)
    env.reset(seed=4)
    _, _, _, _, infos = env.step({a: env.action_space(a).sample() for a in env.agents})
    snap = env.unwrapped.sim.snapshot()
    for j, agent in enumerate(env.possible_agents):
        info = infos[agent]
        err = np.array(info["survey_error_en_m"])
        cov = np.array(info["survey_cov_en_m2"])
        assert err.shape == (env.unwrapped.sim.S, 2) and cov.shape == (env.unwrapped.sim.S, 2, 2)
        np.testing.assert_allclose(np.linalg.norm(err, axis=-1), info["survey_error_m_per_vehicle"], rtol=1e-9)
        own = np.linalg.norm(snap.beacon_est_m[0, j, :2] - snap.beacon_true_m[0, j, :2])
        assert info["beacon_error_m"] == pytest.approx(own, rel=1e-9, abs=1e-12)
    if name != "matos_moving_lbl":  # east/north: the snapshot's estimate minus truth
        np.testing.assert_allclose(
            np.array(infos["beacon_0"]["survey_error_en_m"]),
            snap.survey_est_m[0, :, :2] - snap.survey_true_m[0, :, :2],
            atol=1e-9,
        )
