"""Quantum-like Bayesian (QLB) networks and the pedestrian crossing-intention model built on them.

The method follows C. Moreira and A. Wichert, "Quantum-Like Bayesian Networks for Modeling Decision
Making", Front. Psychol. 7:11 (2016) (below: M&W 2016), as used by Q. Song et al., "Research on quantum
cognition in autonomous driving", Sci. Rep. 12:300 (2022) (below: Song 2022). Every CPT entry becomes an
amplitude ``psi = sqrt(P) * exp(i * theta)``; the probability of a query sums the amplitudes of the
unobserved configurations before squaring, so it carries interference terms
``2 * sqrt(p_i * p_j) * cos(theta_i - theta_j)`` on top of the classical marginal, and is normalised over
the query values (alpha). With ``cos = 0`` everything collapses to the classical Bayesian network.

Two layers on top of the QLB maths in `crossing_env.pedestrians.quantum` (the simulated pedestrians share
them, so they sit in the simulator's layer):

* :class:`Node` / :class:`QuantumLikeBayesNet`: a small exact-inference network (full enumeration;
  fine for the handful of variables used here), classical or quantum-like; in `predictors.qlb_network`,
  re-exported here.
* The Song 2022 case 1: crossing probability over two lane beliefs (:func:`cbm_cross_probability`,
  :func:`qlb_cross_probability`).

Departures from the papers (each also noted where it happens):

* Song 2022 prints the similarity heuristic's side as ``||c|| = ||a|| - ||b||``; that flattens the triangle
  and yields ``theta = pi`` for every input. We use M&W 2016's ``||c|| = ||a - b||``.
* Degenerate geometry (``||a|| = 0``, ``||b|| = 0`` or ``a = b``) has no angles; we fall back to
  ``cos(theta) = 0``, i.e. the classical result. When interference cancels both scores down to rounding
  noise (``T + F ~ 0``) we also return the classical result instead of dividing noise by noise.
* With more than two unobserved configurations the network's heuristic mode applies the rule to each pair
  ``(i, j)`` with the 2-D vectors ``[a_i, a_j]`` and ``[b_i, b_j]``, one reading of M&W 2016 Fig. 3 (not
  verified).
* How Song 2022 feed lane beliefs into their network and how they update force intensities is not
  documented in a form we could verify. The crossing CPTs, the per-lane phases combined as a Kronecker
  product (:func:`crossing_pair_cosines`) and the force-update mapping (:class:`ForceUpdateConfig`) are our
  design.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from crossing_env.pedestrians.quantum import (
    FloatArray,
    _check_theta,
    _check_unit,
    _normalise_with_fallback,
    _phase,
)
from predictors.qlb_network import Node, QuantumLikeBayesNet

__all__ = [
    "CASES",
    "ZONE_BELIEF",
    "CrossingCase",
    "Node",
    "QuantumLikeBayesNet",
    "cbm_cross_probability",
    "crossing_network",
    "crossing_neutral_phases",
    "crossing_pair_cosines",
    "qlb_cross_probability",
]


# ---------------------------------------------------------------------------------------------------------
# Song 2022, Case 1: does the pedestrian cross a two-lane zebra?
# ---------------------------------------------------------------------------------------------------------
ZONE_BELIEF: dict[str, float] = {"far": 1.0, "mid": 0.5, "near": 0.0}
"""Song 2022's belief values for a lane whose approaching car is far, mid-distance or near."""


@dataclass(frozen=True)
class CrossingCase:
    """CPT ``P(cross | lane 1 safe?, lane 2 safe?)`` for one distance case of the nearest approaching car.

    Our design, not Song 2022's (their Eq. 13 is not documented in a form we could check): the CPTs are
    additive in the two lane states, so the classical model is an exact plane over the two beliefs
    (Song 2022's Figures 3, 5 and 7 show planes), and they fall as the car comes closer (more caution).
    Lane 1 is the near-side lane, crossed first, so it weighs a little more.
    """

    name: str
    """Case name (far / mid / near)."""
    p_safe_safe: float
    """``P(cross | lane 1 safe, lane 2 safe)``."""
    p_safe_unsafe: float
    """``P(cross | lane 1 safe, lane 2 unsafe)``."""
    p_unsafe_safe: float
    """``P(cross | lane 1 unsafe, lane 2 safe)``."""
    p_unsafe_unsafe: float
    """``P(cross | lane 1 unsafe, lane 2 unsafe)``."""

    def __post_init__(self) -> None:
        for f in ("p_safe_safe", "p_safe_unsafe", "p_unsafe_safe", "p_unsafe_unsafe"):
            v = getattr(self, f)
            if not 0.0 <= v <= 1.0:
                raise ValueError(f"CrossingCase {self.name!r}: {f} must be in [0, 1], got {v}")

    def cpt(self) -> FloatArray:
        """``P(cross | z1, z2)`` as shape (2, 2), index 0 = safe, 1 = unsafe."""
        return np.array([[self.p_safe_safe, self.p_safe_unsafe], [self.p_unsafe_safe, self.p_unsafe_unsafe]])


