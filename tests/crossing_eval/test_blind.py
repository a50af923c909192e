"""Blind evaluation: a policy is told the road, the crossing and its car, never which scenario it is in."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from agents import blind_scenario, scenario_settings
from crossing_eval.cli import main
from scenarios import list_scenarios, load_scenario

PLUGIN = "tests.crossing_eval.plugin_policies:knows_where"


@pytest.mark.parametrize("name", sorted(list_scenarios()))
def test_blind_keeps_what_the_built_ins_read_and_drops_what_names_the_scenario(name: str) -> None:
    full = load_scenario(name)
    blind = blind_scenario(full)
    assert scenario_settings(blind) == scenario_settings(full)  # the built-ins drive exactly as told all
    assert blind.name == "" and blind.description == "" and blind.conflict is None
    assert blind.pedestrians == type(full.pedestrians)() and blind.traffic.spawns == ()
    assert blind.road == full.road and blind.crossing == full.crossing


def _distance(out: Path, *extra: str) -> float:
    argv = ["--scenarios", "zebra_case1", "--policies", PLUGIN, "--episodes", "1", "--workers", "1"]
    assert main([*argv, "--no-progress", "--out", str(out), *extra]) == 0
    doc = json.loads((out / "results.json").read_text())
    assert doc["settings"]["blind"] is (not extra)
    (episode,) = doc["episodes"]
    return episode["metrics"]["distance_travelled"]


def test_a_plug_in_is_not_told_the_scenario_unless_the_user_opts_in(tmp_path: Path) -> None:
    # Blind, it cannot tell zebra_case1 from anywhere else and holds its speed; told, it stands still there.
    assert _distance(tmp_path / "blind") > 50.0
    assert _distance(tmp_path / "told", "--reveal-scenario") < 20.0
