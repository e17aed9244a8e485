"""Parts as registered plug-ins: a sensor, reward terms and a training signal declared
from this file alone drive a scenario through the survey simulator and the views, and
leave nothing behind (the registrations are undone after each test)."""

import numpy as np
import pytest

import coopnav_env
from coopnav_env.core import make_simulator, measurements, reward
from coopnav_env.core.channel import channel_model_names
from coopnav_env.core.reward import (
    SURVEY_TERMS,
    check_training_terms,
    register_term,
    terms_for,
    unregister_term,
    weighted_reward,
)
from coopnav_env.scenarios import base

STEPS, B = 10, 3


class LostRanges:
    """A toy sensor: every range is lost (the modem's lost flags, nothing fused); it reads
    its own registered draws to show that they reach ``fuse``."""

    def __init__(self, sim):
        self.sim = sim
        self.draw_shapes = []

    def heard_mask(self, cycle):
        return None  # every beacon pings every cycle

    def fuse(self, draws, out):
        self.draw_shapes.append(draws["toy_u"].shape)
        out.lost[:] = True


def _reject_twtt(config):
    if config.ranging_mode != "owtt":
        raise ValueError("acoustic_sensor='toy' hears one-way pings only: ranging_mode='owtt'")


def _speed(ctx):
    return np.hypot(ctx.state.b_vel[..., 0], ctx.state.b_vel[..., 1])  # (B, N): the beacons' speed


@pytest.fixture
def toy_parts():
    measurements.register_sensor(
        "toy",
        LostRanges,
        draws=[("toy_u", "uniform", lambda S, N, K: (N, S))],
        validate=_reject_twtt,
        doc="every range lost",
    )
    only_toy = {"acoustic_sensor": ("toy",)}  # the terms belong to the scenarios with the toy sensor
    register_term(
        "toy_speed",
        compute=_speed,
        networks=("survey_beacons",),
        modes=only_toy,
        doc="the beacon's speed over ground (m/s)",
    )
    register_term(
        "toy_const",
        weight="geofence_penalty",
        penalty=True,
        compute=lambda ctx: 1.0,
        networks=("survey_beacons",),
        modes=only_toy,
        doc="1 every cycle",
    )
    register_term(
        "toy_signal",
        kind="training",
        compute=lambda ctx: 2.0 * ctx.result.terms["toy_speed"],
        doc="twice the beacon's speed",
    )
    yield
    for name in ("toy_speed", "toy_const", "toy_signal"):
        unregister_term(name)
    measurements.unregister_sensor("toy")


def test_a_toy_sensor_and_toy_terms_run_through_the_survey_simulator(toy_parts):
    config = coopnav_env.make_config(
        "gao_lawnmower", acoustic_sensor="toy", geofence_penalty=0.25, beacon_kinds=("beacon_auv", "asv")
    )
    sim = make_simulator(config, B)
    assert sim.reward_terms == SURVEY_TERMS + ("toy_speed", "toy_const") == terms_for(config)
    assert sim.reward_weights["toy_speed"] == 1.0 and sim.reward_weights["toy_const"] == -0.25
    sim.reset(np.arange(B) + 5)
    rng = np.random.default_rng(1)
    builtin = {k: w for k, w in sim.reward_weights.items() if not k.startswith("toy_")}
    for _ in range(STEPS):
        res = sim.step(rng.uniform(-1, 1, (B, 2, 2)))
        assert tuple(res.terms) == sim.reward_terms
        speed = np.hypot(sim.state.b_vel[..., 0], sim.state.b_vel[..., 1])
        np.testing.assert_array_equal(res.terms["toy_speed"], speed)
        np.testing.assert_array_equal(res.terms["toy_const"], np.ones((B, 2)))
        np.testing.assert_array_equal(res.reward, weighted_reward(res.terms, sim.reward_weights))
        # the toy terms' weighted contribution: +1 x speed - geofence_penalty x 1
        np.testing.assert_allclose(res.reward - weighted_reward(res.terms, builtin), speed - 0.25, rtol=0, atol=1e-12)
        # the toy sensor: nothing fused, every range lost, no information gained, no contact
        assert (res.info["ranges_fused"] == 0).all() and (res.info["packets_lost"] == 2).all()
        assert (res.terms["info_gain"] == 0.0).all() and (res.terms["contact"] == 1.0).all()
    assert sim.sensor.draw_shapes == [(B, 2, 1)] * STEPS  # its own draws, (B, N, S)
    # the penalties (the training signal "penalties") count a registered penalty term
    assert "toy_const" in reward.PENALTY_TERMS and reward.TERM_WEIGHTS["toy_const"] == "geofence_penalty"
    np.testing.assert_allclose(
        reward.penalties(res.terms, sim.reward_weights),
        0.25 * (res.terms["geofence"] + 1.0) + config.safety_penalty * res.terms["safety"],
    )


