"""The one observation wrapper that turns any `Forecaster` into the observation keys policies read.

Each step it gathers a `ForecastInput` from the observation (histories, presence, tracks, the scene
geometry refreshed at every reset), asks the forecaster, checks the answer (`validate_forecast`: a
malformed one is a `ForecastError` naming the forecaster, never a silent zero) and writes:

- paths: ``predicted_paths`` (N, H, 2), the most likely path (the forecaster's mode, else its heaviest
  sample), and the distribution: ``predicted_samples`` (N, S, H, 2) with ``sample_weights`` (N, S) (equal
  weights where the forecaster gives none; 0 in absent slots, so the weights are the samples' presence
  flags);
- plans: ``plan_paths`` (P, N, H, 2) and ``plan_accelerations`` (P,);
- intent: ``crossing_intention`` and ``crossing_intent`` (N,), and ``crossing_intent_bound`` (1,) where
  the forecaster publishes one.

Absent slots are zeros; paths are clipped to the space's bound (the history's bound plus 3 m per step).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from crossing_env.observation import (
    CROSSING_INTENT_KEY,
    CROSSING_INTENTION_KEY,
    PEDESTRIAN_HISTORY_KEY,
    PEDESTRIAN_TRACKS_KEY,
    PEDESTRIANS_KEY,
    PREDICTED_PATHS_KEY,
    PREDICTED_SAMPLES_KEY,
    SAMPLE_WEIGHTS_KEY,
    PedestrianColumn,
    PointColumn,
)
from predictors.forecast import (
    Forecast,
    Forecaster,
    ForecastError,
    ForecastInput,
    ForecastSpec,
    SceneGeometry,
    compile_step,
    scene_from_env,
    validate_forecast,
    validate_plan_paths,
)
from predictors.learned_intent_weights import CROSSING_INTENT_BOUND_KEY

__all__ = ["MAX_STEP", "PLAN_ACCELERATIONS_KEY", "PLAN_PATHS_KEY", "ForecastObservation"]

PLAN_PATHS_KEY = "plan_paths"
"""Observation key of the plan-conditioned paths (P, N, H, 2), one ``predicted_paths`` per plan."""
PLAN_ACCELERATIONS_KEY = "plan_accelerations"
"""Observation key of the plans' ego accelerations (P,), m/s², in the order of ``plan_paths``."""
MAX_STEP = 3.0
"""Largest displacement (m) per forecast step assumed when bounding paths (clipped beyond)."""


def _scene(env: gym.Env) -> SceneGeometry | None:
    return scene_from_env(env) if getattr(env.unwrapped, "scenario", None) is not None else None


