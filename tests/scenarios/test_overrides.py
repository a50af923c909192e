"""One-line overrides, dict configs and the generated field reference (issue 16)."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import gymnasium as gym
import pytest

from crossing_env import ENV_ID
from scenarios import ScenarioError, load_scenario
from scenarios.overrides import apply_overrides, env_config_from_dict
from scenarios.reference import _classes, field_docs, reference_markdown

REPO = Path(__file__).resolve().parents[2]


def test_gym_make_with_overrides_changes_only_that_field():
    env = gym.make(ENV_ID, scenario="busy_zebra", overrides={"pedestrians.spawn_rate": 12.0})
    cfg = env.unwrapped.scenario
    base = load_scenario("busy_zebra")
    assert cfg.pedestrians.spawn_rate == 12.0 != base.pedestrians.spawn_rate
    assert dataclasses.replace(cfg, pedestrians=base.pedestrians) == base


def test_list_items_and_nested_tables_can_be_overridden():
    base = load_scenario("zebra_case1")
    cfg = apply_overrides(
        base, {"traffic.spawns[0].speed": 5.0, "pedestrians.behaviour.distraction_rate": 0.0}
    )
    assert cfg.traffic.spawns[0].speed == 5.0
    assert cfg.traffic.spawns[1:] == base.traffic.spawns[1:]


@pytest.mark.parametrize(
    ("overrides", "needles"),
    [
        ({"pedestrians.spawn_rat": 1.0}, ["pedestrians.spawn_rat", "spawn_rate"]),
        ({"pedestrians.spawn_rate": -1.0}, ["pedestrians.spawn_rate = -1.0", "[0, 300]"]),
        ({"pedestrians.spawn_rate": "many"}, ["'many'"]),
        ({"traffic.spawns[9].lane": 0}, ["traffic.spawns[9].lane", "out of range"]),
        ({"duration.seconds": 1.0}, ["not a table"]),
    ],
)
def test_bad_overrides_fail_with_field_value_and_rule(overrides, needles):
    with pytest.raises(ScenarioError) as err:
        gym.make(ENV_ID, scenario="busy_zebra", overrides=overrides)
    for needle in needles:
        assert needle in str(err.value)


def test_config_as_a_validated_dict():
    env = gym.make(ENV_ID, config={"dt": 0.05, "reward": {"collision": -50.0}, "render_size": [400, 200]})
    assert env.unwrapped.config.dt == 0.05 and env.unwrapped.config.reward.collision == -50.0
    assert env.unwrapped.config.render_size == (400, 200)
    with pytest.raises(ScenarioError, match=re.escape("divide 0.4")):
        env_config_from_dict({"dt": 0.3})
    with pytest.raises(
        ScenarioError, match=re.escape("reward.colision = -5.0: unknown key; allowed keys: progress")
    ):
        env_config_from_dict({"reward": {"colision": -5.0}})


def test_scenario_as_a_dict_goes_through_the_schema():
    env = gym.make(ENV_ID, scenario={"name": "mine", "pedestrians": {"spawn_rate": 3.0}})
    assert env.unwrapped.scenario.pedestrians.spawn_rate == 3.0
    with pytest.raises(ScenarioError, match=re.escape("pedestrians.spawn_rate = 'x'")):
        gym.make(ENV_ID, scenario={"pedestrians": {"spawn_rate": "x"}})


def test_docs_scenarios_md_is_in_sync_with_the_docstrings():
    committed = (REPO / "docs" / "scenarios.md").read_text(encoding="utf-8")
    assert committed == reference_markdown(), "regenerate: python -m scenarios.reference docs/scenarios.md"


def test_every_config_field_is_documented():
    for cls in _classes():
        docs = field_docs(cls)
        missing = [f.name for f in dataclasses.fields(cls) if not docs.get(f.name)]
        assert not missing, f"{cls.__name__}: fields without a docstring: {missing}"
