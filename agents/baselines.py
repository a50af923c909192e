"""Baseline driving policies: constant speed, a TTC-triggered emergency brake and highway-env's rule.

Every policy reads only the observation and returns the normalised action of `CrossingEnv` (−1 full braking …
+1 full throttle). All but `ConstantSpeed` follow vehicles ahead with the Intelligent Driver Model, so that
they differ only in how they treat pedestrians.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from agents.config import ConstantSpeedConfig, HighwayRuleConfig, TTCBrakeConfig
from agents.view import (
    EPS,
    ObsLike,
    View,
    corridor_interval,
    cruise,
    finish,
    follow,
    parse_observation,
)


class ConstantSpeed:
    """Holds its current speed: never yields, never brakes (the worst-case baseline).

    Args:
        config: only `ego` (the action scaling) matters.
    """

    name: ClassVar[str] = "constant_speed"
    uses_predictors: ClassVar[bool] = False
    batched: ClassVar[bool] = True
    """Acts for a batch of episodes in one call, each element as alone (`agents.policy_is_batched`)."""

    def __init__(self, config: ConstantSpeedConfig | None = None) -> None:
        self.config = config or ConstantSpeedConfig()

    def reset(self, seed: int | None = None) -> None:
        """Stateless: nothing to forget between episodes (`agents.Policy.reset`)."""

    def __call__(self, obs: ObsLike) -> np.ndarray:
        """Action 0 ("hold speed") for every observation in the batch."""
        view = parse_observation(obs)
        return finish(np.zeros_like(view.speed), view, self.config)


class TTCEmergencyBrake:
    """Cruises at the speed limit and brakes fully when the TTC to any pedestrian drops below a threshold.

    TTC: constant velocities for both; the pedestrian (disc) must be inside the ego's corridor
    (half the ego width + radius + margin) while the ego's footprint spans its x; the first instant of that
    overlap is the TTC. A reactive AEB-like baseline: no anticipation, no legal yielding.
    """

    name: ClassVar[str] = "ttc_brake"
    uses_predictors: ClassVar[bool] = False
    batched: ClassVar[bool] = True
    """Acts for a batch of episodes in one call, each element as alone (`agents.policy_is_batched`)."""

    def __init__(self, config: TTCBrakeConfig | None = None) -> None:
        self.config = config or TTCBrakeConfig()

    def ttc(self, obs: ObsLike) -> np.ndarray:
        """(B,) smallest pedestrian TTC under constant velocities (inf when none)."""
        return self._ttc(parse_observation(obs))

    def _ttc(self, view: View) -> np.ndarray:
        cfg = self.config
        front = cfg.ego_length / 2
        r = cfg.pedestrian_radius
        hw = cfg.ego_width / 2 + r + cfg.lateral_margin
        t_in, t_out = corridor_interval(view.py, view.vy, hw)
        rel_v = view.speed[:, None] - view.vx  # closing speed along x
        with np.errstate(divide="ignore", invalid="ignore"):
            gap_front = view.px - r - front
            gap_rear = view.px + r + front
            t_arr = np.where(gap_front <= 0.0, 0.0, np.where(rel_v > EPS, gap_front / rel_v, np.inf))
            t_clr = np.where(gap_rear <= 0.0, -np.inf, np.where(rel_v > EPS, gap_rear / rel_v, np.inf))
        start = np.maximum(t_arr, t_in)
        end = np.minimum(t_clr, t_out)
        ttc = np.where(view.present & (start <= end) & (view.speed[:, None] > 5e-3), start, np.inf)
        return ttc.min(axis=1, initial=np.inf)

    def reset(self, seed: int | None = None) -> None:
        """Stateless: nothing to forget between episodes (`agents.Policy.reset`)."""

    def __call__(self, obs: ObsLike) -> np.ndarray:
        """Full braking if TTC < threshold, else cruise / follow."""
        view = parse_observation(obs)
        cfg = self.config
        a = np.minimum(cruise(view, cfg), follow(view, cfg))
        a = np.where(self._ttc(view) < cfg.ttc_threshold, -cfg.ego.max_deceleration, a)
        return finish(a, view, cfg)


class HighwayEnvRule:
    """highway-env's priority rule, applied to pedestrians: yield when a collision is predicted within 2 s.

    Like `highway_env.road.regulation.RegulatedRoad.respect_priorities` /
    `is_conflict_possible`, ego and pedestrians are propagated with constant speed in `step` increments up
    to `horizon`; if the ego's box (grown by `lateral_margin`) overlaps a pedestrian disc at any sample, the
    car yields: target speed 0 tracked with highway-env's speed gain (KP_A = 1/0.6), clipped to the maximum
    deceleration. Departure: highway-env compares vehicle pairs by lane priority; here pedestrians always
    have priority once a collision is predicted, and no stop line is targeted.
    """

    name: ClassVar[str] = "highway_rule"
    uses_predictors: ClassVar[bool] = False
    batched: ClassVar[bool] = True
    """Acts for a batch of episodes in one call, each element as alone (`agents.policy_is_batched`)."""

    def __init__(self, config: HighwayRuleConfig | None = None) -> None:
        self.config = config or HighwayRuleConfig()

    def _predicted_collision(self, view: View) -> np.ndarray:
        cfg = self.config
        t = np.arange(0.0, cfg.horizon + 1e-9, cfg.step)  # (T,)
        ex = view.speed[:, None] * t  # (B, T) ego centre x
        px = view.px[..., None] + view.vx[..., None] * t  # (B, K, T)
        py = view.py[..., None] + view.vy[..., None] * t
        hx = cfg.ego_length / 2 + cfg.lateral_margin
        hy = cfg.ego_width / 2 + cfg.lateral_margin
        qx = np.maximum(np.abs(px - ex[:, None, :]) - hx, 0.0)
        qy = np.maximum(np.abs(py) - hy, 0.0)
        hit = (qx * qx + qy * qy <= cfg.pedestrian_radius**2) & view.present[..., None]
        return hit.any(axis=(1, 2))

    def reset(self, seed: int | None = None) -> None:
        """Stateless: nothing to forget between episodes (`agents.Policy.reset`)."""

    def __call__(self, obs: ObsLike) -> np.ndarray:
        """Yield (target speed 0) if a collision is predicted, else cruise / follow."""
        view = parse_observation(obs)
        cfg = self.config
        a = np.minimum(cruise(view, cfg), follow(view, cfg))
        brake = np.maximum(-cfg.brake_gain * view.speed, -cfg.ego.max_deceleration)
        a = np.where(self._predicted_collision(view), np.minimum(a, brake), a)
        return finish(a, view, cfg)
