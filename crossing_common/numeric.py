"""numpy's two-float ``maximum`` / ``minimum`` inside numba kernels, to the last bit.

Kernels that replace numpy expressions must give the same floats, so that a compiled rule drives exactly
as its numpy form did. Python's ``max`` and a plain ``a if a > b else b`` differ from ``np.maximum`` on
NaN (numpy returns it) and on a tie of ``-0.0`` and ``0.0`` (numpy returns the second operand).
"""

from __future__ import annotations

from numba import njit

__all__ = ["numpy_maximum", "numpy_minimum"]


@njit(cache=True, nogil=True, error_model="numpy")
def _numpy_pick(a: float, b: float, a_wins: bool) -> float:
    """What `np.maximum` / `np.minimum` return for two floats, given whether `a` compares better.

    A NaN operand is returned itself (the first if both are NaN); otherwise `a` if it wins, else `b` (so
    `b` on a tie, as numpy: ±0).
    """
    if a != a:
        return a
    if b != b:
        return b
    return a if a_wins else b


@njit(cache=True, nogil=True, error_model="numpy")
def numpy_maximum(a: float, b: float) -> float:
    """`np.maximum(a, b)` of two floats, as numpy gives it."""
    return _numpy_pick(a, b, a > b)


@njit(cache=True, nogil=True, error_model="numpy")
def numpy_minimum(a: float, b: float) -> float:
    """`np.minimum(a, b)` of two floats, as numpy gives it."""
    return _numpy_pick(a, b, a < b)
