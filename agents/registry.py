"""The policy registry: names → policy factories, and `make_policy` to build one by name or plug-in spec.

A policy is an `agents.policy.Policy`: ``policy(obs) -> action`` (float32, shape (1,)) reading only the
observation, and ``policy.reset(seed)`` before each episode; a class attribute ``uses_predictors = True``
asks the rollout for the prediction wrappers. What a factory returns goes through `agents.policy.as_policy`
(a plain function becomes a stateless `Policy`). Besides the built-in names, `make_policy` accepts (also
inside worker processes and Ray tasks, which get the spec string, never a live object):

- a name registered with `register_policy` in this process,
- a name from the ``crossing_env.policies`` entry-point group of installed packages,
- ``"pkg.module:attr"`` (a module in the current folder is found, as ``python -m`` finds it): a plain
  function ``attr(obs) -> action`` (or a policy object) that is the policy itself; a policy class whose
  constructor takes its config (``attr.config_class``, a `DrivingConfig` subclass, as the built-ins); or a
  factory (a function or class) called with those of ``scenario=`` and ``dt=`` that it names (all with
  ``**kwargs``; none for a no-argument constructor). A callable that requires a positional argument other
  than those two is the policy; one that requires none is a factory.
- ``"sb3:path/model.zip"``: a Stable-Baselines3 model (`agents.sb3.SB3Policy`, the ``rl`` extra),
- ``"mlp:path/policy.npz"``: a learned policy stored as data (`agents.mlp`, numpy only), deployed through
  the yielding shield when the file says it was trained through it.
"""

from __future__ import annotations

import hashlib
import inspect
import json
from collections.abc import Callable
from dataclasses import dataclass, fields, replace
from importlib.metadata import entry_points
from pathlib import Path
from typing import Any

from agents.adversaries import BrakeLate, Crawl, FullThrottle, StopAndGo, StopFar, StopNear
from agents.baselines import ConstantSpeed, HighwayEnvRule, TTCEmergencyBrake
from agents.config import (
    AdversaryConfig,
    BrakeLateConfig,
    CautiousConfig,
    ConstantSpeedConfig,
    DrivingConfig,
    HighwayRuleConfig,
    PlannerConfig,
    PredictiveYieldingConfig,
    TTCBrakeConfig,
    YieldingConfig,
)
from agents.planner import SamplingPlanner
from agents.policy import ConstantAction, Policy, RandomAction, as_policy
from agents.predictive import PredictiveYielding
from agents.yielding import AlwaysCautious, YieldingPolicy
from crossing_common.imports import import_plugin_module
from scenarios.config import ScenarioConfig, TrafficConfig

ENTRY_POINT_GROUP = "crossing_env.policies"
"""Entry-point group under which installed packages publish policies (value: ``"pkg.module:attr"``)."""
WEIGHTS_DIR = Path(__file__).resolve().parent / "weights"
"""Where the shipped learned policies live (with ``manifest.json``, the sha256 of each file)."""
SHIPPED_POLICIES: dict[str, Path] = {
    "ppo_shielded": WEIGHTS_DIR / "ppo_shielded.npz",
    "ppo_lagrangian": WEIGHTS_DIR / "ppo_lagrangian.npz",
}
"""Learned policies shipped as data (`agents.mlp`; numpy only), trained by ``studies/safe_rl.py``: PPO acting
through the yielding shield, and PPO-Lagrangian (no rule in the loop)."""
SHIPPED_SUMMARIES: dict[str, str] = {
    "ppo_shielded": "Learned: PPO acting through the yielding shield, shipped as data",
    "ppo_lagrangian": "Learned: PPO-Lagrangian, no rule in the loop, shipped as data",
}
"""One line on each shipped learned policy (`crossing-eval --list`)."""
DEFAULT_LEARNED = "ppo_shielded"
"""The shipped learned policy in `crossing-eval`'s default table (the better of the two on the selection
episodes; ``docs/rl.md``)."""


@dataclass(frozen=True)
class PolicyEntry:
    """How to build a policy: a class taking `config` (built-in protocol) or a factory(scenario, dt)."""

    factory: Callable[..., Any]
    """The policy class (with `config`) or factory called as ``factory(scenario=..., dt=...)``."""
    config: type[DrivingConfig] | None = None
    """The class's config dataclass; None for a factory."""
    uses_predictors: bool | None = None
    """Whether it reads the prediction wrappers' keys; None: the factory's ``uses_predictors`` attribute."""


