"""The kernels' stable argsort (one copy per module that sorts) gives exactly NumPy's mergesort indices."""

from __future__ import annotations

import numpy as np
import pytest

from crossing_env import observation
from crossing_env.pedestrians import social_force


@pytest.mark.parametrize("module", [observation, social_force], ids=lambda m: m.__name__)
@pytest.mark.parametrize("n", [0, 1, 2, 3, 7, 16, 33, 200])
def test_same_indices_as_numpy_mergesort(module: object, n: int) -> None:
    rng = np.random.default_rng(n)
    for _ in range(20):
        ties = rng.choice([0.0, 1.5, -2.0, np.inf, -np.inf, np.nan], size=n)  # many ties, NaN and inf
        values = np.where(rng.random(n) < 0.5, ties, rng.normal(size=n))
        got = module._stable_argsort(values)
        assert got.dtype == np.int64
        np.testing.assert_array_equal(got, np.argsort(values, kind="mergesort"))
