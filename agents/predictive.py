"""The prediction-aware yielding policy: predictions may release the car as well as hold it back.

`YieldingPolicy` only ever adds caution from a prediction, so no prediction can make it faster. This
variant lets a confident prediction *release* it, within the law, and trusts predicted paths:

- **Release.** A pedestrian by the kerb whose ``crossing_intent`` (the predicted probability of being on the
  road within 10 s: the intent to cross here) is at most the predictor's risk bound is not yielded to as
  "waiting to cross", unless the legal duty is visible in the observation: the pedestrian is on the zebra
  (or the road), or is stepping towards the road (speed towards it above `stepping_speed` within
  `kerb_distance` of the kerb). The duty of UK rule 195 / StVO §26 is to people who (recognisably) want to
  cross; a bystander at a bus stop is not one. The bound is the predictor's own ``crossing_intent_bound``
  when it publishes one (the learned, QLB and classical wrappers do: chosen by `studies.release_bounds`, the
  largest bound at which this policy keeps yield compliance ≥ 0.99 with no collision on selection episodes
  never evaluated), else `release_threshold` (the oracle, whose intent is 0, 0.5 or 1). The near-term
  ``crossing_intention`` never releases: it estimates "on the road ahead within 2 s", which is low for a
  pedestrian who waits *because* the car is coming (measured: median 0.09 classical / 0.02 QLB for waiting
  pedestrians who do cross, against 0.70 / 0.73 for pedestrians standing at the kerb who do not), and
  releasing on it broke 12 % of yield obligations in a first grid run.
- **Caution where it is due.** A pedestrian the near-term estimate expects to cross is treated as
  waiting only within `anticipation_kerb_distance` of the kerb: standing at it, not walking up the
  sidewalk; and not at a signalised crossing that shows the car green, where people wait for their own
  signal. Such a pedestrian is also anticipated to walk straight into the road in the conflict check,
  except at a zebra ahead, where the legal yield already holds the car (with its offer timeout). The
  intent to cross at all (the oracle's values, which carry no release bound) only releases: it says who
  will cross, not when, and anticipating a walk-in from it held the car in front of people waiting for
  their green or for a gap in the far lanes (dev grid runs: signalised_red_light 1.0 → 8.1 s,
  four_lane_arterial pass rate 1.00 → 0.36).
- **Paths instead of constant velocity.** Where ``predicted_paths`` exist, the conflict check uses them,
  and constant velocity only as a guard for pedestrians it puts in the ego's corridor within
  `constant_velocity_guard` seconds (paths built from 0.4 s histories lag a child who starts to run: a
  first grid run without the guard hit one in children_running with CVM and S-CGRU paths).

- **Plans scored against plan-conditioned forecasts.** Where ``plan_paths`` exist (the path oracle's
  futures under each candidate plan: go, keep, slow), every step each plan is scored by driving it against
  its own forecast with the reward's terms (`agents.plans`), one is chosen with hysteresis (a switching
  margin and a minimum hold time, lifted when the plan held forecasts a collision), the conflict check runs
  on the chosen plan's paths, and a keep or slow plan caps the acceleration. The prediction and the
  car's intent are then consistent: with paths for a car that holds its speed, the car that chose its
  speed on them chattered (a dev run: −8 / +2 m/s² alternating for 9 s on signalised_red_light). Under a
  slowing plan the conflict check times the car's arrival on the plan's braking profile, not as if it
  drove on (`plan_arrival`): otherwise it braked for someone the plan's forecast has crossing well ahead,
  a little harder than the plan, and a pedestrian who steps off on the car's time to arrive stayed on the
  kerb until it stood (a dev trace, ncap_cpna). The legal rules and the constant-velocity guard still
  hold: a plan only chooses among safe speeds.

With no predictor (no ``crossing_intention``, no ``predicted_paths``) it is exactly `YieldingPolicy`:
conservative, ready to give way to anyone at the kerb by a zebra who is not walking away. Registered as
``predictive_yielding`` next to ``yielding`` rather than replacing it, so the value-of-prediction table can
compare the two on the same seeds and the established policy's figures stay what they were.
"""

from __future__ import annotations

from dataclasses import replace
from typing import ClassVar

import numpy as np