_REGISTRY: dict[str, PolicyEntry] = {
    "yielding": PolicyEntry(YieldingPolicy, YieldingConfig),
    "predictive_yielding": PolicyEntry(PredictiveYielding, PredictiveYieldingConfig),
    "constant_speed": PolicyEntry(ConstantSpeed, ConstantSpeedConfig),
    "ttc_brake": PolicyEntry(TTCEmergencyBrake, TTCBrakeConfig),
    "always_cautious": PolicyEntry(AlwaysCautious, CautiousConfig),
    "highway_rule": PolicyEntry(HighwayEnvRule, HighwayRuleConfig),
}
BUILTIN_POLICIES: tuple[str, ...] = tuple(_REGISTRY)
"""The rule-based policies (always available)."""
POLICIES: tuple[str, ...] = (*BUILTIN_POLICIES, DEFAULT_LEARNED)
"""The default table of `crossing-eval`: the rule-based policies and the default shipped learned policy."""
_REGISTRY["sampling_planner"] = PolicyEntry(SamplingPlanner, PlannerConfig)
"""The sampling planner (`agents.planner`): not in the default table yet."""
_REGISTRY["constant"] = PolicyEntry(ConstantAction, None, uses_predictors=False)
_REGISTRY.update(
    {
        "full_throttle": PolicyEntry(FullThrottle, AdversaryConfig),
        "crawl": PolicyEntry(Crawl, AdversaryConfig),
        "stop_far": PolicyEntry(StopFar, AdversaryConfig),
        "stop_near": PolicyEntry(StopNear, AdversaryConfig),
        "brake_late": PolicyEntry(BrakeLate, BrakeLateConfig),
        "stop_and_go": PolicyEntry(StopAndGo, AdversaryConfig),
    }
)
"""The adversary suite (`agents.adversaries.ADVERSARIES`, with ``random``): not in the table."""
_REGISTRY["random"] = PolicyEntry(RandomAction, None, uses_predictors=False)
"""Trivial ones for replays and smoke runs (action 0; uniform from the episode seed); not in the table."""


SHIPPED_MANIFEST = WEIGHTS_DIR / "manifest.json"
"""sha256 of each shipped policy file: a replaced or corrupted policy file is refused."""
_VERIFIED: set[str] = set()


class ShippedPolicyError(ValueError):
    """A shipped policy file is missing or differs from the manifest (the message names it)."""


def verify_shipped_policy_files() -> None:
    """Check every file listed in ``agents/weights/manifest.json`` against its sha256 (once per process).

    Raises:
        ShippedPolicyError: a file is missing or differs from the manifest (the message names it).
    """
    manifest = json.loads(SHIPPED_MANIFEST.read_text(encoding="utf-8"))
    for name, expected in manifest.items():
        if name in _VERIFIED:
            continue
        path = WEIGHTS_DIR / name
        if not path.is_file():
            raise ShippedPolicyError(f"{path}: shipped policy file is missing")
        actual = hashlib.sha256(path.read_bytes()).hexdigest()
        if actual != expected:
            raise ShippedPolicyError(
                f"{path}: sha256 {actual[:12]}... does not match the manifest's {expected[:12]}...;"
                " the shipped policy file was replaced or corrupted (restore it from the repository)"
            )
        _VERIFIED.add(name)


def _shipped(name: str) -> Callable[..., Policy]:
    def factory(scenario: ScenarioConfig | None = None, dt: float | None = None) -> Policy:
        verify_shipped_policy_files()
        return mlp_policy(SHIPPED_POLICIES[name], scenario, dt)

    factory.__doc__ = (
        f"{SHIPPED_SUMMARIES[name]} ({SHIPPED_POLICIES[name].name}, checked against the manifest)."
    )
    return factory


for _name in SHIPPED_POLICIES:
    _REGISTRY[_name] = PolicyEntry(_shipped(_name), None, uses_predictors=False)


def register_policy(
    name: str,
    factory: Callable[..., Any],
    config: type[DrivingConfig] | None = None,
    *,
    uses_predictors: bool | None = None,
    overwrite: bool = False,
) -> None:
    """Make `name` available to `make_policy` (and `crossing-eval --policies`) in this process.

    `factory` is a policy class built from `config` (a `DrivingConfig` subclass, like the built-ins) or,
    with `config=None`, a callable ``factory(scenario=ScenarioConfig, dt=float) -> policy``. Worker
    processes only know names registered at import time of a module they import: for `crossing-eval`
    with several workers or Ray, publish the policy as ``pkg.module:attr`` or as an entry point.

    Raises:
        ValueError: the name is taken (unless `overwrite`), malformed, or `factory` is not callable.
    """
    if not isinstance(name, str) or not name or ":" in name or "," in name:
        raise ValueError(f"register_policy: name must be a non-empty string without ':' or ',', got {name!r}")
    if not callable(factory):
        raise ValueError(f"register_policy({name!r}): factory must be callable, got {factory!r}")
    if name in _REGISTRY and not overwrite:
        raise ValueError(f"register_policy: {name!r} is already registered (pass overwrite=True to replace)")
    _REGISTRY[name] = PolicyEntry(factory, config, uses_predictors)


