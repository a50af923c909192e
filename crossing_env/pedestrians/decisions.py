"""Crossing-decision models: when does a pedestrian waiting at the kerb step onto the road?

The world calls a decision model once per step with a `DecisionContext` covering every waiting
pedestrian and draws the decision from the returned probabilities with its own RNG. Models are plain
objects, so new ones (drift-diffusion, learned) plug in without touching the world.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from crossing_env.types import BoolArray, FloatArray


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
