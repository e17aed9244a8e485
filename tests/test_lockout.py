"""The survey filter recovers from gate lock-out (issue: 'the survey filter never
recovers'): after ``reinit_after_rejected_ranges`` ranges in a row rejected with
innovations of one sign it restarts along the range (``navigation.reinit_on_range``)."""

from __future__ import annotations

import numpy as np
import pytest

import baselines
import coopnav_env
from coopnav_env.core import make_simulator
from coopnav_env.core.navigation import range_prediction, reinit_on_range


def test_reinit_moves_onto_the_range_and_keeps_the_across_variance_plus_the_miss():
    """Beacon at the origin, same depth; estimate 10 m east, measured range 15 m:
    the estimate moves to 15 m east; along the line of sight its variance is R plus
    the 5 m miss squared, across it the old variance plus the miss squared; the depth
    is untouched."""
    x = np.array([10.0, 0.0, 3.0])
    P = np.diag([4.0, 9.0, 0.25])
    P[0, 1] = P[1, 0] = 1.0
    P[0, 2] = P[2, 0] = 0.1
    h, H = range_prediction(x, np.zeros(3), np.zeros(1), np.array([0.0, 0.0, 3.0]))
    assert h == pytest.approx(10.0)
    assert reinit_on_range(x, P, 15.0, h, H, 2.0)
    np.testing.assert_allclose(x, [15.0, 0.0, 3.0], atol=1e-12)
    np.testing.assert_allclose(P, [[2.0 + 25.0, 0.0, 0.0], [0.0, 9.0 + 25.0, 0.0], [0.0, 0.0, 0.25]], atol=1e-12)


def test_reinit_on_a_sloping_line_of_sight_moves_by_the_miss_over_its_horizontal_share():
    """Beacon 80 m above and 60 m west of the estimate at the origin: h = 100 m,
    H = (0.6, 0, -0.8), |H_xy| = 0.6. A range of 110 m (y = 10) moves the estimate
    y / |H_xy| = 16.667 m east, which lengthens the predicted range by 10 m to first order
    (by the miss itself it would move only 6); the variance along the line of sight is
    (R + y^2) / |H_xy|^2 = (2 + 100) / 0.36 = 283.33, across it 9 + 100 = 109."""
    x, P = np.zeros(3), np.diag([4.0, 9.0, 0.25])
    h, H = range_prediction(x, np.zeros(3), np.zeros(1), np.array([-60.0, 0.0, 80.0]))
    assert h == pytest.approx(100.0)
    np.testing.assert_allclose(H, [0.6, 0.0, -0.8], atol=1e-12)
    assert reinit_on_range(x, P, 110.0, h, H, 2.0)
    np.testing.assert_allclose(x, [10.0 / 0.6, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(np.diag(P), [102.0 / 0.36, 109.0, 0.25], rtol=1e-12)


def test_reinit_refuses_a_steep_line_of_sight():
    x, P = np.array([1.0, 0.0, 30.0]), np.eye(3)
    h, H = range_prediction(x, np.zeros(3), np.zeros(1), np.zeros(3))  # 30 m below, 1 m aside
    assert not reinit_on_range(x, P, h + 10.0, h, H, 1.0)
    np.testing.assert_array_equal(x, [1.0, 0.0, 30.0])
    np.testing.assert_array_equal(P, np.eye(3))


def _episode(seed, reinit, speed_scale=1.18, **overrides):
    """The kind of episode that decided the shallow lawnmower cells: sousa_asv at 1 m on
    the lawnmower with an 18 % speed-scale error (a 3.6-sigma draw at the default
    spread), fim_a driving the ASV."""
    c = coopnav_env.make_config(
        "sousa_asv", survey_path="lawnmower", depth_m=1.0, reinit_after_rejected_ranges=reinit, **overrides
    )
    sim = make_simulator(c, 1)
    obs = sim.reset([seed])
    sim.state.s_speed_scale[:] = speed_scale
    policy = baselines.make_policy("fim_a", c, seed=seed)
    errors, restarts = [], 0
    while True:
        res = sim.step(policy.act(obs[0, 0])[None, None])
        obs = res.obs
        errors.append(res.info["survey_error_m"][0, 0])
        restarts += int(res.info["filter_restarts"][0, 0])
        if res.terminated[0] or res.truncated[0]:
            return float(np.mean(errors)), restarts


def test_recovery_on_the_lockout_episodes():
    seeds = range(800000, 800006)
    off = [_episode(s, 0) for s in seeds]
    on = [_episode(s, 3) for s in seeds]
    assert all(r == 0 for _, r in off)
    assert all(r > 0 for _, r in on)
    # every episode ends with a lower mean error, and the mean over them by > 25 %
    assert all(a < b for (a, _), (b, _) in zip(on, off)), (on, off)
    assert np.mean([e for e, _ in on]) < 0.75 * np.mean([e for e, _ in off])


def test_window_refix_holds_on_the_lockout_episodes():
    """Issue 21: 'the lock-out recovery is a single Gaussian at the nearest point of the
    range circle'. On the lock-out episodes above, the least-squares re-fix from the
    locked-out beacon's last ranges (``lockout_recovery="window"``, eqs. R1-R5, with its
    residual test dropping multipath ranges) recovers as the nearest-point restart does:
    episode means within 1.5 m of it and their mean within 5 % (measured: 3.56 against
    3.49 m, the largest difference 1.17 m). It does not beat it here: an 18 % speed-scale
    error re-drifts the filter within a few cycles of any restart, whichever the restart
    (12-15 restarts an episode). Where it wins is benchmarks/nees_per_cycle.py case 8
    over 100 held-out runs: worst episode mean 13.0 m against the nearest point's 522 m
    (docs/scenarios/consider-fusion.md). Before the residual test, a multipath range in
    the window sent fixes hundreds of metres off and a beacon that follows the estimate
    after them (168 m episode mean); this test fails on that code."""
    seeds = range(800000, 800006)
    window = [_episode(s, 3, lockout_recovery="window") for s in seeds]
    nearest = [_episode(s, 3, lockout_recovery="nearest_point") for s in seeds]
    print("window", window, "nearest point", nearest)
    assert all(r > 0 for _, r in window)
    assert np.mean([e for e, _ in window]) < 1.05 * np.mean([e for e, _ in nearest]), (window, nearest)
    assert all(a < b + 1.5 for (a, _), (b, _) in zip(window, nearest)), (window, nearest)


def test_no_runaway_when_the_beacon_follows_the_estimate():
    """The circle planner orbits the survey's reported estimate; a restart that trusted
    one range (variance R along the line of sight) let it drag the estimate away,
    restart after restart, on this episode (1.9 km). With the miss in the restarted
    variance the episode stays as good as without restarts: one restart at cycle 12,
    from a range that a multipath excess made too long, costs one cycle (31.8 m) and
    the next ranges pull the estimate back."""
    from evaluation.episodes import run_episodes

    c = coopnav_env.make_config("sousa_asv")
    (on,), steps = run_episodes(c, "circle", [300014])
    (off,), _ = run_episodes(c.replace(reinit_after_rejected_ranges=0), "circle", [300014])
    assert max(r["survey_error_m"] for r in steps[15:]) < 10.0
    assert on["mean_error_m"] < off["mean_error_m"] + 0.5


def test_no_restart_without_a_lockout():
    """Without a speed-scale error the gate rejects only the odd outlier: no restart."""
    assert _episode(800000, 3, speed_scale=1.0)[1] == 0
