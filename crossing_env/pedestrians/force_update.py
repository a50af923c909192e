"""Social-force intensities raised by others' irrational behaviour (case 2 of Song et al. 2022), QLB style.

Q. Song et al., "Research on quantum cognition in autonomous driving", Sci. Rep. 12:300 (2022) (below:
Song 2022) raise an agent's social-force intensity when it sees others behave irrationally. How they map
the observation to an intensity is not given in a form we could verify; the mapping here
(:class:`ForceUpdateConfig`) is our design, built on the quantum-like disjunction of
`crossing_env.pedestrians.quantum` (C. Moreira and A. Wichert, Front. Psychol. 7:11, 2016).

The world uses :func:`irrational_neighbour_fraction` and :func:`updated_ped_intensity` each step when
``pedestrians.behaviour.update_force_intensity`` is on; the social-force predictor's QLB variant does too.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from crossing_env.pedestrians.quantum import (
    FloatArray,
    _check_unit,
    disjunction_probabilities,
    similarity_phase,
)
from crossing_env.types import BoolArray

__all__ = [
    "IRRATIONAL_VIEW_RADIUS",
    "PED_PED_INTENSITY",
    "VEHICLE_PED_INTENSITY",
    "ForceUpdateConfig",
    "classical_updated_force_intensity",
    "irrational_neighbour_fraction",
    "updated_force_intensity",
    "updated_ped_intensity",
]

PED_PED_INTENSITY = 0.42
"""Classical calibration of the pedestrian-pedestrian social-force intensity in Song 2022, Case 2."""
VEHICLE_PED_INTENSITY = 0.71
"""Classical calibration of the vehicle-pedestrian social-force intensity in Song 2022, Case 2."""


@dataclass(frozen=True)
class ForceUpdateConfig:
    """Our design for the force-intensity update (Song 2022 do not give theirs in a checkable form).

    Hidden cause R: "the agent I interact with behaves irrationally", prior ``P(R) = f``, the observed
    fraction of irrational behaviour. Query K: "treat that agent as a hazard". The intensity is

        ``base * (1 + gain * (P(K) - P(K | rational)) / (P(K | irrational) - P(K | rational)))``

    which is ``base`` at ``f = 0`` (the classical calibration), ``base * (1 + gain)`` at ``f = 1``, a straight
    line in between for the classical P(K) and a bent curve for the QLB P(K).

    The phase is set by the similarity heuristic at the neutral prior :attr:`phase_prior` (the setting in
    which M&W 2016 tuned its thresholds) and then kept for every f. Applying the heuristic at the actual,
    skewed prior would hit its ``theta = pi`` branch for small f and send the intensity to almost 0 for a
    few irrational agents, which is no use in a force model.
    """

    hazard_given_rational: float = 0.2
    """``P(K | agent rational)``: vigilance toward a well-behaved agent."""
    hazard_given_irrational: float = 0.8
    """``P(K | agent irrational)``: vigilance toward an agent seen to break the rules; above the former."""
    gain: float = 1.0
    """Relative intensity increase when every observed agent behaves irrationally (1.0 doubles it)."""
    phase_prior: float = 0.5
    """Prior of R at which the heuristic sets the phase."""

    def __post_init__(self) -> None:
        for name in ("hazard_given_rational", "hazard_given_irrational", "phase_prior"):
            v = getattr(self, name)
            if not 0.0 <= v <= 1.0:
                raise ValueError(f"ForceUpdateConfig.{name} must be in [0, 1], got {v}")
        if not self.hazard_given_irrational > self.hazard_given_rational:
            raise ValueError(
                "ForceUpdateConfig.hazard_given_irrational must exceed hazard_given_rational, got "
                f"{self.hazard_given_irrational} <= {self.hazard_given_rational}"
            )
        if not (np.isfinite(self.gain) and self.gain >= 0.0):
            raise ValueError(f"ForceUpdateConfig.gain must be finite and >= 0, got {self.gain}")

    def heuristic_phase(self) -> float:
        """The similarity-heuristic phase at :attr:`phase_prior` (radians); cached per config."""
        return _force_phase(self)


@functools.lru_cache(maxsize=64)
def _force_phase(cfg: ForceUpdateConfig) -> float:
    """Heuristic phase of a force-update config at its neutral prior (cached: called every env step)."""
    w = cfg.phase_prior
    ki, kr = cfg.hazard_given_irrational, cfg.hazard_given_rational
    return float(similarity_phase([w * ki, (1.0 - w) * kr], [w * (1.0 - ki), (1.0 - w) * (1.0 - kr)]))


def _check_base(base: ArrayLike) -> FloatArray:
    """Reject negative or non-finite base intensities."""
    b = np.asarray(base, dtype=np.float64)
    if not np.all(np.isfinite(b)) or np.any(b < 0.0):
        raise ValueError(f"base intensity must be finite and non-negative, got {base!r}")
    return b


def _intensity(base: ArrayLike, p_hazard: FloatArray, cfg: ForceUpdateConfig) -> FloatArray:
    """Map ``P(K)`` to an intensity (see :class:`ForceUpdateConfig`), floored at 0."""
    kr, ki = cfg.hazard_given_rational, cfg.hazard_given_irrational
    scale = 1.0 + cfg.gain * (p_hazard - kr) / (ki - kr)
    return _check_base(base) * np.maximum(scale, 0.0)


def classical_updated_force_intensity(
    base: ArrayLike, irrational_fraction: ArrayLike, config: ForceUpdateConfig | None = None
) -> FloatArray:
    """Classical counterpart of :func:`updated_force_intensity`: a straight line in the irrational fraction.

    Args:
        base: Classically calibrated intensity.
        irrational_fraction: Observed fraction of irrational behaviour of others, in [0, 1].
        config: The update's CPT; defaults to ``ForceUpdateConfig()``.

    Returns:
        Updated intensity, broadcast shape of the inputs.
    """
    cfg = config or ForceUpdateConfig()
    f = _check_unit("irrational_fraction", irrational_fraction)
    return _intensity(base, f * cfg.hazard_given_irrational + (1.0 - f) * cfg.hazard_given_rational, cfg)


def updated_force_intensity(
    base: ArrayLike,
    irrational_fraction: ArrayLike,
    theta: ArrayLike | None = None,
    config: ForceUpdateConfig | None = None,
) -> FloatArray:
    """Social-force intensity after seeing a fraction of others behave irrationally (QLB update), vectorised.

    The QLB hazard probability (disjunction over the unobserved "is this agent irrational?" cause) mapped
    to an intensity as in :class:`ForceUpdateConfig` (our design; Song 2022, Figures 10-11, show such
    update curves for the two calibrated intensities). Equals ``base`` at fraction 0 and
    ``base * (1 + gain)`` at fraction 1, and departs from the classical straight line in between.

    Args:
        base: Classically calibrated intensity, e.g. :data:`PED_PED_INTENSITY` or
            :data:`VEHICLE_PED_INTENSITY`.
        irrational_fraction: Observed fraction of irrational behaviour of others, in [0, 1].
        theta: Phase in radians, or None for the heuristic phase of :meth:`ForceUpdateConfig.heuristic_phase`.
        config: The update's CPT; defaults to ``ForceUpdateConfig()``.

    Returns:
        Updated intensity, broadcast shape of ``base`` and ``irrational_fraction``.
    """
    cfg = config or ForceUpdateConfig()
    th = cfg.heuristic_phase() if theta is None else theta
    p = disjunction_probabilities(
        cfg.hazard_given_irrational, cfg.hazard_given_rational, irrational_fraction, th
    )
    return _intensity(base, p, cfg)


IRRATIONAL_VIEW_RADIUS = 10.0
"""Metres within which a pedestrian notices others' irrational acts (Case 2 force update)."""


