"""A stable argsort for the compiled kernels, cheap to compile.

``np.argsort(x, kind="mergesort")`` inside an ``@njit`` kernel pulls in numba's generic merge sort, about
3 s of compilation on a fresh install (every kernel is compiled once, then cached). A stable sort's
permutation is fully determined by the order it sorts by, so this plain bottom-up merge sort, with
NumPy's float order (NaN last), returns exactly the same indices.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _before(a: float, b: float) -> bool:
    """NumPy's sort order for floats: NaN after every number, NaNs equal among themselves."""
    return a < b or (np.isnan(b) and not np.isnan(a))


@njit(cache=True, nogil=True)
def stable_argsort(values: np.ndarray) -> np.ndarray:
    """Indices that sort the 1-D float array `values`, ties in index order (``np.argsort``, mergesort)."""
    n = values.shape[0]
    order = np.empty(n, np.int64)
    for i in range(n):
        order[i] = i
    spare = np.empty(n, np.int64)
    width = 1
    while width < n:
        lo = 0
        while lo < n:
            mid = min(lo + width, n)
            hi = min(lo + 2 * width, n)
            i, j, k = lo, mid, lo
            while i < mid and j < hi:
                if _before(values[order[j]], values[order[i]]):  # strictly before: ties keep the left
                    spare[k] = order[j]
                    j += 1
                else:
                    spare[k] = order[i]
                    i += 1
                k += 1
            while i < mid:
                spare[k] = order[i]
                i += 1
                k += 1
            while j < hi:
                spare[k] = order[j]
                j += 1
                k += 1
            lo = hi
        order, spare = spare, order
        width *= 2
    return order
