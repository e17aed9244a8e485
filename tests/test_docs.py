"""The generated reference pages of the documentation site list what the code has."""

import dataclasses
import importlib.util
import sys
from pathlib import Path

import pytest

from coopnav_env.scenarios.base import SECTIONS, ScenarioConfig, parameter_names, range_text

HOOK = Path(__file__).resolve().parent.parent / "docs" / "hooks" / "generate.py"


@pytest.fixture(scope="module")
def hook():
    spec = importlib.util.spec_from_file_location("docs_hook", HOOK)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


def test_parameter_reference_has_one_table_per_section_with_unit_range_and_doc(hook):
    page = hook.parameters_page()
    for spec in SECTIONS:
        assert f"{{#{spec.attr}}}" in page, spec.attr
        for f in dataclasses.fields(spec.cls):
            m = f.metadata
            assert m["doc"], f.name
            row = next((line for line in page.splitlines() if f'<a id="{f.name}"></a>`{f.name}`' in line), None)
            assert row is not None, f.name
            cells = [c.strip() for c in row.split(" | ")]
            assert cells[3] == m["unit"], (f.name, cells)
            if m["low"] is not None:  # every number shows its range
                assert cells[4] == range_text(f), (f.name, cells)
    assert hook.unit_of("ping_interval_s") == "s" and hook.unit_of("current_speed_mps") == "m/s"
    assert "`ping_interval_s` | float | `20.0` | s | (0, 3600] |" in page  # name, type, default, unit, range
    assert set(parameter_names()) - {"name", "network"} == {
        f.name for spec in SECTIONS for f in dataclasses.fields(spec.cls)
    }


def test_scenarios_page_lists_every_registered_scenario_with_its_sections(hook):
    import coopnav_env

    page = hook.scenarios_page()
    for name in coopnav_env.list_scenarios():
        config = coopnav_env.make_config(name)
        assert f"## `{name}`" in page, name
        section = page.split(f"## `{name}`")[1].split("\n## ")[0]
        for attr in config.sections():
            assert f"[`{attr}`](parameters.md#{attr})" in section, (name, attr)
        flat, default = config.to_flat_dict(), ScenarioConfig().to_flat_dict(all_parameters=True)
        for key, value in flat.items():
            if key not in ("name", "network") and value != default[key]:
                assert f"[`{key}`](parameters.md#{key})" in section, (name, key)


def test_observation_reference_matches_the_layouts(hook):
    page = hook.observations_page()
    from coopnav_env.core.moving_network import OBS_FIELDS

    for name, _ in OBS_FIELDS:
        assert name in page


def test_reward_tables_are_generated_from_the_registry(hook):
    from coopnav_env.core.reward import registered_terms

    root = HOOK.parent.parent
    for name, kind, page in (("REWARD_TERMS", "env", "design.md"), ("TRAINING_SIGNALS", "training", "training/sb3.md")):
        assert f"<!-- generated: {name} -->" in (root / page).read_text()
        table = hook.column_table(name)
        for term in registered_terms(kind):
            assert f"| `{term.name}` |" in table, term.name
