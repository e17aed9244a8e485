"""The readable PPO loop on the batched core (agents/training/batched_ppo.py) and its runs as
policies (agents/batched_policy.py): GAE by hand, a tiny training run end to end, bad input."""

import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from optional import require

require("torchrl")
import torch  # noqa: E402

import agents  # noqa: E402
from agents.batched_policy import push_window  # noqa: E402
from agents.training.batched_ppo import (  # noqa: E402
    BatchedPPOConfig,
    RunningNorm,
    gae,
    main,
    next_state_values,
    train,
    widen_to_history,
)

ROOT = Path(__file__).resolve().parents[1]


def test_gae_by_hand_bootstraps_a_truncated_end_and_not_a_terminated_one():
    """Three steps, one environment, one beacon, gamma 0.5, lambda 0.5 (P1, P2):
    step 0 continues, step 1 ends by the cycle limit (truncated: V of its last state counts),
    step 2 terminates (its next value is ignored)."""
    r = torch.tensor([1.0, 2.0, 3.0]).reshape(3, 1, 1)
    v = torch.tensor([0.5, 1.0, 4.0]).reshape(3, 1, 1)
    v_next = torch.tensor([1.0, 8.0, 100.0]).reshape(3, 1, 1)  # V of the state each step ended in
    term = torch.tensor([0.0, 0.0, 1.0]).reshape(3, 1, 1)
    done = torch.tensor([0.0, 1.0, 1.0]).reshape(3, 1, 1)
    adv = gae(r, v, v_next, term, done, 0.5, 0.5).flatten().tolist()
    d2 = 3.0 - 4.0  # terminated: no bootstrap
    d1 = 2.0 + 0.5 * 8.0 - 1.0  # truncated: bootstrapped; the sum stops here (done)
    d0 = 1.0 + 0.5 * 1.0 - 0.5
    assert adv == pytest.approx([d0 + 0.25 * d1, d1, d2])


def test_gae_broadcasts_the_environment_flags_over_the_beacons():
    r = torch.ones(2, 3, 2)
    zeros = torch.zeros(2, 3, 2)
    done = torch.tensor([1.0, 0.0]).reshape(2, 1, 1).expand(2, 3, 1)
    adv = gae(r, zeros, zeros, torch.zeros(2, 3, 1), done, 1.0, 1.0)
    assert adv.shape == (2, 3, 2)
    assert torch.equal(adv[0], torch.ones(3, 2))  # step 0 ended the episode: step 1 is not added
    assert torch.equal(adv[1], torch.ones(3, 2))


def test_next_state_values_come_from_the_next_step_except_at_an_episode_end():
    """Two environments, three steps: environment 1's episode ends at step 1, so its value
    there is the one computed on the episode's last state, not step 2's (a new episode)."""
    value = torch.tensor([[1.0, 10.0], [2.0, 20.0], [3.0, 30.0]]).reshape(3, 2, 1)
    at_ends = torch.full((3, 2, 1), -1.0)
    at_ends[1, 1] = 99.0
    done = torch.zeros(3, 2, 1)
    done[1, 1] = 1.0
    got = next_state_values(value, at_ends, done, torch.tensor([4.0, 40.0]).reshape(2, 1))
    assert got.flatten().tolist() == [2.0, 20.0, 3.0, 99.0, 4.0, 40.0]


def test_the_loop_bootstraps_from_the_next_step_and_from_each_episode_end_state(monkeypatch):
    """End to end, what the loop hands to GAE: where an episode went on, the next value is the
    next step's value; where it ended, it is the end state's own (not the new episode's)."""
    from agents.training import batched_ppo

    seen = []
    real_gae = batched_ppo.gae
    monkeypatch.setattr(batched_ppo, "gae", lambda *a: seen.append([x.clone() for x in a[:5]]) or real_gae(*a))
    config = BatchedPPOConfig(
        scenario="sousa_asv", n_envs=3, n_steps=6, minibatch=18, seed=4, overrides={"max_cycles": 4}
    )
    torch.manual_seed(0)
    result = train(config, 18, progress=False)
    _, value, next_value, _, done = seen[0]
    assert done.sum() >= 3  # every environment ended an episode inside the rollout (max_cycles 4)
    # where an episode went on, the next value is the next step's value; at an end it is not
    going = done[:-1, :, 0] == 0
    assert torch.equal(next_value[:-1][going], value[1:][going])
    ended = done[:-1, :, 0] == 1
    assert not torch.equal(next_value[:-1][ended], value[1:][ended])
    assert result["steps"] == 18


def test_running_norm_in_chunks_is_the_mean_and_variance_of_all_the_data():
    data = np.random.default_rng(1).normal([3.0, -2.0], [0.5, 4.0], (1000, 2))
    norm = RunningNorm((2,))
    for chunk in np.array_split(data, 7):  # unequal chunks, as batches of rows
        norm.update(torch.as_tensor(chunk))
    np.testing.assert_allclose(norm.mean.numpy(), data.mean(0), rtol=1e-6)
    np.testing.assert_allclose(norm.var.numpy(), data.var(0), rtol=2e-5)  # the prior count 1e-4
    z = norm.normalize(torch.tensor([[3.0 + 0.5, 1e6]], dtype=torch.float32))
    assert z[0, 0].item() == pytest.approx((0.5 + 3.0 - data[:, 0].mean()) / data[:, 0].std(), rel=1e-5)
    assert z[0, 1].item() == 10.0  # clipped


@pytest.mark.parametrize("critic", ["state", "observation"])
def test_a_tiny_run_trains_saves_and_loads_as_a_policy(tmp_path, critic):
    """Three iterations of 8 environments of gao_team (two beacons, one shared actor): the
    files are written, the log has a row per iteration with its clock, and agents.load
    gives a deterministic policy that acts on every beacon and refuses another action size."""
    out = tmp_path / "run"
    out.mkdir()
    config = BatchedPPOConfig(scenario="gao_team", n_envs=8, n_steps=8, minibatch=32, critic=critic, seed=3)
    result = train(config, 3 * 8 * 8, out=out, progress=False)
    assert result["steps"] == 192
    rows = [json.loads(line) for line in (out / "log.jsonl").read_text().splitlines()]
    assert [r["iteration"] for r in rows] == [1, 2, 3]
    assert all(r["env_s"] > 0 and r["update_s"] > 0 for r in rows)
    record = json.loads((out / "run.json").read_text())
    assert record["trainer"] == "batched_ppo" and record["config"]["critic"] == critic
    policy = agents.load(str(out), scenario="gao_team")
    obs = np.random.default_rng(0).uniform(-1, 1, (5, policy.obs_dim))
    a = policy.act_batch(obs)
    assert a.shape == (5, 2) and np.all(np.abs(a) <= 1)
    assert np.array_equal(a, policy.act_batch(obs))
    with torch.no_grad():  # the mean of the trained actor on the observation as training scaled it
        x = result["obs_norm"].normalize(torch.as_tensor(obs, dtype=torch.float32))
        want = np.clip(result["actor"](x).numpy(), -1, 1)
    np.testing.assert_array_equal(a, want)
    assert policy.config_problem(agents_config("sousa_ping")) is not None  # a third action component


