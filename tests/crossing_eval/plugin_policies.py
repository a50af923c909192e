"""A user's policy module, as `crossing-eval --policies tests.crossing_eval.plugin_policies:...` finds it."""

from __future__ import annotations

import sys
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from agents import DrivingConfig


def cruise(obs):
    """A plain function: the policy itself (``obs -> action``), as the README describes."""
    return np.full(1, 0.25, dtype=np.float32)


def cruise_at(obs, gain=2.0):
    """A plain function with an optional argument of its own: still the policy itself."""
    return np.full(1, 0.25 * gain, dtype=np.float32)


def gentle_brake(scenario=None, dt=None):
    """A factory: a policy that always brakes gently (an obviously different row from the built-ins)."""

    def policy(obs):
        return np.full((*np.shape(obs["ego"])[:-1], 1), -0.2, dtype=np.float32)

    return policy


@dataclass(frozen=True)
class CoastConfig(DrivingConfig):
    """Config of `Coast` (the built-ins' protocol: a config dataclass filled from the scenario)."""

    throttle: float = 0.1
    """Constant action."""


class Coast:
    """A policy class with the built-ins' protocol: `Coast(config)`, `config_class`, `uses_predictors`."""

    config_class: ClassVar[type] = CoastConfig
    uses_predictors: ClassVar[bool] = False

    def __init__(self, config: CoastConfig) -> None:
        self.config = config

    def __call__(self, obs):
        return np.full((*np.shape(obs["ego"])[:-1], 1), self.config.throttle, dtype=np.float32)


class Fixed:
    """A policy class with a no-argument constructor (no config, no scenario): built as ``Fixed()``."""

    def __init__(self) -> None:
        self.action = np.full(1, 0.05, dtype=np.float32)

    def __call__(self, obs):
        return self.action

    def reset(self, seed=None):
        """Stateless."""


class NeedsThings:
    """A plug-in whose constructor cannot be called by `make_policy`: it fails in the parent, exit 2."""

    def __init__(self, weights_file) -> None:
        self.weights_file = weights_file

    def __call__(self, obs):
        return np.zeros(1, np.float32)


def knows_where(scenario=None, dt=None):
    """A factory that games the table if it can: it stands still in `zebra_case1` alone, else holds speed."""
    told = scenario is not None and scenario.name == "zebra_case1"

    def policy(obs):
        return np.full((*np.shape(obs["ego"])[:-1], 1), -1.0 if told else 0.0, dtype=np.float32)

    return policy


class _Trouble:
    """A plug-in that drives at constant speed until it misbehaves (the subclasses say how)."""

    def __init__(self, scenario=None, dt=None) -> None:
        self.calls = 0

    def reset(self, seed=None) -> None:
        self.calls = 0

    def __call__(self, obs):
        self.calls += 1
        return np.zeros(1, np.float32)


class ExitsLater(_Trouble):
    """Calls sys.exit(3) at its 20th action (after the preflight's one)."""

    def __call__(self, obs):
        if self.calls >= 19:
            sys.exit(3)
        return super().__call__(obs)


class RaisesInReset(_Trouble):
    """Its reset raises."""

    def reset(self, seed=None) -> None:
        raise KeyError("episode_state")


class ResetWithoutSeed(_Trouble):
    """Its reset takes no seed."""

    def reset(self) -> None:  # type: ignore[override]
        self.calls = 0


class ReturnsNaN(_Trouble):
    """Its action is NaN."""

    def __call__(self, obs):
        return np.array([np.nan], np.float32)


class ReturnsText(_Trouble):
    """Its action is the string "0.5"."""

    def __call__(self, obs):
        return "0.5"


class ExitsInInit(_Trouble):
    """Calls sys.exit() while being built."""

    def __init__(self, scenario=None, dt=None) -> None:
        sys.exit("no GPU")
