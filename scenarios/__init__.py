"""Scenario library: validated TOML scenario files and the built-in situations.

`load_scenario("zebra_case1")` or `load_scenario("path/to/file.toml")` returns a frozen
`crossing_env.config.ScenarioConfig`; `list_scenarios()` maps built-in names to one-line descriptions;
`dump_scenario(cfg)` writes TOML that loads back to an equal config. Bad files raise `ScenarioError`
(a `ValueError`) naming the file, the field, the value and what is allowed.
"""

from __future__ import annotations

from scenarios.schema import (
    BUILTIN_DIR,
    VALUE_RULES,
    Problem,
    ScenarioError,
    available_scenarios,
    dump_scenario,
    list_scenarios,
    load_scenario,
    parse_scenario,
    resolve_scenario_path,
    save_scenario,
    scenario_from_dict,
    to_toml,
    validate_scenario,
)

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
    "to_toml",
    "validate_scenario",
]
