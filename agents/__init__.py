"""Driving policies for the crossing environment and the evaluation script (`crossing-eval`)."""

from __future__ import annotations

from agents.policies import (
    POLICIES,
    AlwaysCautious,
    CautiousConfig,
    ConstantSpeed,
    ConstantSpeedConfig,
    DrivingConfig,
    HighwayEnvRule,
    HighwayRuleConfig,
    TTCBrakeConfig,
    TTCEmergencyBrake,
    YieldingConfig,
    YieldingPolicy,
    make_policy,
    policy_uses_predictors,
    scenario_settings,
)

__all__ = [
    "POLICIES",
    "AlwaysCautious",
    "CautiousConfig",
    "ConstantSpeed",
    "ConstantSpeedConfig",
    "DrivingConfig",
    "HighwayEnvRule",
    "HighwayRuleConfig",
    "TTCBrakeConfig",
    "TTCEmergencyBrake",
    "YieldingConfig",
    "YieldingPolicy",
    "make_policy",
    "policy_uses_predictors",
    "scenario_settings",
]
