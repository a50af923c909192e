"""The constrained-RL interface: the Lagrange multiplier's dual ascent, the shaped reward, the 6-tuple."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from crossing_env import ENV_ID
from crossing_env.constrained import CostBudget, LagrangianReward, Multiplier, SafetyStep


def test_multiplier_rises_above_the_budget_and_falls_to_zero_below_it():
    lam = Multiplier(0.0)
    budget = CostBudget().per_episode
    values = [lam.update(budget + 5.0, budget, 0.1) for _ in range(3)]
    assert values == pytest.approx([0.5, 1.0, 1.5])  # cost above the budget: λ grows by lr·excess
    assert lam.update(budget, budget, 0.1) == pytest.approx(1.5)  # on the budget: unchanged
    for _ in range(10):
        lam.update(0.0, budget, 0.1)
    assert lam.value == 0.0  # below the budget λ falls, and never below zero


def _constant_speed_run(env: gym.Env, steps: int = 120) -> list[tuple[float, dict]]:
    env.reset(seed=1)
    out = []
    for _ in range(steps):
        _, reward, terminated, truncated, info = env.step(np.zeros(1, dtype=np.float32))
        out.append((float(reward), info))
        if terminated or truncated:
            break
    return out


def test_lagrangian_reward_subtracts_lambda_times_the_cost_and_names_the_term():
    plain = _constant_speed_run(gym.make(ENV_ID, scenario="midblock_jaywalker"))
    lam = Multiplier(3.0)
    shaped = _constant_speed_run(LagrangianReward(gym.make(ENV_ID, scenario="midblock_jaywalker"), lam))
    assert len(plain) == len(shaped)
    costly = 0
    for (r0, info0), (r1, info1) in zip(plain, shaped, strict=True):
        assert info1["cost"] == info0["cost"]
        assert r1 == pytest.approx(r0 - 3.0 * info0["cost"])
        assert info1["rewards"]["lagrangian"] == pytest.approx(-3.0 * info0["cost"])
        costly += info0["cost"] > 0
    assert costly > 0  # the jaywalker run at constant speed does cost something


def test_safety_step_returns_the_cost_as_its_third_value():
    env = SafetyStep(gym.make(ENV_ID, scenario="midblock_jaywalker"))
    env.reset(seed=1)
    for _ in range(120):
        _, reward, cost, terminated, truncated, info = env.step(np.zeros(1, dtype=np.float32))
        assert cost == info["cost"] and isinstance(reward, float)
        if terminated or truncated:
            break
