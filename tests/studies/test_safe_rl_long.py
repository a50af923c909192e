"""The long PPO-Lagrangian study: the safe-RL recipe with only its length, checkpoints and budget changed."""

from __future__ import annotations

import types
from pathlib import Path

import numpy as np
import pytest

import studies.safe_rl as safe_rl
import studies.safe_rl_long as long


def test_recipe_is_the_safe_rl_lagrangian_recipe_with_only_length_checkpoints_and_budget_changed() -> None:
    base = [*safe_rl.RECIPE, *safe_rl.LEARNER_RECIPE["ppo_lagrangian"]]
    args = long.recipe(1.0)
    assert args[-2:] == ["--cost-budget", "1"]
    changed = {base[i - 1]: (base[i], args[i]) for i in range(1, len(base)) if base[i] != args[i]}
    assert changed == {
        "--timesteps": ("50000", str(long.LONG_TIMESTEPS)),
        "--eval-every": ("10000", str(long.CHECKPOINT_EVERY)),
    }
    assert len(args) == len(base) + 2
    assert long.run_folder(Path("r"), 2.0, 1) == Path("r/budget_2.0/seed_1")


def _record(scenario: str, collision: bool, violations: int) -> types.SimpleNamespace:
    result = {
        "collision": collision,
        "yield_obligations": 4,
        "yield_violations": violations,
        "delay": 2.0,
        "passed_crossing": True,
        "serious_conflict_time": 0.3,
        "steps": 200,
        "duration": 20.0,
    }
    return types.SimpleNamespace(task=types.SimpleNamespace(scenario=scenario), result=result)


def test_at_yielding_counts_scenarios_with_no_more_collisions_and_at_least_the_compliance(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(safe_rl, "_duration", lambda scenario: 30.0)
    reference = {
        "a": {"collisions": 0, "compliance": 1.0},
        "b": {"collisions": 1, "compliance": 0.75},
        "c": {"collisions": 0, "compliance": float("nan")},
        "d": {"collisions": 0, "compliance": 1.0},
    }
    records = [
        _record("a", False, 0),  # as safe
        _record("b", True, 1),  # one collision and 0.75 compliance, like the reference
        _record("c", False, 2),  # no obligations in the reference: compliance is not compared
        _record("d", True, 0),  # a collision the reference does not have
    ]
    assert long._at_yielding(records, reference) == 3
    records[1] = _record("b", True, 2)  # 0.5 < 0.75
    assert long._at_yielding(records, reference) == 2


def test_mean_cost_adds_the_collision_the_violations_and_the_near_miss_steps() -> None:
    records = [_record("a", True, 2), _record("a", False, 0)]  # 1 + 2 + 3 steps, then 3 steps
    assert long.mean_cost(records) == pytest.approx(4.5)


def test_seed_curve_adds_the_mean_multiplier_per_bin() -> None:
    episodes = {
        "step": np.array([10.0, 20.0, 150.0]),
        "return": np.zeros(3),
        "cost": np.array([1.0, 3.0, 0.0]),
        "collision": np.array([0.0, 1.0, 0.0]),
        "obligations": np.array([1.0, 1.0, 0.0]),
        "violations": np.array([0.0, 1.0, 0.0]),
        "delay": np.array([1.0, np.nan, 2.0]),
        "duration": np.array([30.0, 30.0, 30.0]),
        "multiplier": np.array([0.5, 1.5, 4.0]),
    }
    out = long.seed_curve(episodes, np.array([0.0, 100.0, 200.0, 300.0]))
    np.testing.assert_allclose(out["multiplier"], [1.0, 4.0, np.nan])
    np.testing.assert_allclose(out["cost"], [2.0, 0.0, np.nan])
    np.testing.assert_allclose(out["censored_delay"], [15.5, 2.0, np.nan])


def test_render_body_has_a_row_per_budget_and_checkpoint() -> None:
    cell = {
        "collisions": 3,
        "compliance": 0.9,
        "censored_delay": 20.0,
        "cost": 2.5,
        "scenarios_at_yielding": 7,
        "episodes": 96,
    }
    data = {
        "timesteps": 300000,
        "seeds": [0, 1],
        "budgets": ["2", "1"],
        "episodes_per_scenario": 8,
        "scenarios": 12,
        "checkpoints": {
            "yielding": {
                "collisions": 0,
                "compliance": 1.0,
                "censored_delay": 9.0,
                "cost": 0.8,
                "episodes": 96,
            },
            "budgets": {b: {"0": {"0": cell, "50000": cell}, "1": {"0": cell}} for b in ("2", "1")},
        },
        "runs": {
            f"{b}/{s}": {
                "train_wall_s": 400.0,
                "final_multiplier": 4.5,
                "last_20k_cost": 1.9,
                "last_20k_collision_rate": 0.05,
            }
            for b in ("2", "1")
            for s in (0, 1)
        },
    }
    text = long.render_body(data)
    assert "| - | `yielding` | 0 / 1.000 / 9.0 / 0.80 / 12 |" in text
    assert "| 2 | 50,000 | 3 / 0.900 / 20.0 / 2.50 / 7 | - |" in text
    assert "| 1 | 0 | 3 / 0.900 / 20.0 / 2.50 / 7 | 3 / 0.900 / 20.0 / 2.50 / 7 |" in text
    assert "| 1 | 1 | 1.90 | 0.050 | 4.50 | 400 |" in text
