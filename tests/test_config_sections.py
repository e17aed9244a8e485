"""ScenarioConfig in sections: flat, dotted and sectioned access agree; a section the
scenario does not use is absent and its parameters are refused by name."""

import dataclasses
import pickle

import numpy as np
import pytest

import coopnav_env
from coopnav_env.scenarios.base import (
    SECTIONS,
    ScenarioConfig,
    bounds,
    default_of,
    make_config,
    parameter_names,
    section_of,
)
from coopnav_env.scenarios.sections import Timing


def test_flat_dotted_mapping_and_section_forms_agree():
    flat = make_config("gao_sea", ping_interval_s=10.0)
    assert make_config("gao_sea", **{"timing.ping_interval_s": 10.0}) == flat
    assert make_config("gao_sea", timing={"ping_interval_s": 10.0}) == flat
    assert make_config("gao_sea").replace(timing=dataclasses.replace(flat.timing)) == flat
    assert dataclasses.replace(make_config("gao_sea"), ping_interval_s=10.0) == flat
    assert flat.ping_interval_s == flat.timing.ping_interval_s == 10.0
    assert isinstance(flat.timing, Timing) and section_of("ping_interval_s") == "timing"


def test_configs_stay_frozen_hashable_and_picklable():
    for name in coopnav_env.list_scenarios():
        c = make_config(name)
        assert pickle.loads(pickle.dumps(c)) == c and hash(pickle.loads(pickle.dumps(c))) == hash(c)
        with pytest.raises(dataclasses.FrozenInstanceError):
            c.name = "x"
        with pytest.raises(dataclasses.FrozenInstanceError):
            c.timing.ping_interval_s = 1.0
        assert ScenarioConfig(**c.to_flat_dict()) == c  # run.json's flat dict rebuilds the config


def test_absent_sections_are_none_and_not_shown():
    gao, matos, river = make_config("gao_sea"), make_config("matos_moving_lbl"), make_config("matos_river")
    assert gao.moving is None and gao.river is None and gao.boat is None and gao.channel is None
    assert matos.beacon_auv is None and matos.river is None and river.river is not None
    assert make_config("sousa_ping").channel is not None and make_config("swarm_mls").mls is not None
    assert "moving=" not in repr(gao) and "river=" not in repr(gao) and "timing=Timing(" in repr(gao)
    assert "river_width_m" not in gao.to_flat_dict() and "river_width_m" in gao.to_flat_dict(all_parameters=True)
    assert not gao.applies("river_width_m") and gao.applies("timing.ping_interval_s")


def test_a_parameter_of_an_absent_section_is_one_clear_error():
    with pytest.raises(
        ValueError,
        match=r"^scenario parameter baseline_target_m belongs to section 'moving', which "
        r"applies only with network='moving_lbl'; this scenario has "
        r"network='survey_beacons'$",
    ):
        make_config("gao_sea", baseline_target_m=50.0)
    with pytest.raises(ValueError, match=r"tdma_frame_slots belongs to section 'channel'.*channel_mode='decide'"):
        make_config("sousa_asv", tdma_frame_slots=2)
    with pytest.raises(AttributeError, match=r"no parameter river_width_m.*section 'river'"):
        make_config("gao_sea").river_width_m  # noqa: B018 - the attribute access is what must raise
    assert not hasattr(make_config("gao_sea"), "mls_max_range_m")
    # the switch and the section's parameters together are fine
    c = make_config("sousa_asv", channel_mode="decide", tdma_frame_slots=2, ping_interval_s=20.0)  # real packets
    assert c.tdma_frame_slots == 2
    # switching a section off drops it (its values came from the base scenario, not the caller)
    assert make_config("sousa_ping").replace(channel_mode="clock").channel is None


def test_unknown_names_suggest_the_closest():
    with pytest.raises(ValueError, match=r"unknown scenario 'gao_se' \(did you mean 'gao_sea'\?\)"):
        make_config("gao_se")
    with pytest.raises(ValueError, match=r"'ping_intervl_s' \(did you mean 'ping_interval_s'\?\)"):
        make_config("gao_sea", ping_intervl_s=1.0)
    with pytest.raises(ValueError, match=r"did you mean 'timing.ping_interval_s'"):
        make_config("gao_sea", **{"timing.ping_intervl_s": 1.0})
    with pytest.raises(ValueError, match="ping_interval_s is in section 'timing'"):
        make_config("gao_sea", **{"path.ping_interval_s": 1.0})


def test_numpy_scalars_and_lists_are_coerced():
    c = make_config(
        "gao_sea",
        max_cycles=np.int64(7),
        ping_interval_s=np.float32(10.0),
        randomize_depth_m=[1.0, 5.0],
        survey_area_m=[100.0, 100.0],
    )
    assert type(c.max_cycles) is int and type(c.ping_interval_s) is float
    assert c.randomize_depth_m == (1.0, 5.0) and c.survey_area_m == (100.0, 100.0)


def test_every_parameter_is_declared_once_with_unit_and_doc():
    names = parameter_names()
    assert len(names) == len(set(names)) and names[:2] == ["name", "network"]
    for spec in SECTIONS:
        for f in dataclasses.fields(spec.cls):
            assert f.metadata["doc"] and f.metadata["unit"], f.name
            assert default_of(f.name) == f.default
            if type(f.default) in (int, float):
                lo, hi, open_low = bounds()[f.name]
                assert (f.default > lo if open_low else f.default >= lo) and f.default <= hi, f.name
