"""Bad input raises a clear exception naming what was wrong; nothing is silently
accepted except finite out-of-range actions (clipped), and a NaN never enters the filter."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest

import coopnav_env
from coopnav_env.gym_env import CoopNavGymEnv


def _env(**kw):
    kw.setdefault("max_cycles", 5)
    env = coopnav_env.parallel_env("gao_lawnmower", **kw)
    env.reset(seed=0)
    return env


ZERO = np.zeros(2, dtype=np.float32)


# --- actions -----------------------------------------------------------------------
@pytest.mark.parametrize("bad", [np.zeros(3), np.zeros((1, 2)), np.zeros(1), np.float32(0.5), np.zeros((2, 2))])
def test_wrong_action_shape(bad):
    env = _env()
    with pytest.raises(ValueError, match=r"beacon_0 must have shape \(2,\)"):
        env.step({"beacon_0": bad})


def test_non_numeric_action():
    env = _env()
    with pytest.raises(ValueError, match="beacon_0 is not numeric"):
        env.step({"beacon_0": "north"})


@pytest.mark.parametrize("value", [np.nan, np.inf, -np.inf])
def test_non_finite_action(value):
    env = _env()
    with pytest.raises(ValueError, match="beacon_0 must be finite"):
        env.step({"beacon_0": np.array([0.1, value], dtype=np.float32)})


def test_bad_action_does_not_advance_the_env():
    env = _env()
    t0 = env.sim.state.t_s.copy()
    with pytest.raises(ValueError):
        env.step({"beacon_0": np.array([np.nan, 0.0])})
    assert np.array_equal(env.sim.state.t_s, t0)
    env.step({"beacon_0": ZERO})  # still usable


def test_bad_action_names_the_offending_agent():
    env = _env(beacon_kinds=("beacon_auv", "asv"))
    with pytest.raises(ValueError, match="beacon_1 must be finite"):
        env.step({"beacon_0": ZERO, "beacon_1": np.array([np.inf, 0.0])})


def test_action_for_unknown_agent():
    """A name that is no agent is named with the closest, in step() as in the spaces and
    the AEC view's observe() (which returned a Box, or raised a bare KeyError)."""
    env = _env()
    with pytest.raises(ValueError, match=r"unknown agent 'beacon_7'; did you mean 'beacon_0'\? agents: beacon_0"):
        env.step({"beacon_0": ZERO, "beacon_7": ZERO})
    with pytest.raises(ValueError, match=r"unknown agent 'becon_0'; did you mean 'beacon_0'"):
        env.step({"becon_0": ZERO})
    for space in (env.observation_space, env.action_space):
        with pytest.raises(ValueError, match=r"unknown agent 'beacon_7'"):
            space("beacon_7")
    aec = coopnav_env.env("gao_team")
    aec.reset(seed=0)
    with pytest.raises(ValueError, match=r"unknown agent 'beacon_9'; did you mean"):
        aec.observe("beacon_9")


def test_aec_refuses_a_nan_on_its_own_turn_and_does_not_keep_it():
    """PettingZoo's parallel-to-AEC wrapper stores each action until the last agent's turn:
    a NaN from beacon_0 failed on beacon_1's turn, then at every turn until reset()."""
    aec = coopnav_env.env("gao_team")
    aec.reset(seed=0)
    with pytest.raises(ValueError, match="action for beacon_0 must be finite"):
        aec.step(np.array([np.nan, 0.0]))
    assert aec.agent_selection == "beacon_0"
    with pytest.raises(ValueError, match="action for beacon_0 is None: a live agent needs one"):
        aec.step(None)
    aec.step(ZERO)
    aec.step(ZERO)  # beacon_1's turn: the cycle runs
    assert aec.agent_selection == "beacon_0" and np.isfinite(aec.last()[0]).all()


