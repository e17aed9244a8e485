"""benchmarks/policy_vs_planners.py: its planner cache's key."""

from benchmarks.policy_vs_planners import FIELDS_ADDED_AFTER_CACHE_V1, config_key
from coopnav_env.scenarios import make_config


def test_cache_key_takes_every_scenario_and_changes_with_a_parameter():
    """The key compares each later parameter with its default; the default config leaves out
    sections such as the MLS array's, which a getattr refuses, so the key of every scenario
    (sousa_asv's crashed the script's documented command) must come out, and differ when a
    parameter does, a later one at its default leaving the key alone."""
    from coopnav_env.scenarios import list_scenarios

    keys = {name: config_key(make_config(name)) for name in list_scenarios()}
    assert all(len(k) == 16 for k in keys.values())
    assert len(set(keys.values())) == len(keys)
    base = make_config("sousa_asv")
    assert config_key(make_config("sousa_asv", depth_m=5.0)) != keys["sousa_asv"]
    later = next(k for k in FIELDS_ADDED_AFTER_CACHE_V1 if k in base.to_flat_dict(all_parameters=True))
    assert config_key(make_config("sousa_asv", **{later: getattr(base, later)})) == keys["sousa_asv"]


def test_the_script_plays_cells_through_the_evaluations_runner(tmp_path):
    """Its per-episode means are run_episodes' (the evaluation's runner: the oracle told the
    truth, so it is not horizon), the same on one worker and on two."""
    import json

    from benchmarks.policy_vs_planners import main
    from evaluation.episodes import run_episodes

    argv = ["--scenario", "gao_lawnmower", "--policies", "oracle,horizon", "--episodes", "2", "--seed", "4100"]
    argv += ["--set", "max_cycles=12"]
    outs = []
    cache = tmp_path / "cache.json"
    for workers in ("1", "2"):
        out = tmp_path / f"w{workers}.json"
        assert main([*argv, "--workers", workers, "--out", str(out), "--cache", str(cache)]) == 0
        outs.append(json.loads(out.read_text())["per_episode"])
        cache.unlink()  # each run plays its cells
    assert outs[0] == outs[1]
    assert main([*argv, "--out", str(tmp_path / "c.json"), "--cache", str(cache)]) == 0
    # the oracle's cached figures under their own name: a cache from before it was told the truth
    # (horizon's figures under "oracle") is not read back
    assert sorted(k.split("|")[0] for k in json.loads(cache.read_text())) == ["horizon", "oracle@truth"]
    config = make_config(
        "gao_lawnmower", max_cycles=12, randomize_survey_path=(), randomize_depth_m=(), randomize_noise_scale=()
    )
    rows, _ = run_episodes(config, "oracle", [4100, 4101])
    per_episode = outs[0]
    (oracle_key,) = [k for k in per_episode if k.endswith("|oracle")]
    (horizon_key,) = [k for k in per_episode if k.endswith("|horizon")]
    assert per_episode[oracle_key] == [round(r["mean_error_m"], 5) for r in rows]
    assert per_episode[oracle_key] != per_episode[horizon_key]
