"""Ground-truth safety measures shared by the env's reward and the evaluator.

Surrogate-safety geometry (TTC, DRAC, separation, occupancy) and the per-episode accumulator of TTC, PET,
braking, yield compliance and delay. The quantities both need every step (yield obligations, TTC, the
conflict-area and braking tests, separation) are computed once by the env (`SafetyMonitor`) and attached
to the step's ground truth as a `StepSafety`, which `EpisodeMetrics` reuses.
"""

from crossing_env.safety.episode import EpisodeMetrics
from crossing_env.safety.geometry import (
    box_box_separation,
    box_circle_separation,
    box_circle_ttc,
    crossing_drac,
    following_drac,
    following_ttc,
    rect_occupancy_interval,
    time_to_collision,
)
from crossing_env.safety.results import DEFAULT_METRICS, EpisodeResult, MetricsConfig, json_safe
from crossing_env.safety.step import COST_TERMS, SafetyMonitor, StepSafety, step_costs
from crossing_env.safety.yielding import (
    YieldTracker,
    ego_in_conflict_area,
    is_hard_braking,
    min_pedestrian_ttc,
    obligation_candidates,
)

__all__ = [
    "COST_TERMS",
    "DEFAULT_METRICS",
    "EpisodeMetrics",
    "EpisodeResult",
    "MetricsConfig",
    "SafetyMonitor",
    "StepSafety",
    "YieldTracker",
    "box_box_separation",
    "box_circle_separation",
    "box_circle_ttc",
    "crossing_drac",
    "ego_in_conflict_area",
    "following_drac",
    "following_ttc",
    "is_hard_braking",
    "json_safe",
    "min_pedestrian_ttc",
    "obligation_candidates",
    "rect_occupancy_interval",
    "step_costs",
    "time_to_collision",
]
