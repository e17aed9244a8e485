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
