"""Scenario validation: parsed TOML data or a config built in Python → a checked `ScenarioConfig`.

The schema is the frozen dataclasses in `scenarios.config`; nothing here repeats their fields. Checks come in
layers so that a bad file fails at load, never mid-episode:

1. Structure: a strict pydantic model generated from each dataclass forbids unknown keys and wrong types
   (no coercion: `"2"` is not an int, `1` is not a bool, `2.0` is not an int; an int is accepted where a
   float is expected, as TOML writes `30` for `30.0`). NaN and infinities are rejected.
2. Values: a table of ranges per field (`scenarios.ranges.VALUE_RULES`) plus checks across fields (lane
   indices against the road, positions within the road, overlapping vehicles, truncation bounds, pool
   capacities).

Every problem found is collected and raised together as one `ScenarioError` whose message names the source,
the field path (`pedestrians.behaviour.running_rate`, `traffic.spawns[2].lane`), the value and what is
allowed. (TOML syntax is checked by `scenarios.loading`.)
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
import json
import sys
import types
import typing
from collections.abc import Iterator, Mapping
from typing import Any, Literal, Union, get_args, get_origin

import pydantic

from scenarios.config import (
    ScenarioConfig,
)
from scenarios.cross_field import cross_field_problems
from scenarios.errors import Problem, ScenarioError
from scenarios.ranges import _IDENTIFIER, VALUE_RULES

"""Names and bare keys: letters, digits, '_', '-' (`\\Z`, unlike `$`, refuses a trailing newline)."""


def _key_text(key: str) -> str:
    """A key as TOML would write it: bare when it is an identifier, else quoted with escapes."""
    return key if _IDENTIFIER.match(key) else json.dumps(key)


# ------------------------------------------------------------------------------- structural (pydantic)


@functools.cache
def _field_types(cls: type) -> dict[str, Any]:
    """Resolved annotations of a config dataclass (strings under `from __future__ import annotations`)."""
    module = sys.modules[cls.__module__]
    return typing.get_type_hints(cls, globalns=vars(module))


def _is_optional(tp: Any) -> tuple[bool, Any]:
    """Split `X | None` into (True, X); anything else into (False, tp)."""
    if get_origin(tp) in (Union, types.UnionType):
        args = [a for a in get_args(tp) if a is not type(None)]
        if len(args) == len(get_args(tp)) - 1 and len(args) == 1:
            return True, args[0]
    return False, tp


def _pydantic_type(tp: Any) -> Any:
    """Map a dataclass field type onto the strict model type: dataclasses → models, tuples → lists."""
    optional, inner = _is_optional(tp)
    if optional:
        return _pydantic_type(inner) | None
    if dataclasses.is_dataclass(tp):
        return _model_for(tp)
    if get_origin(tp) is tuple:
        args = get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            # TOML arrays load as lists; strict pydantic would refuse them for a tuple field.
            return list[_pydantic_type(args[0])]
    return tp


@functools.cache
def _model_for(cls: type) -> type[pydantic.BaseModel]:
    """Strict pydantic model mirroring one config dataclass (built once, on first use).

    Pydantic validates stdlib dataclasses directly, but its strict mode then insists on dataclass
    instances rather than tables and on tuples rather than arrays; a generated mirror model keeps the
    dataclasses the single source of truth while getting strict, no-coercion checks from TOML data.
    """
    config = pydantic.ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)
    hints = _field_types(cls)
    fields: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        required = f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
        # Optional keys get a placeholder default: values left unset are dropped before `_build`, so the
        # dataclass's own defaults apply and are never duplicated here.
        fields[f.name] = (_pydantic_type(hints[f.name]), ... if required else None)
    return pydantic.create_model(f"{cls.__name__}Schema", __config__=config, **fields)


def _build(cls: type, data: Mapping[str, Any]) -> Any:
    """Instantiate a dataclass from structurally valid data; absent keys keep the dataclass defaults."""
    hints = _field_types(cls)
    kwargs: dict[str, Any] = {}
    for name, value in data.items():
        kwargs[name] = _build_value(hints[name], value)
    return cls(**kwargs)


def _build_value(tp: Any, value: Any) -> Any:
    optional, inner = _is_optional(tp)
    if value is None:
        return None
    tp = inner if optional else tp
    if dataclasses.is_dataclass(tp):
        return _build(tp, value)
    if get_origin(tp) is tuple:
        (item_type, _) = get_args(tp)
        return tuple(_build_value(item_type, v) for v in value)
    if tp is float:
        return float(value)
    return value


def _type_at(loc: tuple[Any, ...]) -> tuple[Any, list[str]]:
    """The schema type reached by a pydantic error location, and the field path as readable parts."""
    tp: Any = ScenarioConfig
    parts: list[str] = []
    for item in loc:
        _, tp = _is_optional(tp)
        if isinstance(item, int) and get_origin(tp) is tuple:
            tp = get_args(tp)[0]
            parts.append(f"[{item}]")
        elif isinstance(item, str) and dataclasses.is_dataclass(tp) and item in _field_types(tp):
            tp = _field_types(tp)[item]
            parts.append(item)
        elif isinstance(item, str) and dataclasses.is_dataclass(tp):
            parts.append(item)  # an unknown key: stop descending
            tp = None
        # anything else is a pydantic union tag; it is not part of the user's path
    return tp, parts


def _join(parts: list[str]) -> str:
    out = ""
    for part in parts:
        out += part if part.startswith("[") or not out else "." + part
    return out


def _describe_type(tp: Any) -> str:
    optional, inner = _is_optional(tp)
    if optional:
        return _describe_type(inner)
    if get_origin(tp) is Literal:
        return "one of " + ", ".join(repr(a) for a in get_args(tp))
    if dataclasses.is_dataclass(tp):
        return "a table"
    if get_origin(tp) is tuple:
        return "an array of tables"
    names = {bool: "true or false", int: "an integer", float: "a finite number", str: "a string"}
    return names.get(tp, str(tp))


def _pydantic_problems(error: pydantic.ValidationError) -> list[Problem]:
    problems = []
    for err in error.errors():
        loc = tuple(err["loc"])
        if err["type"] == "extra_forbidden":
            owner, parts = _type_at(loc[:-1])
            key = str(loc[-1])
            allowed_keys = sorted(_field_types(owner)) if dataclasses.is_dataclass(owner) else []
            hint = difflib.get_close_matches(key, allowed_keys, n=1)
            allowed = f"unknown key {key!r}"
            allowed += f" (did you mean {hint[0]!r}?)" if hint else ""
            allowed += "; allowed keys: " + ", ".join(allowed_keys)
            problems.append(Problem(_join([*parts, _key_text(key)]), err["input"], allowed))
            continue
        tp, parts = _type_at(loc)
        path = _join(parts)
        if err["type"] == "missing":
            problems.append(Problem(path, None, "required key is missing", has_value=False))
        elif tp is not None:
            problems.append(Problem(path, err["input"], f"must be {_describe_type(tp)}"))
        else:  # pragma: no cover - defensive: pydantic reported a location outside the schema
            problems.append(Problem(path, err["input"], err["msg"]))
    return problems


def _walk(obj: Any, parts: list[str]) -> Iterator[tuple[type, str, list[str], Any]]:
    """Yield (owner class, field name, path parts, value) for every leaf and table in a config tree."""
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        path = [*parts, f.name]
        yield type(obj), f.name, path, value
        if dataclasses.is_dataclass(value):
            yield from _walk(value, path)
        elif isinstance(value, tuple):
            for i, item in enumerate(value):
                if dataclasses.is_dataclass(item):
                    yield from _walk(item, [*path, f"[{i}]"])


def _rule_problems(cfg: ScenarioConfig) -> list[Problem]:
    problems = []
    for owner, name, parts, value in _walk(cfg, []):
        rule = VALUE_RULES.get((owner, name))
        if rule is not None and value is not None and not rule.check(value):
            problems.append(Problem(_join(parts), value, rule.allowed))
    return problems


# ---------------------------------------------------------------------------------------- public API


def scenario_from_dict(
    data: Mapping[str, Any], source: str = "<dict>", *, default_name: str | None = None
) -> ScenarioConfig:
    """Validate parsed TOML data (nested dicts and lists) and build the `ScenarioConfig`.

    Args:
        data: Parsed TOML document.
        source: Name used in error messages (normally the file path).
        default_name: Scenario name used when `data` has no `name` (a file's stem).

    Raises:
        ScenarioError: on unknown keys, wrong types or values outside the allowed ranges.
    """
    if not isinstance(data, Mapping):
        raise ScenarioError(
            source, [Problem("", data, f"a scenario must be a TOML table, got {type(data).__name__}")]
        )
    data = dict(data)
    if default_name is not None and "name" not in data:
        data["name"] = default_name
    try:
        model = _model_for(ScenarioConfig).model_validate(data)
    except pydantic.ValidationError as exc:
        raise ScenarioError(source, _pydantic_problems(exc)) from None
    cfg = _build(ScenarioConfig, model.model_dump(exclude_unset=True))
    problems = _rule_problems(cfg)
    if not problems:  # cross-field messages assume each field is sane on its own
        problems = cross_field_problems(cfg)
    if problems:
        raise ScenarioError(source, problems)
    return cfg


def validate_scenario(cfg: ScenarioConfig, source: str = "<config>") -> ScenarioConfig:
    """Check a config built in Python (e.g. with `dataclasses.replace`) against the same schema as files.

    Raises:
        ScenarioError: as for a file.
    """
    if not isinstance(cfg, ScenarioConfig):
        raise ScenarioError(
            source, [Problem("", cfg, f"expected a ScenarioConfig, got {type(cfg).__name__}")]
        )
    return scenario_from_dict(to_data(cfg), source)


def to_data(obj: Any) -> dict[str, Any]:
    """Config tree → TOML-ready nested dicts; `None` fields are omitted (optional fields default to None)."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        if value is None:
            continue
        if dataclasses.is_dataclass(value):
            out[f.name] = to_data(value)
        elif isinstance(value, tuple):
            out[f.name] = [to_data(v) if dataclasses.is_dataclass(v) else v for v in value]
        else:
            out[f.name] = value
    return out
