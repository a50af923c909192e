"""A user's predictor module, as `crossing-eval --predictor tests.crossing_eval.plugin_predictors:...` finds.

Each forecaster but `Steady` is broken in one way a user's first try might be.
"""

from __future__ import annotations

import numpy as np

from predictors.forecast import Forecast, ForecastInput, ForecastSpec


class Steady:
    """Every pedestrian stands still: one path, weight 1."""

    spec = ForecastSpec()

    def reset(self, seed: int | None) -> None:
        """Nothing to reset."""

    def forecast(self, inputs: ForecastInput) -> Forecast:
        """The last position, held."""
        return Forecast(paths=np.repeat(inputs.history[:, None, -1:], 12, axis=2))


class RaisesInInit(Steady):
    """Cannot be built."""

    def __init__(self) -> None:
        raise RuntimeError("weights.bin not found")


class ReturnsNaN(Steady):
    """Returns NaN paths."""

    def forecast(self, inputs: ForecastInput) -> Forecast:
        """NaN everywhere."""
        return Forecast(paths=np.full((len(inputs.present), 1, 12, 2), np.nan))


class WrongShape(Steady):
    """Returns paths without the sample axis."""

    def forecast(self, inputs: ForecastInput) -> Forecast:
        """(N, 12, 2) instead of (N, 1, 12, 2)."""
        return Forecast(paths=np.zeros((len(inputs.present), 12, 2)))


class RaisesInForecast(Steady):
    """Its forecast raises."""

    def forecast(self, inputs: ForecastInput) -> Forecast:
        """A bug."""
        raise IndexError("index 8 is out of bounds")


class NoSpec:
    """Forgot its spec."""

    def reset(self, seed: int | None) -> None:
        """Nothing to reset."""

    def forecast(self, inputs: ForecastInput) -> Forecast:
        """Nothing."""
        return Forecast()


NOT_CALLABLE = 3
"""Not a forecaster at all."""
