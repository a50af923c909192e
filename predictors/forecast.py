"""The forecast protocol: what a pedestrian predictor is given each step and what it must hand back.

Every predictor, built in or a user's, is a `Forecaster`: each env step it receives a `ForecastInput` (the
pedestrians' observed histories in the observation's ego frame, a presence mask, their track ids, the static
scene geometry and, for models that want more, the whole observation) and returns a `Forecast`: for each
pedestrian K weighted path samples over the horizon it declared in its `ForecastSpec`, optionally a most
likely path apart from the samples, optionally crossing-intent probabilities, and, where it offers
plan-conditioned forecasts, one path per ego plan (`Forecaster.forecast_plans`: the ego's candidate plan
in, the pedestrians' futures under it out). `predictors.forecast_wrapper.ForecastObservation` turns any
forecaster into the observation keys the policies read, after `validate_forecast` has checked what came
back. Shapes below use N for the observation's pedestrian slots, T for the history length (8), S for the
samples, H for the horizon steps (12) and P for the plans; positions are metres in the observation's frame
(x along the ego's lane, the ego's centre at the origin), one step `STEP_SECONDS` apart.

Privileged forecasters (the oracles) declare it in their spec and are handed the env once
(``bind(env)``) to read the world's ground truth; no other forecaster is.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from crossing_common.cadence import HISTORY_INTERVAL

__all__ = [
    "HORIZON_STEPS",
    "STEP_SECONDS",
    "Forecast",
    "ForecastError",
    "ForecastInput",
    "ForecastSpec",
    "Forecaster",
    "SceneGeometry",
    "scene_from_env",
    "validate_forecast",
]

STEP_SECONDS = HISTORY_INTERVAL
"""Seconds between two positions of a history or a forecast (0.4 s, the ETH/UCY protocol)."""
HORIZON_STEPS = 12
"""Forecast positions per path by default (12 × 0.4 s = 4.8 s, the ETH/UCY protocol)."""


class ForecastError(ValueError):
    """A forecaster that cannot be built or returned a malformed forecast; the message names it."""


@dataclass(frozen=True)
class SceneGeometry:
    """Static map facts relative to the ego's lane (what an HD map gives a car); y grows to the north."""

    kerb_low: float
    """y of the south kerb minus the ego's y (m)."""
    kerb_high: float
    """y of the north kerb minus the ego's y (m)."""
    ego_length: float
    """Ego length (m)."""
    crossing_offset: float
    """Added to the observed distance to the stop line: the crossing centre's x relative to the ego (m)."""
    crossing_half_width: float
    """Half the crossing width along x (m)."""
    signalised: bool
    """The crossing has a pedestrian signal."""
    has_crossing: bool
    """There is a marked crossing."""


def scene_from_env(env: Any) -> SceneGeometry:
    """The static scene geometry of a crossing_env env's scenario, relative to the ego's lane.

    Raises:
        ValueError: the env is not a crossing_env env (no ``unwrapped.scenario``).
    """
    scenario = getattr(env.unwrapped, "scenario", None)
    if scenario is None:
        raise ValueError("the scene geometry needs a crossing_env env (env.unwrapped.scenario)")
    road, crossing = scenario.road, scenario.crossing
    ego_y = (scenario.ego.lane + 0.5) * road.lane_width
    length = scenario.traffic.length
    return SceneGeometry(
        kerb_low=-ego_y,
        kerb_high=road.num_lanes * road.lane_width - ego_y,
        ego_length=length,
        crossing_offset=crossing.stop_line_offset + crossing.width / 2 + length / 2,
        crossing_half_width=crossing.width / 2,
        signalised=crossing.kind == "signalised",
        has_crossing=crossing.kind != "none",
    )