class ForecastObservation(gym.ObservationWrapper, gym.utils.RecordConstructorArgs):
    """Add a forecaster's predictions to a crossing_env Dict observation (see the module docstring).

    Args:
        env: an env whose observation is a Dict with ``pedestrians`` (N, F) and ``pedestrian_history``
            (N, T, 2) (`crossing_env.observation`).
        forecaster: the `Forecaster`.
        name: how errors name it (the ``--predictor`` / ``--intention`` value).
    """

    def __init__(self, env: gym.Env, forecaster: Forecaster, name: str) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, forecaster=forecaster, name=name)
        gym.ObservationWrapper.__init__(self, env)
        spec = getattr(forecaster, "spec", None)
        if not isinstance(spec, ForecastSpec):
            raise ForecastError(f"forecaster {name!r}: needs a `spec` (ForecastSpec), got {spec!r}")
        for method in ("reset", "forecast", *(("forecast_plans",) if spec.plans else ())):
            if not callable(getattr(forecaster, method, None)):
                raise ForecastError(f"forecaster {name!r}: has no {method}() method")
        space = env.observation_space
        hist = space.spaces.get(PEDESTRIAN_HISTORY_KEY) if isinstance(space, spaces.Dict) else None
        if (
            not isinstance(hist, spaces.Box)
            or len(hist.shape) != 3
            or hist.shape[2] != len(PointColumn)
            or PEDESTRIANS_KEY not in space.spaces
        ):
            raise ValueError(
                f"forecaster {name!r} needs a Dict observation with {PEDESTRIANS_KEY!r} and "
                f"{PEDESTRIAN_HISTORY_KEY!r} (N, T, 2), got {space}"
            )
        self.forecaster = forecaster
        """The forecaster asked each step."""
        self.name = name
        self.forecast_spec: ForecastSpec = spec
        """What the forecaster produces."""
        self.num_slots = hist.shape[0]
        bound = float(max(np.abs(hist.low).max(), np.abs(hist.high).max())) + spec.horizon * MAX_STEP
        self.bound = np.float32(bound) if np.isfinite(bound) else np.float32(np.finfo(np.float32).max)
        """Largest |coordinate| of a path in the observation (m)."""
        self.observation_space = spaces.Dict({**space.spaces, **self._spaces()})
        if spec.privileged:
            bind = getattr(forecaster, "bind", None)
            if not callable(bind):
                raise ForecastError(f"forecaster {name!r}: privileged but has no bind(env) method")
            bind(env)
        self._scene = _scene(env)
        self._step = 0

    def _spaces(self) -> dict[str, spaces.Box]:
        spec, n, b = self.forecast_spec, self.num_slots, self.bound
        path = (spec.horizon, len(PointColumn))
        new: dict[str, spaces.Box] = {}
        if spec.paths:
            new[PREDICTED_PATHS_KEY] = spaces.Box(-b, b, (n, *path), np.float32)
            new[PREDICTED_SAMPLES_KEY] = spaces.Box(-b, b, (n, spec.samples, *path), np.float32)
            new[SAMPLE_WEIGHTS_KEY] = spaces.Box(0.0, 1.0, (n, spec.samples), np.float32)
        if spec.plans:
            new[PLAN_PATHS_KEY] = spaces.Box(-b, b, (len(spec.plans), n, *path), np.float32)
            # The plans' own accelerations: constants, so the box is exactly their range.
            low, high = np.float32(min(spec.plans)), np.float32(max(spec.plans))
            new[PLAN_ACCELERATIONS_KEY] = spaces.Box(low, high, (len(spec.plans),), np.float32)
        if spec.intent:
            new[CROSSING_INTENTION_KEY] = spaces.Box(0.0, 1.0, (n,), np.float32)
            new[CROSSING_INTENT_KEY] = spaces.Box(0.0, 1.0, (n,), np.float32)
            if spec.intent_bound:
                new[CROSSING_INTENT_BOUND_KEY] = spaces.Box(0.0, 1.0, (1,), np.float32)
        return new

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        """Reset the forecaster (with the seed) and the env; refresh the scene (options may change it)."""
        self.forecaster.reset(seed)
        obs, info = self.env.reset(seed=seed, options=options)
        self._scene = _scene(self.env)
        self._step = 0
        return self._add(obs), info

    def step(self, action: Any) -> tuple[Any, Any, bool, bool, dict[str, Any]]:
        """Step the env and add the forecast."""
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._step += 1
        return self._add(obs), reward, terminated, truncated, info

    def observation(self, observation: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The observation with the forecast's keys added (the forecaster sees the current step count)."""
        return self._add(observation)

    def _add(self, observation: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        present = np.asarray(observation[PEDESTRIANS_KEY])[:, PedestrianColumn.PRESENCE] > 0.5
        tracks = observation.get(PEDESTRIAN_TRACKS_KEY)
        inputs = ForecastInput(
            history=np.asarray(observation[PEDESTRIAN_HISTORY_KEY], dtype=np.float32),
            present=present,
            tracks=None if tracks is None else np.asarray(tracks).astype(np.int64),
            scene=self._scene,
            observation=observation,
            step=self._step,
        )
        spec, name = self.forecast_spec, self.name
        forecast = validate_forecast(name, self.forecaster.forecast(inputs), spec, inputs)
        out = dict(observation)
        where = present[:, None, None]
        if spec.paths:
            self._write_paths(out, forecast, present)
        if spec.plans:
            plans = validate_plan_paths(name, self.forecaster.forecast_plans(inputs), spec, inputs)  # type: ignore[attr-defined]
            plans = np.where(where[None], np.asarray(plans, dtype=np.float32), np.float32(0.0))
            out[PLAN_PATHS_KEY] = np.clip(plans, -self.bound, self.bound)
            out[PLAN_ACCELERATIONS_KEY] = np.asarray(spec.plans, np.float32)
        if spec.intent:
            for key, value in (
                (CROSSING_INTENTION_KEY, forecast.intention),
                (CROSSING_INTENT_KEY, forecast.intent),
            ):
                out[key] = np.where(present, np.asarray(value, dtype=np.float32), np.float32(0.0))
            if spec.intent_bound:
                out[CROSSING_INTENT_BOUND_KEY] = np.array([forecast.intent_bound], dtype=np.float32)
        return out

    def _write_paths(self, out: dict[str, np.ndarray], forecast: Forecast, present: np.ndarray) -> None:
        """``predicted_paths``, ``predicted_samples`` and ``sample_weights`` of a checked forecast."""
        spec, bound = self.forecast_spec, self.bound
        paths = np.asarray(forecast.paths, dtype=np.float32)
        weights = None if forecast.weights is None else np.asarray(forecast.weights, dtype=np.float32)
        if spec.mode:
            best = np.asarray(forecast.mode, dtype=np.float32)
        elif spec.samples == 1 or weights is None:
            best = paths[:, 0]
        else:
            best = paths[np.arange(len(paths)), np.argmax(weights, axis=1)]
        where = present[:, None, None]
        best = np.clip(np.where(where, best, np.float32(0.0)), -bound, bound)
        out[PREDICTED_PATHS_KEY] = best
        if spec.samples == 1 and not spec.mode:
            out[PREDICTED_SAMPLES_KEY] = best[:, None]  # the one sample is the path shown
        else:
            samples = np.where(where[:, None], paths, np.float32(0.0))
            out[PREDICTED_SAMPLES_KEY] = np.clip(samples, -bound, bound)
        if weights is None:  # equal weights: 1 / S in a present slot
            out[SAMPLE_WEIGHTS_KEY] = np.repeat(
                present[:, None] * np.float32(1.0 / spec.samples), spec.samples, 1
            )
        else:
            out[SAMPLE_WEIGHTS_KEY] = np.where(present[:, None], weights, np.float32(0.0))

    def kernel_to_compile(self) -> Callable[[], None] | None:
        """The forecaster's compile step to run ahead (`crossing_eval.tasks.warm_up`), None where none."""
        return compile_step(self.forecaster)
