"""What a driving policy is: the `Policy` protocol, the adapter for plain functions, and two trivial policies.

A policy maps one observation (the env's dict, possibly with the prediction wrappers' keys) to one action
(float32, shape (1,), in [-1, 1]) and reads nothing else: never the ground truth. Before every episode the
rollout calls ``policy.reset(seed=episode_seed)``, so a policy with memory (offer timers, a recurrent state,
a random generator) starts each episode from the same state whatever ran before it in the process; that is
what lets an evaluation worker reuse a policy and still give the same record as a fresh one.

A plain function ``obs -> action`` is not a `Policy`; `as_policy` adapts it explicitly (a no-op reset), so
nothing downstream ever guesses how to call an object.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np

from agents.view import ObsLike


@runtime_checkable
class Policy(Protocol):
    """A driving policy: ``policy(obs) -> action`` plus ``policy.reset(seed)`` at the start of each episode.

    Optional class attribute ``uses_predictors: bool`` (default False): the policy reads the keys the
    prediction wrappers add (``crossing_intention``, ``predicted_paths``), so the rollout puts them on.

    Optional attribute ``batched: bool`` (default False, see `policy_is_batched`): one call may take a batch
    of observations of different episodes (leading axis B), and each element gets the action it would get
    alone, bit for bit; memory is kept per batch position and nothing is drawn at random. The evaluation
    then steps several episodes of such a policy together (`rollout.run_episodes`).
    """

    def __call__(self, obs: ObsLike) -> np.ndarray:
        """The action for one observation: float32 of shape (1,) in [-1, 1]."""
        ...

    def reset(self, seed: int | None = None) -> None:
        """Forget everything from the previous episode; `seed` seeds any randomness of the policy."""
        ...


class FunctionPolicy:
    """A plain function ``obs -> action`` as a `Policy` (stateless: `reset` does nothing)."""

    uses_predictors: ClassVar[bool] = False

    def __init__(self, function: Callable[[ObsLike], Any]) -> None:
        self.function = function

    def __call__(self, obs: ObsLike) -> np.ndarray:
        """The function's action as float32 (at least 1-d; a batch keeps its shape)."""
        return np.atleast_1d(np.asarray(self.function(obs), dtype=np.float32))

    def reset(self, seed: int | None = None) -> None:
        """Nothing to forget."""


def policy_is_batched(policy: object) -> bool:
    """Whether `policy` declares ``batched = True``: it may act for several episodes in one call."""
    return getattr(policy, "batched", False) is True


def as_policy(obj: Any) -> Policy:
    """`obj` itself when it is a `Policy`, a `FunctionPolicy` around a plain callable.

    Raises:
        TypeError: `obj` is not callable (the message names its type).
    """
    if isinstance(obj, Policy):
        return obj
    if callable(obj):
        return FunctionPolicy(obj)
    raise TypeError(f"a policy must be callable as policy(obs) -> action; got {type(obj).__name__}")


class ConstantAction:
    """Action 0 every step ("hold speed" in the env's action scaling): the replay's default policy."""

    uses_predictors: ClassVar[bool] = False

    def __init__(self, scenario: object = None, dt: float | None = None) -> None:
        del scenario, dt  # the factory protocol of `agents.registry`; nothing depends on them

    def __call__(self, obs: ObsLike) -> np.ndarray:
        """Zero acceleration."""
        return np.zeros(1, dtype=np.float32)

    def reset(self, seed: int | None = None) -> None:
        """Stateless."""


class RandomAction:
    """Uniform actions in [-1, 1] from a generator reseeded with the episode's seed: a smoke-test policy."""

    uses_predictors: ClassVar[bool] = False

    def __init__(self, scenario: object = None, dt: float | None = None) -> None:
        del scenario, dt
        self._rng = np.random.default_rng(0)

    def __call__(self, obs: ObsLike) -> np.ndarray:
        """One uniform draw."""
        return self._rng.uniform(-1.0, 1.0, size=1).astype(np.float32)

    def reset(self, seed: int | None = None) -> None:
        """A fresh generator seeded with `seed` (the same episode seed gives the same actions)."""
        self._rng = np.random.default_rng(seed)