@dataclass(frozen=True)
class ForecastSpec:
    """What a forecaster produces, fixed for its life: the observation space is built from it."""

    paths: bool = True
    """It forecasts paths (False: intent only)."""
    samples: int = 1
    """S, path samples per pedestrian (1 for a deterministic model)."""
    mode: bool = False
    """It also gives a most-likely path apart from its samples (`Forecast.mode`)."""
    horizon: int = HORIZON_STEPS
    """H, positions per path, `STEP_SECONDS` apart, the first one step after now."""
    intent: bool = False
    """It gives crossing-intent probabilities (`Forecast.intention` and `Forecast.intent`)."""
    intent_bound: bool = False
    """It publishes a release risk bound with its intent (`Forecast.intent_bound`)."""
    plans: tuple[float, ...] = ()
    """Ego plans (accelerations, m/s², each held over the horizon) it forecasts under
    (`Forecaster.forecast_plans`); empty: no plan-conditioned forecasts."""
    privileged: bool = False
    """It reads the world's ground truth (an oracle bound, never a deployable predictor); only such a
    forecaster is handed the env (``bind(env)``)."""

    def __post_init__(self) -> None:
        if not self.paths and not self.intent:
            raise ValueError("a forecaster must forecast paths, intent, or both")
        if not (isinstance(self.samples, int) and self.samples >= 1):
            raise ValueError(f"samples must be an integer >= 1, got {self.samples!r}")
        if not (isinstance(self.horizon, int) and self.horizon >= 1):
            raise ValueError(f"horizon must be an integer >= 1, got {self.horizon!r}")
        if not all(np.isfinite(self.plans)):
            raise ValueError(f"plan accelerations must be finite, got {self.plans}")
        if self.plans and not self.paths:
            raise ValueError("plan-conditioned forecasts are paths: a plan needs paths=True")


@dataclass(frozen=True)
class ForecastInput:
    """What a forecaster sees at one step (read-only arrays, owned by the observation)."""

    history: np.ndarray
    """(N, T, 2) float32: each slot's last T positions, `STEP_SECONDS` apart, oldest first, ego frame, m;
    zeros in absent slots."""
    present: np.ndarray
    """(N,) bool: the slot holds a pedestrian."""
    tracks: np.ndarray | None
    """(N,) int64: each slot's track id, stable for a pedestrian within an episode (None where the
    observation carries none)."""
    scene: SceneGeometry | None
    """The static scene geometry (None for an env that is not a crossing_env env)."""
    observation: Mapping[str, np.ndarray]
    """The whole observation the wrapper received (velocities, flags, vehicles, the ego's state: the keys and
    columns named in `crossing_env.observation`)."""
    step: int
    """Env steps since the reset (0: the reset's observation)."""


@dataclass(frozen=True)
class Forecast:
    """A forecaster's answer for every slot (values in absent slots are ignored)."""

    paths: np.ndarray | None = None
    """(N, S, H, 2): S path samples per pedestrian (required when the spec forecasts paths)."""
    weights: np.ndarray | None = None
    """(N, S): each sample's probability, >= 0, summing to 1 over a present pedestrian's samples
    (None: equal weights)."""
    mode: np.ndarray | None = None
    """(N, H, 2): the most likely path, where the model has one apart from its samples (spec ``mode``);
    otherwise the heaviest sample stands for it."""
    intention: np.ndarray | None = None
    """(N,): probability the pedestrian is on the carriageway ahead of the ego's rear within the model's
    near-term horizon (required when the spec forecasts intent)."""
    intent: np.ndarray | None = None
    """(N,): probability the pedestrian is on the carriageway anywhere within 10 s, the intent to cross
    here (required when the spec forecasts intent)."""
    intent_bound: float | None = None
    """The release risk bound: an intent at or below it may release a legal wait (required when the spec
    publishes one)."""


@runtime_checkable
class Forecaster(Protocol):
    """A pedestrian predictor. Optional methods, called where defined.

    - ``forecast_plans(inputs, plans) -> (P, N, H, 2)``: the most likely paths under each ego plan of the
      spec (required when ``spec.plans`` is not empty);
    - ``bind(env)``: hand a privileged forecaster the env (called once, only when ``spec.privileged``);
    - ``kernel_to_compile() -> Callable | None``: a compile step to run ahead in another process.
    """

    spec: ForecastSpec
    """What it produces."""

    def reset(self, seed: int | None) -> None:
        """Start an episode; a seed makes any sampling reproducible."""

    def forecast(self, inputs: ForecastInput) -> Forecast:
        """The forecast for the step `inputs` describes."""


_SUM, _MIN, _MAX = np.add.reduce, np.minimum.reduce, np.maximum.reduce
"""The reductions the checks run every step, called as ufuncs (without the array methods' wrappers)."""


def _array(name: str, field: str, value: Any, shape: tuple[int, ...]) -> np.ndarray:
    """`value` as a real array of `shape`."""
    try:
        arr = value if isinstance(value, np.ndarray) else np.asarray(value)
    except Exception as exc:
        raise ForecastError(f"forecaster {name!r}: {field} is not an array ({exc})") from None
    if arr.dtype.kind not in "fiu":
        raise ForecastError(f"forecaster {name!r}: {field} must be real numbers, got dtype {arr.dtype}")
    if arr.shape != shape:
        raise ForecastError(f"forecaster {name!r}: {field} must have shape {shape}, got {arr.shape}")
    return arr


