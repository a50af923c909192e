"""Adversaries: lazy or reckless drivers that a benchmark's score must rank below a careful one.

Each is a registered policy (`agents.make_policy`), so `crossing-eval --policies full_throttle,...` runs
them; `benchmarks/adversaries.py` shows each one's score beside `yielding`'s per scenario. Every way of
looking good on one column while driving badly gets a driver here: speed (`full_throttle`), never arriving
(`crawl`, `stop_far`, `stop_near`), braking only at the last moment (`brake_late`), a token stop
(`stop_and_go`) and noise (`random`, in `agents.policy`). They read only the observation, like every policy.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from agents.baselines import TTCEmergencyBrake
from agents.config import AdversaryConfig, BrakeLateConfig
from agents.view import ObsLike, View, cruise, finish, follow, parse_observation, stop_acceleration

ADVERSARIES: tuple[str, ...] = (
    "full_throttle",
    "crawl",
    "stop_far",
    "stop_near",
    "brake_late",
    "stop_and_go",
    "random",
)
"""The shipped adversary suite, by registered name."""


class _Adversary:
    """Shared plumbing: a config, no predictors, one call acts for a batch of episodes."""

    uses_predictors: ClassVar[bool] = False
    batched: ClassVar[bool] = True
    """Acts for a batch of episodes in one call, each element as alone (`agents.policy_is_batched`)."""

    def __init__(self, config: AdversaryConfig | None = None) -> None:
        self.config = config or AdversaryConfig()

    def reset(self, seed: int | None = None) -> None:
        """Stateless: nothing to forget between episodes (`agents.Policy.reset`)."""

    def __call__(self, obs: ObsLike) -> np.ndarray:
        """The normalised action for every observation in the batch."""
        view = parse_observation(obs)
        return finish(self._accel(view), view, self.config)

    def _accel(self, view: View) -> np.ndarray:
        raise NotImplementedError

    def _stop_at(self, view: View, distance: np.ndarray) -> np.ndarray:
        """Come to rest `distance` ahead (0 or less: as hard as the car can) and stay there."""
        cfg = self.config
        a = stop_acceleration(
            view, np.maximum(distance, 0.0), cfg.stop_deceleration, cfg.stop_gain, cfg.ego.max_deceleration
        )
        return np.minimum(np.minimum(cruise(view, cfg), follow(view, cfg)), a)


class FullThrottle(_Adversary):
    """Full throttle from start to end: fast past every crossing, over the limit, never brakes."""

    name: ClassVar[str] = "full_throttle"

    def _accel(self, view: View) -> np.ndarray:
        return np.full(view.speed.shape, self.config.ego.max_acceleration)


class Crawl(_Adversary):
    """Drives the whole road at a walking pace (`crawl_speed`): no conflict ever, and barely any progress."""

    name: ClassVar[str] = "crawl"

    def _accel(self, view: View) -> np.ndarray:
        cfg = self.config
        return np.minimum(cruise(view, cfg, cfg.crawl_speed), follow(view, cfg))


class StopFar(_Adversary):
    """Stops `far_stop_distance` before the stop line and waits there for good: perfect margins, no trip."""

    name: ClassVar[str] = "stop_far"

    def _accel(self, view: View) -> np.ndarray:
        return self._stop_at(view, view.to_stop - self.config.far_stop_distance)


class StopNear(_Adversary):
    """Stops at the stop line and waits there for good, whether anyone crosses or not."""

    name: ClassVar[str] = "stop_near"

    def _accel(self, view: View) -> np.ndarray:
        return self._stop_at(view, view.to_stop)


class BrakeLate(TTCEmergencyBrake):
    """Holds its speed and brakes fully only while the TTC to a pedestrian is under 1 s: no yielding."""

    name: ClassVar[str] = "brake_late"

    def __init__(self, config: BrakeLateConfig | None = None) -> None:
        super().__init__(config or BrakeLateConfig())

    def __call__(self, obs: ObsLike) -> np.ndarray:
        """Full braking if TTC < threshold, else hold the speed (follow vehicles ahead)."""
        view = parse_observation(obs)
        cfg = self.config
        a = np.minimum(np.zeros_like(view.speed), follow(view, cfg))
        a = np.where(self._ttc(view) < cfg.ttc_threshold, -cfg.ego.max_deceleration, a)
        return finish(a, view, cfg)


class StopAndGo(_Adversary):
    """A token stop: halts at the stop line for `stop_time`, then drives on at the limit whoever is there."""

    name: ClassVar[str] = "stop_and_go"

    def __init__(self, config: AdversaryConfig | None = None) -> None:
        super().__init__(config)
        self._stood = np.zeros(0)

    def reset(self, seed: int | None = None) -> None:
        """Forget the stop: the next episode stops again."""
        self._stood = np.zeros(0)

    def _accel(self, view: View) -> np.ndarray:
        cfg = self.config
        if self._stood.shape != view.speed.shape:
            self._stood = np.zeros(view.speed.shape)
        going = self._stood >= cfg.stop_time
        stopped = view.speed < 0.1
        self._stood = np.where(stopped | going, self._stood + cfg.dt, self._stood)
        before_line = view.past < 0.0
        go = np.minimum(cruise(view, cfg), follow(view, cfg))
        return np.where(going | ~before_line, go, self._stop_at(view, view.to_stop))
