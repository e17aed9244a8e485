"""Ranges too short: a lock-out already after two gated out (eq. R8,
``reinit_after_short_ranges``; docs/scenarios/consider-fusion.md#short-ranges), and a gate of
their own (``range_gate_short_probability``, docs/scenarios/consider-fusion.md#one-sided-gate).

The channel's outliers are longer paths: a multipath arrival is never shorter than the
direct one. So a streak of ranges rejected as too *long* may be multipath, and the filter
waits for ``reinit_after_rejected_ranges`` (3) of them; a streak rejected as too *short*
has no explanation but a filter that has drifted, and the gao scenarios restart after 2.
"""

from __future__ import annotations

import numpy as np
import pytest
from ping_harness import fuse_one_ping

from coopnav_env import make_config
from coopnav_env.scenarios.sections import PAPER_FILTER


def _first_restart(scenario: str, offset_east_m: float, calls: int = 4, fused_ok: bool = False, **overrides):
    """The call (0-based) of the survey sensor's fusion at which the filter restarts: a
    noiseless range every call from a beacon 100 m east of the survey vehicle, the filter's
    estimate held ``offset_east_m`` off the truth with a small covariance (so each range is
    gated out), west (negative) making every range too short and east too long."""
    from coopnav_env.core import make_simulator

    c = make_config(scenario, outlier_probability=0.0, max_range_m=5000.0, **overrides)
    sim = make_simulator(c, 1)
    sim.reset(np.array([0]))
    st = sim.state
    depth = st.s_pos[0, 0, 2]
    fused = []
    for call in range(calls):
        st.s_pos[0, 0] = [0.0, 0.0, depth]
        st.s_Pxd[:] = 0.0
        st.s_Pxb[:] = 0.0
        est, P = np.array([offset_east_m, 0.0, depth]), np.diag([1.0, 1.0, 0.01])
        out = fuse_one_ping(sim, est, P, [100.0, 0.0, depth], P_after_predict=True)
        fused.append(bool(out.fused[0, 0, 0]))
        assert fused_ok or not fused[-1]  # 20 m off with sigma 1 m: every range is gated out
        st.t_s = st.t_s + c.ping_interval_s
        if out.restarts[0, 0]:
            return call
    if fused_ok:
        return fused
    raise AssertionError(f"no restart in {calls} rejected ranges")


@pytest.mark.parametrize("scenario", ["gao_lawnmower", "gao_sea"])
def test_too_short_ranges_restart_after_two_too_long_after_three(scenario):
    """Estimate 20 m west of the truth, the beacon east: each range is 20 m shorter than
    predicted, and the filter restarts at the second; 20 m east, 20 m too long, at the third
    (a multipath streak must not restart it sooner). With the rule off (0, the papers' and
    the Sousa scenarios' setting), the short streak waits for the third too."""
    assert make_config(scenario).reinit_after_short_ranges == 2
    assert _first_restart(scenario, -20.0) == 1
    assert _first_restart(scenario, 20.0) == 2
    assert _first_restart(scenario, -20.0, reinit_after_short_ranges=0) == 2


def test_the_rule_is_off_in_the_papers_filter_and_on_sousa():
    assert PAPER_FILTER["reinit_after_short_ranges"] == 0 and PAPER_FILTER["range_gate_short_probability"] == 0.0
    assert make_config("gao_lawnmower", **PAPER_FILTER).reinit_after_short_ranges == 0
    assert make_config("sousa_asv").reinit_after_short_ranges == 0
    assert _first_restart("sousa_asv", -20.0) == 2


def test_gao_lawnmower_seed_950061_restarts_at_its_second_short_range():
    """End to end, the episode that set the rule (``ellipse`` driving): the told current's
    error drifts the filter 17 m east; the direct ranges of cycles 9 and 10 are 10 and 18 m
    shorter than predicted and gated out, and a multipath range at cycle 11 happens to fit
    the drifted estimate, is fused and ends the streak. Without the rule the filter restarts
    only at cycle 17, with the NEES above the 99.9 % point (13.8) at cycles 11-16; with it,
    at cycle 10, and no cycle of the episode exceeds the point."""
    from baselines.rollout import planned_steps

    def run(**over):
        restarts, nees = [], []
        for _cfg, _sim, res, live in planned_steps("gao_lawnmower", "ellipse", over, 1, 950061):
            if not live[0]:
                break
            e = np.asarray(res.info["survey_error_en_m"])[0, 0]
            P = np.asarray(res.info["survey_cov_en_m2"])[0, 0]
            nees.append(float(e @ np.linalg.solve(P, e)))
            restarts.append(int(np.asarray(res.info["filter_restarts"]).sum()))
        return np.flatnonzero(restarts), np.array(nees)

    at, nees = run(reinit_after_short_ranges=0)
    assert at[0] == 17 and np.all(nees[11:17] > 13.8)
    at, nees = run()
    assert at[0] == 10 and nees.max() < 13.8


@pytest.mark.parametrize("scenario", ["sousa_asv", "gao_lawnmower"])
def test_a_gate_of_their_own_fuses_a_range_too_short_and_still_rejects_one_too_long(scenario):
    """The estimate 4 m off along the line of sight, P = I (m^2) and R about 1 m^2: the
    innovation is about +-4 m with S about 2 m^2, a normalized square of about 8, beyond the
    99 % gate (6.63) and inside 99.99 % (15.1). With one gate both ways
    (``range_gate_short_probability=0``, gao's default) both are rejected; with 0.9999 (the
    Sousa scenarios' default) the short one is fused and the long one still rejected."""
    short, long = -4.0, 4.0
    one = {"range_gate_short_probability": 0.0}
    assert _first_restart(scenario, short, calls=1, fused_ok=True, **one) == [False]
    assert _first_restart(scenario, long, calls=1, fused_ok=True, **one) == [False]
    g = {"range_gate_short_probability": 0.9999}
    assert _first_restart(scenario, short, calls=1, fused_ok=True, **g) == [True]
    assert _first_restart(scenario, long, calls=1, fused_ok=True, **g) == [False]


@pytest.mark.parametrize(
    ("scenario", "expected"), [("sousa_asv", 0.9999), ("sousa_ping", 0.9999), ("gao_lawnmower", 0.0)]
)
def test_the_short_side_gate_is_the_sousa_default_and_off_in_the_papers_filter(scenario, expected):
    """The one-sided gate is the Sousa scenarios' default (their excess came from the symmetric
    gate) and not gao's; the papers' filter keeps one gate both ways."""
    from coopnav_env.scenarios import make_config
    from coopnav_env.scenarios.sections import PAPER_FILTER

    assert make_config(scenario).range_gate_short_probability == expected
    assert make_config(scenario, **PAPER_FILTER).range_gate_short_probability == 0.0
