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
  fine for the handful of variables used here), classical or quantum-like.
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

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from crossing_env.pedestrians.quantum import (
    _DEGENERATE_RTOL,
    _PROB_ATOL,
    FloatArray,
    Interference,
    _check_theta,
    _check_unit,
    _normalise_with_fallback,
    _pair_indices,
    _phase,
    similarity_phase,
)

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
# Network with exact inference by enumeration
# ---------------------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Node:
    """A discrete variable with its CPT (and optional CPT phases) in a (quantum-like) Bayesian network."""

    name: str
    """Variable name, unique in the network."""
    states: tuple[str, ...]
    """Names of the variable's values; at least two."""
    cpt: NDArray[np.float64]
    """``P(node | parents)``, shape ``(*parent cardinalities, len(states))``; the last axis sums to 1."""
    parents: tuple[str, ...] = ()
    """Parent names, in the order of the CPT's leading axes."""
    phases: NDArray[np.float64] | None = None
    """Phase (radians) of each CPT entry's amplitude ``sqrt(P) e^{i theta}``, CPT shape; None = all 0."""

    def __post_init__(self) -> None:
        cpt = np.asarray(self.cpt, dtype=np.float64)
        object.__setattr__(self, "cpt", cpt)
        object.__setattr__(self, "states", tuple(self.states))
        object.__setattr__(self, "parents", tuple(self.parents))
        where = f"Node {self.name!r}"
        if len(self.states) < 2 or len(set(self.states)) != len(self.states):
            raise ValueError(f"{where}: states must be at least two distinct names, got {self.states}")
        if cpt.ndim != len(self.parents) + 1 or cpt.shape[-1] != len(self.states):
            raise ValueError(
                f"{where}: cpt shape {cpt.shape} does not match {len(self.parents)} parent axes plus "
                f"{len(self.states)} states"
            )
        if not np.all(np.isfinite(cpt)) or np.any(cpt < 0.0):
            raise ValueError(f"{where}: cpt entries must be finite and non-negative")
        sums = cpt.sum(axis=-1)
        if np.any(np.abs(sums - 1.0) > _PROB_ATOL):
            raise ValueError(
                f"{where}: cpt rows must sum to 1 over the node's states; row sums {sums.ravel()}"
            )
        if self.phases is not None:
            ph = np.asarray(self.phases, dtype=np.float64)
            if ph.shape != cpt.shape or not np.all(np.isfinite(ph)):
                raise ValueError(
                    f"{where}: phases must be finite with the cpt's shape {cpt.shape}, got {ph.shape}"
                )
            object.__setattr__(self, "phases", ph)


