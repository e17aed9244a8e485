"""Per-episode domain randomization: drawn from the episode's seed, inside the bounds."""

import numpy as np
import pytest

import coopnav_env
from coopnav_env import make_config
from coopnav_env.core.sim import Simulator

DR = dict(
    randomize_survey_path=("lawnmower", "circle"), randomize_depth_m=(1.0, 50.0), randomize_noise_scale=(0.5, 2.0)
)


def test_variants_cover_the_grid_and_follow_the_seed():
    config = make_config("sousa_asv", **DR)
    sim = Simulator(config, 64)
    sim.reset(np.arange(64))
    st = sim.state
    assert sim.variants == [("lawnmower", 1.0), ("lawnmower", 50.0), ("circle", 1.0), ("circle", 50.0)]
    assert set(st.ep_variant.tolist()) == {0, 1, 2, 3}
    depth = np.array([sim.variants[v][1] for v in st.ep_variant])
    np.testing.assert_allclose(st.s_pos[:, 0, 2], depth)  # each survey starts at its variant's depth
    assert np.all((st.ep_noise_scale >= 0.5) & (st.ep_noise_scale <= 2.0))
    assert st.ep_noise_scale.std() > 0.2
    # a circle's waypoints lie on its circle, a lawnmower's on its tracks
    for b in range(64):
        kind = sim.variants[st.ep_variant[b]][0]
        wp = st.s_waypoints[b, 0, : st.s_n_waypoints[b, 0], :2]
        radius = np.linalg.norm(wp - wp.mean(0), axis=1)
        assert (np.ptp(radius) < 1.0) == (kind == "circle")
    # the same seed alone draws the same episode
    alone = Simulator(config, 1)
    alone.reset([37])
    assert alone.state.ep_variant[0] == st.ep_variant[37]
    assert alone.state.ep_noise_scale[0] == st.ep_noise_scale[37]


def test_noise_scale_scales_the_range_noise():
    """Range residuals against the true geometry grow with the drawn noise scale."""
    spread = {}
    for scale in (0.5, 2.0):
        env = coopnav_env.parallel_env(
            "gao_lawnmower",
            randomize_noise_scale=(scale, scale),
            outlier_probability=0.0,
            compass_bias_std_deg=0.0,
            survey_speed_scale_error_std=0.0,
        )
        env.reset(seed=3)
        errs = []
        while env.agents:
            _, _, _, _, infos = env.step({a: np.zeros(2) for a in env.agents})
            errs.append(infos["beacon_0"]["survey_error_m"])
        spread[scale] = np.mean(errs)
    assert spread[2.0] > spread[0.5]


def test_bad_randomization_bounds_are_refused():
    with pytest.raises(ValueError, match="randomize_survey_path"):
        make_config("gao_lawnmower", randomize_survey_path=("zigzag",))
    with pytest.raises(ValueError, match="randomize_noise_scale"):
        make_config("gao_lawnmower", randomize_noise_scale=(2.0, 1.0))
    with pytest.raises(ValueError, match="randomize_depth_m"):
        make_config("gao_lawnmower", randomize_depth_m=(-1.0,))