def test_the_gymnasium_view_plays_parallel_envs_episode_and_stops_at_its_end():
    """``reset(seed=s)`` is episode s of ``parallel_env`` (it drew another from Gymnasium's
    generator), a seed out of range is the same ValueError, and a step after the end is
    refused (it ran on: 300 steps later the error was 883 m). Only one-beacon scenarios
    are registered."""
    g = gymnasium.make("coopnav/gao_lawnmower-v0", max_cycles=5)
    obs, _ = g.reset(seed=5)
    p_obs, _ = coopnav_env.parallel_env("gao_lawnmower", max_cycles=5).reset(seed=5)
    assert np.array_equal(obs, p_obs["beacon_0"])
    with pytest.raises(ValueError, match="seed must be"):
        g.reset(seed=-1)
    g.reset(seed=0)
    ended = False
    for _ in range(5):
        *_, terminated, truncated, _ = g.step(ZERO)
        ended = terminated or truncated
    assert ended
    with pytest.raises(ValueError, match=r"step\(\) after the episode ended"):
        g.step(ZERO)
    assert "coopnav/gao_team-v0" not in gymnasium.registry and "coopnav/sousa_asv-v0" in gymnasium.registry


def test_action_after_episode_end():
    env = _env(max_cycles=2)
    while env.agents:
        env.step(dict.fromkeys(env.agents, ZERO))
    with pytest.raises(ValueError, match=r"not alive.*beacon_0"):
        env.step({"beacon_0": ZERO})


def test_step_after_episode_end_without_actions():
    """An empty step after the end must not advance a finished episode silently."""
    env = _env(max_cycles=2)
    while env.agents:
        env.step(dict.fromkeys(env.agents, ZERO))
    t_end = env.sim.state.t_s.copy()
    with pytest.raises((ValueError, RuntimeError), match="reset"):
        env.step({})
    assert np.array_equal(env.sim.state.t_s, t_end)


def test_step_before_reset():
    env = coopnav_env.parallel_env("gao_lawnmower")
    with pytest.raises((ValueError, RuntimeError), match="reset"):
        env.step({"beacon_0": ZERO})


def test_missing_action():
    env = _env(beacon_kinds=("beacon_auv", "asv"))
    with pytest.raises(ValueError, match=r"no action.*beacon_1"):
        env.step({"beacon_0": ZERO})


def test_actions_not_a_dict():
    env = _env()
    with pytest.raises(ValueError, match="dict"):
        env.step([ZERO])


def test_gym_view_bad_actions():
    env = CoopNavGymEnv("gao_lawnmower", max_cycles=5)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="must be finite"):
        env.step(np.array([np.nan, 0.0], dtype=np.float32))
    with pytest.raises(ValueError, match=r"shape \(2,\)"):
        env.step(np.zeros(4, dtype=np.float32))


# --- configuration -----------------------------------------------------------------
@pytest.mark.parametrize("value", [-20.0, 0.0])
def test_non_positive_ping_interval(value):
    with pytest.raises(ValueError, match=r"ping_interval_s must be in \(0, 3600\], got"):
        coopnav_env.parallel_env("gao_lawnmower", ping_interval_s=value)


@pytest.mark.parametrize("value", [-1.0, 0.0, 5e-324, 9e-4])
def test_non_positive_or_subnormal_substep(value):
    """Below 1 ms the step count per cycle overflows (5e-324 s gave an OverflowError)."""
    with pytest.raises(ValueError, match=r"substep_s must be in \[0.001, 60\], got"):
        coopnav_env.parallel_env("gao_lawnmower", substep_s=value)


@pytest.mark.parametrize("ping, sub", [(20.0, 3.0), (20.0, 0.7), (10.0, 4.0)])
def test_substep_not_dividing_ping_interval(ping, sub):
    with pytest.raises(ValueError, match=r"ping_interval_s .* whole multiple of substep_s"):
        coopnav_env.parallel_env("gao_lawnmower", ping_interval_s=ping, substep_s=sub)


def test_substep_dividing_ping_interval_is_fine():
    env = coopnav_env.parallel_env("gao_lawnmower", ping_interval_s=10.0, substep_s=0.5)
    assert env.config.substeps_per_cycle == 20


@pytest.mark.parametrize("value", [float("nan"), float("inf")])
def test_non_finite_parameter(value):
    with pytest.raises(ValueError, match="current_speed_mps must be finite"):
        coopnav_env.parallel_env("gao_lawnmower", current_speed_mps=value)


