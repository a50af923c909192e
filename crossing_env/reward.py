"""The env's named reward terms, computed from the ground truth with `crossing-eval`'s own definitions.

Yield obligations, TTC and hard braking come from `crossing_env.safety.SafetyMonitor`, once per step: the
quantities are attached to the step's ground truth, and `EpisodeMetrics` reuses them, so the reward
penalises exactly what the evaluation counts and nothing is computed twice.
"""

from __future__ import annotations

from crossing_env.safety.results import DEFAULT_METRICS, MetricsConfig
from crossing_env.safety.step import SafetyMonitor
from crossing_env.safety.yielding import YieldTracker
from crossing_env.types import GroundTruth
from scenarios.config import RewardConfig, ScenarioConfig

REWARD_TERMS: tuple[str, ...] = (
    "progress",
    "time",
    "collision",
    "failing_to_yield",
    "near_miss",
    "hard_braking",
    "speeding",
)
"""Keys of `info['rewards']`, in a fixed order."""


class RewardTerms:
    """Per-episode reward state (the yield obligations seen so far) and the weighted terms of each step."""

    def __init__(
        self, scenario: ScenarioConfig, dt: float, weights: RewardConfig, metrics: MetricsConfig | None = None
    ) -> None:
        """Start an episode of `scenario` stepped every `dt` seconds."""
        self.scenario = scenario
        self.dt = float(dt)
        self.weights = weights
        self.metrics = metrics if metrics is not None else DEFAULT_METRICS
        self.safety = SafetyMonitor(scenario.crossing.kind, self.dt, self.metrics)
        """Computes the step's safety quantities and attaches them to the ground truth."""

    @property
    def yields(self) -> YieldTracker:
        """The episode's yield obligations."""
        return self.safety.yields

    def __call__(self, gt: GroundTruth, progress: float) -> dict[str, float]:
        """Weighted terms of one step; `progress` is the metres the ego moved along the road.

        Also attaches the step's safety quantities to `gt` (`GroundTruth.safety`).
        """
        w = self.weights
        s = self.safety(gt)
        over_limit = float(gt.ego_velocity[0]) - self.scenario.road.speed_limit
        return {
            "progress": w.progress * float(progress),
            "time": w.time * self.dt,
            "collision": w.collision if gt.collisions else 0.0,
            "failing_to_yield": w.failing_to_yield * s.yield_violations,
            "near_miss": w.near_miss * self.dt if s.min_ttc < self.metrics.serious_ttc else 0.0,
            "hard_braking": w.hard_braking if s.hard_braking else 0.0,
            "speeding": w.speeding * over_limit if over_limit > 0 else 0.0,
        }
