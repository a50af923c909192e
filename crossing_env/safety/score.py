"""One driving score per episode in [0, 1], in the family of nuPlan's closed-loop score and NAVSIM's PDMS.

    score = (pedestrian gate · vehicle gate · yield gate · progress gate · near-miss factor)
            · (w_p·progress + w_t·ttc + w_s·speed_limit + w_c·comfort) / Σw

Gates multiply: an at-fault pedestrian or vehicle collision, a broken yield obligation or an episode
without progress zero the episode whatever its margins, and a near miss (close to a pedestrian on the road,
at speed) takes its severity off the whole score: a pass that only luck kept from a collision scores
nearly as one. The weighted mean rewards what is left: progress (the free-flow time to the delay target
over the ego's), time-to-collision margin, the speed limit and comfort. Each term reads the world's
ground truth through `EpisodeResult`, never the policy's view; the anchors and every departure from
nuPlan / NAVSIM are documented in docs/results.md ("The score") and in the fields of `ScoreConfig`.

Two references, one per use of progress. The term is against a free-flow driver (the same start at the
speed limit, alone on the road): a policy that passes safely sooner than the careful one must gain, or a
better predictor could never show. The gate is against a careful driver on the same seed, `yielding` (the
project's rule-based driver, as NAVSIM's is the rule-based PDM-Closed): a car that made less than a fifth
of its progress scores 0, but waiting as long as the careful driver had to is never zeroed.
`crossing-eval` runs the reference on every seed it scores.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from crossing_env.safety.results import EpisodeResult

__all__ = [
    "DEFAULT_SCORE",
    "REFERENCE_POLICY",
    "SCORE_TERMS",
    "EpisodeScore",
    "ScoreConfig",
    "episode_score",
    "free_flow_progress",
    "makes_progress",
]

REFERENCE_POLICY = "yielding"
"""The careful driver whose progress on the same seed the progress gate compares with."""


_WEIGHTS = ("progress_weight", "ttc_weight", "speed_limit_weight", "comfort_weight")


@dataclass(frozen=True)
class ScoreConfig:
    """Weights, anchors and gate factors of the episode score (SI units)."""

    progress_weight: float = 5.0
    """Weight of progress (nuPlan and NAVSIM: 5)."""
    ttc_weight: float = 5.0
    """Weight of the time-to-collision margin (nuPlan and NAVSIM: 5)."""
    speed_limit_weight: float = 4.0
    """Weight of speed-limit compliance (nuPlan: 4; NAVSIM drops it)."""
    comfort_weight: float = 2.0
    """Weight of comfort (nuPlan and NAVSIM: 2)."""
    ttc_anchor: float = 1.5
    """Minimum TTC (s) from which the TTC term is 1; it falls linearly to 0 at 0 s. nuPlan tests a binary
    0.95 s bound; a ramp to the serious-conflict threshold (`MetricsConfig.serious_ttc`) keeps one tick
    across a bound from flipping an episode."""
    overspeed_anchor: float = 2.23
    """Largest excess over the speed limit (m/s) at which the speed-limit term reaches 0, linearly from 1
    at none (nuPlan's `max_overspeed_value_threshold`, 5 mph; nuPlan averages the excess over time, here
    the worst moment counts, so a burst is not diluted by a long episode)."""
    comfortable_deceleration: float = 4.05
    """Deceleration (m/s²) up to which the comfort term is 1 (nuPlan's `ego_is_comfortable` bound)."""
    emergency_deceleration: float = 8.0
    """Deceleration (m/s²) at which the comfort term reaches 0, linearly from the comfortable one (full
    emergency braking on dry asphalt). nuPlan's comfort is binary."""
    min_progress: float = 0.2
    """Share of the reference driver's progress below which the episode scores 0 (nuPlan's
    `ego_is_making_progress` threshold, against its expert)."""
    reference_min_distance: float = 5.0
    """When neither car reached the delay target, the gate compares distances travelled; a reference that
    travelled less than this (m) cannot be compared with, and the gate passes (nuPlan does the same when
    its expert barely moves)."""
    unresolved_factor: float = 0.5
    """Factor for an episode that ended with a yield obligation still open (neither met nor broken): the
    episode cannot vouch for it. nuPlan multiplies lesser infractions by 0.5."""
    static_collision_factor: float = 0.5
    """Factor for a contact with a static body (nuPlan: 0.5 for an at-fault collision with a static
    object); an at-fault contact with a pedestrian or a vehicle scores 0."""

    def __post_init__(self) -> None:
        """Reject weights and anchors that would take the score out of [0, 1] or divide by zero."""
        for name in _WEIGHTS:
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"ScoreConfig.{name} must be a finite number >= 0, got {value!r}")
        if self.total_weight <= 0.0:
            raise ValueError("ScoreConfig: at least one weight must be positive")
        for name in ("ttc_anchor", "overspeed_anchor", "reference_min_distance"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"ScoreConfig.{name} must be a finite number > 0, got {value!r}")
        if not 0.0 < self.comfortable_deceleration < self.emergency_deceleration:
            raise ValueError(
                "ScoreConfig: need 0 < comfortable_deceleration < emergency_deceleration, got "
                f"{self.comfortable_deceleration!r} and {self.emergency_deceleration!r}"
            )
        for name in ("min_progress", "unresolved_factor", "static_collision_factor"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise ValueError(f"ScoreConfig.{name} must lie in [0, 1], got {value!r}")

    @property
    def total_weight(self) -> float:
        """Sum of the weights of the weighted mean."""
        return sum(getattr(self, name) for name in _WEIGHTS)


DEFAULT_SCORE = ScoreConfig()
"""The score every table reports."""


@dataclass(frozen=True)
class EpisodeScore:
    """An episode's score and every term it is made of, each in [0, 1]."""

    score: float
    """Product of the gates times the weighted mean of the terms."""
    pedestrian_gate: float
    """0 after an at-fault pedestrian collision, else 1."""
    vehicle_gate: float
    """0 after an at-fault vehicle collision, `static_collision_factor` after a static contact, else 1."""
    yield_gate: float
    """0 after a broken yield obligation, `unresolved_factor` with one left open, else 1."""
    progress_gate: float
    """0 when the ego made less than `min_progress` of the reference driver's progress on the seed, else 1."""
    progress: float
    """Free-flow time to the delay target / the ego's time to it (capped at 1); 0 if it never got there."""
    ttc: float
    """min(1, minimum pedestrian TTC / `ttc_anchor`)."""
    near_miss_factor: float
    """1 − `EpisodeResult.near_miss` (proximity × speed of the worst pass of a pedestrian
    on the road). It multiplies like a gate, graded: nuPlan has no such term (its pedestrians are replayed
    logs, and a pass 1 cm from one at 72 km/h is no collision there)."""
    speed_limit: float
    """1 − largest excess over the speed limit / `overspeed_anchor`, floored at 0."""
    comfort: float
    """1 up to the comfortable deceleration, 0 at the emergency one, linear between."""

    def as_dict(self) -> dict[str, float]:
        """The score and its terms by name (`SCORE_TERMS` order)."""
        return asdict(self)


SCORE_TERMS: tuple[str, ...] = tuple(EpisodeScore.__dataclass_fields__)
"""Names of the score and its terms, as `EpisodeScore.as_dict` and the episode records carry them."""


def _ramp(value: float, zero: float, one: float) -> float:
    """Linear from 0 at `zero` to 1 at `one`, clipped to [0, 1] (either direction)."""
    t = (value - zero) / (one - zero)
    return min(max(t, 0.0), 1.0)


def free_flow_progress(result: EpisodeResult) -> float:
    """Free-flow time to the delay target / the ego's time to it (capped at 1); 0 if it never got there."""
    if not (result.passed_crossing and math.isfinite(result.target_time) and result.target_time > 0.0):
        return 0.0
    free_flow = result.target_time - result.delay
    return min(max(free_flow / result.target_time, 0.0), 1.0)


def makes_progress(
    result: EpisodeResult, reference: EpisodeResult, config: ScoreConfig = DEFAULT_SCORE
) -> bool:
    """Whether the ego made at least `min_progress` of the reference driver's progress on the same seed.

    Both reached the delay target: free-flow progress compared. Only the reference did: no. Only the ego
    did: yes. Neither: distances travelled compared (a reference that barely moved cannot be compared with).
    """
    if reference.passed_crossing:
        return free_flow_progress(result) >= config.min_progress * free_flow_progress(reference)
    if result.passed_crossing or reference.distance_travelled < config.reference_min_distance:
        return True
    return result.distance_travelled >= config.min_progress * reference.distance_travelled


def episode_score(
    result: EpisodeResult, reference: EpisodeResult, config: ScoreConfig = DEFAULT_SCORE
) -> EpisodeScore:
    """Score `result` against `reference`, the reference driver's episode on the same scenario and seed."""
    if result.scenario != reference.scenario:
        raise ValueError(
            f"episode_score: the reference ran {reference.scenario!r}, the episode {result.scenario!r}"
        )
    c = config
    pedestrian_gate = 0.0 if result.pedestrian_collisions_at_fault else 1.0
    vehicle_gate = 1.0
    if result.vehicle_collisions_at_fault:
        vehicle_gate = 0.0
    elif result.static_collisions:
        vehicle_gate = c.static_collision_factor
    yield_gate = 0.0 if result.yield_violations else c.unresolved_factor if result.yield_unresolved else 1.0
    progress = free_flow_progress(result)
    progress_gate = 1.0 if makes_progress(result, reference, c) else 0.0
    ttc = min(result.min_ttc / c.ttc_anchor, 1.0) if result.min_ttc >= 0.0 else 0.0
    near_miss_factor = 1.0 - min(max(result.near_miss, 0.0), 1.0)
    speed_limit = 1.0 - _ramp(result.max_speed_over_limit, 0.0, c.overspeed_anchor)
    comfort = 1.0 - _ramp(result.max_deceleration, c.comfortable_deceleration, c.emergency_deceleration)
    mean = (
        c.progress_weight * progress
        + c.ttc_weight * ttc
        + c.speed_limit_weight * speed_limit
        + c.comfort_weight * comfort
    ) / c.total_weight
    gates = pedestrian_gate * vehicle_gate * yield_gate * progress_gate * near_miss_factor
    return EpisodeScore(
        score=gates * mean,
        pedestrian_gate=pedestrian_gate,
        vehicle_gate=vehicle_gate,
        yield_gate=yield_gate,
        progress_gate=progress_gate,
        progress=progress,
        ttc=ttc,
        near_miss_factor=near_miss_factor,
        speed_limit=speed_limit,
        comfort=comfort,
    )
