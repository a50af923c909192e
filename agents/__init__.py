"""Driving policies for `crossing_env/Crossing-v0`: the `Policy` protocol, the policies, and their registry.

Every policy reads only the observation (never the ground truth). `make_policy("yielding", scenario=cfg)`
builds a registered one; `POLICIES` lists the default table, `register_policy` adds one, and
`make_policy` also takes ``"pkg.module:attr"`` and ``"sb3:model.zip"`` plug-ins (`agents.registry`).
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
from agents.policy import Policy, as_policy, policy_is_batched
from agents.predictive import PredictiveYielding
from agents.registry import (
    BUILTIN_POLICIES,
    ENTRY_POINT_GROUP,
    POLICIES,
    blind_scenario,
    make_policy,
    policy_names,
    policy_uses_predictors,
    register_policy,
    scenario_settings,
)
from agents.yielding import AlwaysCautious, YieldingPolicy

__all__ = [
    "BUILTIN_POLICIES",
    "ENTRY_POINT_GROUP",
    "POLICIES",
    "AlwaysCautious",
    "CautiousConfig",
    "ConstantSpeed",
    "ConstantSpeedConfig",
    "DrivingConfig",
    "HighwayEnvRule",
    "HighwayRuleConfig",
    "Policy",
    "PredictiveYielding",
    "PredictiveYieldingConfig",
    "TTCBrakeConfig",
    "TTCEmergencyBrake",
    "YieldingConfig",
    "YieldingPolicy",
    "as_policy",
    "blind_scenario",
    "make_policy",
    "policy_is_batched",
    "policy_names",
    "policy_uses_predictors",
    "register_policy",
    "scenario_settings",
]
