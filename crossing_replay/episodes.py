"""Episodes to record: the env with its predictor wrappers, the policy by name, and the frames of a run.

Policies come from ``agents.make_policy`` when it knows the name, else the built-ins ``constant`` and
``random``; a policy that reads predictions gets the best available predictor wrappers unless the caller
names them.
"""

from __future__ import annotations

import inspect
import os
import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

import crossing_env  # registers the env
from agents import make_policy as agents_make_policy
from agents import policy_uses_predictors
from crossing_env.types import GroundTruth
from crossing_replay.errors import ReplayError
from predictors import intention as intention_module
from scenarios.config import EnvConfig, ScenarioConfig

BUILTIN_POLICIES: tuple[str, ...] = ("constant", "random")

INTENTION_WRAPPERS: dict[str, str] = {"qlb": "QLBIntention", "classical": "ClassicalIntention"}
"""``--intention`` names → wrappers in ``predictors.intention`` that add ``crossing_intention``."""

Policy = Callable[[dict[str, np.ndarray]], np.ndarray]


# ---------------------------------------------------------------------------------------------------------
# Policies
# ---------------------------------------------------------------------------------------------------------


def _builtin_policy(name: str, seed: int) -> Policy:
    if name == "constant":
        return lambda obs: np.zeros(1, dtype=np.float32)
    rng = np.random.default_rng(seed)
    return lambda obs: rng.uniform(-1.0, 1.0, size=1).astype(np.float32)


def _adapt_policy(obj: Any, seed: int) -> Policy:
    """Wrap whatever `agents.make_policy` returned into ``obs -> action``."""
    reset = getattr(obj, "reset", None)
    if callable(reset):
        try:
            reset(seed=seed)
        except TypeError:
            reset()
    if callable(getattr(obj, "act", None)):
        return lambda obs: np.asarray(obj.act(obs), dtype=np.float32).reshape(1)
    if callable(getattr(obj, "predict", None)):  # Stable-Baselines3 models
        return lambda obs: np.asarray(obj.predict(obs, deterministic=True)[0], dtype=np.float32).reshape(1)
    if callable(obj):
        return lambda obs: np.asarray(obj(obs), dtype=np.float32).reshape(1)
    raise ReplayError(f"policy object {obj!r} has no act(), predict() or __call__")


def make_policy(name: str, seed: int, env: Any = None) -> Policy:
    """A policy by name: through ``agents.make_policy`` when it knows the name, else the built-ins.

    The built-ins are ``constant`` (action 0: hold speed) and ``random`` (uniform in [−1, 1] from a
    generator seeded with `seed`). ``agents.make_policy`` is offered only the arguments its signature names.
    """
    offer: dict[str, Any] = {"env": env, "seed": seed, "rng": np.random.default_rng(seed)}
    if env is not None:
        offer["scenario"] = env.unwrapped.scenario
        offer["dt"] = env.unwrapped.config.dt
    params = inspect.signature(agents_make_policy).parameters
    named = {k for k, p in params.items() if p.kind not in (p.VAR_KEYWORD, p.VAR_POSITIONAL)}
    kwargs = {k: v for k, v in offer.items() if k in named}
    try:
        return _adapt_policy(agents_make_policy(name, **kwargs), seed)
    except (KeyError, LookupError, ValueError) as exc:
        if name not in BUILTIN_POLICIES:
            raise ReplayError(f"--policy {name!r}: {exc}") from exc
    return _builtin_policy(name, seed)


def _policy_uses_predictors(name: str) -> bool:
    """Whether an ``agents`` policy reads ``predicted_paths`` / ``crossing_intention`` (False if unknown)."""
    try:
        return bool(policy_uses_predictors(name))
    except (KeyError, ValueError):
        return False


# ---------------------------------------------------------------------------------------------------------
# Envs
# ---------------------------------------------------------------------------------------------------------


def _wrap_intention(env: Any, intention: str) -> Any:
    """`env` under the ``predictors.intention`` wrapper named by ``--intention`` (or the oracle)."""
    if intention == "oracle":  # a crossing-eval log of the value-of-prediction grid's upper bound
        from predictors.oracle import OracleIntention

        return OracleIntention(env)
    if intention not in INTENTION_WRAPPERS:
        raise ReplayError(f"--intention {intention!r}: allowed {', '.join(INTENTION_WRAPPERS)}")
    cls = getattr(intention_module, INTENTION_WRAPPERS[intention], None)
    if cls is None:
        raise ReplayError(
            f"--intention {intention!r}: predictors.intention has no {INTENTION_WRAPPERS[intention]}"
        )
    return cls(env)


