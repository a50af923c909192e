"""Gymnasium's env checker on every row of the wrapper table (and the degraded oracles), as users run it."""

from __future__ import annotations

import warnings

import pytest
from gymnasium.utils.env_checker import check_env

from rollout.build import make_env
from rollout.wrappers import INTENTION_WRAPPERS, NONE, TRAJECTORY_WRAPPERS

WRAPPED_NOTICE = "is different from the unwrapped version"
"""Gymnasium's notice that the env under test is wrapped: that is the point of these checks."""

COMBOS = [(name, NONE) for name in INTENTION_WRAPPERS] + [(NONE, name) for name in TRAJECTORY_WRAPPERS]
COMBOS += [("oracle-flip=0.2", "oracle-noise=0.5"), ("learned", "s-cgru")]


@pytest.mark.parametrize(("intention", "predictor"), COMBOS)
def test_gymnasium_checker_passes_with_no_warning_under_each_wrapper(intention: str, predictor: str):
    env, used = make_env("busy_zebra", intention, predictor)
    try:
        assert len(used) == (intention != NONE) + (predictor != NONE)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            check_env(env, skip_render_check=True)
        unexpected = [str(w.message) for w in caught if WRAPPED_NOTICE not in str(w.message)]
        assert not unexpected, unexpected
    finally:
        env.close()
