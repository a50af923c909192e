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
- **Legal stops to the end.** While a legal duty holds (the rule's `LegalDuty`: someone on the zebra in or
  towards the ego's half, someone waiting at the kerb who has not declined the rule's offer, a red light)
  and a stop before the stop line needs at most the rule's `yield_max_deceleration`, the car stays on the
  comfortable profile of the rule's stop point, and stands once there, until the duty ends (the rule's offer
  timer included). Above the profile it brakes comfortably, or as hard as the stop before the line needs.
  The rule's own stop target lapses in its last centimetres above walking pace; a learner that brakes late
  could reach that point a little fast and roll on into the crossing (`_duty_limit`).
- **Readiness for pedestrians who may yet need a stop.** Someone at a zebra ahead who is off the road, not set
  aside by the rule (crossed, walking away along the kerb, declined its offer) and able to reach the kerb at
  the crossing before the car reaches the stop point: for them the car stays on the comfortable profile of
  the stop point, or drives no faster than the rule itself would (`_readiness_limit`).
- **Everything else the rule caps.** Following a vehicle ahead (IDM), the occlusion speed beside a stationary
  vehicle, no overtaking at a zebra, and the speed limit (no speeding).

Below the limit the learned policy is free: it may brake earlier or harder than the rule, accelerate harder
(up to the car's limit, where the rule's cruise control is gentler), and keep speed up to the last point
from which a comfortable stop is still possible (the rule starts braking with a proportional controller
before that). So the learned part can be faster than the rule only where a comfortable stop stays possible
for everyone who has, or may yet have, right of way at the zebra, and never less cautious than the rule
elsewhere: every stop the rule would make, the shielded policy makes too, at most as late as the comfortable
profile allows.

Change logs:
    - The legal-stop limit and the readiness limit were added after the shipped shielded learner lost yield
      compliance by rolling over the stop line where the rule's stop target lapses (docs/rl.md).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np

from agents.config import YieldingConfig
from agents.policy import Policy, policy_is_batched
from agents.view import EPS, ObsLike, View, follow, parse_observation, stop_acceleration, travel_time
from agents.yielding import LegalDuty, YieldingPolicy
from crossing_env.env import acceleration_to_action, action_to_acceleration

__all__ = ["ShieldAction", "ShieldedPolicy", "YieldingShield"]


