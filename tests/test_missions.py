"""Whole-mission behaviour: ranging bounds the survey error, dead reckoning drifts
(Gao & Chitre Fig. 11, sea trial)."""

import numpy as np

from coopnav_env import make_config
from coopnav_env.core.sim import Simulator


def orbit_action(sim, radius_m=80.0):
    """A simple beacon that orbits the survey's last reported estimate (test helper)."""
    st = sim.state
    rel = st.k_est[:, 0, 0, :2] - (st.b_pos + st.b_nav_err)[:, 0, :2]
    d = np.linalg.norm(rel, axis=-1, keepdims=True)
    tangent = np.stack([-rel[:, 1], rel[:, 0]], -1) / d
    return np.clip(tangent + (d - radius_m) / 40.0 * rel / d, -1, 1)[:, None]


def test_gao_sea_two_hours_error_bounded_while_dead_reckoning_drifts():
    config = make_config("gao_sea", path_repeats=6)  # six passes of the 150 x 200 m lawnmower: ~2 h
    runs = 8
    sim = Simulator(config, runs)
    sim.reset(np.arange(runs))
    err, dr = [], []
    while True:
        res = sim.step(orbit_action(sim))
        err.append(res.info["survey_error_m"][:, 0])
        dr.append(res.info["dr_error_m"][:, 0])
        if (res.terminated | res.truncated).all():
            break
    err, dr = np.array(err), np.array(dr)
    hours = len(err) * config.ping_interval_s / 3600
    assert hours >= 2.0
    quarter = len(err) // 4
    # dead reckoning: the current (0.2-0.4 m/s) carries it away, it keeps growing
    assert dr[-1].mean() > 3 * dr[quarter].mean() > 300.0
    # with ranges, the error stays bounded: tens of metres, not kilometres
    assert err.mean(1).max() < 50.0
    # and by the end dead reckoning is many times worse
    assert dr[-1].mean() > 20 * err[-1].mean()


def test_static_beacon_cannot_fix_drift_as_well_as_a_moving_one():
    """A beacon parked at its start sees the survey from few directions; orbiting helps."""
    config = make_config("gao_lawnmower")
    runs = 16
    errors = {}
    for name in ("static", "orbit"):
        sim = Simulator(config, runs)
        sim.reset(np.arange(runs))
        e = []
        while True:
            action = np.zeros((runs, 1, 2)) if name == "static" else orbit_action(sim, 50.0)
            res = sim.step(action)
            e.append(res.info["survey_error_m"][:, 0])
            if (res.terminated | res.truncated).all():
                break
        errors[name] = np.mean(e)
    assert errors["orbit"] < errors["static"]