def installed_policies() -> dict[str, str]:
    """Installed plug-in policies: entry-point name → ``"pkg.module:attr"`` (nothing imported)."""
    return {ep.name: ep.value for ep in entry_points(group=ENTRY_POINT_GROUP)}


def policy_names() -> tuple[str, ...]:
    """Every name `make_policy` accepts now: registered ones, then installed entry points."""
    return tuple(dict.fromkeys([*_REGISTRY, *installed_policies()]))


def _import_attr(spec: str) -> Any:
    module, _, attr = spec.partition(":")
    if not module or not attr:
        raise ValueError(f"policy {spec!r}: expected 'pkg.module:attr'")
    try:
        obj: Any = import_plugin_module(module)
    except ImportError as exc:
        raise ValueError(f"policy {spec!r}: cannot import module {module!r} ({exc})") from None
    except Exception as exc:  # the plug-in's own import-time code raised: one line, not a traceback
        raise ValueError(
            f"policy {spec!r}: importing {module!r} raised {type(exc).__name__}: {exc}"
        ) from None
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise ValueError(f"policy {spec!r}: module {module!r} has no attribute {attr!r}")
        obj = getattr(obj, part)
    if not callable(obj):
        raise ValueError(f"policy {spec!r}: {attr!r} is not a class or factory")
    return obj


def _plugin_entry(obj: Any) -> PolicyEntry:
    cfg = getattr(obj, "config_class", None)
    if isinstance(obj, type) and isinstance(cfg, type) and issubclass(cfg, DrivingConfig):
        return PolicyEntry(obj, cfg)
    if not isinstance(obj, type) and _takes_observation(obj):
        return PolicyEntry(_itself(obj), None, uses_predictors=bool(getattr(obj, "uses_predictors", False)))
    return PolicyEntry(obj, None)


FACTORY_KEYWORDS = frozenset({"scenario", "dt"})
"""The keywords a plug-in factory may name (`_call_factory`)."""


def _takes_observation(obj: Any) -> bool:
    """Whether `obj` (a function or instance, not a class) is the policy itself: ``obj(obs) -> action``.

    It is when it requires a positional argument other than the factory keywords: ``def cruise(obs)``.
    A callable that requires nothing (or only ``scenario`` / ``dt``) is a factory, called to make one.
    """
    try:
        params = inspect.signature(obj).parameters.values()
    except (TypeError, ValueError):  # no signature to read: the documented factory protocol
        return False
    positional = (inspect.Parameter.POSITIONAL_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)
    return any(
        p.kind in positional and p.default is inspect.Parameter.empty and p.name not in FACTORY_KEYWORDS
        for p in params
    )


def _itself(policy: Callable[..., Any]) -> Callable[..., Any]:
    """A factory that hands back `policy` itself (a plain ``obs -> action`` function or policy object)."""

    def factory(scenario: ScenarioConfig | None = None, dt: float | None = None) -> Any:
        return policy

    return factory


def _file_entry(
    spec: str, example: str, build: Callable[..., Policy], uses_predictors: bool | None
) -> PolicyEntry:
    """The entry of a ``prefix:path`` spec (the file must exist); ``build(path, scenario, dt)`` makes it."""
    path = spec.partition(":")[2]
    if not path:
        raise ValueError(f"policy {spec!r}: expected {example!r}")
    if not Path(path).is_file():
        raise ValueError(f"policy {spec!r}: no such file {path!r}")

    def factory(scenario: ScenarioConfig | None = None, dt: float | None = None) -> Policy:
        return build(path, scenario, dt)

    return PolicyEntry(factory, None, uses_predictors)


def _sb3_policy(path: str, scenario: ScenarioConfig | None = None, dt: float | None = None) -> Policy:
    from agents.sb3 import SB3Policy

    return SB3Policy(path)


def mlp_policy(path: str | Path, scenario: ScenarioConfig | None = None, dt: float | None = None) -> Policy:
    """The numpy policy in `path` (`agents.mlp`), through the yielding shield if it was trained so."""
    from agents.mlp import MLPPolicy
    from agents.shield import ShieldedPolicy, YieldingShield

    learned = MLPPolicy(path)
    if not learned.weights.shielded:
        return learned
    cfg = YieldingConfig() if scenario is None else replace(YieldingConfig(), **scenario_settings(scenario))
    shield = YieldingShield(cfg if dt is None else replace(cfg, dt=float(dt)))
    w = learned.weights
    return ShieldedPolicy(learned, shield, w.residual_scale, w.residual_offset)


