"""benchmarks/nees_per_cycle.py --beacon: another policy drives the beacons (the filter's
consistency depends on where the beacon goes), with a one-line refusal of a bad name."""

import numpy as np
import pytest

from benchmarks import nees_per_cycle


def test_beacon_drives_instead_of_the_case_planner(capsys):
    # the same planner through either path: the same filter, the same NEES (ellipse is deterministic)
    a = nees_per_cycle.nees_of_case("gao_sea", "ellipse", {"max_cycles": 12}, 3, 700000)
    b = nees_per_cycle.nees_of_case("gao_sea", "ellipse", {"max_cycles": 12}, 3, 700000, beacon="ellipse")
    assert a["run_cycles"] == b["run_cycles"] == 36 and np.isclose(a["mean"], b["mean"], rtol=1e-12)
    # another beacon, another filter history
    c = nees_per_cycle.nees_of_case("gao_sea", "ellipse", {"max_cycles": 12}, 3, 700000, beacon="static")
    assert c["mean"] != a["mean"]
    assert nees_per_cycle.main(["--runs", "2", "--cases", "1", "--beacon", "static", "--set", "max_cycles=5"]) == 0
    out = capsys.readouterr().out
    assert "| gao_sea | static | 10 |" in out


def test_a_bad_beacon_is_one_line_and_exit_2(capsys):
    assert nees_per_cycle.main(["--runs", "2", "--cases", "1", "--beacon", "elipse"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--beacon 'elipse'" in err[0] and "Traceback" not in err[0]
    assert "did you mean 'ellipse'?" in err[0]


def test_by_distance_splits_the_run_cycles():
    """Hand-made run-cycles: NEES 1 at 10 m, 20 at 30 m (above the 99.9 % point), 2 and 4
    at 60 m, none beyond 100 m."""
    nees = np.array([1.0, 20.0, 2.0, 4.0])
    dist = np.array([10.0, 30.0, 60.0, 99.9])
    bands = nees_per_cycle.by_distance(nees, dist)
    assert [b["band_m"] for b in bands] == [(0.0, 20.0), (20.0, 50.0), (50.0, 100.0), (100.0, np.inf)]
    assert [b["share"] for b in bands] == [0.25, 0.25, 0.5, 0.0]
    assert [b["mean"] for b in bands] == [1.0, 20.0, 3.0, None]
    assert bands[1]["above_x"] == pytest.approx(1000.0) and bands[0]["above_x"] == 0.0 and bands[3]["above_x"] is None


def test_given_draws_against_quadrature():
    """(G1-G3) by hand: P = I, the compass bias (variance 1) explains 0.9 of the east
    variance (Pxd[0, 1] = sqrt 0.9) and was drawn 4 sigma out. Given it, e_E ~ N(4 sqrt 0.9,
    0.1) and e_N ~ N(0, 1), and P(e_E^2 + e_N^2 > 13.8) is a one-dimensional integral."""
    from scipy import integrate, stats

    a = np.sqrt(0.9)
    P = np.eye(2)[None]
    Pxd = np.zeros((1, 2, 4))
    Pxd[0, 0, 1] = a
    var = np.array([[0.0, 1.0, 0.0, 0.0]])  # only beta conditioned on
    phi = np.array([[0.3, 4.0, 0.0, 0.0]])  # k is not: its value must not matter
    mu = 4.0 * a
    e = np.array([[mu + np.sqrt(0.1) * 1.0, 2.0]])  # one sigma out east given the draw, 2 north
    cond, p = nees_per_cycle.given_draws(e, P, Pxd, var, phi)
    assert cond[0] == pytest.approx(1.0 + 4.0, rel=1e-9)  # (G2): 1^2 + 2^2
    point = nees_per_cycle.P999

    def tail(n):  # P(e_E^2 > point - n^2) for e_E ~ N(mu, 0.1)
        c = point - n * n
        if c <= 0:
            return 1.0
        s = np.sqrt(0.1)
        return stats.norm.sf((np.sqrt(c) - mu) / s) + stats.norm.cdf((-np.sqrt(c) - mu) / s)

    ref = integrate.quad(lambda n: stats.norm.pdf(n) * tail(n), -8, 8)[0]
    assert 0.1 < ref < 0.9  # a case where the draw matters
    sd = np.sqrt(ref * (1 - ref) / nees_per_cycle.GIVEN_DRAWS_SAMPLES)
    assert abs(p[0] - ref) < 4 * sd
    # with no bias at all it is the nominal 0.1 % (a chi-square(2) tail)
    _, p0 = nees_per_cycle.given_draws(e, P, np.zeros((1, 2, 4)), var, phi)
    assert p0[0] < 0.004


def test_given_draws_average_to_the_nominal_rate():
    """For a consistent filter, averaging (G3) over the draws of phi gives the marginal
    chance, 0.1 %; and the conditional NEES (G2) of errors drawn with the joint covariance is
    chi-square(2). A random joint covariance of (e, phi), 4000 draws."""
    rng = np.random.default_rng(3)
    A = rng.standard_normal((6, 6))
    C = A @ A.T + 0.5 * np.eye(6)
    d = np.sqrt(np.diag(C)[2:])
    C[2:, :] /= d[:, None]
    C[:, 2:] /= d[None, :]
    C[2:, 2:] = np.eye(4)  # Pff diagonal, unit variances
    C += np.diag([5.0, 5.0, 0, 0, 0, 0])  # keep the joint positive definite
    assert np.all(np.linalg.eigvalsh(C) > 0)
    M = 4000
    x = rng.multivariate_normal(np.zeros(6), C, size=M)
    e, phi = x[:, :2], x[:, 2:]
    P = np.broadcast_to(C[:2, :2], (M, 2, 2)).copy()
    Pxd = np.broadcast_to(C[:2, 2:], (M, 2, 4)).copy()
    var = np.ones((M, 4))
    cond, p = nees_per_cycle.given_draws(e, P, Pxd, var, phi)
    assert cond.mean() == pytest.approx(2.0, abs=0.15)
    assert np.mean(cond > stats_chi2_point()) < 0.003
    assert p.mean() == pytest.approx(0.001, abs=0.0006)
    # the marginal NEES of the same errors is chi-square(2) as well
    nees = np.einsum("mi,ij,mj->m", e, np.linalg.inv(C[:2, :2]), e)
    assert np.mean(nees > nees_per_cycle.P999) < 0.004
    # errors and draws sqrt 2 larger than the filter says (an over-confident filter): (G2) doubles
    cond_bad, _ = nees_per_cycle.given_draws(np.sqrt(2) * e, P, Pxd, var, np.sqrt(2) * phi)
    assert cond_bad.mean() == pytest.approx(4.0, abs=0.3)


def stats_chi2_point() -> float:
    from scipy.stats import chi2

    return float(chi2.ppf(0.999, 2))


@pytest.mark.parametrize(
    "scenario, planner, overrides, columns",
    [("sousa_asv", "fim_a", {"max_cycles": 60}, [1]), ("gao_lawnmower", "ellipse", {}, [2, 3])],
)
def test_episode_draws_signs_in_the_simulator(monkeypatch, scenario, planner, overrides, columns):
    """The draws as the simulator keeps them (speed scale, compass bias, the told current as
    sent minus true) with the signs of eq. D1: the conditional NEES of 20 runs is near 2;
    with the compass bias's sign flipped (sousa_asv) or the told current's (gao_lawnmower)
    it is 3.5 and 4.8."""
    r = nees_per_cycle.nees_of_case(scenario, planner, overrides, 20, 0, draws=True)
    assert 1.3 < r["given"]["conditional_mean"] < 2.6
    assert r["given"]["expected"] > 0 and r["given"]["expected_by_run"].shape == (20,)
    orig = nees_per_cycle.episode_draws

    def flipped(cfg, st):
        var, phi = orig(cfg, st)
        phi = phi.copy()
        phi[..., columns] *= -1
        return var, phi

    monkeypatch.setattr(nees_per_cycle, "episode_draws", flipped)
    bad = nees_per_cycle.nees_of_case(scenario, planner, overrides, 20, 0, draws=True)
    assert bad["given"]["conditional_mean"] > 3.0


def test_given_draws_is_na_without_the_consider_states(capsys):
    r = nees_per_cycle.nees_of_case(
        "gao_sea", "ellipse", {"max_cycles": 5, "survey_bias_consider": False}, 2, 0, draws=True
    )
    assert r["given"] is None
    assert (
        nees_per_cycle.main(["--runs", "2", "--cases", "1", "--given-draws", "--per-run", "--set", "max_cycles=5"]) == 0
    )
    assert "given the draws:" in capsys.readouterr().out


def test_given_draws_of_an_untold_current(monkeypatch):
    """An untold current (eq. D1''): phi's current is the episode's mean current. sousa_asv
    with a 0.3 m/s current in a random direction, uninformative ranges and no other bias: the
    conditional NEES of 50 runs is near 2 (1.78 here); with the current's sign flipped, 417."""
    over = {
        "range_noise_std_m": 1000.0,
        "outlier_probability": 0.0,
        "survey_speed_scale_error_std": 0.0,
        "compass_bias_std_deg": 0.0,
        "current_speed_mps": 0.3,
        "current_direction_spread_deg": 180.0,
        "max_cycles": 24,
    }
    r = nees_per_cycle.nees_of_case("sousa_asv", "fim_a", over, 50, 733000, draws=True)
    assert 1.3 < r["given"]["conditional_mean"] < 2.6
    orig = nees_per_cycle.episode_draws

    def flipped(cfg, st):
        var, phi = orig(cfg, st)
        phi = phi.copy()
        phi[..., 2:] *= -1
        return var, phi

    monkeypatch.setattr(nees_per_cycle, "episode_draws", flipped)
    assert (
        nees_per_cycle.nees_of_case("sousa_asv", "fim_a", over, 50, 733000, draws=True)["given"]["conditional_mean"]
        > 10
    )


def test_given_draws_condition_on_the_beacons_errors(monkeypatch):
    """Round 8: G1 also conditions on each heard beacon's error b = -b_nav_err through the
    survey's Pxb (``beacon_draws``). On gao_lawnmower (the lake beacon's Gauss-Markov GPS
    error, Pxb carried by the Schmidt filter), 40 runs: the conditional NEES stays near 2 (1.45
    here; 1.64 without the beacons' columns), and with b's sign flipped it is 21: the filter's
    Pxb has the sign and size of the error it carries. A filter without consider states
    (white fusion) gives no beacon columns."""
    r = nees_per_cycle.nees_of_case("gao_lawnmower", "ellipse", {}, 40, 0, draws=True)
    assert 1.2 < r["given"]["conditional_mean"] < 2.2
    orig = nees_per_cycle.beacon_draws

    def flipped(cfg, st):
        X, var, b = orig(cfg, st)
        return X, var, -b

    monkeypatch.setattr(nees_per_cycle, "beacon_draws", flipped)
    bad = nees_per_cycle.nees_of_case("gao_lawnmower", "ellipse", {}, 40, 0, draws=True)
    assert bad["given"]["conditional_mean"] > 8.0
    from baselines.rollout import planned_steps

    for cfg, sim, _res, _live in planned_steps("gao_lawnmower", "ellipse", {"beacon_error_fusion": "white"}, 2, 0):
        assert orig(cfg, sim.state) is None
        break


def test_block_report_counts_consecutive_and_resampled_blocks():
    """Four runs of 1000 run-cycles, blocks of two: the nominal count of a block is
    2 x 1000 x 0.1 % = 2, so runs with 0, 2, 10 and 0 exceedances make blocks of 1.0x and
    5.0x. A resampled block is above 3x (more than 6) exactly when it draws the run with 10:
    1 - (3/4)^2 = 43.75 %. A consistent filter expecting nothing never is."""
    import re

    r = {"exceed_by_run": np.array([0, 2, 10, 0]), "run_cycles": 4000, "given": {"expected_by_run": np.zeros(4)}}
    text = nees_per_cycle.block_report(r, 2)
    assert "2 consecutive at 1.0x, 5.0x" in text, text
    share = float(re.search(r"above 3x: ([0-9.]+)% of blocks", text).group(1))
    assert abs(share - 43.75) < 1.0, text
    assert "(a consistent filter: 0.00%)" in text, text
    r["given"] = None
    assert "consistent" not in nees_per_cycle.block_report(r, 2)


def test_blocks_larger_than_the_batch_is_one_clear_line(capsys):
    assert nees_per_cycle.main(["--runs", "10", "--blocks", "20", "--cases", "0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["--blocks must be in [1, --runs = 10], got 20"]


@pytest.mark.parametrize("scenario", ["sousa_asv", "gao_lawnmower"])
def test_initial_errors_are_drawn_from_the_filters_initial_covariance(scenario):
    """``initial_draws``: e0^T P0^-1 e0 of each run's first estimate. A start consistent with
    its covariance makes it chi-square(2): over 2,000 runs its mean is 2 within 0.2 (the
    mean's std is 0.045) and about 1 % lie beyond the 99 % point (so a run's early
    exceedances can be told apart as the start's tail, docs/scenarios/consider-fusion.md#initial-draw)."""
    from scipy.stats import chi2

    c2 = nees_per_cycle.initial_draws(scenario, {}, 2000, 3_000_000)
    assert c2.shape == (2000,)
    assert abs(c2.mean() - 2.0) < 0.2
    assert 0.004 < np.mean(c2 > chi2.ppf(0.99, 2)) < 0.02
    # and the script's worst survey vehicle is this one: a hand check of one run
    import coopnav_env
    from coopnav_env.core import make_simulator

    sim = make_simulator(coopnav_env.make_config(scenario), 1)
    sim.reset([3_000_000])
    e0 = sim.state.s_est[0, 0, :2] - sim.state.s_pos[0, 0, :2]
    assert c2[0] == pytest.approx(e0 @ np.linalg.solve(sim.state.s_P[0, 0, :2, :2], e0), rel=1e-12)


def test_the_moving_network_cases_run_and_say_their_initial_error_is_na(capsys):
    """Cases 4-7 (the Matos scenarios) ran into ``initial_draws``, written for the survey
    EKF's world estimate, and stopped with an AttributeError (the moving network's filter is
    in the boats' frame): every matos row of the docs' tables was unreachable from the
    command they name. Now it runs, and --per-run says n/a for the initial error."""
    assert nees_per_cycle.main(["--runs", "2", "--cases", "4", "--per-run", "--set", "max_cycles=5"]) == 0
    out = capsys.readouterr().out
    assert "matos_moving_lbl" in out and "initial errors: n/a" in out