CASES: dict[str, CrossingCase] = {
    "far": CrossingCase("far", 0.95, 0.55, 0.50, 0.10),
    "mid": CrossingCase("mid", 0.80, 0.45, 0.40, 0.05),
    "near": CrossingCase("near", 0.57, 0.32, 0.27, 0.02),
}
"""The three distance cases of Song 2022's Case 1 (CPT values are our design, see :class:`CrossingCase`)."""


def _case(case: str | CrossingCase) -> CrossingCase:
    """Resolve a case name to its CPTs."""
    if isinstance(case, CrossingCase):
        return case
    if case not in CASES:
        raise ValueError(f"unknown crossing case {case!r}; choose one of {sorted(CASES)}")
    return CASES[case]


def _crossing_columns(
    b1: ArrayLike, b2: ArrayLike, case: str | CrossingCase
) -> tuple[list[FloatArray], list[FloatArray]]:
    """``P(cross, z1, z2)`` and ``P(wait, z1, z2)`` as four columns each, configurations (ss, su, us, uu)."""
    cpt = _case(case).cpt().ravel()
    s1 = _check_unit("b1", b1)
    s2 = _check_unit("b2", b2)
    u1, u2 = 1.0 - s1, 1.0 - s2
    prior = (s1 * s2, s1 * u2, u1 * s2, u1 * u2)
    return [w * c for w, c in zip(prior, cpt, strict=True)], [
        w * (1.0 - c) for w, c in zip(prior, cpt, strict=True)
    ]


def _lane_phases(p: Sequence[FloatArray], q: Sequence[FloatArray]) -> tuple[FloatArray, FloatArray]:
    """Heuristic phase of each lane's hidden cause, the other lane summed out classically."""
    a0, a1 = np.broadcast_arrays(p[0] + p[1], p[0] + p[2])  # lane 1 safe / lane 2 safe, query true
    thetas = _phase(
        np.stack([a0, a1]),
        np.stack(np.broadcast_arrays(p[2] + p[3], p[1] + p[3])),
        np.stack(np.broadcast_arrays(q[0] + q[1], q[0] + q[2])),
        np.stack(np.broadcast_arrays(q[2] + q[3], q[1] + q[3])),
    )
    return thetas[0], thetas[1]


def _lane_cosines(
    p: Sequence[FloatArray], q: Sequence[FloatArray], theta: ArrayLike | tuple[ArrayLike, ArrayLike] | None
) -> tuple[FloatArray, FloatArray]:
    """``(cos t1, cos t2)`` from the heuristic (theta None), one phase for both lanes, or a pair."""
    if theta is None:
        t1, t2 = _lane_phases(p, q)
    elif isinstance(theta, tuple):
        if len(theta) != 2:
            raise ValueError(f"theta as a tuple must be (theta1, theta2), got {len(theta)} entries")
        t1, t2 = _check_theta(theta[0]), _check_theta(theta[1])
    else:
        t1 = t2 = _check_theta(theta)
    return np.cos(t1), np.cos(t2)


def _kron_score(p: Sequence[FloatArray], c1: FloatArray, c2: FloatArray) -> FloatArray:
    """``r^T (C1 kron C2) r`` with ``r = sqrt(p)``: Eq. 26 with the lanes interfering independently."""
    r0, r1, r2, r3 = (np.sqrt(x) for x in p)
    return (
        p[0]
        + p[1]
        + p[2]
        + p[3]
        + 2.0 * (c2 * (r0 * r1 + r2 * r3) + c1 * (r0 * r2 + r1 * r3) + c1 * c2 * (r0 * r3 + r1 * r2))
    )


def crossing_pair_cosines(
    b1: ArrayLike,
    b2: ArrayLike,
    case: str | CrossingCase = "mid",
    theta: ArrayLike | tuple[ArrayLike, ArrayLike] | None = None,
) -> FloatArray:
    """Interference cosines of the six pairs of lane configurations, shape ``(..., 6)``.

    The two lanes' hidden causes interfere independently: the 4x4 interference matrix is the Kronecker
    product of the per-lane matrices ``[[1, cos t_k], [cos t_k, 1]]``. Pairs that differ in lane k only get
    ``cos t_k``, pairs that differ in both get ``cos t_1 cos t_2``. This is our design for two hidden
    causes (M&W 2016 do not treat independent causes separately); it keeps both scores non-negative and
    collapses exactly to the classical model when both cosines are 0. Pair order: ``triu_indices(4, 1)``
    over the configurations (ss, su, us, uu).

    Args:
        b1: Belief that lane 1 is safe, in [0, 1].
        b2: Belief that lane 2 is safe, in [0, 1].
        case: Distance case or a :class:`CrossingCase`.
        theta: None: per-lane similarity heuristic, with vector a = ``[P(cross, z_k = safe),
            P(cross, z_k = unsafe)]`` and b the same for waiting (the other lane summed out). A scalar or
            array: the same phase for both lanes. A tuple ``(theta1, theta2)``: one phase per lane.

    Returns:
        Cosines, shape ``(..., 6)``.
    """
    p, q = _crossing_columns(b1, b2, case)
    c1, c2 = np.broadcast_arrays(*_lane_cosines(p, q, theta), p[0])[:2]
    return np.stack([c2, c1, c1 * c2, c1 * c2, c1, c2], axis=-1)


