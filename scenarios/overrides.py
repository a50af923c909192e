"""One-line variants of a scenario and validated dict configs, through the same schema as files.

``apply_overrides(load_scenario("busy_zebra"), {"pedestrians.spawn_rate": 12.0})`` is "busy_zebra with a
higher spawn rate" without nested `dataclasses.replace`. Keys are dotted field paths (list items as
``traffic.spawns[0].lane``); an unknown key names the fields that exist, and the result is validated as
a scenario file would be, so a bad value fails with the same message naming field, value and rule.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Mapping
from typing import Any, get_args, get_origin

import pydantic

from scenarios.config import EnvConfig, ScenarioConfig
from scenarios.errors import Problem, ScenarioError
from scenarios.validation import (
    _build,
    _field_types,
    _is_optional,
    _model_for,
    scenario_from_dict,
    to_data,
)

_PART = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)((?:\[\d+\])*)$")


def _dataclass_of(tp: Any) -> Any:
    """The dataclass behind a field type (through Optional and tuple[X, ...]), or None."""
    optional, inner = _is_optional(tp)
    tp = inner if optional else tp
    if get_origin(tp) is tuple:
        tp = get_args(tp)[0]
    return tp if dataclasses.is_dataclass(tp) else None


def _set(data: dict[str, Any], cls: type, key: str, value: Any, source: str) -> None:
    """Set one dotted key in the nested data of dataclass `cls`, checking every name on the way."""
    node: Any = data
    owner: Any = cls
    parts = key.split(".")
    for depth, part in enumerate(parts):
        where = ".".join(parts[:depth]) or cls.__name__
        m = _PART.match(part)
        names = [f.name for f in dataclasses.fields(owner)] if owner is not None else []
        if m is None or m.group(1) not in names:
            allowed = f"unknown field; {where} has: {', '.join(names)}" if names else f"{where} has no fields"
            raise ScenarioError(source, [Problem(key, value, allowed)])
        name, indices = m.group(1), [int(i) for i in re.findall(r"\[(\d+)\]", m.group(2))]
        tp = _field_types(owner)[name]
        last = depth == len(parts) - 1
        if not indices:
            if last:
                node[name] = value
                return
            node = node.setdefault(name, {})
        else:
            items = node.get(name, [])
            for i in indices:
                if not isinstance(items, list) or i >= len(items):
                    size = len(items) if isinstance(items, list) else 0
                    raise ScenarioError(
                        source, [Problem(key, value, f"index {i} out of range; {size} item(s)")]
                    )
                if last and i == indices[-1]:
                    items[i] = value
                    return
                node, items = items, items[i]
            node = items
        owner = _dataclass_of(tp)
        if owner is None and not last:
            raise ScenarioError(
                source, [Problem(key, value, f"{'.'.join(parts[: depth + 1])} is not a table")]
            )


def apply_overrides(
    cfg: ScenarioConfig, overrides: Mapping[str, Any], source: str = "<overrides>"
) -> ScenarioConfig:
    """`cfg` with dotted-key overrides applied, validated like a scenario file.

    Raises:
        ScenarioError: an unknown key (the message lists the fields that exist) or an invalid value.
    """
    if not isinstance(overrides, Mapping):
        raise ScenarioError(
            source,
            [
                Problem(
                    "", overrides, f"overrides must be a dict of dotted keys, got {type(overrides).__name__}"
                )
            ],
        )
    data = to_data(cfg)
    for key, value in overrides.items():
        if not isinstance(key, str):
            raise ScenarioError(source, [Problem(repr(key), value, "keys must be dotted field names (str)")])
        _set(data, ScenarioConfig, key, value, source)
    return scenario_from_dict(data, f"{source} on {cfg.name!r}")


def _tuples(cls: type, data: Mapping[str, Any]) -> dict[str, Any]:
    """Lists given for tuple fields become tuples (a dict written by hand or read from JSON has lists)."""
    hints = _field_types(cls)
    out = dict(data)
    for name, value in data.items():
        tp = hints.get(name)
        if tp is None:
            continue
        sub = _dataclass_of(tp)
        if sub is not None and isinstance(value, Mapping):
            out[name] = _tuples(sub, value)
        elif get_origin(tp) is tuple and isinstance(value, list):
            out[name] = tuple(value)
    return out


def _config_problems(cls: type, error: pydantic.ValidationError) -> list[Problem]:
    problems = []
    for err in error.errors():
        loc = [str(p) for p in err["loc"]]
        field = ".".join(loc)
        owner: Any = cls
        for part in loc[:-1]:
            owner = _dataclass_of(_field_types(owner).get(part)) if owner is not None else None
        if err["type"] == "extra_forbidden" and owner is not None:
            names = ", ".join(f.name for f in dataclasses.fields(owner))
            problems.append(Problem(field, err.get("input"), f"unknown key; allowed keys: {names}"))
        else:
            problems.append(Problem(field, err.get("input"), err["msg"]))
    return problems


def env_config_from_dict(data: Mapping[str, Any], source: str = "<config>") -> EnvConfig:
    """An `EnvConfig` from a (nested) dict such as ``{"dt": 0.05, "reward": {"collision": -50.0}}``.

    Unknown keys and wrong types are reported as for scenario files; values the dataclass refuses
    (e.g. a `dt` that does not divide 0.4 s) as one problem with its message.

    Raises:
        ScenarioError: naming the field, the value and what is allowed.
    """
    if not isinstance(data, Mapping):
        raise ScenarioError(source, [Problem("", data, f"expected a dict, got {type(data).__name__}")])
    try:
        model = _model_for(EnvConfig).model_validate(_tuples(EnvConfig, data))
        return _build(EnvConfig, model.model_dump(exclude_unset=True))
    except pydantic.ValidationError as exc:
        raise ScenarioError(source, _config_problems(EnvConfig, exc)) from None
    except (ValueError, TypeError) as exc:
        raise ScenarioError(source, [Problem("", None, str(exc))]) from None