def _check(name: str, field: str, value: Any, shape: tuple[int, ...], rows: np.ndarray) -> np.ndarray:
    """`value` as a real array of `shape`, finite in the present rows (the leading axis is the slots)."""
    arr = _array(name, field, value, shape)
    # Every slot finite is the common case: a finite sum says so in one reduction (NaN and inf propagate;
    # an overflow to inf only sends a finite array to the exact check below, on the present rows).
    if not math.isfinite(_SUM(arr, axis=None)) and not np.isfinite(arr[rows]).all():
        raise ForecastError(f"forecaster {name!r}: {field} is NaN or infinite for a present pedestrian")
    return arr


def _check_probability(name: str, field: str, value: Any, n: int, rows: np.ndarray) -> None:
    arr = _array(name, field, value, (n,))
    if not arr.size or (_MIN(arr) >= 0.0 and _MAX(arr) <= 1.0):  # NaN fails both comparisons
        return
    mine = arr[rows]
    if not np.isfinite(mine).all():
        raise ForecastError(f"forecaster {name!r}: {field} is NaN or infinite for a present pedestrian")
    if ((mine < 0.0) | (mine > 1.0)).any():
        raise ForecastError(f"forecaster {name!r}: {field} must be probabilities in [0, 1]")


def validate_forecast(name: str, forecast: Any, spec: ForecastSpec, inputs: ForecastInput) -> Forecast:
    """`forecast` if it is what `spec` promises for `inputs`, else a `ForecastError` naming `name`.

    Checks types, shapes, finite values in present slots, weights (>= 0, summing to 1) and probabilities.
    """
    if not isinstance(forecast, Forecast):
        raise ForecastError(
            f"forecaster {name!r}: forecast() must return a Forecast, got {type(forecast).__name__}"
        )
    n = inputs.present.shape[0]
    rows = inputs.present
    if spec.paths:
        if forecast.paths is None:
            raise ForecastError(f"forecaster {name!r}: paths missing (its spec forecasts paths)")
        _check(name, "paths", forecast.paths, (n, spec.samples, spec.horizon, 2), rows)
        if forecast.weights is not None:
            weights = _check(name, "weights", forecast.weights, (n, spec.samples), rows)[rows]
            if (weights < 0.0).any():
                raise ForecastError(f"forecaster {name!r}: weights must be >= 0")
            if not np.allclose(weights.sum(axis=1), 1.0, atol=1e-4):
                raise ForecastError(f"forecaster {name!r}: weights must sum to 1 for each present pedestrian")
        if spec.mode:
            if forecast.mode is None:
                raise ForecastError(f"forecaster {name!r}: mode missing (its spec gives one)")
            _check(name, "mode", forecast.mode, (n, spec.horizon, 2), rows)
    if spec.intent:
        for field in ("intention", "intent"):
            if getattr(forecast, field) is None:
                raise ForecastError(f"forecaster {name!r}: {field} missing (its spec forecasts intent)")
            _check_probability(name, field, getattr(forecast, field), n, rows)
    if spec.intent_bound:
        bound = forecast.intent_bound
        if not (isinstance(bound, (int, float, np.floating)) and 0.0 <= float(bound) <= 1.0):
            raise ForecastError(f"forecaster {name!r}: intent_bound must be a probability, got {bound!r}")
    return forecast


def validate_plan_paths(name: str, value: Any, spec: ForecastSpec, inputs: ForecastInput) -> np.ndarray:
    """The (P, N, H, 2) array ``forecast_plans`` returned, checked as `validate_forecast` checks paths."""
    arr = _array(name, "plan paths", value, (len(spec.plans), inputs.present.shape[0], spec.horizon, 2))
    if not np.isfinite(arr[:, inputs.present]).all():
        raise ForecastError(
            f"forecaster {name!r}: plan paths have NaN or infinite values for present pedestrians"
        )
    return arr


def compile_step(forecaster: Any) -> Callable[[], None] | None:
    """The forecaster's ``kernel_to_compile()``, None where it has none."""
    offer = getattr(forecaster, "kernel_to_compile", None)
    return offer() if callable(offer) else None