def cbm_cross_probability(b1: ArrayLike, b2: ArrayLike, case: str | CrossingCase = "mid") -> FloatArray:
    """Classical Bayesian model (CBM): ``P(cross)`` from the two lane beliefs, vectorised.

    Mapping (a) of our QLB notes: belief ``b_k`` is the prior ``P(Z_k = safe)`` of the hidden cause "lane k
    is safe to cross"; the query is summed over the four unobserved lane configurations.

    Args:
        b1: Belief that lane 1 (near side) is safe, in [0, 1]; broadcast with b2.
        b2: Belief that lane 2 (far side) is safe, in [0, 1].
        case: Distance case of the approaching car (``"far"``, ``"mid"``, ``"near"``) or a
            :class:`CrossingCase`.

    Returns:
        ``P(cross)``, broadcast shape of the beliefs.
    """
    p, _ = _crossing_columns(b1, b2, case)
    return p[0] + p[1] + p[2] + p[3]


def qlb_cross_probability(
    b1: ArrayLike,
    b2: ArrayLike,
    case: str | CrossingCase = "mid",
    theta: ArrayLike | tuple[ArrayLike, ArrayLike] | None = None,
) -> FloatArray:
    """Quantum-like model: ``P(cross)`` from the two lane beliefs with interference, vectorised.

    Same network and CPTs as :func:`cbm_cross_probability`; the four lane configurations interfere with
    the cosines of :func:`crossing_pair_cosines`. A belief of exactly 0 or 1 removes that lane's
    interference; both certain gives the classical value. The heuristic is used at the actual beliefs,
    so skewed beliefs can push it into its ``theta = pi`` branch and far from the classical plane (the
    irregular surfaces of Song 2022's Figures 4, 6 and 8; see the cautions in our QLB notes). For a
    smoother model pass fixed phases, e.g. ``theta=crossing_neutral_phases(case)``.

    Args:
        b1: Belief that lane 1 is safe, in [0, 1]; broadcast with b2.
        b2: Belief that lane 2 is safe, in [0, 1].
        case: Distance case or a :class:`CrossingCase`.
        theta: None for the per-lane similarity heuristic, a phase for both lanes, or ``(theta1, theta2)``.

    Returns:
        ``P(cross)``, broadcast shape of the beliefs.
    """
    p, q = _crossing_columns(b1, b2, case)
    c1, c2 = _lane_cosines(p, q, theta)
    t = _kron_score(p, c1, c2)
    f = _kron_score(q, c1, c2)
    return _normalise_with_fallback(t, f, p[0] + p[1] + p[2] + p[3], q[0] + q[1] + q[2] + q[3])


def crossing_neutral_phases(case: str | CrossingCase = "mid") -> tuple[float, float]:
    """Per-lane heuristic phases at neutral beliefs (0.5, 0.5), where M&W 2016 tuned the thresholds.

    Passing them as ``theta`` to :func:`qlb_cross_probability` gives a smooth QLB surface that still departs
    from the classical plane, instead of the heuristic's jumps at skewed beliefs.

    Args:
        case: Distance case or a :class:`CrossingCase`.

    Returns:
        ``(theta1, theta2)`` in radians.
    """
    p, q = _crossing_columns(0.5, 0.5, case)
    t1, t2 = _lane_phases(p, q)
    return float(t1), float(t2)


def crossing_network(b1: float, b2: float, case: str | CrossingCase = "mid") -> QuantumLikeBayesNet:
    """The Case 1 network ``lane1 -> cross <- lane2`` for scalar beliefs (for inspection and cross-checks).

    Args:
        b1: Belief that lane 1 is safe.
        b2: Belief that lane 2 is safe.
        case: Distance case or a :class:`CrossingCase`.

    Returns:
        A network with variables ``lane1``, ``lane2`` (states safe/unsafe) and ``cross`` (cross/wait).
    """
    cpt = _case(case).cpt()
    return QuantumLikeBayesNet(
        [
            Node("lane1", ("safe", "unsafe"), np.array([b1, 1.0 - b1])),
            Node("lane2", ("safe", "unsafe"), np.array([b2, 1.0 - b2])),
            Node("cross", ("cross", "wait"), np.stack([cpt, 1.0 - cpt], axis=-1), parents=("lane1", "lane2")),
        ]
    )
