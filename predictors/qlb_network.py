"""A small discrete Bayesian network with exact inference, classical or quantum-like (M&W 2016).

C. Moreira and A. Wichert, "Quantum-Like Bayesian Networks for Modeling Decision Making", Front. Psychol.
7:11 (2016) (below: M&W 2016). Every CPT entry becomes an amplitude ``psi = sqrt(P) * exp(i * theta)``;
the probability of a query sums the amplitudes of the unobserved configurations before squaring, so it
carries interference terms ``2 * sqrt(p_i * p_j) * cos(theta_i - theta_j)`` on top of the classical
marginal, and is normalised over the query values (alpha). With ``cos = 0`` everything collapses to the
classical Bayesian network.

:class:`Node` / :class:`QuantumLikeBayesNet`: full enumeration, fine for the handful of variables used for
crossing intention (:mod:`predictors.qlb` builds Song 2022's crossing network on it). The QLB maths
(phases, the similarity heuristic) is `crossing_env.pedestrians.quantum`'s.

Departures from the paper (each also noted where it happens):

* Degenerate geometry (``||a|| = 0``, ``||b|| = 0`` or ``a = b``) has no angles; we fall back to
  ``cos(theta) = 0``, i.e. the classical result. When interference cancels both scores down to rounding
  noise (``T + F ~ 0``) we also return the classical result instead of dividing noise by noise.
* With more than two unobserved configurations the network's heuristic mode applies the rule to each pair
  ``(i, j)`` with the 2-D vectors ``[a_i, a_j]`` and ``[b_i, b_j]``, one reading of M&W 2016 Fig. 3 (not
  verified).
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
    _pair_indices,
    similarity_phase,
)

__all__ = ["Node", "QuantumLikeBayesNet"]


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