def _wrap_predictor(env: Any, predictor: str) -> Any:
    """`env` under the trajectory-prediction wrapper for model `predictor` (``oracle``: privileged paths)."""
    if predictor == "oracle":
        from predictors.oracle import OracleTrajectory

        return OracleTrajectory(env)
    # Lazy: predictors.trajectory_wrapper imports torch, which `import crossing_replay` must not pay for.
    try:
        from predictors.trajectory_wrapper import TrajectoryPrediction
    except ImportError as exc:
        raise ReplayError(f"--predictor {predictor!r}: predictors unavailable ({exc})") from exc
    try:
        return TrajectoryPrediction(env, model=predictor)
    except (OSError, ValueError, RuntimeError) as exc:
        raise ReplayError(f"--predictor {predictor!r}: {exc}") from exc


def make_env(
    scenario: str | os.PathLike[str] | ScenarioConfig,
    predictor: str | None = None,
    config: EnvConfig | None = None,
    intention: str | None = None,
) -> Any:
    """``gym.make("crossing_env/Crossing-v0", ...)`` with the requested predictor wrappers.

    The intention wrapper goes on first and the trajectory predictor second, as in ``crossing-eval``, so
    a policy sees the same observations as in the evaluation.
    """
    kwargs: dict[str, Any] = {"scenario": scenario}
    if config is not None:
        kwargs["config"] = config
    env = gym.make(crossing_env.ENV_ID, **kwargs)
    try:
        if intention:
            env = _wrap_intention(env, intention)
        if predictor:
            env = _wrap_predictor(env, predictor)
    except BaseException:
        env.close()
        raise
    return env


def _auto_env(
    scenario: str | os.PathLike[str] | ScenarioConfig, config: EnvConfig | None
) -> tuple[Any, str | None, str | None]:
    """Env for a predictor-using policy when no wrapper was asked for: the best available combination."""
    notes = []
    for predictor, intention in (
        ("s-cgru", "qlb"),
        ("cvm", "qlb"),
        ("s-cgru", None),
        ("cvm", None),
        (None, None),
    ):
        try:
            env = make_env(scenario, predictor, config, intention)
        except ReplayError as exc:
            notes.append(str(exc))
            continue
        print(
            f"crossing-replay: the policy uses predictors: predictor={predictor}, intention={intention}"
            + (f" (skipped: {'; '.join(notes)})" if notes else ""),
            file=sys.stderr,
        )
        return env, predictor, intention
    raise AssertionError("unreachable: the bare env always builds")


def env_for_policy(
    scenario: str | os.PathLike[str] | ScenarioConfig,
    policy: str,
    predictor: str | None = None,
    intention: str | None = None,
    config: EnvConfig | None = None,
    replaying: bool = False,
) -> tuple[Any, str | None, str | None]:
    """``(env, predictor, intention)`` to run `policy` in, with the wrappers really used.

    When the policy itself acts (not `replaying` logged actions) and reads predictions, and no wrapper was
    asked for, it gets the best available ones (S-CGRU, else constant velocity; QLB intention if present).
    """
    if not replaying and predictor is None and intention is None and _policy_uses_predictors(policy):
        return _auto_env(scenario, config)
    return make_env(scenario, predictor, config, intention), predictor, intention


# ---------------------------------------------------------------------------------------------------------
# Running an episode
# ---------------------------------------------------------------------------------------------------------


@dataclass
class Frame:
    """One logged frame of an episode."""

    step: int
    """Frame index (0 = after reset)."""
    observation: dict[str, np.ndarray]
    """The observation the policy saw."""
    ground_truth: GroundTruth
    """The world's true state."""
    slot_ids: np.ndarray
    """(K,) pedestrian id shown in each observation slot (−1 = empty), for predictions and intentions."""
    action: np.ndarray | None
    """Action that produced this frame (None for frame 0)."""


def _slot_ids(env: Any) -> np.ndarray:
    base = env.unwrapped
    observer = getattr(base, "_observer", None)
    slots = getattr(observer, "last_slots", None)
    if slots is None or base.world is None:
        return np.zeros(0, dtype=np.int64)
    ids = base.world.pedestrians.ids
    return np.where(slots >= 0, ids[np.maximum(slots, 0)], -1).astype(np.int64)


def run_episode(
    env: Any,
    seed: int,
    policy: Policy | None = None,
    actions: np.ndarray | None = None,
    max_steps: int | None = None,
) -> Iterator[Frame]:
    """Reset with `seed` and step with `policy` (or the given `actions`), yielding every frame.

    Stops at termination, truncation, `max_steps`, or the end of `actions`.
    """
    if (policy is None) == (actions is None):
        raise ValueError("run_episode needs exactly one of policy and actions")
    obs, info = env.reset(seed=seed)
    yield Frame(0, obs, info["ground_truth"], _slot_ids(env), None)
    limit = len(actions) if actions is not None else (max_steps if max_steps is not None else sys.maxsize)
    if max_steps is not None:
        limit = min(limit, max_steps)
    step = 0
    while step < limit:
        action = actions[step] if actions is not None else policy(obs)  # type: ignore[misc]
        action = np.asarray(action, dtype=np.float32).reshape(1)
        obs, _, terminated, truncated, info = env.step(action)
        step += 1
        yield Frame(step, obs, info["ground_truth"], _slot_ids(env), action)
        if terminated or truncated:
            break