SHIELD_MAX_RESIDUAL = 2.0
"""m/s² per unit of residual of `shield_max_policy` (the shielded learner's ``--residual``)."""


def shield_max_policy(scenario: ScenarioConfig | None = None, dt: float | None = None) -> Policy:
    """The envelope-max reference (not learned): `yielding` + the full residual, through the shield.

    Every step asks for the rule's acceleration plus `SHIELD_MAX_RESIDUAL` and lets the shield clip it:
    the most the envelope allows. It is the shielded learner's starting point (``--residual-offset 1``,
    actor action 0), built the same way (spec ``agents.registry:shield_max_policy``).
    """
    from agents.shield import ShieldedPolicy, YieldingShield

    cfg = YieldingConfig() if scenario is None else replace(YieldingConfig(), **scenario_settings(scenario))
    shield = YieldingShield(cfg if dt is None else replace(cfg, dt=float(dt)))
    return ShieldedPolicy(ConstantAction(), shield, SHIELD_MAX_RESIDUAL, residual_offset=1.0)


def policy_entry(name: str) -> PolicyEntry:
    """The entry for a registered name, an entry point, ``pkg.module:attr`` or ``sb3:path``.

    Raises:
        ValueError: unknown name or a spec that cannot be loaded (the message says why and lists names).
    """
    if name in _REGISTRY:
        return _REGISTRY[name]
    if name.startswith("sb3:"):
        return _file_entry(name, "sb3:path/to/model.zip", _sb3_policy, None)
    if name.startswith("mlp:"):
        return _file_entry(name, "mlp:path/to/policy.npz", mlp_policy, False)
    eps = installed_policies()
    if name in eps:
        return _plugin_entry(_import_attr(eps[name]))
    if ":" in name:
        return _plugin_entry(_import_attr(name))
    raise ValueError(
        f"unknown policy {name!r}; choose from {', '.join(policy_names())},"
        " 'pkg.module:attr', 'sb3:model.zip' or 'mlp:policy.npz'"
    )


def blind_scenario(scenario: ScenarioConfig) -> ScenarioConfig:
    """What a policy is told of a scenario when evaluated blind: the road, the crossing and its own car.

    Kept: the road (lanes, speed limit), the crossing, the ego's limits and the cars' size, all that
    `scenario_settings` reads, so a built-in policy drives exactly as when told everything. Dropped: the
    name and description, the pedestrians, the background traffic, the conflict, the duration and the
    light, which a car on a real road is not told in advance. What it sees it reads from its observation.
    """
    traffic = replace(TrafficConfig(), length=scenario.traffic.length, width=scenario.traffic.width)
    return ScenarioConfig(
        name="",
        description="",
        road=scenario.road,
        crossing=scenario.crossing,
        ego=scenario.ego,
        traffic=traffic,
    )


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


def _call_factory(factory: Callable[..., Any], scenario: ScenarioConfig | None, dt: float | None) -> Any:
    """``factory(...)`` with the keywords among ``scenario`` and ``dt`` that it accepts (the rule above)."""
    offered = {"scenario": scenario, "dt": dt}
    try:
        params = inspect.signature(factory).parameters
    except (TypeError, ValueError):  # a builtin without a signature: the documented keywords
        return factory(**offered)
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values()):
        return factory(**offered)
    return factory(**{k: v for k, v in offered.items() if k in params})


def make_policy(
    name: str, scenario: ScenarioConfig | None = None, dt: float | None = None, **overrides: Any
) -> Policy:
    """Build a policy by name or plug-in spec (see the module docstring).

    `scenario` fills the road-dependent settings, `dt` the step time of policies with timers (ignored by
    the others), `overrides` any config field (config-class policies only).

    Raises:
        ValueError: unknown policy or config field (the message lists the allowed ones).
    """
    entry = policy_entry(name)
    if entry.config is None:
        if overrides:
            raise ValueError(f"policy {name!r} has no config class; overrides {sorted(overrides)} refused")
        return as_policy(_call_factory(entry.factory, scenario, dt))
    cfg_cls = entry.config
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
    return as_policy(entry.factory(cfg))


def policy_uses_predictors(name: str) -> bool:
    """Whether the evaluation should put the predictor wrappers on for this policy.

    For an SB3 model this is whether its observation space has the predictors' keys (it loads the model).
    """
    entry = policy_entry(name)
    if entry.uses_predictors is not None:
        return entry.uses_predictors
    if name.startswith("sb3:"):
        from agents.sb3 import SB3Policy

        return SB3Policy(name[len("sb3:") :]).uses_predictors
    return bool(getattr(entry.factory, "uses_predictors", False))