@pytest.mark.parametrize("value", [0, -3])
def test_bad_max_cycles(value):
    with pytest.raises(ValueError, match="max_cycles"):
        coopnav_env.parallel_env("gao_lawnmower", max_cycles=value)


def test_unknown_scenario_lists_valid_ones():
    with pytest.raises(ValueError, match=r"unknown scenario 'gao_lake'.*gao_lawnmower.*gao_sea"):
        coopnav_env.parallel_env("gao_lake")
    with pytest.raises(ValueError, match=r"unknown scenario.*gao_lawnmower.*gao_sea"):
        coopnav_env.env("nope")


def test_a_name_in_another_case_or_misspelt_names_the_one_meant():
    """``coopnav_env.names.closest``, the one home of "did you mean": the same name in another
    case first (difflib alone finds nothing for 'GAO_SEA' or 'PPO'), else the closest spelling,
    for scenarios and for a parameter's choices alike."""
    from coopnav_env.names import closest, did_you_mean

    assert closest("GAO_SEA", coopnav_env.list_scenarios()) == "gao_sea"
    assert did_you_mean("PPO", ["static", "ppo"]) == "; did you mean 'ppo'?"
    assert closest("Sousa_AS", coopnav_env.list_scenarios()) == "sousa_asv"
    assert closest("zzz", ["static", "ppo"]) is None and did_you_mean("zzz", ["ppo"]) == ";"
    with pytest.raises(ValueError, match=r"unknown scenario 'GAO_SEA' \(did you mean 'gao_sea'\?\)"):
        coopnav_env.make_config("GAO_SEA")
    with pytest.raises(ValueError, match=r"unknown survey_path 'spirl'; did you mean 'spiral'\? valid: "):
        coopnav_env.make_config("sousa_asv", survey_path="spirl")


def test_unknown_keyword_lists_valid_parameters():
    with pytest.raises(ValueError, match=r"ping_intervall_s.*did you mean 'ping_interval_s'") as err:
        coopnav_env.parallel_env("gao_lawnmower", ping_intervall_s=10.0)
    msg = str(err.value)
    assert "valid parameters" in msg
    for name in ("ping_interval_s", "substep_s", "current_speed_mps", "beacon_kinds", "max_cycles"):
        assert name in msg


def test_unknown_keyword_through_gymnasium_make():
    with pytest.raises(ValueError, match="unknown scenario parameter"):
        gymnasium.make("coopnav/gao_lawnmower-v0", no_such_parameter=1)


@pytest.mark.parametrize("mode", ["rgb", "ansi", "RGB_ARRAY"])
def test_bad_render_mode(mode):
    with pytest.raises(ValueError, match=rf"render_mode '{mode}'.*rgb_array"):
        coopnav_env.parallel_env("gao_lawnmower", render_mode=mode)
    with pytest.raises(ValueError, match=rf"render_mode '{mode}'"):
        CoopNavGymEnv("gao_lawnmower", render_mode=mode)


def test_unknown_beacon_kind():
    with pytest.raises(ValueError, match=r"unknown beacon kind 'submarine'.*beacon_auv.*asv"):
        coopnav_env.parallel_env("gao_lawnmower", beacon_kinds=("beacon_auv", "submarine"))


def test_empty_beacon_kinds():
    with pytest.raises(ValueError, match="beacon_kinds"):
        coopnav_env.parallel_env("gao_lawnmower", beacon_kinds=())


def test_unknown_survey_path():
    with pytest.raises(ValueError, match=r"unknown survey_path 'zigzag'.*lawnmower"):
        coopnav_env.parallel_env("gao_lawnmower", survey_path="zigzag")


def test_unknown_action_mode_and_ranging_mode():
    with pytest.raises(ValueError, match=r"unknown action_mode 'polar'"):
        coopnav_env.parallel_env("gao_lawnmower", action_mode="polar")
    with pytest.raises(ValueError, match=r"unknown ranging_mode 'usbl'"):
        coopnav_env.parallel_env("gao_lawnmower", ranging_mode="usbl")


