"""A learned, observation-only crossing-intention model: logistic regression on hand-made features.

`LearnedIntention` adds ``crossing_intention`` (K,) (on the carriageway ahead of the ego's rear within the
wrapper's horizon: 1, 2 or 4 s, the event `predictors.intention` estimates) and ``crossing_intent`` (K,) (on
the carriageway anywhere within `INTENT_HORIZON` = 10 s: the intent to cross here, the event the oracle's
intent stands for). Each is one logistic-regression head on the same `FEATURES`, computed per pedestrian
slot from the observation and the static map only (no ground truth, no hidden state): where the pedestrian
is relative to the kerb and the crossing, how it moves, whether its 3.2 s position history touched the road
(someone who has just crossed), the ego's time to reach it and the gap to the first approaching car.

The heads are fitted by ``python -m studies.train_learned_intent`` on simulated ground truth from
training seeds disjoint from every evaluation seed, and shipped as JSON (`learned_intent_weights`) with
the release risk bound that ``python -m studies.release_bounds`` chooses by driving on selection seeds,
which the wrapper publishes as ``crossing_intent_bound`` (1,). Fitted
by maximum likelihood, the probabilities are calibrated on the training distribution;
`benchmarks/intention.py` measures calibration (ECE) on the evaluation seeds.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from crossing_env.observation import (
    EGO_KEY,
    HISTORY_INTERVAL,
    PEDESTRIAN_HISTORY_KEY,
    PEDESTRIANS_KEY,
    VEHICLES_KEY,
    EgoColumn,
    PedestrianColumn,
    PointColumn,
    VehicleColumn,
)
from predictors.forecast import Forecast, ForecastInput, ForecastSpec, SceneGeometry
from predictors.forecast_wrapper import ForecastObservation
from predictors.intention import INTENT_HORIZON
from predictors.learned_intent_weights import release_threshold, shipped_weights

__all__ = ["FEATURES", "HEADS", "LearnedIntent", "LearnedIntention", "intent_features", "predict"]

FEATURES: tuple[str, ...] = (
    "kerb_offset",
    "near_kerb",
    "towards_road",
    "speed",
    "along_speed",
    "waiting",
    "on_road",
    "on_crossing",
    "crossing_distance",
    "at_crossing",
    "heading_to_crossing",
    "zebra",
    "faces_red",
    "ego_speed",
    "ego_time_to_reach",
    "ahead",
    "gap",
    "was_on_road",
    "history_towards",
    "near_kerb_x_towards",
    "near_kerb_x_at_crossing",
    "near_kerb_x_gap",
    "near_kerb_x_ego_time",
    "waiting_x_zebra",
)
"""Feature names, in column order (documented in `intent_features`)."""
HEADS: tuple[str, ...] = ("1", "2", "4", "intent")
"""Logistic heads: ``crossing_intention`` at 1, 2 and 4 s, and ``crossing_intent``."""
CAP = 10.0
"""Times (s) and distances (m) in the features are clipped to this."""


def intent_features(obs: dict[str, np.ndarray], road_map: SceneGeometry) -> np.ndarray:
    """(K, len(FEATURES)) float64 features of every pedestrian slot (zeros for absent slots).

    Columns: signed distance outside the nearer kerb (m, negative on the road), within 1.5 m of the kerb
    off the road, speed towards the road (m/s), speed, |speed along the road|, the observation's waiting /
    on-road / on-crossing flags, distance along the road to the crossing's edge (m), within 1 m of it,
    speed along the road towards the crossing, zebra, facing red (signalised, cars green, at the crossing),
    ego speed, the ego front's time to reach the pedestrian's x (s; negative once passed), the pedestrian
    ahead of the ego's rear, the time until the first approaching car reaches its x (s), its position
    history inside the road, its mean speed towards the road over the history, and four products with
    "near the kerb". Times and distances are clipped to ± `CAP`.
    """
    ped = obs[PEDESTRIANS_KEY].astype(np.float64)
    ego = obs[EGO_KEY].astype(np.float64)
    veh = obs[VEHICLES_KEY].astype(np.float64)
    hist = obs[PEDESTRIAN_HISTORY_KEY].astype(np.float64)
    c = PedestrianColumn
    present = ped[:, c.PRESENCE] > 0.5
    dx, dy, vx, vy = ped[:, c.DX], ped[:, c.DY], ped[:, c.VX], ped[:, c.VY]
    lo, hi = road_map.kerb_low, road_map.kerb_high
    kerb_offset = np.clip(np.maximum(lo - dy, dy - hi), -CAP, CAP)
    south = dy < 0.5 * (lo + hi)
    towards = np.where(south, vy, -vy)
    near_kerb = ((kerb_offset > 0.0) & (kerb_offset <= 1.5)).astype(np.float64)
    speed = np.hypot(vx, vy)
    ego_speed = max(float(ego[EgoColumn.SPEED]), 0.0)
    half_len = road_map.ego_length / 2
    if road_map.has_crossing:
        cross_dx = float(ego[EgoColumn.DISTANCE_TO_STOP_LINE]) + road_map.crossing_offset - dx
        along = np.clip(np.abs(cross_dx) - road_map.crossing_half_width, 0.0, CAP)
        heading = np.clip(vx * np.sign(cross_dx), -2.0, 2.0)
    else:
        cross_dx = np.full_like(dx, CAP)
        along = np.full_like(dx, CAP)
        heading = np.zeros_like(dx)
    at_crossing = (along <= 1.0).astype(np.float64)
    zebra = float(road_map.has_crossing and not road_map.signalised)
    faces_red = float(road_map.signalised and ego[EgoColumn.CAR_GREEN] > 0.5) * at_crossing
    ego_time = np.clip((dx - half_len) / max(ego_speed, 0.5), -CAP, CAP)
    ahead = (dx + half_len > 0.0).astype(np.float64)
    # Gap: the first approaching car (the ego or a background vehicle) to reach the pedestrian's x.
    cars = np.empty((veh.shape[0] + 1, 3))
    cars[0] = (0.0, ego_speed, road_map.ego_length)
    cars[1:] = veh[:, (VehicleColumn.DX, VehicleColumn.VX, VehicleColumn.LENGTH)]
    car_speed = np.abs(cars[:, 1])
    dist = (dx[:, None] - cars[:, 0]) * np.sign(cars[:, 1]) - 0.5 * cars[:, 2]
    tta = np.where((dist >= 0.0) & (car_speed > 0.3), dist / np.maximum(car_speed, 0.3), np.inf)
    gap = np.minimum(tta.min(axis=1), CAP)
    hy = hist[:, :, PointColumn.Y]
    was_on_road = ((hy > lo) & (hy < hi)).any(axis=1).astype(np.float64)
    span = max(hist.shape[1] - 1, 1) * HISTORY_INTERVAL
    moved = hist[:, -1, PointColumn.Y] - hist[:, 0, PointColumn.Y]
    history_towards = np.clip(np.where(south, moved, -moved) / span, -3.0, 3.0)
    columns = (
        kerb_offset,
        near_kerb,
        np.clip(towards, -3.0, 3.0),
        np.clip(speed, 0.0, 5.0),
        np.clip(np.abs(vx), 0.0, 5.0),
        ped[:, c.WAITING],
        ped[:, c.ON_ROAD],
        ped[:, c.ON_CROSSING],
        along,
        at_crossing,
        heading,
        np.full_like(dx, zebra),
        faces_red,
        np.full_like(dx, ego_speed),
        ego_time,
        ahead,
        gap,
        was_on_road,
        history_towards,
        near_kerb * np.clip(towards, -3.0, 3.0),
        near_kerb * at_crossing,
        near_kerb * gap,
        near_kerb * ego_time,
        ped[:, c.WAITING] * zebra,
    )
    out = np.stack(columns, axis=1)
    out[~present] = 0.0
    return out


def predict(features: np.ndarray, head: dict[str, Any]) -> np.ndarray:
    """Probabilities of one logistic head (``mean``, ``scale``, ``coef``, ``bias``) for (N, F) features."""
    z = (features - np.asarray(head["mean"])) / np.asarray(head["scale"])
    logit = z @ np.asarray(head["coef"]) + float(head["bias"])
    return 0.5 * (1.0 + np.tanh(0.5 * logit))


class LearnedIntent:
    """Forecaster of ``crossing_intention`` and ``crossing_intent`` from the shipped logistic heads.

    Args:
        horizon: Seconds of ``crossing_intention``: one of the fitted horizons (1, 2 or 4).
    """

    def __init__(self, horizon: float = 2.0) -> None:
        key = f"{float(horizon):g}"
        if key not in HEADS[:-1]:
            raise ValueError(f"learned intention: horizon must be one of 1, 2, 4 s, got {horizon}")
        weights = shipped_weights()
        if tuple(weights["features"]) != FEATURES:
            raise ValueError("learned intention: the shipped weights were fitted on other features")
        if float(weights["intent_horizon"]) != INTENT_HORIZON:
            raise ValueError("learned intention: the shipped weights use another intent horizon")
        self.horizon = float(horizon)
        self.spec = ForecastSpec(paths=False, intent=True, intent_bound=True)
        self._near = weights["heads"][key]
        self._intent = weights["heads"]["intent"]
        self._bound = release_threshold("learned")

    def reset(self, seed: int | None) -> None:
        """Nothing to reset: the heads read the current observation."""

    def forecast(self, inputs: ForecastInput) -> Forecast:
        """Both probabilities of every slot (0 for absent slots)."""
        if inputs.scene is None:
            raise ValueError(
                "learned intention needs a crossing_env env (env.unwrapped.scenario) for the map"
            )
        feats = intent_features(inputs.observation, inputs.scene)
        present = inputs.present
        return Forecast(
            intention=(predict(feats, self._near) * present).astype(np.float32),
            intent=(predict(feats, self._intent) * present).astype(np.float32),
            intent_bound=self._bound,
        )


class LearnedIntention(ForecastObservation):
    """Add ``crossing_intention`` and ``crossing_intent`` (K,): a `LearnedIntent` in the one wrapper.

    Args:
        env: A ``crossing_env/Crossing-v0`` env (possibly wrapped).
        horizon: Seconds of ``crossing_intention``: one of the fitted horizons (1, 2 or 4).
    """

    def __init__(self, env: gym.Env, horizon: float = 2.0) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, horizon=horizon)
        model = LearnedIntent(horizon)
        space = env.observation_space
        needed = {PEDESTRIANS_KEY, VEHICLES_KEY, EGO_KEY, PEDESTRIAN_HISTORY_KEY}
        if not isinstance(space, spaces.Dict) or not needed <= set(space.spaces):
            raise ValueError(f"learned intention needs the crossing_env Dict observation, got {space}")
        if getattr(env.unwrapped, "scenario", None) is None:
            raise ValueError(
                "learned intention needs a crossing_env env (env.unwrapped.scenario) for the map"
            )
        super().__init__(env, model, "learned")
        self.horizon = model.horizon
