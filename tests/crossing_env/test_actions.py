"""Strict actions: wrong types and shapes are refused, out-of-range values clipped (issue 16)."""

from __future__ import annotations

import numpy as np
import pytest

from crossing_env import CrossingEnv
from crossing_env.env import check_action


@pytest.mark.parametrize(
    "bad",
    ["0.5", b"0.5", 0.5 + 0.1j, np.array([0.5 + 0j]), np.zeros((1, 1)), np.zeros(2), [], True, None, np.nan],
)
def test_bad_actions_are_refused_with_the_value_named(bad):
    with pytest.raises(ValueError, match="one finite real number") as err:
        check_action(bad)
    assert "clipped" in str(err.value)


@pytest.mark.parametrize(
    "good", [0.5, np.float32(0.5), np.array([0.5], dtype=np.float32), np.array(0.5), [0.5]]
)
def test_good_actions_are_accepted(good):
    assert check_action(good) == pytest.approx(0.5)


def test_out_of_range_actions_are_clipped_like_the_bounds():
    def ego_speed_after(action: float) -> float:
        env = CrossingEnv()
        env.reset(seed=3)
        for _ in range(5):
            env.step(np.array([action], dtype=np.float32))
        return float(env.unwrapped.world.ground_truth().ego_velocity[0])

    assert ego_speed_after(7.0) == ego_speed_after(1.0)
    assert ego_speed_after(-7.0) == ego_speed_after(-1.0)
    assert ego_speed_after(1.0) > ego_speed_after(-1.0)


def test_env_step_refuses_a_string():
    env = CrossingEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"'0\.5'"):
        env.step("0.5")