def test_probability_out_of_range():
    with pytest.raises(ValueError, match=r"sensor_nan_probability must be in \[0, 1\]"):
        coopnav_env.parallel_env("gao_lawnmower", sensor_nan_probability=1.5)


# --- finite out-of-range actions are clipped ---------------------------------------
def _run(actions_seq, **kw):
    env = coopnav_env.parallel_env("gao_lawnmower", max_cycles=len(actions_seq), **kw)
    env.reset(seed=11)
    out = []
    for act in actions_seq:
        out.append(env.step({"beacon_0": act}))
    return out, env


@pytest.mark.parametrize("mode", ["velocity", "heading_speed"])
def test_out_of_range_actions_are_clipped(mode):
    raw = [np.array([5.0, -3.0]), np.array([-1.7, 0.2]), np.array([0.3, 40.0]), np.array([-2.0, -2.0])]
    clipped = [np.clip(a, -1.0, 1.0) for a in raw]
    out_raw, env_raw = _run(raw, action_mode=mode)
    out_clip, env_clip = _run(clipped, action_mode=mode)
    for (o1, r1, te1, tr1, i1), (o2, r2, te2, tr2, i2) in zip(out_raw, out_clip):
        for a in o1:
            np.testing.assert_array_equal(o1[a], o2[a])
        assert r1 == r2 and te1 == te2 and tr1 == tr2 and i1 == i2
    np.testing.assert_array_equal(env_raw.sim.state.b_pos, env_clip.sim.state.b_pos)
    # and clipping matters: the unclipped direction would have moved the beacon elsewhere
    # (velocity mode: (5, -3) normalized is not (1, -1) normalized)
    if mode == "velocity":
        _out_other, env_other = _run([raw[0] / np.linalg.norm(raw[0])] + clipped[1:], action_mode=mode)
        assert not np.array_equal(env_other.sim.state.b_pos, env_clip.sim.state.b_pos)


def test_gym_view_clips_like_the_parallel_env():
    genv = CoopNavGymEnv("gao_lawnmower", max_cycles=3)
    genv.reset(seed=4)
    o1, r1, *_ = genv.step(np.array([3.0, -9.0], dtype=np.float32))
    genv2 = CoopNavGymEnv("gao_lawnmower", max_cycles=3)
    genv2.reset(seed=4)
    o2, r2, *_ = genv2.step(np.array([1.0, -1.0], dtype=np.float32))
    np.testing.assert_array_equal(o1, o2)
    assert r1 == r2


# --- a NaN from a sensor never enters the filter -------------------------------------
@pytest.mark.parametrize("ranging_mode", ["owtt", "twtt"])
def test_sensor_nan_is_rejected_and_counted(ranging_mode):
    env = coopnav_env.parallel_env(
        "gao_lawnmower", sensor_nan_probability=0.5, ranging_mode=ranging_mode, max_cycles=25, seed=2
    )
    obs, _ = env.reset(seed=2)
    rng = np.random.default_rng(0)
    nan_total, fused_total, steps = 0, 0, 0
    while env.agents:
        obs, rewards, _, _, infos = env.step({a: rng.uniform(-1, 1, 2).astype(np.float32) for a in env.agents})
        steps += 1
        st = env.sim.state
        assert np.all(np.isfinite(st.s_est)), f"NaN/inf in the EKF estimate at step {steps}"
        assert np.all(np.isfinite(st.s_P)), f"NaN/inf in the EKF covariance at step {steps}"
        P = st.s_P[0, 0]
        np.testing.assert_allclose(P, P.T, atol=1e-9)
        assert np.all(np.linalg.eigvalsh(P) > 0)
        # a rejected depth reading is not replaced by a made-up one: depth stays right
        depth_err = np.abs(st.s_est[..., 2] - st.s_pos[..., 2])
        assert np.all(depth_err < 1.0), f"depth estimate off by {depth_err.max():.2f} m at step {steps}"
        for a in env.possible_agents:
            if a in obs:
                assert np.all(np.isfinite(obs[a]))
                assert np.isfinite(rewards[a])
        info = infos["beacon_0"]
        assert np.isfinite(info["survey_error_m"]) and np.isfinite(info["cov_logdet"])
        assert info["nan_rejected"] == sum(info["nan_rejected_per_vehicle"])
        nan_total += info["nan_rejected"]
        fused_total += info["ranges_fused"]
    assert nan_total > 0, "no NaN measurement was counted with sensor_nan_probability=0.5"
    # a NaN is a rejected measurement, nothing more: other measurements are still fused
    assert fused_total > 0


