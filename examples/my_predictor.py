"""A user's own pedestrian forecaster, evaluated in the loop with one flag.

    crossing-eval --predictor examples.my_predictor:Forecaster --policies predictive_yielding

This file is written as a user would write it outside the project: it imports only the forecast protocol
(`predictors.forecast`) and a data loader. The model is the constant-velocity model with a noise model:
each of its samples turns the last observed velocity by a heading error and scales it by a speed error, both
drawn from the distributions of the constant-velocity model's own 4.8 s errors on ETH/UCY's training split
(the ``eth`` leave-one-out fold: hotel, univ, zara1, zara2). The most likely path (the forecast's mode) is
the plain constant-velocity path; the samples weigh equally. Refit the three numbers with

    python examples/my_predictor.py --fit

(robust scales: 1.4826 × the median absolute deviation, so a few pedestrians who turn round do not set the
spread of everyone else's).
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from predictors.forecast import Forecast, ForecastInput, ForecastSpec

HEADING_SIGMA_DEG = 14.62
"""Standard deviation of the heading error (degrees) of the final displacement, fitted (`fit`)."""
LOG_SPEED_MEDIAN = -0.0333
"""Median of log(true / predicted final displacement), fitted."""
LOG_SPEED_SIGMA = 0.216
"""Robust standard deviation of that log speed ratio, fitted."""
SAMPLES = 12
"""Path samples per pedestrian."""


class Forecaster:
    """Constant velocity with sampled heading and speed errors (see the module docstring)."""

    def __init__(self, samples: int = SAMPLES) -> None:
        self.spec = ForecastSpec(samples=samples, mode=True)
        self._rng = np.random.default_rng(0)

    def reset(self, seed: int | None) -> None:
        """A seed restarts the noise, so the same seed gives the same episode."""
        if seed is not None:
            self._rng = np.random.default_rng(seed)

    def forecast(self, inputs: ForecastInput) -> Forecast:
        """The mode and the samples for every slot (the wrapper ignores absent slots)."""
        last = inputs.history[:, -1].astype(np.float64)  # (N, 2), metres, ego frame
        velocity = last - inputs.history[:, -2]  # per 0.4 s step
        steps = np.arange(1, self.spec.horizon + 1)[None, :, None]  # (1, H, 1)
        mode = last[:, None] + steps * velocity[:, None]  # (N, H, 2)
        n, s = len(last), self.spec.samples
        turn = self._rng.normal(0.0, math.radians(HEADING_SIGMA_DEG), (n, s))
        scale = np.exp(self._rng.normal(LOG_SPEED_MEDIAN, LOG_SPEED_SIGMA, (n, s)))
        c, si = np.cos(turn) * scale, np.sin(turn) * scale
        vx, vy = velocity[:, 0, None], velocity[:, 1, None]
        sampled = np.stack([c * vx - si * vy, si * vx + c * vy], axis=-1)  # (N, S, 2)
        paths = last[:, None, None] + steps[:, None] * sampled[:, :, None]  # (N, S, H, 2)
        return Forecast(paths=paths, mode=mode)


def fit(data_root: str | None = None, fold: str = "eth") -> tuple[float, float, float]:
    """(heading sigma in degrees, log speed median, log speed sigma) on the fold's training split."""
    from predictors.data import default_data_root, load_split

    windows = load_split(data_root or default_data_root(), fold, "train")
    traj = windows.traj.astype(np.float64)
    observed, future = traj[:, :8], traj[:, 8:]
    predicted = 12 * (observed[:, -1] - observed[:, -2])
    actual = future[:, -1] - observed[:, -1]
    moving = (np.linalg.norm(predicted, axis=1) > 1.0) & (np.linalg.norm(actual, axis=1) > 1.0)
    p, a = predicted[moving], actual[moving]
    heading = np.arctan2(a[:, 1], a[:, 0]) - np.arctan2(p[:, 1], p[:, 0])
    heading = (heading + np.pi) % (2 * np.pi) - np.pi
    log_speed = np.log(np.linalg.norm(a, axis=1) / np.linalg.norm(p, axis=1))
    median = float(np.median(log_speed))

    def robust(x: np.ndarray, centre: float = 0.0) -> float:
        return float(1.4826 * np.median(np.abs(x - centre)))

    return math.degrees(robust(heading)), median, robust(log_speed, median)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="Refit the noise model on ETH/UCY's training split.")
    parser.add_argument("--fit", action="store_true", help="print the fitted constants")
    parser.add_argument(
        "--data", default=None, help="data folder (default: $CROSSING_DATA or ../shared/data)"
    )
    if parser.parse_args().fit:
        heading, median, sigma = fit(parser.parse_args().data)
        print(f"HEADING_SIGMA_DEG = {heading:.2f}")
        print(f"LOG_SPEED_MEDIAN = {median:.4f}")
        print(f"LOG_SPEED_SIGMA = {sigma:.3f}")
