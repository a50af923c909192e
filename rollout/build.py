"""From a description of a run to the wrapped env and the policy: the one assembly every tool uses.

`RolloutSpec` names everything that decides what a policy sees (scenario, env overrides, intention and
trajectory wrappers, policy spec, render mode); `build` turns it into a `Rollout`. Wrappers default by the
policy: one that reads predictions (``uses_predictors``) gets `DEFAULT_INTENTION` and `DEFAULT_PREDICTOR`
unless the spec names others, any other policy gets none. A wrapper that cannot be built is a
`WrapperError`, whatever the tool.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym

import crossing_env  # registers the env id
from agents import Policy, blind_scenario, make_policy, policy_uses_predictors
from rollout.episode import Episode, run_episode
from rollout.wrappers import DEFAULT_INTENTION, DEFAULT_PREDICTOR, NONE, wrap
from scenarios.config import EnvConfig, ScenarioConfig

ScenarioLike = str | os.PathLike[str] | ScenarioConfig


@dataclass(frozen=True)
class RolloutSpec:
    """Everything that decides what the policy sees and does (not the seed: one spec, many episodes)."""

    scenario: ScenarioLike = "default"
    """Built-in scenario name, scenario file, or a `ScenarioConfig`."""
    policy: str = "constant"
    """Policy spec for `agents.make_policy`: a name, ``pkg.module:attr``, an entry point or ``sb3:path``."""
    intention: str | None = None
    """Intention wrapper name (`rollout.wrappers.INTENTION_WRAPPERS` or ``none``); None: by the policy."""
    predictor: str | None = None
    """Trajectory predictor name or checkpoint path (or ``none``); None: by the policy."""
    config: EnvConfig | None = None
    """Env overrides (step time, horizon, observation sizes); None: the defaults."""
    render_mode: str | None = None
    """Gymnasium render mode (``rgb_array`` for videos); None: no rendering."""
    policy_overrides: dict[str, Any] = field(default_factory=dict)
    """Config fields of a config-class policy (e.g. ``{"min_gap": 8.0}``)."""


@dataclass
class Rollout:
    """A built run: the wrapped env, the policy, and the wrappers actually on."""

    env: gym.Env
    """`crossing_env/Crossing-v0` under the prediction wrappers."""
    policy: Policy
    """The policy (reset by `rollout.episode.run_episode` before every episode)."""
    intention: str
    """Intention wrapper name on (``none`` if none)."""
    predictor: str
    """Trajectory predictor on (``none`` if none)."""
    wrappers: list[str]
    """Labels of the wrappers on, e.g. ``["intention:qlb", "trajectory:s-cgru"]``."""


def wrappers_for(policy: str, intention: str | None, predictor: str | None) -> tuple[str, str]:
    """(intention, predictor) for `policy`: the names given, else the defaults for a predicting policy."""
    uses = policy_uses_predictors(policy)
    if intention is None:
        intention = DEFAULT_INTENTION if uses else NONE
    if predictor is None:
        predictor = DEFAULT_PREDICTOR if uses else NONE
    return intention, predictor


def make_env(
    scenario: ScenarioLike,
    intention: str = NONE,
    predictor: str = NONE,
    config: EnvConfig | None = None,
    render_mode: str | None = None,
) -> tuple[gym.Env, list[str]]:
    """``gym.make(crossing_env.ENV_ID, ...)`` under the named wrappers, and their labels.

    Raises:
        WrapperError: a wrapper that is unknown or cannot be built (the env is closed first).
        scenarios.ScenarioError: a scenario that cannot be loaded.
    """
    kwargs: dict[str, Any] = {"scenario": scenario}
    if config is not None:
        kwargs["config"] = config
    if render_mode is not None:
        kwargs["render_mode"] = render_mode
    return wrap(gym.make(crossing_env.ENV_ID, **kwargs), intention, predictor)


def build_policy(spec: str, env: gym.Env, *, blind: bool = False, **overrides: Any) -> Policy:
    """`agents.make_policy` for the scenario and step time of `env` (its road, limits and timers).

    `blind`: tell the policy only the road, the crossing and its car (`agents.blind_scenario`), not the
    scenario's name, pedestrians or conflict; `crossing-eval` evaluates blind unless told otherwise.
    """
    base = env.unwrapped
    scenario = blind_scenario(base.scenario) if blind else base.scenario
    return make_policy(spec, scenario=scenario, dt=base.config.dt, **overrides)


def build(spec: RolloutSpec) -> Rollout:
    """The wrapped env and the policy of `spec` (close ``rollout.env`` when done).

    Raises:
        WrapperError: a wrapper that cannot be built; ValueError: an unknown policy or override.
    """
    intention, predictor = wrappers_for(spec.policy, spec.intention, spec.predictor)
    env, used = make_env(spec.scenario, intention, predictor, spec.config, spec.render_mode)
    try:
        policy = build_policy(spec.policy, env, **spec.policy_overrides)
    except BaseException:
        env.close()
        raise
    return Rollout(env, policy, intention, predictor, used)


def run_spec(spec: RolloutSpec, seed: int, max_steps: int | None = None) -> Episode:
    """Build `spec`, run one episode of it from `seed` and close the env: a one-off rollout (fingerprints)."""
    run = build(spec)
    try:
        return run_episode(run.env, seed, policy=run.policy, max_steps=max_steps)
    finally:
        run.env.close()
