"""Crossing decisions: when does a pedestrian waiting at the kerb step onto the road?

The world calls a decision model once per step with a `DecisionContext` covering every waiting
pedestrian and draws the decision from the returned probabilities with its own RNG. Models are plain
objects (`CrossingDecisionModel`), so new ones (drift-diffusion, learned) plug in without touching the
world. Two are built in: `GapAcceptance` (classical, ``decision_model = "gap"``) and
`QuantumGapAcceptance` (``decision_model = "qlb"``); `make_decision_model` picks the scenario's.

QuantumGapAcceptance: gap acceptance bent by quantum-like interference (QLB). It is the quantum-like
Bayesian network of C. Moreira and A. Wichert, "Quantum-Like Bayesian Networks for Modeling Decision
Making", Front. Psychol. 7:11 (2016) (below: M&W 2016), for one binary hidden cause and one query, with
the CPT entries read as the pedestrian's belief and look probabilities:

* Hidden cause Z = "the gap is safe / the car will yield", never observed by the pedestrian. Its prior is
  the pedestrian's belief ``beta = sigmoid((gap - critical_gap) / belief_scale)``: a smooth classical
  probability, 1/2 at the pedestrian's own critical gap.
* Query C = "step off the kerb at this look", CPT ``P(C | safe) = p_cross_safe`` and
  ``P(C | unsafe) = p_cross_unsafe``.
* With ``p1 = beta P(C | safe)``, ``p2 = (1 - beta) P(C | unsafe)`` and ``q1, q2`` the same for not crossing,
  the quantum marginal of M&W 2016 (Eq. 26, normalised over the query) is
  ``T / (T + F)`` with ``T = p1 + p2 + 2 sqrt(p1 p2) cos(theta)`` and likewise F, where theta is the
  pedestrian's own rationality phase (an explicit phase per pedestrian, drawn by the world, rather than
  one set by M&W 2016's similarity heuristic). ``cos(theta) = 0`` gives exactly the classical
  mixture ``beta P(C | safe) + (1 - beta) P(C | unsafe)``.

Hard floor: no look accepts a gap below ``min(gap_floor, critical_gap)`` (3 s by default, the floor of
the calibration literature), so neither the logistic tail nor impatience sends a pedestrian in front of a
car a second away; a distracted pedestrian's shortened critical gap lowers its own floor.

What interference does with the default CPT: a negative cosine (destructive) cancels the "wait" score more
than the "cross" score at intermediate beliefs, so such pedestrians take marginal gaps more readily (and
are a little more careful when the gap is clearly too short); a positive cosine does the opposite. The
probability rises with the gap for cos >= 0; with cos < 0 it has a dip of at most 2e-4 at beliefs near 0,
where the two "cross" amplitudes nearly cancel (tested).

Calibration (tests/crossing_env/test_crossing_decisions.py, Poisson traffic with a car every 1.2 s at the
pedestrian's line): accepted gaps of classical pedestrians have a median of 5.75 s (this model) / 6.32 s
(step model), 85th percentiles 7.7 / 8.1 s, none below 3 s. The accepted gap is the critical gap plus the
overshoot of the traffic stream, so in lighter traffic its median is larger (about 7 s at a 2.5 s headway).

Per-step hazard. The probability above is per *look* at the traffic. A pedestrian looks every
``decision_interval`` seconds, so the per-step probability is ``1 - (1 - p)^(dt / decision_interval)``: the
survival over any span of time (and therefore the decision rate) does not depend on the step length dt.

Classical limit. With ``belief_scale = 0`` the belief is a step (1 when ``gap >= critical_gap``), so the
interference vanishes (one of ``p1, p2`` is 0) and with ``p_cross_safe = 1``, ``p_cross_unsafe = 0`` the model
is exactly `GapAcceptance`.

Departures from the papers: Song et al. (Sci. Rep. 12:300, 2022) feed lane beliefs from car zones into
their network; here the belief comes from the time gap relative to a per-pedestrian critical gap (the
calibration literature's quantity), and the phase is a per-pedestrian trait rather than set by the
similarity heuristic.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from crossing_env.pedestrians.quantum import interference_probability
from crossing_env.types import BoolArray, FloatArray
from scenarios.config import ScenarioConfig


@dataclass(frozen=True)
class DecisionContext:
    """What a waiting pedestrian perceives, one entry per waiting pedestrian."""

    gap: FloatArray
    """Seconds until the first approaching car reaches the pedestrian's crossing line (inf if none)."""
    critical_gap: FloatArray
    """Each pedestrian's critical gap in seconds."""
    phase: FloatArray
    """Each pedestrian's rationality phase θ in radians (π/2 = classical)."""
    waited: FloatArray
    """Seconds already spent waiting at the kerb."""
    red: BoolArray
    """Facing a red pedestrian signal."""
    red_violator: BoolArray
    """Willing to cross against red if the gap allows."""
    dt: float
    """Step length in seconds (models with rates convert them to per-step probabilities)."""