class YieldingShield:
    """The envelope of `YieldingPolicy` as an upper bound on the acceleration (call `limit` once per step).

    ``ready=False`` leaves out the readiness limit (for comparison; the shipped policy runs with it).
    """

    def __init__(self, config: YieldingConfig | None = None, ready: bool = True) -> None:
        self.rule = YieldingPolicy(config)
        self.config = self.rule.config
        self.ready = ready
        """Also keep a comfortable stop possible for pedestrians who may yet need one (`_readiness_limit`)."""

    def reset(self, seed: int | None = None) -> None:
        """Forget the rule's offer timers and commitments (call at every episode start)."""
        self.rule.reset(seed)

    def _profile(self, view: View, target: np.ndarray) -> np.ndarray:
        """Largest acceleration after which the car is still on the comfortable braking profile of `target`.

        The profile is v = sqrt(2·b·s) (b the rule's `comfortable_deceleration`), checked one step ahead
        with the distance left after a step at the car's largest acceleration (a conservative bound).
        """
        cfg = self.config
        dt, v = cfg.dt, view.speed
        s_next = target - v * dt - 0.5 * cfg.ego.max_acceleration * dt * dt
        return (np.sqrt(2.0 * cfg.comfortable_deceleration * np.maximum(s_next, 0.0)) - v) / dt

    def _profile_limit(self, view: View, target: np.ndarray) -> np.ndarray:
        """The comfortable profile of `target`, or above it the rule's own braking for it (never weaker)."""
        cfg = self.config
        rule = stop_acceleration(
            view, target, cfg.comfortable_deceleration, cfg.stop_gain, cfg.ego.max_deceleration
        )
        return np.where(np.isfinite(target), np.maximum(self._profile(view, target), rule), np.inf)

    def rule_and_limit(self, view: View) -> tuple[np.ndarray, np.ndarray]:
        """(B,) each: the rule's acceleration and the envelope's limit (m/s²); advances the timers once."""
        legal, conflict = self.rule._targets(view)
        rule = self.rule._acceleration_for(view, legal, conflict)
        return rule, self._limit(view, legal, conflict, rule)

    def limit_from_view(self, view: View) -> np.ndarray:
        """(B,) the largest acceleration (m/s²) the envelope allows now; advances the rule's timers."""
        return self.rule_and_limit(view)[1]

    def _duty_limit(self, view: View, duty: LegalDuty) -> np.ndarray:
        """(B,) while a legal duty holds: stay on the comfortable profile of the stop point, stand past it.

        The rule gives its own stop target up within its last 5 cm above 0.5 m/s, and between 0.2 m before
        the stop line and the line; a learner that keeps speed to the last comfortable point and arrives
        there a little fast would roll into the crossing while people have right of way. Here the duty
        holds the car to the comfortable profile of the stop point (`LegalDuty.line`, clamped at 0: past
        it, stand) for as long as a stop before the line (or, past the line, before the crossing) needs at
        most `yield_max_deceleration`, the rule's own test for attempting a legal stop. Above the profile
        it brakes at the comfortable deceleration, or harder where that is needed to stop before the line
        (never harder than that test allows).
        """
        cfg = self.config
        v = view.speed
        to_line = duty.line + cfg.stop_buffer  # front → the stop line; past it, → the crossing's near edge
        due = duty.needs & (to_line > 0.0) & (v * v <= 2.0 * cfg.yield_max_deceleration * to_line)
        profile = self._profile(view, np.maximum(duty.line, 0.0))
        brake = -np.maximum(cfg.comfortable_deceleration, v * v / (2.0 * np.maximum(to_line, 1e-3)))
        return np.where(due, np.maximum(profile, brake), np.inf)

    def _readiness_limit(self, view: View, duty: LegalDuty, rule: np.ndarray) -> np.ndarray:
        """(B,) keep a comfortable stop at the stop point possible while someone may yet need it.

        Someone may yet need it: a `LegalDuty.candidates` pedestrian who, walking at
        `assumed_walking_speed` (or faster, if already faster), can reach the kerb at the crossing (within
        `kerb_distance` of it and the crossing's extent ± `kerb_margin`, the rule's waiting zone) before the
        car reaches the stop point going now (`go_acceleration` up to the speed limit, the rule's conflict
        test). The limit is the comfortable profile of the stop point, but never below the rule's own
        acceleration: the learned part may be faster than the rule only where stopping stays comfortable.
        """
        cfg = self.config
        s = duty.line
        near, far = self.rule._crossing_span(view)
        margin = cfg.kerb_margin
        dx = np.maximum(np.maximum(near - margin - view.px, view.px - far - margin), 0.0)
        dy = np.maximum(self.rule._kerb_gap(view) - cfg.kerb_distance, 0.0)
        walk = np.maximum(np.hypot(view.vx, view.vy), cfg.assumed_walking_speed)
        t_ped = np.hypot(dx, dy) / walk
        t_car = travel_time(s, view.speed, cfg.go_acceleration, max(cfg.speed_limit, EPS))
        reach = (duty.candidates & (t_ped <= t_car[:, None])).any(axis=1)
        target = np.where(reach & (s > 0.0), s, np.inf)
        # The profile itself, not `_profile_limit`: the rule's stop braking for a target nobody is owed yet
        # may ask for more than the profile allows at its edge (found by the property test: on the profile
        # at 38 m, 0.59 m/s² against the rule's 0.40), and that is the rule's own choice only if it acts.
        profile = self._profile(view, target)
        return np.where(np.isfinite(target), np.maximum(profile, rule), np.inf)

    def _limit(self, view: View, legal: np.ndarray, conflict: np.ndarray, rule: np.ndarray) -> np.ndarray:
        cfg = self.config
        # The speed limit, less 0.01 m/s: the float32 action must not round the car over it.
        speed_cap = (cfg.speed_limit - 0.01 - view.speed) / cfg.dt
        caps = np.minimum(
            np.minimum(follow(view, cfg), speed_cap),
            np.minimum(self.rule._occlusion_cap(view), self.rule._no_overtaking(view)),
        )
        stops = np.minimum(self._profile_limit(view, legal), self._profile_limit(view, conflict))
        duty = self.rule.duty
        if duty is not None:
            stops = np.minimum(stops, self._duty_limit(view, duty))
            if self.ready:
                stops = np.minimum(stops, self._readiness_limit(view, duty, rule))
        return np.clip(np.minimum(caps, stops), -cfg.ego.max_deceleration, cfg.ego.max_acceleration)

    def limit(self, obs: ObsLike) -> np.ndarray:
        """(B,) the largest acceleration (m/s²) the envelope allows for `obs`; advances the rule's timers."""
        return self.limit_from_view(parse_observation(obs))

    def apply(
        self, action: Any, obs: ObsLike, residual_scale: float = 0.0, residual_offset: float = 0.0
    ) -> tuple[np.ndarray, bool]:
        """(shielded normalised action of shape (1,), whether the shield changed it) for one observation.

        With ``residual_scale = 0`` the action is the learned acceleration itself (normalised as the env's).
        With ``residual_scale = s > 0`` it is a residual on the rule: the requested acceleration is the rule's
        own plus ``s × action`` m/s², so an action of 0 drives exactly as `yielding` does, and the learned
        part only has to find where to depart from it. ``residual_offset`` (residual only) shifts the
        starting point: the residual asked for is ``offset + action``, clipped to [−1, 1], so with offset 1
        an action of 0 asks for the most the envelope allows and the learned part finds where to hold back
        (down to the rule itself at action −1). Either way the envelope's limit caps the result.
        """
        shielded, changed = self.apply_batch(action, obs, residual_scale, residual_offset)
        return shielded.reshape(-1)[:1], bool(changed[0])

    def apply_batch(
        self, action: Any, obs: ObsLike, residual_scale: float = 0.0, residual_offset: float = 0.0
    ) -> tuple[np.ndarray, np.ndarray]:
        """`apply` for one observation or a batch, each element as `apply` alone gives it.

        Returns (float32 actions shaped as the policies' output, (B,) bool: where the shield changed one).
        """
        view = parse_observation(obs)
        u = np.clip(np.asarray(action, dtype=np.float64).reshape(-1), -1.0, 1.0)
        if residual_scale > 0.0:
            u = np.clip(residual_offset + u, -1.0, 1.0)
        rule, bound = self.rule_and_limit(view)
        ego = self.config.ego
        if residual_scale > 0.0:
            wanted = np.clip(rule + residual_scale * u, -ego.max_deceleration, ego.max_acceleration)
            requested = acceleration_to_action(wanted, ego)
        else:
            wanted = action_to_acceleration(u, ego)
            requested = u.astype(np.float32)
        changed = ~(wanted <= bound)
        shielded = np.where(changed, acceleration_to_action(bound, ego), requested)
        return shielded.reshape(*view.lead, 1), changed


