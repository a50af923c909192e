"""The policy registry: names → (policy class, config class), and `make_policy` to build one by name."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import fields, replace
from typing import Any

import numpy as np

from agents.baselines import ConstantSpeed, HighwayEnvRule, TTCEmergencyBrake
from agents.config import (
    CautiousConfig,
    ConstantSpeedConfig,
    DrivingConfig,
    HighwayRuleConfig,
    PredictiveYieldingConfig,
    TTCBrakeConfig,
    YieldingConfig,
)
from agents.predictive import PredictiveYielding
from agents.view import ObsLike
from agents.yielding import AlwaysCautious, YieldingPolicy
from scenarios.config import ScenarioConfig

Policy = Callable[[ObsLike], np.ndarray]

_REGISTRY: dict[str, tuple[type, type[DrivingConfig]]] = {
    "yielding": (YieldingPolicy, YieldingConfig),
    "predictive_yielding": (PredictiveYielding, PredictiveYieldingConfig),
    "constant_speed": (ConstantSpeed, ConstantSpeedConfig),
    "ttc_brake": (TTCEmergencyBrake, TTCBrakeConfig),
    "always_cautious": (AlwaysCautious, CautiousConfig),
    "highway_rule": (HighwayEnvRule, HighwayRuleConfig),
}
POLICIES: tuple[str, ...] = tuple(_REGISTRY)
"""Names accepted by `make_policy` (and `crossing-eval --policies`)."""


def scenario_settings(scenario: ScenarioConfig) -> dict[str, Any]:
    """`DrivingConfig` fields that follow from a scenario (ego limits, speed limit, geometry)."""
    road = scenario.road
    w = road.lane_width
    ego_y = (scenario.ego.lane + 0.5) * w
    return {
        "ego": scenario.ego,
        "speed_limit": road.speed_limit,
        "lane_width": w,
        "ego_length": scenario.traffic.length,
        "ego_width": scenario.traffic.width,
        "half_right": 0.0 - ego_y,
        "half_left": road.num_forward_lanes * w - ego_y,
        "stop_line_offset": scenario.crossing.stop_line_offset,
        "road_right": 0.0 - ego_y,
        "road_left": road.road_width - ego_y,
    }


def make_policy(
    name: str, scenario: ScenarioConfig | None = None, dt: float | None = None, **overrides: Any
) -> Policy:
    """Build a registered policy by name.

    `scenario` fills the road-dependent settings, `dt` the step time of policies with timers (ignored by
    the others), `overrides` any config field.

    Raises:
        ValueError: unknown policy name or config field (the message lists the allowed ones).
    """
    if name not in _REGISTRY:
        raise ValueError(f"unknown policy {name!r}; choose from {', '.join(POLICIES)}")
    cls, cfg_cls = _REGISTRY[name]
    allowed = {f.name for f in fields(cfg_cls)}
    unknown = sorted(set(overrides) - allowed)
    if unknown:
        raise ValueError(f"policy {name!r}: unknown config field(s) {unknown}; allowed: {sorted(allowed)}")
    cfg = cfg_cls()
    if scenario is not None:
        cfg = replace(cfg, **scenario_settings(scenario))
    if dt is not None and "dt" in allowed:
        cfg = replace(cfg, dt=float(dt))
    if overrides:
        cfg = replace(cfg, **overrides)
    return cls(cfg)


def policy_uses_predictors(name: str) -> bool:
    """Whether the evaluation should put the predictor wrappers on for this policy."""
    if name not in _REGISTRY:
        raise ValueError(f"unknown policy {name!r}; choose from {', '.join(POLICIES)}")
    return bool(getattr(_REGISTRY[name][0], "uses_predictors", False))
