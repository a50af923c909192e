"""Episodes to record: `rollout`'s env, wrappers, policy and frames, with the replay's errors.

Everything here goes through the `rollout` layer, as `crossing-eval` does, so a replayed or recorded episode
sees the same observations as in the evaluation. A policy that reads predictions gets `rollout`'s default
wrappers (QLB intention, S-CGRU paths) unless the caller names others; a wrapper that cannot be built is a
`ReplayError` (exit 2), never a silent switch to another predictor.
"""

from __future__ import annotations

import os

import gymnasium as gym

from agents import Policy
from agents import make_policy as agents_make_policy
from crossing_replay.errors import ReplayError
from rollout import INTENTION_WRAPPERS, NONE, Frame, WrapperError, build_policy, make_env, wrappers_for
from rollout import frames as run_episode
from scenarios import ScenarioError
from scenarios.config import EnvConfig, ScenarioConfig

__all__ = ["INTENTION_WRAPPERS", "Frame", "env_for_policy", "make_policy", "run_episode"]


def make_policy(name: str, seed: int | None = None, env: gym.Env | None = None) -> Policy:
    """The policy `name` (any `agents.make_policy` spec, ``constant`` and ``random`` too), reset with `seed`.

    Built for `env`'s road and step time when given; `rollout.frames` resets it again per episode.

    Raises:
        ReplayError: unknown policy or a spec that cannot be loaded.
    """
    try:
        policy = build_policy(name, env) if env is not None else agents_make_policy(name)
    except (LookupError, ValueError, OSError) as exc:
        raise ReplayError(f"--policy {name!r}: {exc}") from exc
    policy.reset(seed=seed)
    return policy


def env_for_policy(
    scenario: str | os.PathLike[str] | ScenarioConfig,
    policy: str,
    predictor: str | None = None,
    intention: str | None = None,
    config: EnvConfig | None = None,
    replaying: bool = False,
    render_mode: str | None = None,
) -> tuple[gym.Env, str | None, str | None]:
    """``(env, predictor, intention)`` to run `policy` in, with the wrappers really on (None: none).

    A wrapper left as None is `rollout`'s default for a policy that reads predictions, and none for one
    that does not or when `replaying` logged actions (nothing reads the predictions then but the viewer).

    Raises:
        ReplayError: unknown policy, or a wrapper that is unknown or cannot be built.
    """
    intention = NONE if intention == "" else intention  # the CLI's "none" arrives as ""
    predictor = NONE if predictor == "" else predictor
    try:
        if replaying:
            intention, predictor = intention or NONE, predictor or NONE
        else:
            intention, predictor = wrappers_for(policy, intention, predictor)
        env, _ = make_env(scenario, intention, predictor, config, render_mode)
    except WrapperError as exc:
        raise ReplayError(f"--intention/--predictor: {exc}") from exc
    except ScenarioError as exc:  # before ValueError: the scenario is the problem, not the policy
        raise ReplayError(f"--scenario: {exc}") from exc
    except ValueError as exc:  # an unknown policy spec
        raise ReplayError(f"--policy {policy!r}: {exc}") from exc
    return env, (None if predictor == NONE else predictor), (None if intention == NONE else intention)
