"""The planner's proposals: longitudinal speed profiles, each tracking one target speed over the horizon.

As PDM-Closed's IDM proposals (target speeds 20 % to 100 % of the limit), but along the ego's lane only:
the car does not leave it for a pedestrian. A proposal is a target speed and the deceleration it may use;
`command` is the acceleration it asks for at a given speed. The scorer rolls each out (`agents.planner.
scorer`), where the legal stop and a pedestrian in the corridor ahead also brake it.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from agents.config import PlannerConfig


class Proposals(NamedTuple):
    """P proposals (one batch shares them; targets scale with the speed limit)."""

    target: np.ndarray
    """(P,) target speed (m/s)."""
    braking: np.ndarray
    """(P,) largest deceleration (m/s², > 0) the proposal uses to reach its target."""


def make_proposals(cfg: PlannerConfig) -> Proposals:
    """The comfortable proposals (`target_fractions` of the limit) and, optionally, the emergency stop."""
    fractions = np.asarray(cfg.target_fractions, dtype=np.float64)
    if fractions.ndim != 1 or fractions.size == 0 or (fractions < 0).any() or (fractions > 1).any():
        raise ValueError(f"target_fractions must be shares of the speed limit in [0, 1], got {fractions}")
    target = fractions * cfg.speed_limit
    braking = np.full(target.shape, cfg.comfortable_deceleration)
    if cfg.emergency_proposal:
        target = np.append(target, 0.0)
        braking = np.append(braking, cfg.ego.max_deceleration)
    return Proposals(target=target, braking=braking)


def command(speed: np.ndarray, proposals: Proposals, cfg: PlannerConfig) -> np.ndarray:
    """Acceleration (m/s²) each proposal asks for at `speed` (any shape ending in P, or broadcastable).

    The emergency stop brakes at its full rate at once; the others track their target proportionally
    (`speed_gain`), within [−braking, `go_acceleration`].
    """
    full = proposals.braking > cfg.comfortable_deceleration
    tracking = np.clip(cfg.speed_gain * (proposals.target - speed), -proposals.braking, cfg.go_acceleration)
    return np.where(full & (speed > 0.0), -proposals.braking, tracking)