from agents.config import PredictiveYieldingConfig
from agents.plans import choose_plans, score_plans
from agents.view import ObsLike, View, braking_travel_time
from agents.yielding import YieldingPolicy
from predictors.forecast_wrapper import PLAN_ACCELERATIONS_KEY, PLAN_PATHS_KEY
from predictors.learned_intent_weights import CROSSING_INTENT_BOUND_KEY


class PredictiveYielding(YieldingPolicy):
    """Yielding that predictions can release (see the module docstring)."""

    name: ClassVar[str] = "predictive_yielding"
    uses_predictors: ClassVar[bool] = True
    paths_replace_constant_velocity: ClassVar[bool] = True

    def __init__(self, config: PredictiveYieldingConfig | None = None) -> None:
        super().__init__(config or PredictiveYieldingConfig())
        self.config: PredictiveYieldingConfig
        self._bound: np.ndarray | None = None
        self._plan_paths: np.ndarray | None = None
        self._plan_acc: np.ndarray | None = None
        self._plan_braking: np.ndarray | None = None
        """(B,) deceleration of the plan where it slows (NaN elsewhere); set only while the rules run."""

    def reset(self, seed: int | None = None) -> None:
        """Forget the yielding state and the plan being held."""
        super().reset(seed)
        self._plan = np.zeros(0, dtype=np.int64)
        self._held = np.zeros(0)
        self._plan_to_stop = np.zeros(0)
        self._legal = np.zeros(0)
        self.plan_history: list[np.ndarray] = []
        """Chosen plan index (B,) per call since `reset` (for tests and diagnostics)."""

    def _read_bound(self, obs: ObsLike) -> None:
        """Keep the predictor's release bound (B, 1) and the plan forecasts of this observation, if any."""
        get = obs.get if hasattr(obs, "get") else (lambda _key: None)
        bound = get(CROSSING_INTENT_BOUND_KEY)
        self._bound = None if bound is None else np.asarray(bound, dtype=np.float64).reshape(-1, 1)
        paths, acc = get(PLAN_PATHS_KEY), get(PLAN_ACCELERATIONS_KEY)
        if paths is None or acc is None or not self.config.use_plans:
            self._plan_paths = self._plan_acc = None
            return
        acc = np.asarray(acc, dtype=np.float64)
        p = acc.shape[-1]
        self._plan_acc = acc.reshape(-1, p)[0]  # the same plans for every batch element
        paths = np.asarray(paths, dtype=np.float64)
        self._plan_paths = paths.reshape(-1, p, *paths.shape[-3:])  # (B, P, K, T, 2)

    def _acceleration(self, view: View) -> np.ndarray:
        if self._plan_paths is None or self._plan_acc is None:
            return super()._acceleration(view)
        cfg = self.config
        b = view.speed.shape[0]
        if self._plan.shape != (b,):
            self._plan = np.full(b, -1, dtype=np.int64)
            self._held = np.zeros(b)
            self._plan_to_stop = np.full(b, np.inf)
            self._legal = np.full(b, np.inf)
        fresh = view.to_stop > self._plan_to_stop + 0.5  # a vector env restarted this element's episode
        self._plan_to_stop = view.to_stop.copy()
        self._plan[fresh] = -1
        # The legal stop of the previous step (0.1 s old, less the distance since): the rules compute it
        # together with the conflict check, which needs the chosen plan's paths.
        stop = np.where(fresh, np.inf, self._legal - view.speed * cfg.dt)
        stop = np.where(stop > -0.3, np.maximum(stop, 0.0), np.inf)
        start = np.stack([view.px, view.py], axis=-1)
        score, hazard = score_plans(
            view.speed, self._plan_acc, self._plan_paths, view.present, cfg, stop, start
        )
        chosen = choose_plans(score, hazard, self._plan, self._held, cfg)
        self._held = np.where(chosen == self._plan, self._held + cfg.dt, cfg.dt)
        self._plan = chosen
        self.plan_history.append(chosen.copy())
        paths = self._plan_paths[np.arange(b), chosen]
        cap = self._plan_acc[chosen]
        self._plan_braking = np.where(cap < 0.0, -cap, np.nan)
        try:
            a = super()._acceleration(replace(view, paths=paths))
        finally:
            self._plan_braking = None
        return np.where(cap <= 0.0, np.minimum(a, cap), a)

    def _arrival_times(
        self, view: View, s_arr: np.ndarray, s_clr: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        # Under a slowing plan the car brakes at the plan's rate: the conflict check on that plan's forecast
        # asks when the car arrives on that profile, not if it drove on.
        t_arr, t_clr = super()._arrival_times(view, s_arr, s_clr)
        braking = self._plan_braking
        if braking is None or not self.config.plan_arrival:
            return t_arr, t_clr
        slowing = np.isfinite(braking)
        if not slowing.any():
            return t_arr, t_clr
        # No faster than the car can brake (a scenario may give it less than the slow plan's rate).
        rate = np.minimum(np.where(slowing, braking, 1.0), self.config.ego.max_deceleration)[:, None]
        v, slowing = view.speed[:, None], slowing[:, None]
        return (
            np.where(slowing, braking_travel_time(s_arr, v, rate), t_arr),
            np.where(slowing, braking_travel_time(s_clr, v, rate), t_clr),
        )

    def release_bound(self) -> np.ndarray | float:
        """The release threshold in force: the predictor's published bound, else `release_threshold`."""
        return self.config.release_threshold if self._bound is None else self._bound

    def acceleration(self, obs: ObsLike) -> np.ndarray:
        """Commanded acceleration (m/s²) of shape (B,); reads the predictor's release bound first."""
        self._read_bound(obs)
        return super().acceleration(obs)

    def __call__(self, obs: ObsLike) -> np.ndarray:
        """Normalised action(s); reads the predictor's release bound first."""
        self._read_bound(obs)
        return super().__call__(obs)

    def _targets(self, view: View) -> tuple[np.ndarray, np.ndarray]:
        legal, conflict = super()._targets(view)
        if self._legal.shape == legal.shape:
            self._legal = legal.copy()  # remembered for the next step's plan scoring
        return legal, conflict

    def _visible_duty(self, view: View, kerb_gap: np.ndarray) -> np.ndarray:
        """(B, K) pedestrians whose wish to cross the car can see: on the road, or stepping towards it."""
        cfg = self.config
        stepping = (self._towards_road(view) > cfg.stepping_speed) & (kerb_gap <= cfg.kerb_distance)
        return view.on_road | view.on_crossing | stepping

    def _likely_to_cross(self, view: View, kerb_gap: np.ndarray) -> np.ndarray:
        cfg = self.config
        if view.intent is not None and self._bound is None:
            # The oracle's ``crossing_intention`` is its intent to cross at all, which says who will cross,
            # not when: it releases (below) but does not anticipate a walk-in now (a dev grid run that did
            # stopped the car for pedestrians waiting for their own green: signalised_red_light delay 1.0 →
            # 8.1 s). A real predictor (one that publishes a release bound) gives a near-term estimate there,
            # which anticipates as without ``crossing_intent``.
            return np.zeros_like(view.present)
        near_kerb = kerb_gap <= cfg.anticipation_kerb_distance
        # At a signalised crossing showing the car green, people at the kerb wait for their own green:
        # an intent to cross is no sign of stepping out now (a red-light runner is caught when it moves).
        at_crossing = self._at_crossing(view)
        green = ((view.zebra < 0.5) & (view.car_green > 0.5) & (view.past < 0.0))[:, None]
        return super()._likely_to_cross(view, kerb_gap) & near_kerb & ~(green & at_crossing)

    def _anticipated(self, view: View, likely: np.ndarray) -> np.ndarray:
        # At a zebra the legal yield already holds the car for someone expected to cross at the crossing,
        # with the offer timeout when they keep waiting; anticipating a walk-in there as well would hold it
        # without end for a pedestrian who waits for a gap in the other lanes (measured with the oracle
        # intent on four_lane_arterial: pass rate 0.36 against 1.00 without it).
        zebra = (view.zebra > 0.5)[:, None] & (view.past < 0.0)[:, None]
        return likely & ~(zebra & self._at_crossing(view))

    def _yield_waiting(
        self, view: View, waiting: np.ndarray, likely: np.ndarray | None, kerb_gap: np.ndarray
    ) -> np.ndarray:
        waiting = super()._yield_waiting(view, waiting, likely, kerb_gap)
        if view.intent is None or not self.config.use_predictions:
            return waiting
        released = (view.intent <= self.release_bound()) & ~self._visible_duty(view, kerb_gap)
        return waiting & ~released
