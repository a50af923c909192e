"""The safety quantities of one step, computed once and shared by the env's reward and `EpisodeMetrics`.

`SafetyMonitor` is the env's per-episode source: for each ground-truth snapshot it runs the yield
obligations (`YieldTracker`), the minimum ego–pedestrian TTC, the conflict-area test and the hard-braking
test, and attaches the resulting `StepSafety` to the snapshot (`GroundTruth.safety`). The reward reads
it; `EpisodeMetrics.update` reuses it when it was computed with the metric's own thresholds and from the
obligation state the metric holds, and computes everything itself otherwise (snapshots built by hand,
other thresholds, a metric started mid-episode). Both paths run the same functions, so the numbers agree
bit for bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from crossing_env.safety.results import DEFAULT_METRICS, MetricsConfig
from crossing_env.safety.yielding import (
    YieldState,
    YieldTracker,
    ego_in_conflict_area,
    is_hard_braking,
    min_pedestrian_ttc,
)
from crossing_env.types import GroundTruth

__all__ = ["COST_TERMS", "SafetyMonitor", "StepSafety", "min_pedestrian_separation", "step_costs"]

COST_TERMS: tuple[str, ...] = ("collision", "failing_to_yield", "near_miss")
"""Keys of `step_costs` (and of the env's ``info["costs"]``), in order; ``info["cost"]`` is their sum."""


def min_pedestrian_separation(gt: GroundTruth, half: np.ndarray, among: np.ndarray | None = None) -> float:
    """Minimum edge-to-edge distance from the ego box (half extents `half`) to any pedestrian disc (m).

    Negative when overlapping (minus the penetration depth); inf without pedestrians. `among`: a boolean
    mask of the pedestrians to consider (all when None).
    """
    if among is None:
        return _min_separation(gt.ego_position, half, gt.pedestrian_positions, gt.pedestrian_radii)
    return _min_separation(gt.ego_position, half, gt.pedestrian_positions[among], gt.pedestrian_radii[among])


def _min_separation(ego: np.ndarray, half: np.ndarray, positions: np.ndarray, radii: np.ndarray) -> float:
    if not positions.shape[0]:
        return math.inf
    d = np.abs(positions - ego) - half
    sep = np.hypot(np.maximum(d[:, 0], 0.0), np.maximum(d[:, 1], 0.0))
    sep += np.minimum(np.maximum(d[:, 0], d[:, 1]), 0.0) - radii
    return float(sep.min())


@dataclass(frozen=True, eq=False)
class StepSafety:
    """Safety quantities of one ground-truth snapshot (see the module docstring for who computes them)."""

    config: MetricsConfig
    """The thresholds used."""
    crossing_kind: str
    """The crossing kind the yield obligations were tracked for."""
    dt: float
    """The step length the yield obligations were tracked with (s)."""
    ego_in_conflict_area: bool
    """The ego's footprint overlaps the conflict area (`ego_in_conflict_area`)."""
    hard_braking: bool
    """The ego decelerates at least `MetricsConfig.hard_braking_threshold` (`is_hard_braking`)."""
    min_ttc: float
    """Minimum ego–pedestrian TTC (s); inf without pedestrians or while the ego stands still."""
    yield_violations: int
    """Yield obligations the ego violated in this step (`YieldTracker.update`)."""
    yield_before: YieldState
    """The obligations before this step."""
    yield_after: YieldState
    """The obligations after this step."""
    footprints: tuple[np.ndarray, tuple[float, float], np.ndarray, np.ndarray] = field(repr=False)
    """The snapshot's ego position and size, pedestrian positions and radii (for `min_separation`; the
    snapshot itself is not kept, as it refers to this object)."""

    @cached_property
    def min_separation(self) -> float:
        """Minimum ego–pedestrian footprint distance (m), computed on first use; inf without pedestrians."""
        ego, (length, width), positions, radii = self.footprints
        return _min_separation(ego, np.array([0.5 * length, 0.5 * width]), positions, radii)

    def usable_by(self, tracker: YieldTracker) -> bool:
        """Whether these quantities are what `tracker`'s owner would compute itself for this snapshot.

        True when the thresholds, crossing kind and step length match and the tracker holds exactly the
        obligation state this step started from.
        """
        return (
            self.yield_before is tracker.state
            and (self.config is tracker.config or self.config == tracker.config)
            and self.crossing_kind == tracker.kind
            and self.dt == tracker.dt
        )


class SafetyMonitor:
    """One episode's per-step safety quantities, for the env: call once per step with the new snapshot."""

    def __init__(self, crossing_kind: str, dt: float, config: MetricsConfig | None = None) -> None:
        """Start an episode at a crossing of `crossing_kind` stepped every `dt` seconds."""
        self.config = config if config is not None else DEFAULT_METRICS
        self.yields = YieldTracker(crossing_kind, dt, self.config)

    def __call__(self, gt: GroundTruth) -> StepSafety:
        """Compute the step's quantities, advance the obligations and attach the result to `gt`."""
        cfg = self.config
        tracker = self.yields
        before = tracker.state
        ego_in = ego_in_conflict_area(gt)
        violated = tracker.update(gt, ego_in)
        safety = StepSafety(
            config=cfg,
            crossing_kind=tracker.kind,
            dt=tracker.dt,
            ego_in_conflict_area=ego_in,
            hard_braking=is_hard_braking(gt, cfg),
            min_ttc=min_pedestrian_ttc(gt, cfg),
            yield_violations=violated,
            yield_before=before,
            yield_after=tracker.state,
            footprints=(gt.ego_position, gt.ego_size, gt.pedestrian_positions, gt.pedestrian_radii),
        )
        gt.attach_safety(safety)
        return safety


def step_costs(gt: GroundTruth, safety: StepSafety) -> dict[str, float]:
    """The step's unweighted safety indicators, for constrained RL (``info["cost"]`` is their sum).

    - ``collision``: 1.0 if an ego collision began in this step (``gt.collisions``), else 0.0;
    - ``failing_to_yield``: the number of yield obligations violated in this step
      (`StepSafety.yield_violations`, the steps `EpisodeResult.yield_violations` counts);
    - ``near_miss``: 1.0 if the minimum ego–pedestrian TTC is below `MetricsConfig.serious_ttc`, the steps
      `EpisodeResult.serious_conflict_time` adds up (÷ dt), else 0.0.

    The same quantities as the reward's ``collision``, ``failing_to_yield`` and ``near_miss`` terms, without
    their weights (and without the near miss's factor dt), so every term is 0 or a small count, never
    negative.
    """
    return {
        "collision": 1.0 if gt.collisions else 0.0,
        "failing_to_yield": float(safety.yield_violations),
        "near_miss": 1.0 if safety.min_ttc < safety.config.serious_ttc else 0.0,
    }
