"""A post-posed safety shield: the yielding policy's envelope, inside which a learned policy may act freely.

Each step the shield computes the largest acceleration the rule-based `YieldingPolicy` allows
(`YieldingShield.limit`) and replaces a learned action above it by that limit (Alshiekh et al. 2018's
*post-posed* shield: it corrects an action only when it would leave the envelope). What the envelope holds,
exactly:

- **Stops the rule makes.** The rule's stop targets — the legal yield (a pedestrian on the zebra in or
  towards the ego's half, one waiting at the kerb, a red light) and the conflict check (anyone whose path
  overlaps the car's) — come from `YieldingPolicy`'s own code, offer timers and commitments included. For each
  target the car must stay on or below the comfortable braking profile v = sqrt(2·b·s) one step ahead (b the
  rule's `comfortable_deceleration`); above the profile the limit is the rule's own braking, never weaker.
- **Everything else the rule caps.** Following a vehicle ahead (IDM), the occlusion speed beside a stationary
  vehicle, no overtaking at a zebra, and the speed limit (no speeding).

Below the limit the learned policy is free: it may brake earlier or harder than the rule, accelerate harder
(up to the car's limit, where the rule's cruise control is gentler), and keep speed up to the last point
from which a comfortable stop is still possible (the rule starts braking with a proportional controller
before that). So the learned part can only be *less* cautious than the rule where the envelope allows, and
no more: every stop the rule would make, the shielded policy makes too, at most as late as the comfortable
profile allows.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np

from agents.config import YieldingConfig
from agents.policy import Policy
from agents.view import ObsLike, View, follow, parse_observation, stop_acceleration
from agents.yielding import YieldingPolicy
from crossing_env.env import acceleration_to_action, action_to_acceleration

__all__ = ["ShieldAction", "ShieldedPolicy", "YieldingShield"]


class YieldingShield:
    """The envelope of `YieldingPolicy` as an upper bound on the acceleration (call `limit` once per step)."""

    def __init__(self, config: YieldingConfig | None = None) -> None:
        self.rule = YieldingPolicy(config)
        self.config = self.rule.config

    def reset(self, seed: int | None = None) -> None:
        """Forget the rule's offer timers and commitments (call at every episode start)."""
        self.rule.reset(seed)

    def _profile_limit(self, view: View, target: np.ndarray) -> np.ndarray:
        """Largest acceleration that keeps the car on the comfortable braking profile of `target`."""
        cfg = self.config
        b, dt, v = cfg.comfortable_deceleration, cfg.dt, view.speed
        # Distance left after one step at the car's largest acceleration (a conservative bound).
        s_next = target - v * dt - 0.5 * cfg.ego.max_acceleration * dt * dt
        v_allowed = np.sqrt(2.0 * b * np.maximum(s_next, 0.0))
        profile = (v_allowed - v) / dt
        rule = stop_acceleration(view, target, b, cfg.stop_gain, cfg.ego.max_deceleration)
        return np.where(np.isfinite(target), np.maximum(profile, rule), np.inf)

    def rule_and_limit(self, view: View) -> tuple[np.ndarray, np.ndarray]:
        """(B,) each: the rule's acceleration and the envelope's limit (m/s²); advances the timers once."""
        legal, conflict = self.rule._targets(view)
        return self.rule._acceleration_for(view, legal, conflict), self._limit(view, legal, conflict)

    def limit_from_view(self, view: View) -> np.ndarray:
        """(B,) the largest acceleration (m/s²) the envelope allows now; advances the rule's timers."""
        return self.rule_and_limit(view)[1]

    def _limit(self, view: View, legal: np.ndarray, conflict: np.ndarray) -> np.ndarray:
        cfg = self.config
        # The speed limit, less 0.01 m/s: the float32 action must not round the car over it.
        speed_cap = (cfg.speed_limit - 0.01 - view.speed) / cfg.dt
        caps = np.minimum(
            np.minimum(follow(view, cfg), speed_cap),
            np.minimum(self.rule._occlusion_cap(view), self.rule._no_overtaking(view)),
        )
        stops = np.minimum(self._profile_limit(view, legal), self._profile_limit(view, conflict))
        return np.clip(np.minimum(caps, stops), -cfg.ego.max_deceleration, cfg.ego.max_acceleration)

    def limit(self, obs: ObsLike) -> np.ndarray:
        """(B,) the largest acceleration (m/s²) the envelope allows for `obs`; advances the rule's timers."""
        return self.limit_from_view(parse_observation(obs))

    def apply(self, action: Any, obs: ObsLike, residual_scale: float = 0.0) -> tuple[np.ndarray, bool]:
        """(shielded normalised action of shape (1,), whether the shield changed it) for one observation.

        With ``residual_scale = 0`` the action is the learned acceleration itself (normalised as the env's).
        With ``residual_scale = s > 0`` it is a residual on the rule: the requested acceleration is the rule's
        own plus ``s × action`` m/s², so an action of 0 drives exactly as `yielding` does, and the learned
        part only has to find where to depart from it. Either way the envelope's limit caps the result.
        """
        u = float(np.clip(np.asarray(action, dtype=np.float64).reshape(-1)[0], -1.0, 1.0))
        rule, bound = self.rule_and_limit(parse_observation(obs))
        ego = self.config.ego
        if residual_scale > 0.0:
            wanted = float(np.clip(rule[0] + residual_scale * u, -ego.max_deceleration, ego.max_acceleration))
            requested = acceleration_to_action(np.array([wanted]), ego).reshape(1)
        else:
            wanted = float(action_to_acceleration(u, ego))
            requested = np.array([u], dtype=np.float32)
        if wanted <= float(bound[0]):
            return requested, False
        return acceleration_to_action(np.array([bound[0]]), ego).reshape(1), True


