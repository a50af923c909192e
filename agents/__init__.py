"""Driving policies for `crossing_env/Crossing-v0`: callables `policy(obs) -> action`, and their registry.

Every policy reads only the observation (never the ground truth). `make_policy("yielding", scenario=cfg)`
builds a registered one; `POLICIES` lists the names.
"""

from __future__ import annotations

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
from agents.registry import POLICIES, make_policy, policy_uses_predictors, scenario_settings
from agents.yielding import AlwaysCautious, YieldingPolicy

__all__ = [
    "POLICIES",
    "AlwaysCautious",
    "CautiousConfig",
    "ConstantSpeed",
    "ConstantSpeedConfig",
    "DrivingConfig",
    "HighwayEnvRule",
    "HighwayRuleConfig",
    "PredictiveYielding",
    "PredictiveYieldingConfig",
    "TTCBrakeConfig",
    "TTCEmergencyBrake",
    "YieldingConfig",
    "YieldingPolicy",
    "make_policy",
    "policy_uses_predictors",
    "scenario_settings",
]