def irrational_neighbour_fraction(
    positions: FloatArray, active: BoolArray, irrational: BoolArray, radius: float = IRRATIONAL_VIEW_RADIUS
) -> FloatArray:
    """Per pedestrian, the fraction of its active neighbours within `radius` who act irrationally (0 if none).

    Args:
        positions: (n, 2) positions.
        active: (n,) slots in use.
        irrational: (n,) currently acting irrationally (running, on red, jaywalking, hesitating, ...).
        radius: Viewing radius in metres.

    Returns:
        (n,) fractions in [0, 1]; 0 for inactive slots.
    """
    d = positions[:, None, :] - positions[None, :, :]
    near = (
        (d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1] <= radius * radius) & active[None, :] & active[:, None]
    )
    np.fill_diagonal(near, False)
    count = near.sum(axis=1)
    bad = (near & irrational[None, :]).sum(axis=1)
    return np.where(count > 0, bad / np.maximum(count, 1), 0.0)


def updated_ped_intensity(base: float, fraction: FloatArray) -> FloatArray:
    """QLB-updated pedestrian–pedestrian intensity for observed irrational fractions (seed Case 2).

    Equals `base` where nobody misbehaves (the classical calibration, 0.42 in the seed paper). The QLB
    curve dips slightly below `base` at small fractions (interference is destructive there); seeing others
    misbehave should never make a pedestrian less careful, so the result is floored at `base`.
    """
    return np.maximum(base, updated_force_intensity(base, np.clip(fraction, 0.0, 1.0)))
