"""Scenarios: the configuration dataclasses, their validation, TOML loading and saving, the built-in library.

The bottom layer of the project: it imports nothing from the simulator. `load_scenario("zebra_case1")` or
`load_scenario("path/to/file.toml")` returns a frozen `scenarios.config.ScenarioConfig`; `list_scenarios()`
maps built-in names to one-line descriptions; `dump_scenario(cfg)` writes TOML that loads back to an equal
config.
Bad files raise `ScenarioError` (a `ValueError`) naming the file, the field, the value and what is allowed.
"""

from __future__ import annotations

from scenarios.errors import Problem, ScenarioError
from scenarios.loading import (
    BUILTIN_DIR,
    available_scenarios,
    list_scenarios,
    load_scenario,
    parse_scenario,
    resolve_scenario_path,
)
from scenarios.saving import dump_scenario, save_scenario, to_toml
from scenarios.validation import VALUE_RULES, scenario_from_dict, to_data, validate_scenario

__all__ = [
    "BUILTIN_DIR",
    "VALUE_RULES",
    "Problem",
    "ScenarioError",
    "available_scenarios",
    "dump_scenario",
    "list_scenarios",
    "load_scenario",
    "parse_scenario",
    "resolve_scenario_path",
    "save_scenario",
    "scenario_from_dict",
    "to_data",
    "to_toml",
    "validate_scenario",
]
