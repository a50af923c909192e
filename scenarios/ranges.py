"""The allowed range of every scenario field, with its source or reason: `VALUE_RULES`.

`scenarios.validation` checks every value against this table; `scenarios.reference` writes it into
docs/scenarios.md. The rule helpers are in `scenarios.rules`.
"""

from __future__ import annotations

import math
import re

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
from scenarios.rules import _NONNEG, _PROB, CONFLICT_RULES, Rule, _between

# --------------------------------------------------------------------------------------- value rules


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

_IDENTIFIER = re.compile(r"\A[A-Za-z0-9_-]+\Z")
"""A scenario name: letters, digits, '_' and '-' (it becomes part of file names)."""

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
    **CONFLICT_RULES,
}
"""Per-field ranges, keyed by (dataclass, field). Physical quantities have physically plausible bounds, each
with its source or reason in the rule's text (shown in errors and in docs/scenarios.md); they also catch
unit mistakes such as km/h for m/s. Pool sizes have usability caps. Bounds that depend on other fields
(the ego inside the road, a car inside its lane) are checked in `scenarios.cross_field`."""
