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
    unit: str = ""
    """Unit of a physical quantity (empty for counts, rates and names)."""
    why: str = ""
    """Source of or reason for the bounds (part of `allowed` too, so errors and docs show it)."""


def _between(
    lo: float,
    hi: float,
    *,
    lo_open: bool = False,
    hi_open: bool = False,
    unit: str = "",
    why: str = "",
) -> Rule:
    """A closed (or half-open) range; `unit` and `why` (the bounds' source or reason) go into the message."""
    left, right = ("(" if lo_open else "["), (")" if hi_open else "]")

    def check(v: float) -> bool:
        above = v > lo if lo_open else v >= lo
        below = v < hi if hi_open else v <= hi
        return above and below

    text = f"must be in {left}{lo:g}, {hi:g}{right}" + (f" {unit}" if unit else "")
    return Rule(check, text + (f" ({why})" if why else ""), unit, why)


_PROB = _between(0.0, 1.0)
_NONNEG = Rule(lambda v: v >= 0, "must be >= 0")

# Shared physical bounds (each used by several fields; the reason is stated once, with the numbers).
_CAR_SPEED = _between(
    0.0,
    40.0,
    unit="m/s",
    why="144 km/h: the 100 km/h road limit plus a 40 % margin for speeders; 50 km/h typed as m/s fails",
)
_BRAKING = _between(
    1.0,
    12.0,
    unit="m/s²",
    why="1: full braking on ice, tyre-road friction μ ≈ 0.1; 12: μ ≈ 1.2 × g, "
    "the grip limit of good tyres on dry asphalt",
)
_WALKING_SPEED = _between(
    0.3,
    3.0,
    unit="m/s",
    why="0.3: the slowest walkers, with walking aids; 3: a jog, brisk walking being "
    "about 2 m/s; a run doubles it, and the social force caps speed at max_speed_factor times it",
)
_BODY_RADIUS = _between(
    0.15,
    0.5,
    unit="m",
    why="0.15: a toddler, about 0.3 m across the shoulders; 0.5: an adult with a "
    "pram, wheelchair or luggage, about 1 m across; an adult is about 0.25",
)
_CRITICAL_GAP = _between(
    0.0, 15.0, unit="s", why="0 = does not look; reported critical gaps lie between about 2 and 10 s"
)
_PED_ARRIVALS = _between(
    0.0,
    300.0,
    unit="per minute",
    why="about the capacity of two 2 m sidewalks: HCM puts walkway "
    "capacity at about 75 pedestrians per minute per metre",
)
_FORCE_RANGE = _between(
    0.05, 2.0, unit="m", why="Helbing & Molnár-type calibrations use 0.08-0.5 m; a body is about 0.5 m across"
)
_FORCE_STRENGTH = _between(
    0.0, 100.0, unit="m/s²", why="4 × the 25 m/s² of Helbing et al. 2000, 2000 N on 80 kg"
)

