"""The forecast the planner rolls its proposals against: per pedestrian, weighted hypotheses of the future.

Built from the forecast protocol's keys (any forecaster: ``predicted_samples`` with ``sample_weights``,
``plan_paths`` for each of ``plan_accelerations`` where offered, ``crossing_intent`` /
``crossing_intention``), or, with no predictor, from the **conservative prior**: constant velocity.

On top of the path hypotheses, a pedestrian at the kerb who is not walking away (within `kerb_distance`,
off the road) may **step off now**: a hypothesis that walks them straight across at
`assumed_walking_speed`, with probability q:

- no intent estimate: the prior `step_off_prior` (`signal_step_off_prior` at a signalised crossing showing
  the car green, where people wait for their own signal);
- ``crossing_intent`` (the intent to cross at all: the oracle, the learned, QLB and classical wrappers):
  the prior updated by it as by a likelihood ratio against an even base rate (intent 0.5 keeps the prior,
  1 doubles it, 0 removes it), and 0 at or below the predictor's ``crossing_intent_bound`` (the level it
  publishes as confidently not crossing). The intent to cross at all says who will cross, not when;
- only ``crossing_intention`` (the near-term probability of being on the road ahead): that value.

The step-off mass is net of what the paths already put on the road under the same plan (a forecast that
has them crossing within the horizon needs no extra hypothesis), so a forecast that is right about a
crossing costs nothing.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from agents.config import PlannerConfig
from agents.view import ObsLike, View
from crossing_env.observation import HISTORY_INTERVAL, PREDICTED_SAMPLES_KEY, SAMPLE_WEIGHTS_KEY
from predictors.forecast_wrapper import PLAN_ACCELERATIONS_KEY, PLAN_PATHS_KEY
from predictors.learned_intent_weights import CROSSING_INTENT_BOUND_KEY

PRIOR_STEPS = 12
"""Forecast points (0.4 s apart, 4.8 s) of the constant-velocity prior (the forecast protocol's horizon)."""
EVEN_ODDS = 0.5
"""Base rate against which an intent to cross updates the step-off prior."""


class Hypotheses(NamedTuple):
    """Weighted futures per pedestrian, possibly one set per ego plan."""

    points: np.ndarray
    """(B, C, K, H, T + 1, 2) positions in the ego frame at 0.4 s steps, index 0 the current one; C plans
    (1 without plan-conditioned forecasts)."""
    weights: np.ndarray
    """(B, C, K, H) probability of each hypothesis under each plan (summing to 1 per slot; uniform in
    absent slots)."""
    plan_accelerations: np.ndarray | None
    """(C,) the ego acceleration (m/s²) each plan's forecast assumes; None: one forecast for any plan."""
    crossing: np.ndarray
    """(B, C, K) probability that each plan's forecast puts the pedestrian on the road within the horizon."""
    reactive: np.ndarray
    """(H,) True for the step-off hypothesis: a pedestrian who reacts to the car, and so does not walk into
    the side of one passing in front of them (a forecast path is taken as it is)."""

    @property
    def interval(self) -> float:
        """Seconds between forecast points."""
        return HISTORY_INTERVAL


def _get(obs: ObsLike, key: str) -> np.ndarray | None:
    value = obs.get(key) if hasattr(obs, "get") else None
    return None if value is None else np.asarray(value, dtype=np.float64)


def path_hypotheses(view: View, obs: ObsLike) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """(B, C, K, S, T, 2) forecast paths, (B, K, S) weights and the plans' accelerations (or None).

    Plan-conditioned paths where the forecaster offers them; else its samples; else its most likely path;
    else constant velocity (the prior).
    """
    b, k = view.present.shape
    plans, plan_acc = _get(obs, PLAN_PATHS_KEY), _get(obs, PLAN_ACCELERATIONS_KEY)
    if plans is not None and plan_acc is not None:
        c = plan_acc.shape[-1]
        paths = plans.reshape(b, c, k, 1, *plans.shape[-2:])
        return paths, np.ones((b, k, 1)), plan_acc.reshape(-1, c)[0]
    samples, weights = _get(obs, PREDICTED_SAMPLES_KEY), _get(obs, SAMPLE_WEIGHTS_KEY)
    if samples is not None and weights is not None:
        s = weights.shape[-1]
        return samples.reshape(b, 1, k, s, *samples.shape[-2:]), weights.reshape(b, k, s), None
    if view.paths is not None:
        return view.paths.reshape(b, 1, k, 1, *view.paths.shape[-2:]), np.ones((b, k, 1)), None
    t = HISTORY_INTERVAL * np.arange(1, PRIOR_STEPS + 1)
    cv = np.stack(
        [view.px[..., None] + view.vx[..., None] * t, view.py[..., None] + view.vy[..., None] * t], -1
    )
    return cv.reshape(b, 1, k, 1, PRIOR_STEPS, 2), np.ones((b, k, 1)), None


def step_off_probability(
    view: View, obs: ObsLike, cfg: PlannerConfig, kerb_gap: np.ndarray, towards_road: np.ndarray
) -> np.ndarray:
    """(B, K) probability that each pedestrian steps off the kerb now (0 for those who cannot)."""
    can = view.present & ~view.on_road & ~view.on_crossing & (kerb_gap <= cfg.kerb_distance)
    can &= towards_road > -cfg.leaving_speed
    signal_green = (view.zebra < 0.5) & (view.car_green > 0.5) & (view.past < 0.0)
    prior = np.where(signal_green, cfg.signal_step_off_prior, cfg.step_off_prior)[:, None]
    if view.intent is not None:
        q = np.minimum(prior * view.intent / EVEN_ODDS, 1.0)
        bound = _get(obs, CROSSING_INTENT_BOUND_KEY)
        if bound is not None:
            q = np.where(view.intent <= bound.reshape(-1, 1), 0.0, q)
    elif view.intention is not None:
        q = view.intention
    else:
        q = np.broadcast_to(prior, view.present.shape)
    return np.where(can, np.clip(q, 0.0, 1.0), 0.0)


def build_hypotheses(
    view: View, obs: ObsLike, cfg: PlannerConfig, kerb_gap: np.ndarray, towards_road: np.ndarray
) -> Hypotheses:
    """The path hypotheses with the step-off hypothesis appended (see the module docstring)."""
    paths, weights, plan_acc = path_hypotheses(view, obs)
    b, c, k, s, t, _ = paths.shape
    start = np.stack([view.px, view.py], axis=-1)  # (B, K, 2)
    start_b = np.broadcast_to(start[:, None, :, None, None, :], (b, c, k, s, 1, 2))
    points = np.concatenate([start_b, paths], axis=4)  # (B, C, K, S, T + 1, 2)
    total = weights.sum(axis=-1, keepdims=True)
    weights = np.where(total > 0.0, weights / np.where(total > 0.0, total, 1.0), 1.0 / s)
    # Mass each plan's paths already put on the road within the horizon: a plan under which someone stays
    # on the kerb (waiting for the car, say) keeps the step-off hypothesis, so slowing down does not make
    # them vanish from the forecast.
    y = points[..., 1]
    on_road = ((y > cfg.road_right) & (y < cfg.road_left)).any(axis=-1)  # (B, C, K, S)
    crossing_mass = (weights[:, None] * on_road).sum(axis=-1)  # (B, C, K)
    q = step_off_probability(view, obs, cfg, kerb_gap, towards_road)[:, None]
    q = np.clip(q - crossing_mass, 0.0, 1.0)  # (B, C, K)
    mid = 0.5 * (cfg.road_right + cfg.road_left)
    direction = np.where(view.py < mid, 1.0, -1.0)  # towards the far kerb
    times = HISTORY_INTERVAL * np.arange(t + 1)
    walk_y = view.py[..., None] + direction[..., None] * cfg.assumed_walking_speed * times  # (B, K, T + 1)
    walk_x = np.broadcast_to(view.px[..., None], walk_y.shape)
    walk = np.stack([walk_x, walk_y], axis=-1)[:, None, :, None]  # (B, 1, K, 1, T + 1, 2)
    points = np.concatenate([points, np.broadcast_to(walk, (b, c, k, 1, t + 1, 2))], axis=3)
    weights = np.concatenate([weights[:, None] * (1.0 - q)[..., None], q[..., None]], axis=-1)
    reactive = np.append(np.zeros(s, dtype=bool), True)
    return Hypotheses(
        points=points, weights=weights, plan_accelerations=plan_acc, crossing=crossing_mass, reactive=reactive
    )
