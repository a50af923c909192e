"""Quantum-like Bayesian (QLB) probability maths: interference and the similarity heuristic.

The simulated pedestrians decide with it (`crossing_env.pedestrians.crossing_decisions`) and the
crossing-intention predictor builds its network on it (`predictors.qlb`), so it lives here, in the
simulator's layer, once.

The method follows C. Moreira and A. Wichert, "Quantum-Like Bayesian Networks for Modeling Decision
Making", Front. Psychol. 7:11 (2016) (below: M&W 2016), as used by Q. Song et al., "Research on quantum
cognition in autonomous driving", Sci. Rep. 12:300 (2022) (below: Song 2022). Every CPT entry becomes an
amplitude ``psi = sqrt(P) * exp(i * theta)``; the probability of a query sums the amplitudes of the
unobserved configurations before squaring, so it carries interference terms
``2 * sqrt(p_i * p_j) * cos(theta_i - theta_j)`` on top of the classical marginal, and is normalised over
the query values (alpha). With ``cos = 0`` everything collapses to the classical Bayesian probability.

Vectorised for the world's hot path (many pedestrians per step): :func:`similarity_phase`,
:func:`interference_probability`, :func:`pairwise_interference_probability`,
:func:`disjunction_probabilities` and the scalar :func:`disjunction_probability`. Song 2022's case 2
force-intensity update built on them is `crossing_env.pedestrians.force_update`.

Departures from the papers (each also noted where it happens):

* Song 2022 prints the similarity heuristic's side as ``||c|| = ||a|| - ||b||``; that flattens the triangle
  and yields ``theta = pi`` for every input. We use M&W 2016's ``||c|| = ||a - b||``.
* Degenerate geometry (``||a|| = 0``, ``||b|| = 0`` or ``a = b``) has no angles; we fall back to
  ``cos(theta) = 0``, i.e. the classical result. When interference cancels both scores down to rounding
  noise (``T + F ~ 0``) we also return the classical result instead of dividing noise by noise.
* How Song 2022 update force intensities is not documented in a form we could verify; the mapping
  (`crossing_env.pedestrians.force_update.ForceUpdateConfig`) is our design.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "Interference",
    "disjunction_probabilities",
    "disjunction_probability",
    "heuristic_rule",
    "interference_probability",
    "pairwise_interference_probability",
    "similarity_geometry",
    "similarity_phase",
    "triangle_angles",
]

FloatArray = NDArray[np.float64]
Interference = Literal["off", "phases", "heuristic", "explicit"]

PHI_LOW = 0.0
"""Lower threshold of the ratio phi in the similarity heuristic (M&W 2016, Eq. 34)."""
PHI_HIGH = 0.2
"""Upper threshold of the ratio phi in the similarity heuristic (M&W 2016, Eq. 34)."""
_DEGENERATE_RTOL = 1e-12
"""Relative size below which a vector norm, or an interfered score sum, counts as zero."""
_TINY = 1e-300
"""Floor for denominators on the hot path; degenerate entries are overwritten afterwards."""
_PROB_ATOL = 1e-9
"""Tolerance for probabilities slightly outside [0, 1] and CPT rows not summing exactly to 1."""


# ---------------------------------------------------------------------------------------------------------
# Similarity heuristic (M&W 2016, Section 6)
# ---------------------------------------------------------------------------------------------------------
def triangle_angles(
    norm_a: ArrayLike, norm_b: ArrayLike, norm_c: ArrayLike
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Angles of the triangle with sides ``||a||, ||b||, ||c||`` by the law of cosines (M&W 2016, Eqs. 29-31).

    Exposed on its own so that callers (and tests) can see what a wrong ``||c||`` does. Every ``acos``
    argument is clipped to [-1, 1] against rounding; zero-length sides give NaN (callers guard them).

    Args:
        norm_a: ``||a||``, any shape broadcastable with the others.
        norm_b: ``||b||``.
        norm_c: ``||c||``.

    Returns:
        ``(theta_a, theta_b, theta_c)`` in radians: theta_a opposite side a (between b and c), theta_b
        opposite side b (between a and c), theta_c opposite side c (between a and b).
    """
    na, nb, nc = (np.asarray(x, dtype=np.float64) for x in (norm_a, norm_b, norm_c))
    na2, nb2, nc2 = na * na, nb * nb, nc * nc
    with np.errstate(divide="ignore", invalid="ignore"):
        cos_a = (nb2 + nc2 - na2) / (2.0 * nb * nc)
        cos_b = (na2 + nc2 - nb2) / (2.0 * na * nc)
        cos_c = (na2 + nb2 - nc2) / (2.0 * na * nb)
    return (
        np.arccos(np.clip(cos_a, -1.0, 1.0)),
        np.arccos(np.clip(cos_b, -1.0, 1.0)),
        np.arccos(np.clip(cos_c, -1.0, 1.0)),
    )