def test_no_nan_rejections_without_fault_injection():
    env = _env(max_cycles=10)
    total = 0
    while env.agents:
        _, _, _, _, infos = env.step(dict.fromkeys(env.agents, ZERO))
        total += infos["beacon_0"]["nan_rejected"]
    assert total == 0


@pytest.mark.parametrize(
    "overrides, named",
    [
        ({"survey_area_m": (130.0, 1e12)}, "survey_area_m"),
        ({"lawnmower_spacing_m": 1e-7}, "lawnmower_spacing_m"),
        ({"circle_laps": 1e7, "survey_path": "circle"}, "circle_laps"),
        ({"survey_area_m": (1e300, 1e300)}, "survey_area_m"),
        ({"lawnmower_spacing_m": 0}, "lawnmower_spacing_m"),
        ({"survey_origin_m": (float("nan"), 0.0)}, "survey_origin_m"),
        ({"range_noise_std_m": "1.0"}, "range_noise_std_m"),
        ({"range_noise_std_m": 1e200}, "range_noise_std_m"),
        ({"circle_laps": -1.0}, "circle_laps"),
        ({"line_length_m": -5.0}, "line_length_m"),
        ({"waypoint_acceptance_m": -1.0}, "waypoint_acceptance_m"),
        ({"max_cycles": 2.5}, "max_cycles"),
        ({"path_repeats": 1000, "survey_path": "circle", "circle_laps": 100.0}, "waypoints"),
    ],
)
def test_inputs_that_used_to_hang_or_crash_are_refused_at_once(overrides, named):
    """Each refused in well under a second with a ValueError naming the parameter and,
    for numbers, the allowed range (they used to grow to gigabytes, hang, divide by
    zero, or pass and give NaN observations)."""
    import time

    t0 = time.perf_counter()
    with pytest.raises(ValueError, match=named) as info:
        coopnav_env.make_config("gao_lawnmower", **overrides)
    assert time.perf_counter() - t0 < 1.0
    assert "\n" not in str(info.value)


def test_number_refusals_name_the_allowed_range():
    with pytest.raises(ValueError, match=r"range_noise_std_m must be in \(0, 1000\], got 1e\+200"):
        coopnav_env.make_config("gao_lawnmower", range_noise_std_m=1e200)
    with pytest.raises(ValueError, match=r"circle_laps must be in \(0, 1000\], got -1"):
        coopnav_env.make_config("gao_lawnmower", circle_laps=-1)


def test_every_number_parameter_has_limits():
    from coopnav_env.scenarios.base import bounds, default_of, parameter_names

    numeric = {n for n in parameter_names() if type(default_of(n)) in (int, float)}
    assert numeric == set(bounds()), numeric ^ set(bounds())
    for scenario in coopnav_env.list_scenarios():  # the defaults and every scenario lie inside them
        coopnav_env.make_config(scenario)


@pytest.mark.parametrize("seed", [-1, 2**62, 2**63, 1.5, "3", True, None])
def test_pettingzoo_env_and_vecenv_refuse_the_same_seeds(seed):
    """One rule for seeds (coopnav_env.seeds.check_seed): integers in [0, 2**62 - 1]."""
    from coopnav_env.vector import CoopNavVecEnv

    if seed is None:  # None means "draw one" in both
        coopnav_env.parallel_env("gao_lawnmower").reset(seed=None)
        CoopNavVecEnv("gao_lawnmower", n_envs=1, seed=None).reset()
        return
    with pytest.raises(ValueError, match="seed must be"):
        coopnav_env.parallel_env("gao_lawnmower").reset(seed=seed)
    with pytest.raises(ValueError, match="seed must be"):
        CoopNavVecEnv("gao_lawnmower", n_envs=1, seed=seed)


