"""Scenario validation: parsed TOML data or a config built in Python → a checked `ScenarioConfig`.

The schema is the frozen dataclasses in `scenarios.config`; nothing here repeats their fields. Checks come in
layers so that a bad file fails at load, never mid-episode:

1. Structure: a strict pydantic model generated from each dataclass forbids unknown keys and wrong types
   (no coercion: `"2"` is not an int, `1` is not a bool, `2.0` is not an int; an int is accepted where a
   float is expected, as TOML writes `30` for `30.0`). NaN and infinities are rejected.
2. Values: a table of ranges per field (`VALUE_RULES`) plus checks across fields (lane indices against the
   road, positions within the road, overlapping vehicles, truncation bounds, pool capacities).

Every problem found is collected and raised together as one `ScenarioError` whose message names the source,
the field path (`pedestrians.behaviour.running_rate`, `traffic.spawns[2].lane`), the value and what is
allowed. (TOML syntax is checked by `scenarios.loading`.)
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
import json
import math
import re
import sys
import types
import typing
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from typing import Any, Literal, Union, get_args, get_origin

import pydantic

from scenarios.config import (
    BehaviourConfig,
    BystanderConfig,
    CrosswalkConfig,
    EgoConfig,
    IDMConfig,
    PedestrianConfig,
    PedestrianSpawn,
    RoadConfig,
    ScenarioConfig,
    SignalConfig,
    SocialForceConfig,
    TrafficConfig,
    VehicleSpawn,
    WaitingPlace,
)
from scenarios.cross_field import cross_field_problems
from scenarios.errors import Problem, ScenarioError

_IDENTIFIER = re.compile(r"\A[A-Za-z0-9_-]+\Z")
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


# --------------------------------------------------------------------------------------- value rules


@dataclass(frozen=True)
class Rule:
    """A range rule for one field; `None` values (meaning "draw from the population") are not checked."""

    check: Callable[[Any], bool]
    """Predicate the value must satisfy."""
    allowed: str
    """The rule in words, used in the error message."""


def _between(lo: float, hi: float, *, lo_open: bool = False, hi_open: bool = False) -> Rule:
    left, right = ("(" if lo_open else "["), (")" if hi_open else "]")

    def check(v: float) -> bool:
        above = v > lo if lo_open else v >= lo
        below = v < hi if hi_open else v <= hi
        return above and below

    return Rule(check, f"must be in {left}{lo:g}, {hi:g}{right}")


_PROB = _between(0.0, 1.0)
_NONNEG = Rule(lambda v: v >= 0, "must be >= 0")
_POS = Rule(lambda v: v > 0, "must be > 0")

VALUE_RULES: dict[tuple[type, str], Rule] = {
    (ScenarioConfig, "name"): Rule(
        lambda v: bool(_IDENTIFIER.match(v)), "must be a non-empty identifier of letters, digits, '_' or '-'"
    ),
    (ScenarioConfig, "description"): Rule(
        lambda v: bool(v.strip()) and v.isprintable() and len(v) <= 200,
        "must be one non-empty line of printable characters (no control characters), <= 200 chars",
    ),
    (ScenarioConfig, "duration"): _between(0.0, 3600.0, lo_open=True),
    (RoadConfig, "num_lanes"): _between(1, 4),
    (RoadConfig, "lane_width"): _between(2.0, 6.0),
    (RoadConfig, "length"): _between(20.0, 10_000.0),
    (RoadConfig, "speed_limit"): _between(0.0, 40.0, lo_open=True),
    (RoadConfig, "sidewalk_width"): _between(0.0, 20.0, lo_open=True),
    (SignalConfig, "pedestrian_green"): _between(0.0, 600.0, lo_open=True),
    (SignalConfig, "pedestrian_red"): _between(0.0, 600.0, lo_open=True),
    (SignalConfig, "offset"): _NONNEG,
    (CrosswalkConfig, "width"): _between(0.0, 20.0, lo_open=True),
    (CrosswalkConfig, "stop_line_offset"): _between(0.0, 50.0),
    (IDMConfig, "max_acceleration"): _between(0.0, 10.0, lo_open=True),
    (IDMConfig, "comfortable_deceleration"): _between(0.0, 10.0, lo_open=True),
    (IDMConfig, "max_deceleration"): _between(0.0, 15.0, lo_open=True),
    (IDMConfig, "time_headway"): _between(0.0, 10.0, lo_open=True),
    (IDMConfig, "min_gap"): _between(0.0, 20.0),
    (IDMConfig, "delta"): _between(0.0, 20.0, lo_open=True),
    (VehicleSpawn, "lane"): _NONNEG,
    (VehicleSpawn, "speed"): _between(0.0, 60.0),
    (VehicleSpawn, "desired_speed"): _between(0.0, 60.0),
    (TrafficConfig, "flow_per_lane"): _between(0.0, 3600.0),
    (TrafficConfig, "desired_speed_std"): _between(0.0, 10.0),
    (TrafficConfig, "yield_probability"): _PROB,
    (TrafficConfig, "max_vehicles"): _between(1, 1000),
    (TrafficConfig, "length"): _between(0.0, 25.0, lo_open=True),
    (TrafficConfig, "width"): _between(0.0, 3.0, lo_open=True),
    (EgoConfig, "lane"): _NONNEG,
    (EgoConfig, "speed"): _between(0.0, 60.0),
    (EgoConfig, "max_acceleration"): _between(0.0, 10.0, lo_open=True),
    (EgoConfig, "max_deceleration"): _between(0.0, 15.0, lo_open=True),
    (EgoConfig, "max_speed"): _between(0.0, 60.0, lo_open=True),
    (PedestrianSpawn, "time"): _NONNEG,
    (PedestrianSpawn, "desired_speed"): _between(0.0, 6.0, lo_open=True),
    (PedestrianSpawn, "group"): _between(-1, 10_000),
    (PedestrianSpawn, "phase"): Rule(lambda v: 0.0 <= v <= math.pi, "must be in [0, π] radians"),
    (PedestrianSpawn, "radius"): _between(0.0, 1.0, lo_open=True),
    (PedestrianSpawn, "critical_gap"): _between(0.0, 30.0),
    (BehaviourConfig, "phase_mean"): Rule(lambda v: 0.0 <= v <= math.pi, "must be in [0, π] radians"),
    (BehaviourConfig, "phase_std"): Rule(lambda v: 0.0 <= v <= math.pi, "must be in [0, π] radians"),
    (BehaviourConfig, "critical_gap_mean"): _between(0.0, 30.0, lo_open=True),
    (BehaviourConfig, "critical_gap_std"): _between(0.0, 30.0),
    (BehaviourConfig, "critical_gap_floor"): _between(0.0, 30.0),
    (BehaviourConfig, "distraction_rate"): _PROB,
    (BehaviourConfig, "running_rate"): _PROB,
    (BehaviourConfig, "hesitation_rate"): _PROB,
    (BehaviourConfig, "turn_back_rate"): _PROB,
    (BehaviourConfig, "jaywalk_rate"): _PROB,
    (BehaviourConfig, "red_light_rate"): _PROB,
    (SocialForceConfig, "relaxation_time"): _between(0.0, 10.0, lo_open=True),
    (SocialForceConfig, "ped_intensity"): _between(0.0, 100.0),
    (SocialForceConfig, "vehicle_intensity"): _between(0.0, 100.0),
    (SocialForceConfig, "base_strength"): _between(0.0, 1000.0),
    (SocialForceConfig, "ped_range"): _between(0.0, 10.0, lo_open=True),
    (SocialForceConfig, "vehicle_range"): _between(0.0, 10.0, lo_open=True),
    (SocialForceConfig, "kerb_strength"): _between(0.0, 1000.0),
    (SocialForceConfig, "kerb_range"): _between(0.0, 10.0, lo_open=True),
    (SocialForceConfig, "anisotropy"): _PROB,
    (SocialForceConfig, "max_speed_factor"): _between(1.0, 5.0),
    (PedestrianConfig, "spawn_rate"): _between(0.0, 600.0),
    (PedestrianConfig, "cross_fraction"): _PROB,
    (PedestrianConfig, "group_probability"): _PROB,
    (PedestrianConfig, "spawn_extent"): _between(0.0, 10_000.0),
    (PedestrianConfig, "desired_speed_mean"): _between(0.0, 6.0, lo_open=True),
    (PedestrianConfig, "desired_speed_std"): _between(0.0, 3.0),
    (PedestrianConfig, "desired_speed_min"): _between(0.0, 6.0, lo_open=True),
    (PedestrianConfig, "desired_speed_max"): _between(0.0, 6.0, lo_open=True),
    (PedestrianConfig, "radius"): _between(0.0, 1.0, lo_open=True),
    (PedestrianConfig, "max_pedestrians"): _between(1, 10_000),
    (RoadConfig, "parking_strip"): _between(0.0, 5.0),
    (WaitingPlace, "spread"): _between(0.0, 100.0),
    (WaitingPlace, "kerb_distance"): _between(0.3, 20.0),
    (WaitingPlace, "initial"): _between(0, 50),
    (WaitingPlace, "weight"): _NONNEG,
    (BystanderConfig, "arrival_rate"): _between(0.0, 600.0),
    (BystanderConfig, "dwell_mean"): _between(0.0, 3600.0, lo_open=True),
}
"""Per-field ranges, keyed by (dataclass, field). Bounds beyond the physical ones are generous sanity caps
(a 60 m/s car, a 6 m/s pedestrian) that catch unit mistakes such as km/h for m/s."""


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
