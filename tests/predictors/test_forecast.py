"""The forecast protocol: every built-in goes through it; a malformed forecast is an error naming it."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from predictors.forecast import (
    Forecast,
    Forecaster,
    ForecastError,
    ForecastInput,
    ForecastSpec,
    validate_forecast,
)
from predictors.forecast_wrapper import ForecastObservation
from rollout.wrappers import INTENTION_WRAPPERS, NONE, TRAJECTORY_WRAPPERS, wrap

SCENARIO = "busy_zebra"


def _env() -> gym.Env:
    return gym.make("crossing_env/Crossing-v0", scenario=SCENARIO)


class Spread:
    """Three weighted constant-velocity samples: straight on (weight 0.5) and turned ±30 degrees."""

    def __init__(self, weights: tuple[float, float, float] = (0.25, 0.5, 0.25)) -> None:
        self.spec = ForecastSpec(samples=3)
        self.weights = np.asarray(weights)
        self.seeds: list[int | None] = []

    def reset(self, seed: int | None) -> None:
        self.seeds.append(seed)

    def forecast(self, inputs: ForecastInput) -> Forecast:
        vel = inputs.history[:, -1] - inputs.history[:, -2]  # (N, 2) per 0.4 s
        steps = np.arange(1, self.spec.horizon + 1)[:, None]
        paths = []
        for angle in np.radians([-30.0, 0.0, 30.0]):
            c, s = np.cos(angle), np.sin(angle)
            turned = np.stack([c * vel[:, 0] - s * vel[:, 1], s * vel[:, 0] + c * vel[:, 1]], axis=1)
            paths.append(inputs.history[:, -1, None] + steps[None] * turned[:, None])
        n = len(inputs.present)
        return Forecast(paths=np.stack(paths, axis=1), weights=np.tile(self.weights, (n, 1)))


def _inputs(n: int = 4, present: int = 2) -> ForecastInput:
    mask = np.arange(n) < present
    return ForecastInput(np.zeros((n, 8, 2), np.float32), mask, None, None, {}, 0)


def _paths(n: int = 4, s: int = 3) -> np.ndarray:
    return np.zeros((n, s, 12, 2), np.float32)


@pytest.mark.parametrize(
    ("forecast", "message"),
    [
        ("not a forecast", "must return a Forecast"),
        (Forecast(), "paths missing"),
        (Forecast(paths=np.zeros((4, 3, 11, 2))), r"shape \(4, 3, 12, 2\)"),
        (Forecast(paths=_paths().astype(complex)), "real numbers"),
        (Forecast(paths=np.where(np.arange(4)[:, None, None, None] == 1, np.nan, _paths())), "NaN"),
        (Forecast(paths=_paths(), weights=np.array([[0.5, 0.7, -0.2]] * 4)), ">= 0"),
        (Forecast(paths=_paths(), weights=np.full((4, 3), 0.5)), "sum to 1"),
        (Forecast(paths=_paths(), weights=np.full((4, 2), 0.5)), r"shape \(4, 3\)"),
    ],
)
def test_a_malformed_forecast_is_an_error_naming_its_forecaster(forecast: Any, message: str) -> None:
    with pytest.raises(ForecastError, match=f"forecaster 'mine'.*{message}"):
        validate_forecast("mine", forecast, ForecastSpec(samples=3), _inputs())


def test_values_in_absent_slots_are_not_checked() -> None:
    paths = _paths()
    paths[3] = np.nan  # slot 3 is padding
    ok = Forecast(paths=paths, weights=np.array([[0.2, 0.3, 0.5]] * 3 + [[np.nan] * 3]))
    assert validate_forecast("mine", ok, ForecastSpec(samples=3), _inputs()) is ok


def test_intent_must_be_probabilities_and_a_promised_bound_present() -> None:
    spec = ForecastSpec(paths=False, intent=True, intent_bound=True)
    good = Forecast(intention=np.full(4, 0.2), intent=np.full(4, 0.3), intent_bound=0.1)
    assert validate_forecast("mine", good, spec, _inputs()) is good
    with pytest.raises(ForecastError, match=r"\[0, 1\]"):
        validate_forecast("mine", replace(good, intent=np.full(4, 1.5)), spec, _inputs())
    with pytest.raises(ForecastError, match="intention missing"):
        validate_forecast("mine", replace(good, intention=None), spec, _inputs())
    with pytest.raises(ForecastError, match="intent_bound"):
        validate_forecast("mine", replace(good, intent_bound=None), spec, _inputs())


def test_a_spec_that_promises_nothing_or_nonsense_is_refused() -> None:
    with pytest.raises(ValueError, match="paths, intent, or both"):
        ForecastSpec(paths=False)
    with pytest.raises(ValueError, match="samples"):
        ForecastSpec(samples=0)
    with pytest.raises(ValueError, match="plan needs paths"):
        ForecastSpec(paths=False, intent=True, plans=(1.0,))


def test_a_weighted_forecaster_shows_its_heaviest_sample_and_passes_the_env_checker() -> None:
    spread = Spread()
    env = ForecastObservation(_env(), spread, "spread")
    check_env(env, skip_render_check=True)
    obs, _ = env.reset(seed=4)
    assert spread.seeds[-1] == 4
    for _ in range(30):
        obs, *_ = env.step(np.zeros(1, np.float32))
    present = obs["pedestrians"][:, 0] > 0.5
    assert present.any()
    hist = obs["pedestrian_history"]
    straight = hist[:, -1, None] + np.arange(1, 13)[None, :, None] * (hist[:, -1] - hist[:, -2])[:, None]
    np.testing.assert_allclose(obs["predicted_paths"][present], straight[present], atol=1e-4)
    assert not obs["predicted_paths"][~present].any()  # absent slots are zeros
    # The distribution beside it: every sample, and the weights as the samples' presence flags.
    assert obs["predicted_samples"].shape == (len(present), 3, 12, 2)
    np.testing.assert_array_equal(obs["predicted_samples"][present, 1], obs["predicted_paths"][present])
    np.testing.assert_allclose(obs["sample_weights"][present], np.tile([0.25, 0.5, 0.25], (present.sum(), 1)))
    assert not obs["sample_weights"][~present].any() and not obs["predicted_samples"][~present].any()


def test_a_forecast_that_turns_bad_mid_episode_stops_the_episode_with_its_name() -> None:
    class GoesNaN(Spread):
        def forecast(self, inputs: ForecastInput) -> Forecast:
            out = super().forecast(inputs)
            return replace(out, paths=out.paths * np.nan) if inputs.step >= 5 else out

    env = ForecastObservation(_env(), GoesNaN(), "goes-nan")
    env.reset(seed=4)
    with pytest.raises(ForecastError, match=r"'goes-nan'.*NaN"):
        for _ in range(40):
            env.step(np.zeros(1, np.float32))


def test_the_wrapper_refuses_an_incomplete_forecaster() -> None:
    class NoSpec:
        def reset(self, seed: int | None) -> None: ...
        def forecast(self, inputs: ForecastInput) -> Forecast: ...

    with pytest.raises(ForecastError, match=r"'bare'.*spec"):
        ForecastObservation(_env(), NoSpec(), "bare")  # type: ignore[arg-type]
    planner = Spread()
    planner.spec = ForecastSpec(samples=3, plans=(1.0, -2.0))
    with pytest.raises(ForecastError, match="forecast_plans"):
        ForecastObservation(_env(), planner, "no-plans")
    secret = Spread()
    secret.spec = ForecastSpec(samples=3, privileged=True)
    with pytest.raises(ForecastError, match="bind"):
        ForecastObservation(_env(), secret, "secret")


def test_only_a_privileged_forecaster_is_handed_the_env() -> None:
    class Nosy(Spread):
        bound: Any = None

        def bind(self, env: gym.Env) -> None:
            self.bound = env

    nosy = Nosy()
    ForecastObservation(_env(), nosy, "nosy")
    assert nosy.bound is None
    nosy.spec = ForecastSpec(samples=3, privileged=True)
    ForecastObservation(_env(), nosy, "nosy")
    assert nosy.bound is not None


@pytest.mark.parametrize(
    ("intention", "predictor"),
    [(name, NONE) for name in INTENTION_WRAPPERS]
    + [(NONE, name) for name in TRAJECTORY_WRAPPERS]
    + [("oracle-flip=0.2", NONE), (NONE, "oracle-noise=0.5")],
)
def test_every_built_in_is_a_forecaster_in_the_one_wrapper(intention: str, predictor: str) -> None:
    env, used = wrap(_env(), intention, predictor)
    assert isinstance(env, ForecastObservation) and type(env) is ForecastObservation
    assert isinstance(env.forecaster, Forecaster)
    assert used and env.name == used[0].split(":", 1)[1]
    obs, _ = env.reset(seed=1)
    assert env.observation_space.contains(obs)


def test_a_one_path_forecaster_shows_its_path_as_one_sample_of_weight_one() -> None:
    env, _ = wrap(_env(), NONE, "cvm")
    env.reset(seed=2)
    for _ in range(30):
        obs, *_ = env.step(np.zeros(1, np.float32))
    present = obs["pedestrians"][:, 0] > 0.5
    assert present.any()
    np.testing.assert_array_equal(obs["predicted_samples"][:, 0], obs["predicted_paths"])
    np.testing.assert_array_equal(obs["sample_weights"][:, 0], present.astype(np.float32))


def test_sampled_s_cgru_shows_its_mode_and_equal_weights() -> None:
    from predictors.trajectory_wrapper import TrajectoryPrediction

    env = TrajectoryPrediction(_env(), num_samples=4)
    env.reset(seed=2)
    for _ in range(30):
        obs, *_ = env.step(np.zeros(1, np.float32))
    present = obs["pedestrians"][:, 0] > 0.5
    assert obs["predicted_samples"].shape[1] == 4
    np.testing.assert_array_equal(
        obs["sample_weights"][present], np.full((present.sum(), 4), 0.25, np.float32)
    )
    assert not np.array_equal(obs["predicted_samples"][present, 0], obs["predicted_paths"][present])