class CrossingDecisionModel(Protocol):
    """A model mapping a decision context to per-step crossing probabilities."""

    def probability(self, context: DecisionContext) -> FloatArray:
        """Probability, per waiting pedestrian, of starting to cross during this step."""
        ...


class GapAcceptance:
    """Classical gap acceptance: cross when the gap exceeds one's critical gap (and the signal allows).

    Deterministic given the per-pedestrian critical gap, which the world draws from a lognormal
    distribution (calibration: mean 5.5 s, SD 1.2 s, floor 3 s). A pedestrian facing red only crosses
    if it is a red-light violator.
    """

    def probability(self, context: DecisionContext) -> FloatArray:
        """1 where the gap is accepted and the signal permits, else 0."""
        allowed = ~context.red | context.red_violator
        return ((context.gap >= context.critical_gap) & allowed).astype(np.float64)


COS_ZERO_ATOL = 1e-12
"""|cos θ| below this counts as exactly 0 (cos(π/2) is 6e-17 in floating point), the classical pedestrian."""


@dataclass(frozen=True)
class QuantumGapConfig:
    """Parameters of `QuantumGapAcceptance` (our design; defaults keep accepted gaps near critical gaps)."""

    belief_scale: float = 0.4
    """Logistic scale (s) of the belief that the gap is safe around the critical gap; 0 gives a step."""
    p_cross_safe: float = 0.95
    """P(step off at one look | gap safe)."""
    p_cross_unsafe: float = 0.0005
    """P(step off at one look | gap unsafe): impatience; per look, so small (about 0.1 % per second)."""
    gap_floor: float = 3.0
    """No gap below ``min(gap_floor, critical_gap)`` is ever taken (calibration: hard floor about 3 s)."""
    decision_interval: float = 0.5
    """Seconds between two looks at the traffic; converts per-look probabilities into a per-step hazard."""

    def __post_init__(self) -> None:
        if not (np.isfinite(self.belief_scale) and self.belief_scale >= 0.0):
            raise ValueError(f"QuantumGapConfig.belief_scale must be >= 0 seconds, got {self.belief_scale}")
        for name in ("p_cross_safe", "p_cross_unsafe"):
            v = getattr(self, name)
            if not 0.0 <= v <= 1.0:
                raise ValueError(f"QuantumGapConfig.{name} must be in [0, 1], got {v}")
        if not (np.isfinite(self.gap_floor) and self.gap_floor >= 0.0):
            raise ValueError(f"QuantumGapConfig.gap_floor must be >= 0 seconds, got {self.gap_floor}")
        if not self.decision_interval > 0.0:
            raise ValueError(
                f"QuantumGapConfig.decision_interval must be > 0 s, got {self.decision_interval}"
            )