def test_largest_seed_runs_in_both_views():
    from coopnav_env.seeds import MAX_SEED
    from coopnav_env.vector import CoopNavVecEnv

    env = coopnav_env.parallel_env("gao_lawnmower", max_cycles=2)
    obs, _ = env.reset(seed=MAX_SEED)
    venv = CoopNavVecEnv("gao_lawnmower", n_envs=1, seed=MAX_SEED, max_cycles=2)
    assert np.array_equal(venv.reset()[0], obs["beacon_0"])


def test_state_before_reset_is_one_clear_error():
    env = coopnav_env.parallel_env("gao_lawnmower")
    with pytest.raises(RuntimeError, match=r"state\(\) before reset\(\)"):
        env.state()


def test_policies_refuse_a_nan_or_misshapen_observation_in_one_line():
    """``coopnav_env.views.check_observation`` in every policy's act: the planners answered
    a NaN observation with a NaN action, a batch with a numpy broadcasting error; the shipped
    SB3 policy with a multi-line torch error; a seed of -1 was numpy's error."""
    import agents
    import baselines

    env = _env()
    obs = env.reset(seed=0)[0]["beacon_0"]
    bad = obs.copy()
    bad[3] = np.nan
    for policy in (
        baselines.make_policy("fim_a", env),
        baselines.make_policy("ellipse", env),
        agents.load("ppo", scenario="gao_lawnmower"),
    ):
        with pytest.raises(
            ValueError, match=r"observation must be finite, got 1 NaN or infinite value\(s\) \(entries 3\)"
        ):
            policy.act(bad)
        with pytest.raises(ValueError, match=rf"observation must have shape \({obs.size},\), got \(3, {obs.size}\)"):
            policy.act(np.tile(obs, (3, 1)))
        assert np.isfinite(policy.act(obs)).all()
    sb3 = agents.load("ppo_sousa_asv")
    with pytest.raises(ValueError, match=r"observation must be finite, got \d+ NaN"):
        sb3.act_batch(np.full((2, sb3.obs_dim), np.nan))
    with pytest.raises(ValueError, match=r"policy seed must be in \[0, "):
        baselines.make_policy("random", env, seed=-1)


def test_loading_a_policy_names_what_was_mistyped():
    """``agents.load("ppo", scenario=...)`` with a misspelt scenario names the scenario (it
    said "no policy 'ppo'"), and a misspelt shipped name gets its closest."""
    import agents

    with pytest.raises(ValueError, match=r"unknown scenario 'sousa_asb'; did you mean 'sousa_asv'\?"):
        agents.load("ppo", scenario="sousa_asb")
    with pytest.raises(ValueError, match=r"no policy 'ppo_sousa_asb': .*; did you mean 'ppo_sousa_asv'\? shipped: "):
        agents.load("ppo_sousa_asb")
    with pytest.raises(ValueError, match=r"no policy 'PPO': .*; did you mean 'ppo'\?"):
        agents.load("PPO", scenario="sousa_asv")


def test_smaller_slips_are_one_line_naming_the_closest():
    """A training reward term misspelt, a scenario given as a list, a complex action (numpy
    dropped its imaginary part with only a warning)."""
    from coopnav_env.vector import CoopNavVecEnv

    with pytest.raises(ValueError, match=r"unknown reward term 'eror'; did you mean 'error'\? valid terms: "):
        CoopNavVecEnv(coopnav_env.make_config("gao_lawnmower"), n_envs=1, reward_terms={"eror": 1.0})
    with pytest.raises(TypeError, match="scenario must be a scenario name"):
        coopnav_env.make_config(["gao_sea"])
    env = _env()
    with pytest.raises(ValueError, match="action for beacon_0 must be real"):
        env.step({"beacon_0": np.array([1j, 0.0])})
    with pytest.raises(ValueError, match="action for beacon_0 is not numeric"):  # ragged
        env.step({"beacon_0": [[1.0, 2.0], [3.0]]})
    import baselines

    assert baselines.make_policy("random", env, seed=np.array([3, 0])).seed == (3, 0)  # numpy seeds, as before