def heuristic_rule(theta_a: ArrayLike, theta_b: ArrayLike, theta_c: ArrayLike) -> FloatArray:
    """The piecewise rule h(a, b) of M&W 2016, Eqs. 33-34, from the triangle's angles.

    ``phi = (theta_c - theta_b) / theta_a``; ``h = pi`` if ``phi < 0``, ``pi - theta_c / 2`` if ``phi > 0.2``
    and ``pi - theta_c`` otherwise (boundaries included). A flat triangle with ``theta_a = 0`` only arises
    when a and b are parallel, where ``theta_c = 0`` and all three branches give ``pi``; we take the middle
    branch there instead of dividing by zero.

    Args:
        theta_a: Angle opposite side a (radians).
        theta_b: Angle opposite side b (radians).
        theta_c: Angle between a and b (radians).

    Returns:
        The phase theta in radians, broadcast shape of the inputs.
    """
    ta, tb, tc = (np.asarray(x, dtype=np.float64) for x in (theta_a, theta_b, theta_c))
    flat = ~(ta > 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        phi = np.where(flat, PHI_LOW, (tc - tb) / np.where(flat, 1.0, ta))
    return np.where(phi < PHI_LOW, np.pi, np.where(phi > PHI_HIGH, np.pi - 0.5 * tc, np.pi - tc))


def _as_pair_vectors(a: ArrayLike, b: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Validate two stacks of 2-D probability vectors of equal shape ``(..., 2)``."""
    a_arr = np.asarray(a, dtype=np.float64)
    b_arr = np.asarray(b, dtype=np.float64)
    if a_arr.shape != b_arr.shape or a_arr.ndim < 1 or a_arr.shape[-1] != 2:
        raise ValueError(
            f"similarity heuristic: a and b must both have shape (..., 2); "
            f"got a {a_arr.shape}, b {b_arr.shape}"
        )
    _check_probs("similarity heuristic: a", a_arr)
    _check_probs("similarity heuristic: b", b_arr)
    return a_arr, b_arr


def _side_norms(
    a0: FloatArray, a1: FloatArray, b0: FloatArray, b1: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``||a||``, ``||b||`` and the correct ``||c|| = ||a - b||`` (M&W 2016, Eq. 28) of 2-D vectors."""
    return np.hypot(a0, a1), np.hypot(b0, b1), np.hypot(a0 - b0, a1 - b1)


def _degenerate(na: FloatArray, nb: FloatArray, nc: FloatArray) -> NDArray[np.bool_]:
    """Where the triangle is undefined: ``a = 0``, ``b = 0`` or ``a = b`` (relative to the vector sizes)."""
    tiny = _DEGENERATE_RTOL * np.maximum(na, nb)
    return (na <= tiny) | (nb <= tiny) | (nc <= tiny)


def _phase(a0: FloatArray, a1: FloatArray, b0: FloatArray, b1: FloatArray) -> FloatArray:
    """Unchecked similarity heuristic on the components of 2-D vectors a and b (hot path).

    The same triangle as :func:`triangle_angles` with ``||c|| = ||a - b||``, computed with fewer array
    passes: theta_c from the dot product, theta_b by the law of cosines and ``theta_a = pi - theta_b -
    theta_c`` (the angles of a triangle sum to pi). Tests check it against the law-of-cosines path.
    """
    na2 = a0 * a0 + a1 * a1
    nb2 = b0 * b0 + b1 * b1
    d0 = a0 - b0
    d1 = a1 - b1
    nc2 = d0 * d0 + d1 * d1
    tc = np.arccos(np.clip((a0 * b0 + a1 * b1) / np.maximum(np.sqrt(na2 * nb2), _TINY), -1.0, 1.0))
    tb = np.arccos(np.clip((na2 + nc2 - nb2) / np.maximum(2.0 * np.sqrt(na2 * nc2), _TINY), -1.0, 1.0))
    ta = np.pi - tb - tc
    phi = np.where(ta > 0.0, (tc - tb) / np.maximum(ta, _TINY), PHI_LOW)
    theta = np.where(phi < PHI_LOW, np.pi, np.where(phi > PHI_HIGH, np.pi - 0.5 * tc, np.pi - tc))
    tiny2 = (_DEGENERATE_RTOL * _DEGENERATE_RTOL) * np.maximum(na2, nb2)
    degenerate = (na2 <= tiny2) | (nb2 <= tiny2) | (nc2 <= tiny2)
    return np.where(degenerate, 0.5 * np.pi, theta)


def similarity_geometry(a: ArrayLike, b: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Triangle angles and ratio phi of the similarity heuristic, batched over leading axes.

    ``c = a - b`` and ``||c|| = ||a - b||`` (M&W 2016, Eq. 28). Song 2022 misprint this as
    ``||a|| - ||b||``, which makes the triangle flat and the rule constant (``theta = pi``); we follow M&W.

    Args:
        a: Shape ``(..., 2)``: joint probabilities with the query true, one per unobserved configuration.
        b: Shape ``(..., 2)``: the same with the query false.

    Returns:
        ``(theta_a, theta_b, theta_c, phi)``, each of shape ``a.shape[:-1]``; NaN where the geometry is
        degenerate (a zero vector or ``a = b``).
    """
    a_arr, b_arr = _as_pair_vectors(a, b)
    na, nb, nc = _side_norms(a_arr[..., 0], a_arr[..., 1], b_arr[..., 0], b_arr[..., 1])
    ta, tb, tc = triangle_angles(na, nb, nc)
    with np.errstate(divide="ignore", invalid="ignore"):
        phi = (tc - tb) / ta
    bad = _degenerate(na, nb, nc)
    return tuple(np.where(bad, np.nan, x) for x in (ta, tb, tc, phi))  # type: ignore[return-value]


def similarity_phase(a: ArrayLike, b: ArrayLike) -> FloatArray:
    """Phase theta from the similarity heuristic h(a, b) (M&W 2016, Section 6), batched over leading axes.

    Uses ``||c|| = ||a - b||`` (M&W 2016, Eq. 28), fixing the ``||a|| - ||b||`` misprint in Song 2022.
    Where the geometry is degenerate (``||a|| = 0``, ``||b|| = 0`` or ``a = b``) the angles are undefined
    and we return ``pi / 2`` (``cos = 0``): the documented fallback to the classical result.

    Args:
        a: Shape ``(..., 2)``: probabilities (not amplitudes, not normalised) with the query true, one per
            unobserved configuration, e.g. ``[P(y1) P(x | y1), P(y2) P(x | y2)]``.
        b: Shape ``(..., 2)``: the same with the query false.

    Returns:
        theta in radians, shape ``a.shape[:-1]``, in ``[pi / 2, pi]``.
    """
    a_arr, b_arr = _as_pair_vectors(a, b)
    return _phase(a_arr[..., 0], a_arr[..., 1], b_arr[..., 0], b_arr[..., 1])


# ---------------------------------------------------------------------------------------------------------
# Quantum marginal for a binary query (M&W 2016, Eqs. 24-26), vectorised
# ---------------------------------------------------------------------------------------------------------
def _check_probs(name: str, x: FloatArray) -> None:
    """Reject non-finite or negative joint probabilities with a message naming the argument."""
    if x.size and not (x.min() >= 0.0 and x.max() < np.inf):  # NaN fails both comparisons
        raise ValueError(f"{name} must be finite and non-negative (joint probabilities); got {x!r}")


def _check_unit(name: str, x: ArrayLike) -> FloatArray:
    """Reject values outside [0, 1] (beyond a rounding tolerance) and clip the rest."""
    arr = np.asarray(x, dtype=np.float64)
    if arr.size == 0:
        return arr
    lo, hi = arr.min(), arr.max()
    if not (lo >= -_PROB_ATOL and hi <= 1.0 + _PROB_ATOL):  # NaN fails both comparisons
        raise ValueError(f"{name} must be probabilities in [0, 1]; got {x!r}")
    return arr if (lo >= 0.0 and hi <= 1.0) else np.clip(arr, 0.0, 1.0)


def _check_cos(cos_theta: ArrayLike) -> FloatArray:
    """Reject cosines outside [-1, 1] (beyond rounding) and clip the rest."""
    c = np.asarray(cos_theta, dtype=np.float64)
    if c.size == 0:
        return c
    lo, hi = c.min(), c.max()
    if not (lo >= -1.0 - _PROB_ATOL and hi <= 1.0 + _PROB_ATOL):  # NaN fails both comparisons
        raise ValueError(f"cos_theta must be finite and within [-1, 1]; got {cos_theta!r}")
    return c if (lo >= -1.0 and hi <= 1.0) else np.clip(c, -1.0, 1.0)


def _check_theta(theta: ArrayLike) -> FloatArray:
    """Reject non-finite phases."""
    th = np.asarray(theta, dtype=np.float64)
    if not np.all(np.isfinite(th)):
        raise ValueError(f"theta must be finite radians; got {theta!r}")
    return th


def _normalise_with_fallback(t: FloatArray, f: FloatArray, ct: FloatArray, cf: FloatArray) -> FloatArray:
    """``T / (T + F)``, or the classical ``ct / (ct + cf)`` where interference cancelled both to noise."""
    classical_total = ct + cf
    if not np.all(classical_total > 0.0):
        raise ValueError("the evidence has zero probability: every joint entry of the query is 0")
    t = np.maximum(t, 0.0)
    total = t + np.maximum(f, 0.0)
    ok = total > _DEGENERATE_RTOL * classical_total
    return np.where(ok, t / np.where(ok, total, 1.0), ct / classical_total)


def _interference(
    p1: FloatArray, p2: FloatArray, q1: FloatArray, q2: FloatArray, c: FloatArray
) -> FloatArray:
    """Unchecked two-configuration quantum marginal (hot path)."""
    t = p1 + p2 + 2.0 * np.sqrt(p1 * p2) * c
    f = q1 + q2 + 2.0 * np.sqrt(q1 * q2) * c
    return _normalise_with_fallback(t, f, p1 + p2, q1 + q2)


def interference_probability(
    p1: ArrayLike, p2: ArrayLike, q1: ArrayLike, q2: ArrayLike, cos_theta: ArrayLike
) -> FloatArray:
    """``Pr(x = true | e)`` with one binary unobserved cause, batched (M&W 2016, Eqs. 26 and 42-45).

    ``T = p1 + p2 + 2 sqrt(p1 p2) cos theta``, ``F = q1 + q2 + 2 sqrt(q1 q2) cos theta`` with the same theta
    for both outcomes, then ``T / (T + F)``. ``cos_theta = 0`` is exactly the classical posterior. Where
    destructive interference cancels both scores down to rounding noise the classical value is returned.

    Args:
        p1: ``P(x = true, e, y = 1)``; all arguments broadcast together.
        p2: ``P(x = true, e, y = 2)``.
        q1: ``P(x = false, e, y = 1)``.
        q2: ``P(x = false, e, y = 2)``.
        cos_theta: Cosine of the phase difference, in [-1, 1].

    Returns:
        Probabilities in [0, 1], broadcast shape of the inputs.
    """
    arrays = [np.asarray(x, dtype=np.float64) for x in (p1, p2, q1, q2)]
    for name, arr in zip(("p1", "p2", "q1", "q2"), arrays, strict=True):
        _check_probs(name, arr)
    return _interference(*arrays, _check_cos(cos_theta))


def _pair_indices(m: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Indices ``(i, j)`` with ``i < j`` of the interference pairs among m configurations."""
    i, j = np.triu_indices(m, k=1)
    return i.astype(np.intp), j.astype(np.intp)


def _pairwise(p: FloatArray, q: FloatArray, cos_t: FloatArray) -> FloatArray:
    """Unchecked m-configuration quantum marginal with one cosine per pair (hot path)."""
    i, j = _pair_indices(p.shape[-1])
    rp, rq = np.sqrt(p), np.sqrt(q)
    ct, cf = p.sum(axis=-1), q.sum(axis=-1)
    t = ct + 2.0 * np.sum(rp[..., i] * rp[..., j] * cos_t, axis=-1)
    f = cf + 2.0 * np.sum(rq[..., i] * rq[..., j] * cos_t, axis=-1)
    return _normalise_with_fallback(t, f, ct, cf)


def pairwise_interference_probability(
    p: ArrayLike, q: ArrayLike, cos_theta: ArrayLike | None = None
) -> FloatArray:
    """``Pr(x = true | e)`` with m unobserved configurations and one phase per pair, batched.

    ``T = sum_i p_i + 2 sum_{i<j} sqrt(p_i p_j) cos theta_ij`` and likewise F from q (M&W 2016, Eq. 26).
    With ``cos_theta=None`` each ``theta_ij`` comes from the similarity heuristic on ``[p_i, p_j]`` and
    ``[q_i, q_j]``: exact for m = 2, one reading of M&W 2016 Fig. 3 for m > 2. For m > 2 cosines that do
    not come from real phases (or from a positive semi-definite matrix) can make a score negative; it is
    clipped to 0, and if both scores vanish the classical value is returned.

    Args:
        p: Shape ``(..., m)``: ``P(x = true, e, y = i)``.
        q: Shape ``(..., m)``: ``P(x = false, e, y = i)``.
        cos_theta: None (heuristic), or cosines broadcastable to ``(..., m(m-1)/2)`` in the pair order of
            ``numpy.triu_indices(m, 1)``.

    Returns:
        Probabilities of shape ``p.shape[:-1]``.
    """
    p_arr = np.asarray(p, dtype=np.float64)
    q_arr = np.asarray(q, dtype=np.float64)
    if p_arr.shape != q_arr.shape or p_arr.ndim < 1:
        raise ValueError(f"p and q must have the same shape (..., m); got {p_arr.shape} and {q_arr.shape}")
    _check_probs("p", p_arr)
    _check_probs("q", q_arr)
    i, j = _pair_indices(p_arr.shape[-1])
    if cos_theta is None:
        cos_t = np.cos(_phase(p_arr[..., i], p_arr[..., j], q_arr[..., i], q_arr[..., j]))
    else:
        cos_t = _check_cos(cos_theta)
    return _pairwise(p_arr, q_arr, cos_t)


def disjunction_probabilities(
    p_true_given_a: ArrayLike,
    p_true_given_b: ArrayLike,
    prior_a: ArrayLike = 0.5,
    theta: ArrayLike | None = None,
) -> FloatArray:
    """Vectorised :func:`disjunction_probability`: arrays in (broadcast together), array out.

    Args:
        p_true_given_a: ``P(query | cause = A)``.
        p_true_given_b: ``P(query | cause = B)``.
        prior_a: ``P(cause = A)``; ``P(cause = B) = 1 - prior_a``.
        theta: Phase difference in radians (broadcast), or None for the similarity heuristic.

    Returns:
        ``Pr(query)`` with the cause unobserved, in [0, 1].
    """
    pa = _check_unit("p_true_given_a", p_true_given_a)
    pb = _check_unit("p_true_given_b", p_true_given_b)
    pr = _check_unit("prior_a", prior_a)
    p1, p2 = pr * pa, (1.0 - pr) * pb
    q1, q2 = pr * (1.0 - pa), (1.0 - pr) * (1.0 - pb)
    th = _phase(p1, p2, q1, q2) if theta is None else _check_theta(theta)
    return _interference(p1, p2, q1, q2, np.cos(th))


def disjunction_probability(
    p_true_given_a: float, p_true_given_b: float, prior_a: float = 0.5, theta: float | None = None
) -> float:
    """Probability of a binary query when its binary cause is not observed (the disjunction condition).

    The classic case is the prisoner's dilemma with the opponent's move unknown (M&W 2016, Section 7):
    ``P(defect | opponent defected)``, ``P(defect | opponent cooperated)`` and a 0.5 prior give
    ``Pr(defect)`` with interference. ``theta=None`` uses the similarity heuristic (with the correct
    ``||c|| = ||a - b||``); ``theta = pi / 2`` gives the classical law of total probability.

    Args:
        p_true_given_a: ``P(query | cause = A)`` in [0, 1].
        p_true_given_b: ``P(query | cause = B)`` in [0, 1].
        prior_a: ``P(cause = A)`` in [0, 1].
        theta: Phase difference in radians, or None for the similarity heuristic.

    Returns:
        ``Pr(query)`` in [0, 1].
    """
    return float(disjunction_probabilities(p_true_given_a, p_true_given_b, prior_a, theta))