def agents_config(name):
    from coopnav_env.scenarios import make_config

    return make_config(name)


def test_the_policy_runs_in_evaluate(tmp_path):
    out = tmp_path / "run"
    out.mkdir()
    train(BatchedPPOConfig(scenario="sousa_asv", n_envs=4, n_steps=4, minibatch=16), 16, out=out, progress=False)
    res = subprocess.run(
        [sys.executable, "evaluate.py", "--scenario", "sousa_asv", "--policies", str(out), "--episodes", "1"]
        + ["--set", "max_cycles=5", "--out", str(tmp_path / "ev"), "--no-figures"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert res.returncode == 0, res.stderr[-2000:]
    summary = json.loads((tmp_path / "ev" / "summary.json").read_text())
    assert str(out) in json.dumps(summary)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--timesteps", "100", "--critic", "state", "--set", "depth_m=-5"], "depth_m"),
        (["--timesteps", "100", "--n-envs", "0"], "n_envs must be an integer >= 1"),
        (["--timesteps", "0"], "--timesteps must be >= 1"),
        (["--timesteps", "100", "--set", "depth_m"], "--set takes KEY=VALUE"),
        (["--timesteps", "100", "--scenario", "gao_see"], "gao_sea"),
        (["--timesteps", "100", "--reward-term", "stdd=1"], "unknown reward term 'stdd'"),
        (["--timesteps", "100", "--reward-term", "std=a"], "the weight must be a number"),
        (["--timesteps", "100", "--seed", str(2**61)], "--seed"),
    ],
)
def test_bad_input_is_one_line_and_status_2(argv, message, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err


def test_an_occupied_out_folder_is_refused(tmp_path, capsys):
    (tmp_path / "keep.txt").write_text("x")
    assert main(["--timesteps", "100", "--out", str(tmp_path)]) == 2
    assert "nothing is overwritten" in capsys.readouterr().err
    assert (tmp_path / "keep.txt").read_text() == "x"


def test_a_long_run_saves_along_the_way(tmp_path, monkeypatch):
    from agents.training import batched_ppo

    saved = []
    real = batched_ppo.save
    monkeypatch.setattr(batched_ppo, "save", lambda out, *a, **kw: saved.append(a[3]) or real(out, *a, **kw))
    config = BatchedPPOConfig(scenario="sousa_asv", n_envs=4, n_steps=4, minibatch=16)
    train(config, 5 * 16, out=tmp_path, progress=False, save_every_steps=32)
    assert saved == [32, 64, 80]  # every 32 steps, then the end
    assert json.loads((tmp_path / "run.json").read_text())["steps"] == 80


def test_the_command_line_writes_a_run_and_releases_its_folder(tmp_path):
    out = tmp_path / "run"
    argv = ["--scenario", "sousa_asv", "--timesteps", "64", "--n-envs", "8", "--n-steps", "8", "--minibatch", "32"]
    assert main([*argv, "--out", str(out), "--no-progress"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["actor.safetensors", "log.jsonl", "run.json"]


def test_a_run_started_from_a_shipped_policy_acts_as_it_while_the_critic_warms_up(tmp_path):
    """--init-from ppo_gao_team: SB3's policy_net + action_net and its VecNormalize become the
    loop's actor and observation scaling, so after two iterations that train only the critic
    the saved run's actions are the shipped policy's (to float32's rounding), on observations
    of the scenario; the critic learned (its loss is logged) and the actor did not move."""
    out = tmp_path / "run"
    out.mkdir()
    config = BatchedPPOConfig(
        scenario="gao_team",
        n_envs=8,
        n_steps=8,
        minibatch=32,
        seed=3,
        init_from="ppo_gao_team",
        critic_warmup_iterations=2,
    )
    result = train(config, 2 * 8 * 8, out=out, progress=False)
    assert all(r["clip_fraction"] == 0.0 for r in result["log"])  # ratio 1: the actor held
    shipped = agents.load("ppo_gao_team")
    loop = agents.load(str(out), scenario="gao_team")
    stats = _shipped_stats()  # observations as the scenario gives them, by the shipped scaling's statistics
    obs = np.random.default_rng(1).normal(0, 1, (64, loop.obs_dim)) * np.sqrt(stats["obs_var"]) + stats["obs_mean"]
    a_shipped = np.stack([shipped.act(o) for o in obs.astype(np.float32)])
    a_loop = loop.act_batch(obs.astype(np.float32))
    assert np.abs(a_shipped).max() > 0.1  # the actions are not all near 0
    np.testing.assert_allclose(a_loop, a_shipped, atol=2e-3)  # the running statistics moved a little in 128 steps


def _shipped_stats():
    from agents.formats import read_vecnormalize

    return read_vecnormalize(ROOT / "agents" / "policies" / "ppo_gao_team" / "vecnormalize.safetensors")


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--scenario", "gao_team", "--init-from", "ppo_gao_team", "--net", "64,64"], "the loop's --net 64,64"),
        (["--scenario", "sousa_asv", "--init-from", "ppo_gao_team"], "another scenario"),
        (["--scenario", "gao_team", "--init-from", "ppo_gao_tam"], "ppo_gao_team"),
        (["--critic-warmup", "-1"], "critic_warmup_iterations must be an integer >= 0"),
    ],
)
def test_a_policy_that_does_not_fit_is_refused_in_one_line(argv, message, capsys):
    assert main(["--timesteps", "100", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err


def test_teams_share_out_the_environments_and_their_seeds():
    """Two teams of gao_team (the default and a 0.5 m/s current) over 5 environments: 3 and 2,
    each team's scenario its own, episode seeds numbered through the teams (seed + 0..4) as
    MixedTeamVecEnv's, and a step of the whole batch returns every environment."""
    from agents.training.batched_ppo import make_env

    config = BatchedPPOConfig(scenario="gao_team", n_envs=5, seed=40, teams=[{}, {"current_speed_mps": 0.5}])
    env = make_env(config)
    assert env.sizes == [3, 2] and env.n_envs == 5
    assert env.envs[0].config.current_speed_mps == agents_config("gao_team").current_speed_mps != 0.5
    assert env.envs[1].config.current_speed_mps == 0.5
    td = env.reset()
    seeds = np.concatenate([e.episode_seeds for e in env.envs])
    assert seeds.tolist() == [40, 41, 42, 43, 44]
    td.set(("beacons", "action"), torch.zeros(5, env.n_beacons, env.action_dim))
    out, nxt = env.step_and_maybe_reset(td)
    assert out.batch_size == torch.Size([5]) and nxt.batch_size == torch.Size([5])
    train(
        BatchedPPOConfig(scenario="gao_team", n_envs=4, n_steps=4, minibatch=16, teams=config.teams), 16, progress=False
    )


def test_a_centralized_critic_trains_over_teams_of_other_survey_sizes():
    """MAPPO with entity observations over a one-survey and a two-survey team of gao_lawnmower:
    the teams' states are laid out for two survey vehicles (``state_survey_slots``), so one
    critic reads both; each team's episodes are logged. Flat observations of another number of
    beacons differ in size and are refused."""
    from agents.training.batched_ppo import make_env

    teams = [{}, {"n_survey": 2}]
    config = BatchedPPOConfig(
        scenario="gao_lawnmower", n_envs=4, n_steps=4, minibatch=16, teams=teams, critic="state",
        entity={"encoder": "deepsets", "embed_dim": 16, "heads": 1}, net=(16,), overrides={"max_cycles": 3},
    )  # fmt: skip
    env = make_env(config)
    assert [e.n_survey for e in env.envs] == [1, 2] and {e.state_survey_slots for e in env.envs} == {2}
    assert env.state_dim == env.envs[1].state_dim
    log = train(config, 16, progress=False)["log"]
    assert all(v is not None and np.isfinite(v) for v in log[-1]["survey_error_m_per_team"])
    flat = BatchedPPOConfig(scenario="gao_lawnmower", n_envs=4, teams=[{}, {"beacon_kinds": ["beacon_auv", "asv"]}])
    with pytest.raises(ValueError, match="one team makeup only"):
        make_env(flat)


def test_a_centralized_critic_trains_over_teams_of_other_numbers_of_beacons():
    """MAPPO with entity observations over a one-beacon and a two-beacon team: both teams' states
    are laid out for two beacons (``state_beacon_slots``; the one-beacon team's second beacon's
    values zero), the critic gives a value per slot and the padded slot's is out of the loss."""
    from agents.training.batched_ppo import make_env

    teams = [{}, {"beacon_kinds": ["beacon_auv", "asv"]}]
    config = BatchedPPOConfig(
        scenario="gao_lawnmower", n_envs=4, n_steps=4, minibatch=16, teams=teams, critic="state",
        entity={"encoder": "deepsets", "embed_dim": 16, "heads": 1}, net=(16,), overrides={"max_cycles": 3}, seed=7,
    )  # fmt: skip
    env = make_env(config)
    assert [e.n_beacons for e in env.envs] == [1, 2] and {e.state_beacon_slots for e in env.envs} == {2}
    assert (
        env.state_dim == env.envs[1].state_dim and env.agent_mask.tolist() == [[True, False]] * 2 + [[True, True]] * 2
    )
    log = train(config, 32, progress=False)["log"]
    assert all(v is not None and np.isfinite(v) for v in log[-1]["survey_error_m_per_team"])
    assert np.isfinite(log[-1]["value_loss"])


def test_ippo_trains_over_teams_of_other_numbers_of_beacons():
    """IPPO with entity observations over a one-beacon and a two-beacon team: the batch has two
    beacon slots; the one-beacon team's second slot is padded (its observation a copy of beacon
    0's, its reward 0, its action dropped: the team's environment steps on its own beacon's
    action alone, as it would by itself); the padded slots are out of the loss."""
    from agents.training.batched_ppo import make_env
    from coopnav_env.torchrl_env import CoopNavTorchEnv

    teams = [{}, {"beacon_kinds": ["beacon_auv", "asv"]}]
    entity = {"encoder": "deepsets", "embed_dim": 16, "heads": 1}
    config = BatchedPPOConfig(
        scenario="gao_lawnmower", n_envs=4, n_steps=4, minibatch=16, teams=teams, critic="observation",
        entity=entity, net=(16,), overrides={"max_cycles": 3}, seed=7,
    )  # fmt: skip
    env = make_env(config)
    assert env.n_beacons == 2 and env.agent_mask.tolist() == [[True, False]] * 2 + [[True, True]] * 2
    td = env.reset()
    obs = td.get(("beacons", "observation"))
    assert obs.shape == (4, 2, env.obs_dim) and torch.equal(obs[:2, 1], obs[:2, 0])
    alone = CoopNavTorchEnv("gao_lawnmower", n_envs=2, seed=7, infos=True, observation="entities", max_cycles=3)
    a = torch.tensor([[[0.3, -0.2], [0.9, 0.9]]] * 2 + [[[0.1, 0.1], [-0.5, 0.4]]] * 2)
    out, _ = env.step_and_maybe_reset(td.set(("beacons", "action"), a))
    solo = alone.reset()
    solo_out, _ = alone.step_and_maybe_reset(solo.set(("beacons", "action"), a[:2, :1]))
    nxt = out.get("next")
    own = solo_out.get(("next", "beacons", "observation"))
    torch.testing.assert_close(nxt.get(("beacons", "observation"))[:2, :1], own)
    assert not nxt.get(("beacons", "reward"))[:2, 1].any() and nxt.get(("beacons", "reward"))[:2, 0].all()
    run = train(config, 32, progress=False)
    log = run["log"]
    assert all(v is not None and np.isfinite(v) for v in log[-1]["survey_error_m_per_team"])
    assert np.isfinite(log[-1]["value_loss"]) and 0.0 <= log[-1]["clip_fraction"] <= 1.0


@pytest.mark.parametrize("critic", ["observation", "state"])
def test_padded_beacon_slots_do_not_reach_the_update(monkeypatch, critic):
    """Garbage in the padded slots (observations shifted by 3, rewards of 100) trains the same
    weights (to float32 round-off): the slots are out of every mean, scaling and loss, with
    IPPO's critic and with MAPPO's (whose value of a padded slot is computed and dropped)."""
    from agents.training.batched_ppo import TeamEnvs

    config = BatchedPPOConfig(
        scenario="gao_lawnmower", n_envs=4, n_steps=4, minibatch=8, teams=[{}, {"beacon_kinds": ["beacon_auv", "asv"]}],
        critic=critic, entity={"encoder": "deepsets", "embed_dim": 16, "heads": 1}, net=(16,),
        overrides={"max_cycles": 3}, seed=7, center_reward=True,
    )  # fmt: skip
    run = train(config, 48, progress=False)
    clean, clean_critic = run["actor"].state_dict(), run["critic"].state_dict()
    padded = TeamEnvs._padded

    def garbage(self, td):
        paths = [p for p in (("beacons",), ("next", "beacons")) if td.get(p, None) is not None]
        narrow = {p: td.get(p).batch_size[1] for p in paths}
        td = padded(self, td)
        for path, n in narrow.items():
            group = td.get(path)
            if n < self.n_beacons:
                for key, value in group.items():
                    value[:, n:] = value[:, n:] + 3.0 if key == "observation" else 100.0
        return td

    monkeypatch.setattr(TeamEnvs, "_padded", garbage)
    run = train(config, 48, progress=False)
    dirty, dirty_critic = run["actor"].state_dict(), run["critic"].state_dict()
    # equal up to the grouping of the weight gradients' sums over rows: the garbage's masks
    # (3 > 0.5) read as filled, so the encoder embeds all the slots (agents.entity._filled_slots),
    # whose zero gradients regroup the sums (measured: at most 3e-8; a leak of rewards of 100 moves
    # the weights by far more)
    for k in clean:
        torch.testing.assert_close(dirty[k], clean[k], atol=1e-6, rtol=0, msg=k)
    for k in clean_critic:
        torch.testing.assert_close(dirty_critic[k], clean_critic[k], atol=1e-6, rtol=0, msg=k)


def test_advantages_scale_per_team_when_asked():
    """normalize_advantages: over the batch's real entries by default; with team ids, each
    team's real entries to mean 0 and std 1 on their own (a team with rewards 100 times larger
    no longer outweighs the other), the padded entries left alone."""
    from agents.training.batched_ppo import normalize_advantages

    gen = torch.Generator().manual_seed(0)
    adv = torch.randn(400, 2, generator=gen)
    adv[200:] *= 100.0  # team 1's advantages, 100 times team 0's
    team = torch.zeros(400, 2, dtype=torch.long)
    team[200:] = 1
    real = torch.ones(400, 2, dtype=torch.bool)
    real[:200, 1] = False  # team 0 has one beacon: its second slot is padding
    adv[:200, 1] = 1e6  # garbage there
    whole = normalize_advantages(adv, real)
    assert abs(float(whole[real].mean())) < 1e-5 and abs(float(whole[real].std()) - 1.0) < 1e-5
    assert float(whole[:200, 0].std()) < 0.05  # the small team's signal all but vanishes
    per = normalize_advantages(adv, real, team)
    for k, rows in ((0, slice(0, 200)), (1, slice(200, 400))):
        own = per[rows][real[rows]]
        assert abs(float(own.mean())) < 1e-5 and abs(float(own.std()) - 1.0) < 1e-5, k
    assert torch.equal(per[:200, 1], adv[:200, 1])  # padding untouched
    one = normalize_advantages(torch.tensor([[1.0], [5.0], [9.0]]), None, torch.tensor([[0], [1], [1]]))
    assert one.flatten().tolist() == pytest.approx([0.0, -(0.5**0.5), 0.5**0.5], abs=1e-6)  # one entry: 0


def test_advantages_per_team_need_teams():
    with pytest.raises(ValueError, match=r"norm_adv_per_team .* needs two teams or more \(--team\)"):
        BatchedPPOConfig(scenario="gao_lawnmower", norm_adv_per_team=True, teams=[{}]).check()


def test_a_tiny_run_scales_advantages_per_team():
    """The path end to end: two teams of other numbers of beacons, IPPO, per-team scaling."""
    config = BatchedPPOConfig(
        scenario="gao_lawnmower", n_envs=4, n_steps=4, minibatch=8, teams=[{}, {"beacon_kinds": ["beacon_auv", "asv"]}],
        critic="observation", entity={"encoder": "deepsets", "embed_dim": 16, "heads": 1}, net=(16,),
        overrides={"max_cycles": 3}, seed=7, norm_adv_per_team=True,
    )  # fmt: skip
    run = train(config, 32, progress=False)
    row = run["log"][-1]
    assert np.isfinite(row["value_loss"]) and 0.0 <= row["clip_fraction"] <= 1.0
    plain = train(dataclasses.replace(config, norm_adv_per_team=False), 32, progress=False)
    assert not torch.equal(run["actor"].head[0].weight, plain["actor"].head[0].weight)  # the scaling acts


def test_the_log_gives_each_teams_error():
    """With teams each log row has the mean survey error of each team's finished episodes, the
    rows attributed to their team: a team that starts 300 m off (initial_position_std_m) has
    the larger error, whichever order the teams come in."""
    far, near = {"initial_position_std_m": 300.0}, {"initial_position_std_m": 0.5}
    for teams, far_first in (([far, near], True), ([near, far], False)):
        config = BatchedPPOConfig(
            scenario="gao_team", n_envs=6, n_steps=4, minibatch=24, teams=teams, overrides={"max_cycles": 2}
        )
        log = train(config, 24, progress=False)["log"]
        per_team = log[0]["survey_error_m_per_team"]
        assert len(per_team) == 2 and None not in per_team
        big, small = per_team if far_first else per_team[::-1]
        assert big > 10.0 * small
        assert min(per_team) <= log[0]["survey_error_m"] <= max(per_team)
    assert (
        "survey_error_m_per_team"
        not in train(BatchedPPOConfig(scenario="gao_team", n_envs=2, n_steps=2, minibatch=4), 4, progress=False)["log"][
            0
        ]
    )


def test_a_curriculum_trains_each_stage_on_its_own_scenario():
    """Two stages over four iterations: the first half starts the survey 300 m off, the second
    0.5 m off (initial_position_std_m). The log says each iteration's stage, and its errors
    follow the stage's scenario; each stage's environments play their own episode seeds
    (seed + k * n_envs + e), so the second stage does not replay the first's."""
    from agents.training.batched_ppo import make_env

    far, near = {"initial_position_std_m": 300.0}, {"initial_position_std_m": 0.5}
    config = BatchedPPOConfig(
        scenario="gao_team", n_envs=4, n_steps=4, minibatch=16, seed=20, overrides={"max_cycles": 2},
        stages=[(0.0, far), (0.5, near)],
    )  # fmt: skip
    assert [config.stage_at(it, 4) for it in range(4)] == [0, 0, 1, 1]
    assert [config.stage_at(it, 3) for it in range(3)] == [0, 0, 1]  # from iteration ceil(0.5 * 3)
    log = train(config, 64, progress=False)["log"]
    assert [row["stage"] for row in log] == [0, 0, 1, 1]
    errors = [row["survey_error_m"] for row in log]
    assert min(errors[:2]) > 10.0 * max(errors[2:]), errors
    for k, expected in ((0, far), (1, near)):
        env = make_env(config, k)
        env.reset()
        assert env.config.initial_position_std_m == expected["initial_position_std_m"]
        assert env.config.max_cycles == 2  # --set under the stage
        assert env.episode_seeds.tolist() == [20 + 4 * k + e for e in range(4)]
    plain = train(BatchedPPOConfig(scenario="gao_team", n_envs=2, n_steps=2, minibatch=4), 4, progress=False)
    assert "stage" not in plain["log"][0]


@pytest.mark.parametrize(("history", "role"), [(1, False), (3, True)])
def test_validation_keeps_the_best_weights(tmp_path, history, role):
    """With eval_every_steps the loop plays its validation episodes every so often and at the
    end, logs the error, and keeps the best weights in <out>/best: a policy folder whose
    recorded validation error is the lowest logged, and which evaluation.episodes gives
    the same error on the same seeds (the validation is what the benchmark would measure)."""
    from evaluation.episodes import run_episodes

    out = tmp_path / "run"
    out.mkdir()
    config = BatchedPPOConfig(
        scenario="gao_team", n_envs=4, n_steps=4, minibatch=16, overrides={"max_cycles": 6},
        eval_every_steps=32, eval_episodes=3, eval_seed=123, history=history, learning_rate=0.05, role=role,
    )  # fmt: skip
    log = train(config, 80, out=out, progress=False)["log"]  # 5 iterations of 16 env-steps
    validated = [(row["steps"], row["validation_error_m"]) for row in log if "validation_error_m" in row]
    assert [s for s, _ in validated] == [32, 64, 80]  # every 32 env-steps, and the end
    record = json.loads((out / "best" / "run.json").read_text())
    best = min(e for _, e in validated)
    assert record["validation_error_m"] == best and record["validation_seeds"] == [123, 125]
    assert record["steps"] == next(s for s, e in validated if e == best)
    from coopnav_env import make_config

    scenario = make_config("gao_team", max_cycles=6)
    rows, _ = run_episodes(scenario, str(out / "best"), [123, 124, 125])
    assert np.mean([r["mean_error_m"] for r in rows]) == pytest.approx(best, rel=1e-5)
    assert len({e for _, e in validated}) > 1  # the validations differ: the test tells one from another


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--eval-every-steps", "100"], "it needs --out"),
        (["--eval-every-steps", "100", "--eval-episodes", "0", "--out", "x"], "eval_episodes must be an integer >= 1"),
        (["--stage", "0.5", "max_cycles=3"], "the first stage must start at 0"),
        (["--stage", "0", "--stage", "half"], "--stage takes AT [KEY=VALUE ...]"),
        (["--stage", "0", "--stage", "0.6", "--stage", "0.3"], "increasing fractions, got 0.0, 0.6, 0.3"),
        (["--stage", "0", "--stage", "1.0"], "fraction in [0, 1)"),
        (["--stage", "0", "max_cycle=3"], "--stage 0.0: "),
    ],
)
def test_bad_stages_are_one_line(argv, message, capsys):
    assert main(["--timesteps", "100", "--scenario", "gao_team", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err, err


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--scenario", "gao_team", "--team", "{}", "--team", "{n_survey: 1}"], "one team makeup only"),
        (["--scenario", "gao_team", "--team", "[1, 2]"], "--team takes a YAML mapping"),
        (["--scenario", "gao_team", "--team", "{curent_speed_mps: 0.5}"], "teams[0]"),
    ],
)
def test_bad_teams_are_one_line(argv, message, capsys):
    assert main(["--timesteps", "100", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err


def test_the_return_scale_is_inherited_only_for_the_same_reward():
    """ppo_gao_team was trained on std=1 error=0.25 penalties=1: a run on that reward starts
    from its VecNormalize's return variance; a run on the environment's reward or another mix
    starts its own (another reward has another scale); the observation scaling comes either way."""
    from agents.training.batched_ppo import load_sb3_actor

    same = {"std": 1.0, "error": 0.25, "penalties": 1.0}
    stats = _shipped_stats()
    got = load_sb3_actor("ppo_gao_team", "gao_team", (128, 128), 34, 2, same)
    assert float(got["ret_var"]) == pytest.approx(float(stats["ret_var"]))
    for other in (None, {"error": 1.0, "penalties": 1.0}):
        got = load_sb3_actor("ppo_gao_team", "gao_team", (128, 128), 34, 2, other)
        assert "ret_var" not in got and "obs_mean" in got


def test_center_reward_subtracts_the_mean_step_reward():
    """--center-reward pays r - rho with rho the running mean step reward. On the true error
    (reward -e each step) with every episode two steps long, rho is minus the mean of the
    finished episodes' errors; it is logged. Without the flag nothing is logged."""
    config = BatchedPPOConfig(
        scenario="gao_team",
        n_envs=4,
        n_steps=4,
        minibatch=16,
        reward_terms={"error": 1.0},
        overrides={"max_cycles": 2},
        center_reward=True,
    )
    row = train(config, 16, progress=False)["log"][0]
    assert row["episodes"] == 8 and row["survey_error_m"] > 0.0
    assert row["reward_center"] == pytest.approx(-row["survey_error_m"], rel=1e-4)
    config.center_reward = False
    assert "reward_center" not in train(config, 16, progress=False)["log"][0]


def test_center_reward_per_team_gives_each_team_its_own_mean():
    """--center-reward-per-team: each team's rho is minus its own mean error (its rows only),
    and they differ where the teams' errors do (a 0.5 m/s current against none)."""
    config = BatchedPPOConfig(
        scenario="gao_team",
        n_envs=8,
        n_steps=4,
        minibatch=32,
        reward_terms={"error": 1.0},
        overrides={"max_cycles": 2},
        teams=[{"current_speed_mps": 0.0, "current_speed_spread_mps": 0.0}, {"current_speed_mps": 0.5}],
        center_reward=True,
        center_per_team=True,
    )
    row = train(config, 32, progress=False)["log"][0]
    per_team = row["survey_error_m_per_team"]
    assert row["reward_center"] == pytest.approx([-e for e in per_team], rel=1e-4)
    assert abs(per_team[0] - per_team[1]) > 1e-3
    with pytest.raises(ValueError, match="center_per_team needs center_reward"):
        BatchedPPOConfig(center_per_team=True).check()


def test_the_window_shifts_newest_first_and_an_episode_starts_filled_with_its_own_observation():
    window = torch.arange(2 * 1 * 3 * 2, dtype=torch.float32).reshape(2, 1, 3, 2)  # B 2, N 1, K 3, O 2
    obs = torch.tensor([[[100.0, 101.0]], [[200.0, 201.0]]])
    out = push_window(window, obs, torch.tensor([False, True]))
    assert out[0, 0].tolist() == [[100.0, 101.0], [0.0, 1.0], [2.0, 3.0]]  # row 0 goes on: shifted
    assert out[1, 0].tolist() == [[200.0, 201.0]] * 3  # row 1 begins an episode: nothing of the last one
    assert window[0, 0, 0].tolist() == [0.0, 1.0]  # the window given is not changed


def test_a_widened_actor_is_the_same_function_of_the_newest_observation():
    from agents.batched_policy import mlp

    torch.manual_seed(0)
    narrow = mlp(5, (8, 8), 2, 0.01)
    wide = mlp(15, (8, 8), 2, 0.01)
    state = dict(narrow.state_dict())
    state["0.weight"] = widen_to_history(state["0.weight"], 3)
    wide.load_state_dict(state)
    x = torch.randn(4, 5)
    older = torch.randn(4, 10) * 100.0
    torch.testing.assert_close(wide(torch.cat([x, older], -1)), narrow(x))
    assert widen_to_history(state["0.weight"], 1) is state["0.weight"]
    # a window of 3 widened to 7 (not a multiple): the same function of its three newest
    wider = mlp(35, (8, 8), 2, 0.01)
    state["0.weight"] = widen_to_history(state["0.weight"], 7, own=3)
    assert tuple(state["0.weight"].shape) == (8, 35)
    wider.load_state_dict(state)
    three = torch.cat([x, older], -1)
    torch.testing.assert_close(wider(torch.cat([three, torch.randn(4, 20) * 100.0], -1)), wide(three))
    with pytest.raises(ValueError, match="a window of 3 observations cannot be widened to 2"):
        widen_to_history(torch.zeros(8, 15), 2, own=3)


def test_a_wider_actor_is_the_same_function_and_its_copies_part_when_trained():
    """Net2WiderNet (``widen_layers``): (8, 8) widened to (13, 20) gives the same outputs; one
    gradient step moves a unit and its copy apart (equal shares of the outgoing weights would
    keep them equal); a narrower or deeper net is refused."""
    from agents.batched_policy import mlp
    from agents.training.batched_ppo import widen_layers

    torch.manual_seed(0)
    narrow = mlp(5, (8, 8), 2, 0.5)
    state = widen_layers(narrow.state_dict(), (8, 8), (13, 20), seed=1)
    wide = mlp(5, (13, 20), 2, 0.5)
    wide.load_state_dict(state)
    x = torch.randn(64, 5)
    torch.testing.assert_close(wide(x), narrow(x), atol=1e-6, rtol=1e-5)
    # the copies: rows 8.. of the first layer repeat rows of the first 8
    rows = state["0.weight"]
    copies = [(j, next(k for k in range(8) if torch.equal(rows[j], rows[k]))) for j in range(8, 13)]
    wide(x).pow(2).sum().backward()
    grad = wide[0].weight.grad
    assert all(not torch.allclose(grad[j], grad[k]) for j, k in copies)
    with pytest.raises(ValueError, match=r"layers \[8, 8\] cannot be widened to \[4, 8\]"):
        widen_layers(narrow.state_dict(), (8, 8), (4, 8))
    with pytest.raises(ValueError, match="cannot be widened"):
        widen_layers(narrow.state_dict(), (8, 8), (8, 8, 8))


def test_a_loop_run_continued_with_a_wider_net_acts_as_it(tmp_path):
    """--init-from a loop run with a wider --net: after critic-only iterations the wider actor
    acts as the run it started from; a narrower one is refused in one line."""
    first = tmp_path / "first"
    first.mkdir()
    base = dict(scenario="sousa_asv", n_envs=8, n_steps=8, minibatch=32, seed=3)
    train(BatchedPPOConfig(**base, net=(16, 16)), 2 * 64, out=first, progress=False)
    second = tmp_path / "second"
    second.mkdir()
    config = BatchedPPOConfig(**base, net=(24, 32), init_from=str(first), critic_warmup_iterations=2)
    train(config, 2 * 64, out=second, progress=False)
    a, b = agents.load(str(first), scenario="sousa_asv"), agents.load(str(second), scenario="sousa_asv")
    a.obs_mean, a.obs_std = b.obs_mean, b.obs_std
    obs = np.random.default_rng(2).normal(0, 1, (6, a.obs_dim)) * np.asarray(b.obs_std) + np.asarray(b.obs_mean)
    for o in obs:
        np.testing.assert_allclose(b.act(o), a.act(o), atol=1e-5)
    with pytest.raises(
        ValueError, match=r"its actor is \[24, 32\], the loop's --net 16,16 \(a flat actor can be widened"
    ):
        train(BatchedPPOConfig(**base, net=(16, 16), init_from=str(second)), 64, progress=False)


def test_memory_trains_from_a_loop_run_and_acts_with_its_window(tmp_path):
    """A run of the loop continued with --history 3 (--init-from its folder): after critic-only
    iterations it acts as the run it started from (the older observations' weights are zero);
    its policy keeps a window per object, which reset() clears; continued with a longer window
    it acts as it did; a shorter window than the run's is refused in one line."""
    first = tmp_path / "first"
    first.mkdir()
    base = dict(scenario="sousa_asv", n_envs=8, n_steps=8, minibatch=32, seed=3)
    train(BatchedPPOConfig(**base), 2 * 64, out=first, progress=False)
    second = tmp_path / "second"
    second.mkdir()
    config = BatchedPPOConfig(**base, init_from=str(first), history=3, critic_warmup_iterations=2)
    result = train(config, 2 * 64, out=second, progress=False)
    assert all(r["clip_fraction"] == 0.0 for r in result["log"])
    a, b = agents.load(str(first), scenario="sousa_asv"), agents.load(str(second), scenario="sousa_asv")
    assert b.history == 3 and "history=3" in repr(b)
    rng = np.random.default_rng(2)
    obs = rng.normal(0, 1, (6, a.obs_dim)) * np.asarray(a.obs_std) + np.asarray(a.obs_mean)
    # the scaling went on from the first run's statistics and count (128 more observations on its 128)
    from safetensors.torch import load_file

    count = float(load_file(str(second / "actor.safetensors"))["obs_count"][0])
    assert count == pytest.approx(256, abs=1e-3)
    a.obs_mean, a.obs_std = b.obs_mean, b.obs_std  # the actors alone compared, on the same scaling
    for o in obs:  # the same actions step after step: the older observations count for nothing yet
        np.testing.assert_allclose(b.act(o), a.act(o), atol=1e-6)
    # the window: give the second actor's older observations weight, and it remembers
    weights = b.actor.state_dict()
    weights["0.weight"][:, a.obs_dim :] = 1.0
    b.actor.load_state_dict(weights)
    b.reset()
    fresh = b.act(obs[0])
    b.act(obs[1])
    after = b.act(obs[0])  # the same observation after another one: the window differs
    assert not np.allclose(fresh, after)
    b.reset()
    np.testing.assert_array_equal(b.act(obs[0]), fresh)  # reset: the window is the observation's own again
    # a window widens: the history-3 run continued with --history 5 acts as it, window and all
    third = tmp_path / "third"
    third.mkdir()
    train(
        BatchedPPOConfig(**base, init_from=str(second), history=5, critic_warmup_iterations=2),
        2 * 64,
        out=third,
        progress=False,
    )
    b, c = agents.load(str(second), scenario="sousa_asv"), agents.load(str(third), scenario="sousa_asv")
    assert c.history == 5
    b.obs_mean, b.obs_std = c.obs_mean, c.obs_std
    for o in obs:  # step after step, so the windows fill: the two older observations count for nothing
        np.testing.assert_allclose(c.act(o), b.act(o), atol=1e-6)
    with pytest.raises(
        ValueError, match=r"its window is 3 observations, the run's --history 2 \(give --history 3 or more"
    ):
        train(BatchedPPOConfig(**base, init_from=str(second), history=2), 64, progress=False)


def test_history_out_of_range_is_one_line(capsys):
    assert main(["--timesteps", "100", "--history", "0"]) == 2
    err = capsys.readouterr().err.strip()
    assert "history must be an integer in 1..64, got 0" in err and "\n" not in err


def _entity_rows(config, n=48, seed=2):
    """Entity observations of ``config``'s team from a short episode of the planner-free
    environment (every beacon's row), so the comparison below is on real inputs."""
    from coopnav_env.torchrl_env import GROUP, CoopNavTorchEnv

    env = CoopNavTorchEnv(config, n_envs=n // config.n_beacons, seed=seed, observation="entities", infos=False)
    gen = torch.Generator().manual_seed(seed)

    def policy(td):
        td.set((GROUP, "action"), torch.rand(td.get((GROUP, "observation")).shape[:-1] + (2,), generator=gen) * 2 - 1)
        return td

    obs = env.rollout(6, policy, break_when_any_done=False).get(("next", GROUP, "observation"))
    return obs[:, -1].reshape(-1, obs.shape[-1]).numpy(), np.tile(np.arange(config.n_beacons), obs.shape[0])


@pytest.mark.parametrize("history", [1, 3])
def test_an_entity_run_starts_where_the_sb3_entity_policy_stands(tmp_path, history):
    """--entity --init-from ppo_gao_sea: SB3's attention encoder and MLP become the loop's actor
    (entity_net), so after two iterations that train only the critic the saved run acts as the
    shipped policy on every team it drives (the trial's, two beacons with two survey vehicles),
    beacon by beacon (each its role), with a window of 3 too (the older observations' weights
    start at zero)."""
    from coopnav_env import make_config

    out = tmp_path / "run"
    out.mkdir()
    config = BatchedPPOConfig(
        scenario="gao_sea", n_envs=8, n_steps=4, minibatch=16, seed=3, init_from="ppo_gao_sea",
        critic_warmup_iterations=2, critic="observation", entity={"encoder": "attention", "embed_dim": 64, "heads": 4},
        history=history, teams=[{}, {"n_survey": 2}],
    )  # fmt: skip
    result = train(config, 2 * 8 * 4, out=out, progress=False)
    assert all(r["clip_fraction"] == 0.0 for r in result["log"])  # the actor held
    for team in ({}, {"beacon_kinds": ["beacon_auv", "beacon_auv"], "n_survey": 2}):
        scenario = make_config("gao_sea", **team)
        obs, roles = _entity_rows(scenario)
        shipped = agents.load("ppo_gao_sea", scenario=scenario).base.act_batch(obs)
        loop = agents.make_policy(str(out), scenario, agent=scenario.n_beacons - 1).base  # the run's network
        assert np.abs(shipped).max() > 0.1 and len(set(roles)) == scenario.n_beacons
        np.testing.assert_allclose(loop.act_batch(obs), shipped, atol=1e-5)


def test_an_entity_run_is_an_entity_policy_for_every_team(tmp_path):
    """A run of entity observations loads as an EntityPolicy: it drives teams of other sizes
    than its own (the benchmark's team tasks), beacon j reads its row with role j, and a
    window is each beacon's own (make_policy gives each a memory)."""
    from agents.entity import EntityPolicy
    from coopnav_env import make_config
    from coopnav_env.obs_layout import obs_dim
    from evaluation.episodes import run_episodes

    out = tmp_path / "run"
    out.mkdir()
    config = BatchedPPOConfig(
        scenario="gao_sea", n_envs=4, n_steps=4, minibatch=16, history=2, critic="observation",
        entity={"encoder": "attention", "embed_dim": 16, "heads": 2}, net=(16,),
    )  # fmt: skip
    train(config, 16, out=out, progress=False)
    for team in ({}, {"n_survey": 3}, {"beacon_kinds": ["beacon_auv", "asv"], "n_survey": 2}):
        scenario = make_config("gao_sea", max_cycles=4, **team)
        policies = [agents.make_policy(str(out), scenario, agent=j) for j in range(scenario.n_beacons)]
        assert all(isinstance(p, EntityPolicy) and p.agent == j for j, p in enumerate(policies))
        if len(policies) > 1:
            assert policies[0].base is not policies[1].base  # a window each
        rows, _ = run_episodes(scenario, str(out), [11, 12])
        assert all(np.isfinite(r["mean_error_m"]) for r in rows)
        a = policies[0].act_batch(np.zeros((2, obs_dim(scenario))))
        assert a.shape == (2, 2)
    with pytest.raises(ValueError, match="entity view does not read"):
        agents.load(str(out), scenario="matos_moving_lbl")


def test_entity_validation_is_what_the_benchmark_measures(tmp_path):
    """The validation of an entity run equals evaluation.episodes on its best folder."""
    from coopnav_env import make_config
    from evaluation.episodes import run_episodes

    out = tmp_path / "run"
    out.mkdir()
    config = BatchedPPOConfig(
        scenario="gao_sea", n_envs=4, n_steps=4, minibatch=16, overrides={"max_cycles": 6}, critic="state",
        eval_every_steps=16, eval_episodes=3, eval_seed=321, learning_rate=0.05,
        entity={"encoder": "deepsets", "embed_dim": 16, "heads": 1}, net=(16,),
    )  # fmt: skip
    log = train(config, 32, out=out, progress=False)["log"]
    best = min(row["validation_error_m"] for row in log)
    rows, _ = run_episodes(make_config("gao_sea", max_cycles=6), str(out / "best"), [321, 322, 323])
    assert np.mean([r["mean_error_m"] for r in rows]) == pytest.approx(best, rel=1e-5)


def test_validation_over_the_teams(tmp_path):
    """``eval_teams``: each validation plays the episodes on every team's scenario; each team's
    figure is what evaluation.episodes gives the best folder there, the score their mean, and
    best/ keeps the weights with the lowest mean (so it may differ from the trial team's pick)."""
    from coopnav_env import make_config
    from evaluation.episodes import run_episodes

    out = tmp_path / "run"
    out.mkdir()
    teams = [{}, {"current_speed_mps": 0.5}, {"beacon_kinds": ["beacon_auv", "beacon_auv"]}]
    config = BatchedPPOConfig(
        scenario="gao_sea", n_envs=6, n_steps=4, minibatch=24, overrides={"max_cycles": 6}, critic="observation",
        teams=teams, eval_teams=True, eval_every_steps=24, eval_episodes=3, eval_seed=321, learning_rate=0.05,
        entity={"encoder": "deepsets", "embed_dim": 16, "heads": 1}, net=(16,),
    )  # fmt: skip
    log = train(config, 72, out=out, progress=False)["log"]
    assert all(len(row["validation_error_m_per_team"]) == 3 for row in log)
    best = min(log, key=lambda row: row["validation_error_m"])
    assert best["validation_error_m"] == pytest.approx(np.mean(best["validation_error_m_per_team"]), rel=1e-12)
    for team, error in zip(teams, best["validation_error_m_per_team"]):
        rows, _ = run_episodes(make_config("gao_sea", max_cycles=6, **team), str(out / "best"), [321, 322, 323])
        assert np.mean([r["mean_error_m"] for r in rows]) == pytest.approx(error, rel=1e-5)
    saved = json.loads((out / "best" / "run.json").read_text())
    assert saved["validation_error_m_per_team"] == best["validation_error_m_per_team"]
    with pytest.raises(ValueError, match="eval_teams validates on every team: it needs teams"):
        BatchedPPOConfig(scenario="gao_sea", eval_teams=True).check()


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--scenario", "gao_sea", "--init-from", "ppo_gao_sea"], "an entity policy (EntityExtractor): add --entity"),
        (["--scenario", "gao_team", "--entity", "--init-from", "ppo_gao_team"], "--entity needs an entity policy"),
        (["--scenario", "matos_moving_lbl", "--entity"], "entity view does not read"),
        (
            ["--scenario", "gao_sea", "--team", "{}", "--team", "{beacon_kinds: [beacon_auv, beacon_auv]}"],
            "one team makeup only",  # flat observations of one and two beacons differ in size
        ),
    ],
)
def test_entity_inputs_that_do_not_fit_are_one_line(argv, message, capsys):
    assert main(["--timesteps", "100", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err


def test_a_role_input_starts_at_zero_weight_and_then_tells_the_beacons_apart(tmp_path):
    """--role (agent identity): started from the shipped gao_team policy, after critic-only
    iterations the run acts as that policy for both beacons (the one-hot index's weights are
    zero); with weight on it the two beacons' actions differ on the same observation, through
    agents.make_policy's agent index as evaluation binds it; a run with a role continued
    without one, or a beacon index beyond the team, is refused in one line."""
    first = tmp_path / "first"
    first.mkdir()
    base = dict(scenario="gao_team", n_envs=8, n_steps=8, minibatch=32, seed=3)
    result = train(
        BatchedPPOConfig(**base, init_from="ppo_gao_team", critic_warmup_iterations=2, role=True),
        2 * 64,
        out=first,
        progress=False,
    )
    assert all(r["clip_fraction"] == 0.0 for r in result["log"])
    assert json.loads((first / "run.json").read_text())["role_slots"] == 2
    shipped = agents.load("ppo_gao_team")
    b0, b1 = (agents.make_policy(str(first), "gao_team", agent=j) for j in (0, 1))
    assert "role=1 of 2" in repr(b1)
    stats = _shipped_stats()
    obs = np.random.default_rng(1).normal(0, 1, (32, b0.obs_dim)) * np.sqrt(stats["obs_var"]) + stats["obs_mean"]
    obs = obs.astype(np.float32)
    a_shipped = np.stack([shipped.act(o) for o in obs])
    np.testing.assert_allclose(b0.act_batch(obs), a_shipped, atol=2e-3)
    np.testing.assert_allclose(b1.act_batch(obs), a_shipped, atol=2e-3)
    # weight on index 1's input of one network: as beacon 1 its actions move, as beacon 0 they do not
    weights = b1.actor.state_dict()
    weights["0.weight"][:, -1] = 3.0
    b1.actor.load_state_dict(weights)
    as_0 = b1.fork()
    as_0.agent = 0
    assert np.abs(b1.act_batch(obs) - a_shipped).max() > 0.05
    np.testing.assert_allclose(as_0.act_batch(obs), a_shipped, atol=2e-3)
    # trained on: the role's weights leave zero
    second = tmp_path / "second"
    second.mkdir()
    train(
        BatchedPPOConfig(**base, init_from=str(first), role=True, learning_rate=0.01),
        2 * 64,
        out=second,
        progress=False,
    )
    from safetensors.torch import load_file

    w = load_file(str(second / "actor.safetensors"))["actor.0.weight"]
    assert w[:, -2:].abs().max() > 0
    with pytest.raises(ValueError, match=r"its role input is for 2 beacons, the run's none \(give --role\)"):
        train(BatchedPPOConfig(**base, init_from=str(first)), 64, progress=False)
    with pytest.raises(ValueError, match=r"agent must be a beacon index in 0\.\.1, got 2"):
        agents.make_policy(str(first), "gao_team", agent=2)


def test_a_role_with_entity_observations_is_refused_in_one_line(capsys):
    assert main(["--timesteps", "100", "--scenario", "gao_sea", "--entity", "--role"]) == 2
    err = capsys.readouterr().err
    assert "the entity view has its own role input (drop --role)" in err and err.count("\n") == 1
