"""The generated reference pages of the documentation site list what the code has."""

import dataclasses
import importlib.util
import sys
from pathlib import Path

import pytest

from coopnav_env.scenarios.base import ScenarioConfig

HOOK = Path(__file__).resolve().parent.parent / "docs" / "hooks" / "generate.py"


@pytest.fixture(scope="module")
def hook():
    spec = importlib.util.spec_from_file_location("docs_hook", HOOK)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


def test_parameter_reference_lists_every_field_with_unit_default_and_comment(hook):
    page = hook.parameters_page()
    docs, _ = hook.field_docs(ScenarioConfig)
    assert {d.name for d in docs} == {f.name for f in dataclasses.fields(ScenarioConfig)}
    assert all(d.comment for d in docs), [d.name for d in docs if not d.comment]
    for f in dataclasses.fields(ScenarioConfig):
        assert f"`{f.name}`" in page, f.name
    assert hook.unit_of("ping_interval_s") == "s" and hook.unit_of("current_speed_mps") == "m/s"
    assert '`ping_interval_s` | float | `20.0` | s |' in page  # name, type, default, unit on one row


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