VALUE_RULES: dict[tuple[type, str], Rule] = {
    (ScenarioConfig, "name"): Rule(
        lambda v: bool(_IDENTIFIER.match(v)), "must be a non-empty identifier of letters, digits, '_' or '-'"
    ),
    (ScenarioConfig, "description"): Rule(
        lambda v: bool(v.strip()) and v.isprintable() and len(v) <= 200,
        "must be one non-empty line of printable characters (no control characters), <= 200 chars",
    ),
    (ScenarioConfig, "duration"): _between(
        2.0,
        3600.0,
        unit="s",
        why="at least 5 policy steps at the coarsest allowed dt of 0.4 s, dt having to divide the "
        "0.4 s history cadence, and 20 at the default 0.1 s; at most an hour",
    ),
    (RoadConfig, "num_lanes"): _between(1, 4),
    (RoadConfig, "lane_width"): _between(
        2.5,
        5.0,
        unit="m",
        why="2.5: the narrowest urban lanes, about what a 2.55 m lorry needs; 3.0-3.7 "
        "is usual; above 5 drivers use one lane as two",
    ),
    (RoadConfig, "length"): _between(
        50.0,
        2000.0,
        unit="m",
        why="50: a car at 50 km/h needs about 25 m to stop, so less leaves no "
        "approach to the crossing; 2000: 2.4 min at 50 km/h, far beyond what the crossing affects",
    ),
    (RoadConfig, "speed_limit"): _between(
        2.0,
        27.8,
        unit="m/s",
        why="2: walking-pace zones, about 7 km/h; 27.8 = 100 km/h, the highest "
        "limit on roads with at-grade pedestrian crossings",
    ),
    (RoadConfig, "sidewalk_width"): _between(
        1.0,
        12.0,
        unit="m",
        why="1: the absolute minimum at a pinch point in UK Inclusive Mobility, which "
        "asks for 2 m elsewhere; 12: a wide boulevard footway",
    ),
    (RoadConfig, "parking_strip"): _between(
        0.0,
        5.0,
        unit="m",
        why="0: none; parallel bays are 2.0-2.5 m deep, angled or perpendicular bays up to about 5 m",
    ),
    (SignalConfig, "pedestrian_green"): _between(
        4.0,
        240.0,
        unit="s",
        why="4: the shortest walk interval in the MUTCD, 4E.06; 240: longer than the "
        "longest fixed-time cycles in use, about 180 s",
    ),
    (SignalConfig, "pedestrian_red"): _between(
        4.0,
        240.0,
        unit="s",
        why="4: a minimum vehicle green; 240: longer than the longest fixed-time cycles in use, about 180 s",
    ),
    (SignalConfig, "offset"): _NONNEG,
    (CrosswalkConfig, "width"): _between(
        1.8,
        10.0,
        unit="m",
        why="1.8: the minimum marked crosswalk, 6 ft in the MUTCD; 2.4-5 is usual for a "
        "zebra; 10: the widest high-footfall crossings",
    ),
    (CrosswalkConfig, "stop_line_offset"): _between(
        0.0,
        15.0,
        unit="m",
        why="stop lines sit 1.2-3 m before the crossing, advance yield lines up to 15 m (50 ft, MUTCD 3B.16)",
    ),
    (IDMConfig, "max_acceleration"): _between(
        0.2,
        5.0,
        unit="m/s²",
        why="0.2: a loaded lorry; IDM calibrations use 0.3-2.5 for cars; 5: a sports car at full throttle",
    ),
    (IDMConfig, "comfortable_deceleration"): _between(
        0.5,
        5.0,
        unit="m/s²",
        why="IDM calibrations use 0.5-3; AASHTO's design braking is 3.4; more is "
        "hard braking, not comfortable",
    ),
    (IDMConfig, "max_deceleration"): _BRAKING,
    (IDMConfig, "time_headway"): _between(
        0.5,
        5.0,
        unit="s",
        why="0.5: the shortest headways drivers keep; IDM calibrations use 1-2 s; "
        "beyond 5 s a driver is not following",
    ),
    (IDMConfig, "min_gap"): _between(
        0.5,
        10.0,
        unit="m",
        why="stopped cars keep 1-5 m to the car ahead, IDM calibrations 2 m; 0 would mean bumper to bumper",
    ),
    (IDMConfig, "delta"): _between(0.0, 20.0, lo_open=True),
    (VehicleSpawn, "lane"): _NONNEG,
    (VehicleSpawn, "speed"): _CAR_SPEED,
    (VehicleSpawn, "desired_speed"): _CAR_SPEED,
    (TrafficConfig, "flow_per_lane"): _between(
        0.0,
        2400.0,
        unit="vehicles/h",
        why="the HCM capacity of a freeway lane; urban lanes saturate near 1900",
    ),
    (TrafficConfig, "desired_speed_std"): _between(
        0.0, 5.0, unit="m/s", why="drivers' free speeds spread by about 10-15 %, 1-3 m/s at urban limits"
    ),
    (TrafficConfig, "yield_probability"): _PROB,
    (TrafficConfig, "max_vehicles"): _between(
        1,
        200,
        why="a usability cap: 8 × the busiest built-in scenario's 24, more cars than four 300 m "
        "lanes hold bumper to bumper; more only slows every step",
    ),
    (TrafficConfig, "length"): _between(
        2.0,
        20.0,
        unit="m",
        why="2: a quadricycle, Renault Twizy 2.34 m; 20: above the EU maximum of "
        "18.75 m for articulated buses and road trains, Directive 96/53/EC",
    ),
    (TrafficConfig, "width"): _between(
        1.2,
        2.6,
        unit="m",
        why="1.2: a quadricycle, Renault Twizy 1.24 m; 2.6: the EU maximum in "
        "Directive 96/53/EC, 2.55 m or 2.60 m for refrigerated bodies",
    ),
    (EgoConfig, "lane"): _NONNEG,
    (EgoConfig, "speed"): _CAR_SPEED,
    (EgoConfig, "max_acceleration"): _between(
        0.5,
        10.0,
        unit="m/s²",
        why="0.5: a loaded bus; 10: about the tyre-grip limit, μ ≈ 1 × g, that "
        "the quickest production cars reach",
    ),
    (EgoConfig, "max_deceleration"): _BRAKING,
    (EgoConfig, "max_speed"): _between(
        2.0,
        40.0,
        unit="m/s",
        why="2: a walking-pace cap, lower being a typo; 40 = 144 km/h: the 100 km/h "
        "road limit plus 40 %; 50 km/h typed as m/s fails",
    ),
    (PedestrianSpawn, "time"): _NONNEG,
    (PedestrianSpawn, "desired_speed"): _WALKING_SPEED,
    (PedestrianSpawn, "group"): _between(-1, 10_000),
    (PedestrianSpawn, "phase"): Rule(lambda v: 0.0 <= v <= math.pi, "must be in [0, π] radians"),
    (PedestrianSpawn, "radius"): _BODY_RADIUS,
    (PedestrianSpawn, "critical_gap"): _CRITICAL_GAP,
    (BehaviourConfig, "phase_mean"): Rule(lambda v: 0.0 <= v <= math.pi, "must be in [0, π] radians"),
    (BehaviourConfig, "phase_std"): Rule(lambda v: 0.0 <= v <= math.pi, "must be in [0, π] radians"),
    (BehaviourConfig, "critical_gap_mean"): _between(
        0.0, 15.0, lo_open=True, unit="s", why="reported critical gaps lie between about 2 and 10 s"
    ),
    (BehaviourConfig, "critical_gap_std"): _between(0.0, 5.0, unit="s", why="reported spreads are 0.5-2 s"),
    (BehaviourConfig, "critical_gap_floor"): _CRITICAL_GAP,
    (BehaviourConfig, "distraction_rate"): _PROB,
    (BehaviourConfig, "running_rate"): _PROB,
    (BehaviourConfig, "hesitation_rate"): _PROB,
    (BehaviourConfig, "turn_back_rate"): _PROB,
    (BehaviourConfig, "jaywalk_rate"): _PROB,
    (BehaviourConfig, "red_light_rate"): _PROB,
    (SocialForceConfig, "relaxation_time"): _between(
        0.1, 2.0, unit="s", why="Helbing & Molnár use 0.5 s; calibrations give 0.2-1 s"
    ),
    (SocialForceConfig, "ped_intensity"): _between(0.0, 100.0),
    (SocialForceConfig, "vehicle_intensity"): _between(0.0, 100.0),
    (SocialForceConfig, "base_strength"): _FORCE_STRENGTH,
    (SocialForceConfig, "ped_range"): _FORCE_RANGE,
    (SocialForceConfig, "vehicle_range"): _FORCE_RANGE,
    (SocialForceConfig, "kerb_strength"): _FORCE_STRENGTH,
    (SocialForceConfig, "kerb_range"): _FORCE_RANGE,
    (SocialForceConfig, "anisotropy"): _PROB,
    (SocialForceConfig, "max_speed_factor"): _between(
        1.0, 2.0, why="Helbing & Molnár use 1.3; a pedestrian pressed by others speeds up, not to a run"
    ),
    (PedestrianConfig, "spawn_rate"): _PED_ARRIVALS,
    (PedestrianConfig, "cross_fraction"): _PROB,
    (PedestrianConfig, "group_probability"): _PROB,
    (PedestrianConfig, "spawn_extent"): _between(
        0.0, 2000.0, unit="m", why="no longer than the longest road"
    ),
    (PedestrianConfig, "desired_speed_mean"): _WALKING_SPEED,
    (PedestrianConfig, "desired_speed_std"): _between(
        0.0, 1.0, unit="m/s", why="observed spreads of walking speed are 0.15-0.3 m/s"
    ),
    (PedestrianConfig, "desired_speed_min"): _WALKING_SPEED,
    (PedestrianConfig, "desired_speed_max"): _WALKING_SPEED,
    (PedestrianConfig, "radius"): _BODY_RADIUS,
    (PedestrianConfig, "max_pedestrians"): _between(
        1,
        500,
        why="a usability cap: 8 × the busiest built-in scenario's 64; a step's cost grows with the "
        "crowd, 1-2 ms per world step at 500 in benchmarks/scaling.py",
    ),
    (WaitingPlace, "spread"): _between(
        0.0, 100.0, unit="m", why="a bus-stop queue is 2-10 m; 100 m is a long parade of shop fronts"
    ),
    (WaitingPlace, "kerb_distance"): _between(
        0.3, 12.0, unit="m", why="a body's width from the kerb at least; within the widest sidewalk"
    ),
    (WaitingPlace, "initial"): _between(0, 50),
    (WaitingPlace, "weight"): _NONNEG,
    (BystanderConfig, "arrival_rate"): _PED_ARRIVALS,
    (BystanderConfig, "dwell_mean"): _between(
        0.0, 3600.0, lo_open=True, unit="s", why="at most the longest episode, an hour"
    ),
}
"""Per-field ranges, keyed by (dataclass, field). Physical quantities have physically plausible bounds, each
with its source or reason in the rule's text (shown in errors and in docs/scenarios.md); they also catch
unit mistakes such as km/h for m/s. Pool sizes have usability caps. Bounds that depend on other fields
(the ego inside the road, a car inside its lane) are checked in `scenarios.cross_field`."""


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