@dataclass(eq=False)
class QuantumLikeBayesNet:
    """A discrete Bayesian network whose inference can add quantum-like interference (M&W 2016).

    The classical network is the same object queried with ``interference="off"``. The full joint
    probability and amplitude tensors are built once (one axis per variable, in :attr:`variables` order),
    so inference is exact enumeration: fine for the few-variable networks used for crossing intention.
    """

    nodes: Sequence[Node]
    """The network's nodes, any order; parents must be nodes of the network and the graph acyclic."""
    variables: tuple[str, ...] = field(init=False)
    """Variable names in topological order; the axis order of the joint tensors."""

    def __post_init__(self) -> None:
        by_name: dict[str, Node] = {}
        for node in self.nodes:
            if node.name in by_name:
                raise ValueError(f"duplicate node name {node.name!r}")
            by_name[node.name] = node
        for node in self.nodes:
            for parent in node.parents:
                if parent not in by_name:
                    raise ValueError(f"Node {node.name!r}: unknown parent {parent!r}")
                if by_name[parent].cpt.shape[-1] != node.cpt.shape[node.parents.index(parent)]:
                    raise ValueError(
                        f"Node {node.name!r}: cpt axis for parent {parent!r} has size "
                        f"{node.cpt.shape[node.parents.index(parent)]}, the parent has "
                        f"{len(by_name[parent].states)} states"
                    )
        order: list[str] = []
        pending = dict(by_name)
        while pending:
            ready = [n for n, node in pending.items() if all(p in order for p in node.parents)]
            if not ready:
                raise ValueError(f"the network has a cycle among {sorted(pending)}")
            for n in ready:
                order.append(n)
                del pending[n]
        self.variables = tuple(order)
        self._by_name = by_name
        self._axis = {n: k for k, n in enumerate(order)}
        shape = tuple(len(by_name[n].states) for n in order)
        joint = np.ones(shape, dtype=np.float64)
        amplitude = np.ones(shape, dtype=np.complex128)
        for node in by_name.values():
            phases = np.zeros_like(node.cpt) if node.phases is None else node.phases
            joint = joint * self._broadcast(node, node.cpt)
            amplitude = amplitude * self._broadcast(node, np.sqrt(node.cpt) * np.exp(1j * phases))
        self._joint = joint
        self._amplitude = amplitude

    def _broadcast(self, node: Node, table: NDArray[np.generic]) -> NDArray[np.generic]:
        """Lay a CPT-shaped table on the joint tensor's axes (size 1 on uninvolved variables)."""
        axes = [self._axis[p] for p in node.parents] + [self._axis[node.name]]
        perm = np.argsort(axes)
        shape = [1] * len(self.variables)
        for ax in axes:
            shape[ax] = len(self._by_name[self.variables[ax]].states)
        return np.transpose(table, perm).reshape(shape)

    def node(self, name: str) -> Node:
        """The node called ``name``."""
        if name not in self._by_name:
            raise KeyError(f"unknown variable {name!r}; variables are {self.variables}")
        return self._by_name[name]

    def joint(self) -> FloatArray:
        """The full classical joint distribution, one axis per variable in :attr:`variables` order."""
        return self._joint.copy()

    def _state_index(self, var: str, state: int | str) -> int:
        """Index of ``state`` (a name or an index) of variable ``var``, with a clear error."""
        states = self.node(var).states
        if isinstance(state, str):
            if state not in states:
                raise ValueError(f"variable {var!r} has no state {state!r}; states are {states}")
            return states.index(state)
        if not 0 <= int(state) < len(states):
            raise ValueError(f"variable {var!r}: state index {state} out of range for {len(states)} states")
        return int(state)

    def _slice(
        self, tensor: NDArray[np.generic], query: str, evidence: Mapping[str, int | str]
    ) -> NDArray[np.generic]:
        """Rows = query values, columns = configurations of the unobserved variables (C order)."""
        self.node(query)
        if query in evidence:
            raise ValueError(f"query variable {query!r} is also given as evidence")
        index: list[int | slice] = [slice(None)] * len(self.variables)
        for var, state in evidence.items():
            index[self._axis[self.node(var).name]] = self._state_index(var, state)
        sliced = tensor[tuple(index)]
        free = [v for v in self.variables if v not in evidence]
        sliced = np.moveaxis(sliced, free.index(query), 0)
        return sliced.reshape(sliced.shape[0], -1)

    def posterior(
        self,
        query: str,
        evidence: Mapping[str, int | str] | None = None,
        *,
        interference: Interference = "off",
        theta: ArrayLike | None = None,
        positive: int | str = 0,
    ) -> FloatArray:
        """``Pr(query | evidence)`` over the query's states, classical or with interference.

        Args:
            query: Query variable.
            evidence: Observed variables, state name or index each.
            interference: ``"off"``: classical enumeration (plain Bayes). ``"phases"``: the exact quantum
                marginal ``alpha |sum_y prod_k psi|^2`` with the nodes' CPT phases (M&W 2016, Eq. 25).
                ``"heuristic"``: the expanded form (Eq. 26) with one theta per pair of unobserved
                configurations from the similarity heuristic, the same theta for every query value; the
                query must be binary. For more than two configurations this pairwise reading is
                unverified and the cosines need not come from real phases, so a score can go negative;
                it is clipped to 0. ``"explicit"``: Eq. 26 with the caller's ``theta``.
            theta: For ``"explicit"``: a scalar for every pair, or ``m(m-1)/2`` values for the pairs of
                the m unobserved configurations in ``numpy.triu_indices(m, 1)`` order (C order of the
                unobserved variables in :attr:`variables` order).
            positive: For ``"heuristic"``: the query state that plays "true" (vector a); the heuristic is
                not symmetric in a and b.

        Returns:
            Probabilities over the query's states; they sum to 1.
        """
        evidence = dict(evidence or {})
        probs = self._slice(self._joint, query, evidence)
        if np.sum(probs) <= 0.0:
            raise ValueError(f"evidence {evidence} has zero probability")
        if interference == "off":
            scores = probs.sum(axis=1)
        elif interference == "phases":
            scores = np.abs(self._slice(self._amplitude, query, evidence).sum(axis=1)) ** 2
            if np.sum(scores) <= _DEGENERATE_RTOL * np.sum(probs):
                scores = probs.sum(axis=1)  # total destructive interference: documented classical fallback
        elif interference in ("heuristic", "explicit"):
            scores = self._pairwise_scores(probs, query, interference, theta, positive)
        else:
            raise ValueError(
                f"interference must be 'off', 'phases', 'heuristic' or 'explicit', got {interference!r}"
            )
        return scores / scores.sum()

    def _pairwise_scores(
        self,
        probs: FloatArray,
        query: str,
        interference: Interference,
        theta: ArrayLike | None,
        positive: int | str,
    ) -> FloatArray:
        """Unnormalised Eq. 26 scores per query value with one cosine per configuration pair."""
        m = probs.shape[1]
        i, j = _pair_indices(m)
        if interference == "heuristic":
            if probs.shape[0] != 2:
                raise ValueError(
                    f"the similarity heuristic needs a binary query; {query!r} has {probs.shape[0]} states"
                )
            pos = self._state_index(query, positive)
            a, b = probs[pos], probs[1 - pos]
            cos_t = np.cos(similarity_phase(np.stack([a[i], a[j]], -1), np.stack([b[i], b[j]], -1)))
        else:
            if theta is None:
                raise ValueError("interference='explicit' needs theta")
            th = np.asarray(theta, dtype=np.float64)
            if th.ndim > 0 and th.shape != (i.size,):
                raise ValueError(
                    f"theta must be a scalar or have {i.size} entries (pairs of {m} configurations), "
                    f"got shape {th.shape}"
                )
            cos_t = np.broadcast_to(np.cos(th), (i.size,))
        scores = probs.sum(axis=1) + 2.0 * (np.sqrt(probs[:, i] * probs[:, j]) @ cos_t)
        scores = np.maximum(scores, 0.0)
        if scores.sum() <= _DEGENERATE_RTOL * probs.sum():
            return probs.sum(axis=1)  # interference cancelled everything: documented classical fallback
        return scores


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