def safe_belief(gap: FloatArray, critical_gap: FloatArray, scale: float) -> FloatArray:
    """Belief that the gap is safe: ``sigmoid((gap - critical_gap) / scale)``; a step at ``scale = 0``.

    An infinite gap (no car) gives 1. Computed in a form that never overflows.
    """
    gap = np.asarray(gap, dtype=np.float64)
    critical_gap = np.asarray(critical_gap, dtype=np.float64)
    if scale == 0.0:
        return (gap >= critical_gap).astype(np.float64)
    z = (gap - critical_gap) / scale
    e = np.exp(-np.abs(z))
    return np.where(z >= 0, 1.0 / (1.0 + e), e / (1.0 + e))


def per_step_hazard(p_per_look: FloatArray, dt: float, interval: float) -> FloatArray:
    """Per-step probability of a decision taken with probability ``p_per_look`` at every look.

    ``1 - (1 - p)^(dt / interval)``, so that the probability of having decided within any time span is the
    same for every dt (a constant hazard between looks).
    """
    if not (dt > 0.0 and interval > 0.0):
        raise ValueError(f"per_step_hazard: dt and interval must be > 0, got dt={dt}, interval={interval}")
    p = np.clip(np.asarray(p_per_look, dtype=np.float64), 0.0, 1.0)
    with np.errstate(divide="ignore"):  # p = 1 gives log(0) = -inf and a hazard of exactly 1
        return -np.expm1((dt / interval) * np.log1p(-p))


class QuantumGapAcceptance:
    """Gap acceptance bent by quantum-like interference with each pedestrian's phase (see the module doc).

    Implements `CrossingDecisionModel`. Vectorised over the waiting
    pedestrians.

    Args:
        config: Model parameters; defaults to `QuantumGapConfig()`.
    """

    def __init__(self, config: QuantumGapConfig | None = None) -> None:
        self.config = config or QuantumGapConfig()

    def _joint(self, gap: FloatArray, critical_gap: FloatArray) -> tuple[FloatArray, ...]:
        c = self.config
        beta = safe_belief(gap, critical_gap, c.belief_scale)
        p1, p2 = beta * c.p_cross_safe, (1.0 - beta) * c.p_cross_unsafe
        q1, q2 = beta * (1.0 - c.p_cross_safe), (1.0 - beta) * (1.0 - c.p_cross_unsafe)
        return p1, p2, q1, q2

    def classical_probability(self, gap: FloatArray, critical_gap: FloatArray) -> FloatArray:
        """Per-look crossing probability of the classical pedestrian (no interference), for comparison."""
        p1, p2, q1, q2 = self._joint(gap, critical_gap)
        return np.where(self._above_floor(gap, critical_gap), (p1 + p2) / (p1 + p2 + q1 + q2), 0.0)

    def _above_floor(self, gap: FloatArray, critical_gap: FloatArray) -> BoolArray:
        return np.asarray(gap) >= np.minimum(self.config.gap_floor, critical_gap)

    def look_probability(self, gap: FloatArray, critical_gap: FloatArray, phase: FloatArray) -> FloatArray:
        """Per-look crossing probability with interference (M&W 2016, Eq. 26, via `pedestrians.quantum`)."""
        p1, p2, q1, q2 = self._joint(gap, critical_gap)
        cos = np.cos(np.asarray(phase, dtype=np.float64))
        cos = np.where(np.abs(cos) < COS_ZERO_ATOL, 0.0, cos)
        return np.where(
            self._above_floor(gap, critical_gap), interference_probability(p1, p2, q1, q2, cos), 0.0
        )

    def probability(self, context: DecisionContext) -> FloatArray:
        """Per-step probability of starting to cross, 0 for pedestrians facing red who are not violators."""
        allowed = ~context.red | context.red_violator
        look = self.look_probability(context.gap, context.critical_gap, context.phase)
        return np.where(allowed, per_step_hazard(look, context.dt, self.config.decision_interval), 0.0)


def make_decision_model(scenario: ScenarioConfig) -> CrossingDecisionModel:
    """The decision model a scenario asks for (``pedestrians.behaviour.decision_model``)."""
    if scenario.pedestrians.behaviour.decision_model == "qlb":
        return QuantumGapAcceptance()
    return GapAcceptance()