def test_the_toy_sensor_keeps_the_shared_draws_and_reaches_every_view(toy_parts):
    """The sensor's draws go after the shared ones: the same seed and actions give the
    beacons the same navigation errors and the water the same current as with the modem
    (the survey vehicles, steered by their own estimates, differ: nothing is fused)."""
    toy = coopnav_env.parallel_env("gao_lawnmower", seed=3, acoustic_sensor="toy", max_cycles=STEPS)
    modem = coopnav_env.parallel_env("gao_lawnmower", seed=3, max_cycles=STEPS)
    toy.reset(), modem.reset()
    zero = {a: np.zeros(2, dtype=np.float32) for a in toy.agents}
    for _ in range(3):
        _, rewards, _, _, _ = toy.step(zero)
        modem.step(zero)
    res = toy.last_result
    assert rewards["beacon_0"] == pytest.approx(float(res.reward[0, 0]))
    np.testing.assert_array_equal(toy.sim.state.b_nav_err, modem.sim.state.b_nav_err)
    np.testing.assert_array_equal(toy.sim.state.current_gm, modem.sim.state.current_gm)
    assert "toy_speed" in res.terms and "toy_speed" not in modem.last_result.terms


def test_a_registered_training_signal_drives_the_vector_env(toy_parts):
    from coopnav_env.vector import REWARD_TERMS, CoopNavVecEnv, check_reward_terms

    assert "toy_signal" in REWARD_TERMS and check_reward_terms({"toy_signal": 3}) == {"toy_signal": 3.0}
    venv = CoopNavVecEnv("gao_lawnmower", n_envs=2, seed=0, acoustic_sensor="toy", reward_terms={"toy_signal": 0.5})
    venv.reset()
    actions = np.random.default_rng(0).uniform(-1, 1, (2, 2))
    _, r, _, _ = venv.step(actions)
    speed = np.hypot(venv.sim.state.b_vel[..., 0], venv.sim.state.b_vel[..., 1]).reshape(-1)
    np.testing.assert_allclose(r, 0.5 * 2.0 * speed, rtol=1e-6)


def test_the_registry_validates_and_unregisters(toy_parts):
    assert "toy" in base.ACOUSTIC_SENSORS and "toy" in measurements.sensor_names()
    with pytest.raises(ValueError, match="hears one-way pings only"):  # the sensor's own hook
        coopnav_env.make_config("gao_lawnmower", acoustic_sensor="toy", ranging_mode="twtt")
    with pytest.raises(ValueError, match="acoustic_sensor='toy' needs network='survey_beacons'"):
        coopnav_env.make_config("matos_moving_lbl", acoustic_sensor="toy")
    with pytest.raises(ValueError, match="registered twice"):
        measurements.register_sensor("toy", LostRanges)
    with pytest.raises(ValueError, match="registered twice"):
        register_term("toy_speed", compute=_speed, doc="again")
    with pytest.raises(ValueError, match="'toy_weight' is not a scenario parameter"):
        register_term("toy_weighed", weight="toy_weight", compute=_speed, doc="weighed by nothing")
    with pytest.raises(ValueError, match="needs a compute"):
        register_term("toy_nothing", kind="training", doc="no hook")
    with pytest.raises(
        ValueError, match="valid terms: env, error, log_error, std, logdet, penalties, rejected, toy_signal"
    ):
        check_training_terms({"speed": 1.0})
    assert "| `toy_speed` | the beacon's speed over ground (m/s) | +1 |" in reward.markdown_table()
    assert "| `toy_signal` |" in reward.markdown_table("training")


def test_nothing_is_left_registered_after_a_test():
    assert "toy" not in measurements.sensor_names() and "toy" not in base.ACOUSTIC_SENSORS
    assert not any(t.name.startswith("toy_") for t in reward.registered_terms(None))
    with pytest.raises(ValueError, match="unknown acoustic_sensor 'toy'; valid: modem, mls"):
        coopnav_env.make_config("gao_lawnmower", acoustic_sensor="toy")
    # the built-in registries match what the scenario validation accepts
    assert channel_model_names() == base.CHANNEL_MODES
    assert reward.SURVEY_TERMS == ("info_gain", "safety", "geofence", "contact")
    assert reward.CHANNEL_TERMS == reward.SURVEY_TERMS + ("ping",)
    assert reward.MOVING_NETWORK_TERMS == ("info_gain", "safety", "baseline", "approach", "rotation", "contact")
    assert reward.RIVER_NETWORK_TERMS == reward.MOVING_NETWORK_TERMS + ("bank",)
    assert reward.PENALTY_TERMS == ("safety", "geofence", "baseline", "approach", "rotation", "ping", "bank")


def test_a_planner_is_one_class_and_its_decorator():
    import baselines
    from baselines import Policy, make_policy, register_policy, unregister_policy

    @register_policy("toy_north")
    class North(Policy):
        """Always north at full speed."""

        def act(self, obs):
            return np.array([0.0, 1.0], dtype=np.float32)

    try:
        assert "toy_north" in baselines.list_policies("survey_beacons")
        policy = make_policy("toy_north", "gao_lawnmower")
        assert isinstance(policy, North) and policy.act(None).tolist() == [0.0, 1.0]
        with pytest.raises(ValueError, match="registered twice"):
            register_policy("toy_north")(type("Other", (Policy,), {}))
    finally:
        unregister_policy("toy_north")
    assert "toy_north" not in baselines.list_policies()