class ShieldedPolicy:
    """A learned policy acting through `YieldingShield` (the composite is what "shielded PPO" deploys)."""

    uses_predictors = False

    def __init__(
        self,
        learned: Policy,
        shield: YieldingShield,
        residual_scale: float = 0.0,
        residual_offset: float = 0.0,
    ) -> None:
        self.learned = learned
        self.shield = shield
        self.residual_scale = residual_scale
        """0: the learned action is the acceleration; > 0: a residual on the rule's (see `apply`)."""
        self.residual_offset = residual_offset
        """Added to the learned residual before clipping (see `apply`)."""
        self.interventions = 0
        """Steps in which the shield replaced the learned action (since the last reset)."""

    @property
    def batched(self) -> bool:
        """Acts for a batch of episodes in one call when the learned policy does (the shield always can)."""
        return policy_is_batched(self.learned)

    def __call__(self, obs: ObsLike) -> np.ndarray:
        """The learned action, replaced by the envelope's limit when above it (one observation or a batch)."""
        action, changed = self.shield.apply_batch(
            self.learned(obs), obs, self.residual_scale, self.residual_offset
        )
        self.interventions += int(np.count_nonzero(changed))
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
        self,
        env: gym.Env,
        make_config: Callable[[Any, float], YieldingConfig],
        residual_scale: float = 0.0,
        residual_offset: float = 0.0,
    ) -> None:
        super().__init__(env)
        self.make_config = make_config
        self.residual_scale = residual_scale
        self.residual_offset = residual_offset
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
        safe, changed = self.shield.apply(action, self._obs, self.residual_scale, self.residual_offset)
        obs, reward, terminated, truncated, info = self.env.step(safe)
        self._obs = obs
        return obs, reward, terminated, truncated, {**info, "shield": 1.0 if changed else 0.0}
