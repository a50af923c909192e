"""The constrained-RL interface: a per-episode cost budget and wrappers that expose ``info["cost"]``.

The env reports a per-step safety cost in ``info["cost"]`` (the sum of ``info["costs"]``: a collision
beginning, each yield obligation violated, a step with pedestrian TTC below the serious threshold — the same
code as the metrics, `crossing_env.safety.step_costs`). A constrained learner keeps the expected episode
cost J_C below a **budget** d (`CostBudget`): max J_R subject to J_C ≤ d.

Two ways to read the cost, as the constrained-RL libraries do:

- ``info["cost"]`` on the Gymnasium 5-tuple (MetaDrive's convention; Safety-Gymnasium's
  ``SafetyGymnasium2Gymnasium`` converter writes the same key) — the bare env already does this;
- `SafetyStep`: Safety-Gymnasium's 6-tuple ``(obs, reward, cost, terminated, truncated, info)``.

`LagrangianReward` shapes the reward to r − λ·cost for a Lagrangian learner (PPO-Lagrangian on
Stable-Baselines3: the multiplier λ is updated by dual ascent outside the env, see
``examples/ppo_crossing.py``) and records the penalty as the named reward term ``lagrangian``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, SupportsFloat

import gymnasium as gym

__all__ = ["CostBudget", "LagrangianReward", "Multiplier", "SafetyStep"]


@dataclass(frozen=True)
class CostBudget:
    """The constraint of a constrained learner: expected episode cost at most `per_episode`."""

    per_episode: float = 2.0
    """Budget d on the expected sum of ``info["cost"]`` over an episode. The rule-based `yielding` policy
    stays below it (its mean episode cost, measured beside the learners in docs/rl.md, is near-miss steps
    that children running out and the NCAP cases make unavoidable); one collision alone costs several times
    the budget (1 plus the near-miss steps before it), one violated obligation 1. A budget this size still
    admits a collision every several episodes (docs/rl.md, "Where PPO-Lagrangian stalls")."""


class Multiplier:
    """The Lagrange multiplier λ ≥ 0, shared by the reward wrappers of one process and the dual update."""

    def __init__(self, value: float = 0.0) -> None:
        self.value = float(value)

    def update(self, mean_episode_cost: float, budget: float, learning_rate: float) -> float:
        """One dual-ascent step λ ← max(0, λ + lr·(J̄_C − d)); returns the new λ."""
        self.value = max(0.0, self.value + learning_rate * (float(mean_episode_cost) - budget))
        return self.value


class LagrangianReward(gym.Wrapper):
    """Reward r − λ·cost (λ from a shared `Multiplier`); the penalty is ``info["rewards"]["lagrangian"]``."""

    def __init__(self, env: gym.Env, multiplier: Multiplier) -> None:
        super().__init__(env)
        self.multiplier = multiplier

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        """Step the env and shape its reward."""
        obs, reward, terminated, truncated, info = self.env.step(action)
        penalty = -self.multiplier.value * float(info["cost"])
        info = {**info, "rewards": {**info.get("rewards", {}), "lagrangian": penalty}}
        return obs, float(reward) + penalty, terminated, truncated, info


class SafetyStep(gym.Wrapper):
    """Safety-Gymnasium's step signature: ``(obs, reward, cost, terminated, truncated, info)``.

    Not a Gymnasium env any more (its checkers expect five values): hand it only to code that reads the cost
    as a separate return, such as a Safety-Gymnasium-style training loop.
    """

    def step(self, action: Any) -> tuple[Any, float, float, bool, bool, dict[str, Any]]:  # type: ignore[override]
        """Step the env; the cost comes out as the third value."""
        obs, reward, terminated, truncated, info = self.env.step(action)
        return obs, float(reward), float(info["cost"]), terminated, truncated, info