class ShieldedPolicy:
    """A learned policy acting through `YieldingShield` (the composite is what "shielded PPO" deploys)."""

    uses_predictors = False

    def __init__(self, learned: Policy, shield: YieldingShield, residual_scale: float = 0.0) -> None:
        self.learned = learned
        self.shield = shield
        self.residual_scale = residual_scale
        """0: the learned action is the acceleration; > 0: a residual on the rule's (see `apply`)."""
        self.interventions = 0
        """Steps in which the shield replaced the learned action (since the last reset)."""

    def __call__(self, obs: ObsLike) -> np.ndarray:
        """The learned action, replaced by the envelope's limit when above it."""
        action, changed = self.shield.apply(self.learned(obs), obs, self.residual_scale)
        self.interventions += int(changed)
        return action

    def reset(self, seed: int | None = None) -> None:
        """Reset the learned policy and the shield's timers."""
        self.learned.reset(seed)
        self.shield.reset(seed)
        self.interventions = 0


class ShieldAction(gym.Wrapper):
    """Training through the shield: each action passes `YieldingShield.apply` on the latest observation.

    The shield is rebuilt at every reset from the episode's scenario (``make_config(scenario, dt)`` gives the
    rule's config, as `agents.make_policy("yielding", ...)` would), so a scenario drawn per reset gets its
    own speed limit and geometry. ``info["shield"]`` is 1.0 in a step whose action the shield replaced.
    """

    def __init__(
        self, env: gym.Env, make_config: Callable[[Any, float], YieldingConfig], residual_scale: float = 0.0
    ) -> None:
        super().__init__(env)
        self.make_config = make_config
        self.residual_scale = residual_scale
        self.shield: YieldingShield | None = None
        self._obs: Any = None

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[Any, dict]:
        """Reset the env and build the shield for the episode's scenario."""
        obs, info = self.env.reset(seed=seed, options=options)
        base = self.env.unwrapped
        self.shield = YieldingShield(self.make_config(base.scenario, base.config.dt))
        self._obs = obs
        return obs, info

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        """Step with the shielded action; ``info['shield']`` says whether it was replaced."""
        if self.shield is None:
            raise RuntimeError("ShieldAction.step before reset")
        safe, changed = self.shield.apply(action, self._obs, self.residual_scale)
        obs, reward, terminated, truncated, info = self.env.step(safe)
        self._obs = obs
        return obs, reward, terminated, truncated, {**info, "shield": 1.0 if changed else 0.0}
