"""Degraded oracles: the privileged predictions made wrong by a known amount, for the accuracy-to-value curve.

"Does a more accurate predictor make the car drive better?" (Wu et al., NeurIPS 2023, ask it of trajectory
prediction) needs predictors whose accuracy can be dialled. These wrappers sit on top of the oracles
(`predictors.oracle`) and spoil them in a controlled, seeded way, so the value of each accuracy level can be
measured on the same episodes as the real predictors:

- `FlippedIntention` (``--intention oracle-flip=q``): the true intent to cross, wrong for each pedestrian
  track with probability ``q``. The error belongs to a track, not to a step: a classifier that misreads a
  person keeps misreading them, and a per-step coin would average out over a few steps (the policy
  remembers). One uniform draw per (episode, track) decides, so the levels are nested: every pedestrian
  flipped at q = 0.1 is flipped at q = 0.2. Its open-loop Brier score against the truth is q on decided
  pedestrians.
- `NoisyPaths` (``--predictor oracle-noise=sigma``): the true future paths (and each plan's, so plans stay
  comparable) shifted by an error that grows linearly with the horizon, ``(k / 12) * e`` at step k, with
  ``e ~ N(0, sigma^2 I)`` per track: sigma is the standard deviation per axis of the final (4.8 s)
  displacement error, as a velocity error would give. ``e`` is redrawn every `hold_steps` env steps (the
  oracle's refresh, 0.4 s): real forecast errors are correlated in time, and independent noise every 0.1 s
  would make the car chatter for a reason no predictor has. Its ADE is about 0.68 sigma, FDE 1.25 sigma.

Both draw only from generators seeded by ``reset(seed=...)`` and the track id, never from the world's
generator, so a degraded row runs the same pedestrians as every other row of the grid.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

from predictors.forecast import Forecast, ForecastInput
from predictors.forecast_wrapper import ForecastObservation
from predictors.oracle import IntentOracle, PathOracle

__all__ = ["FlippedIntent", "FlippedIntention", "NoisyOraclePaths", "NoisyPaths", "flip_draws", "path_errors"]

_FLIP_SALT = 0x464C4950
"""Mixed into the seed of the flip draws, so they never coincide with another generator's stream."""
_NOISE_SALT = 0x4E4F4953
"""Mixed into the seed of the path errors."""
HOLD_STEPS = 4
"""Env steps an error of `NoisyPaths` is held (0.4 s, the path oracle's refresh)."""


def _episode_key(seed: int | None, previous: np.random.Generator | None, salt: int) -> tuple[int, Any]:
    """A per-episode key from the reset seed (a seeded reset restarts the stream; an unseeded one goes on)."""
    gen = np.random.default_rng([0 if seed is None else int(seed) & 0xFFFFFFFF, salt])
    if seed is None and previous is not None:
        gen = previous
    return int(gen.integers(2**32)), gen


def _flip_draw(key: int, track: int) -> float:
    return float(np.random.default_rng([key, track]).random())


def _path_offset(key: int, track: int, period: int) -> np.ndarray:
    return np.random.default_rng([key, track, period]).standard_normal(2)


def flip_draws(seed: int, tracks: np.ndarray) -> np.ndarray:
    """The uniform draw of each track in the episode reset with `seed`: flipped at level q where below q."""
    key, _ = _episode_key(seed, None, _FLIP_SALT)
    return np.array([_flip_draw(key, int(t)) for t in tracks])


def path_errors(seed: int, tracks: np.ndarray, steps: np.ndarray, sigma: float, horizon: int) -> np.ndarray:
    """The error (N, horizon, 2) that `NoisyPaths(sigma)` adds to a track at an env step.

    ``tracks[i]`` at step ``steps[i]`` (0 = the reset's observation) of the episode reset with `seed`,
    with the default `hold_steps`: the accuracy study recomputes the closed-loop rows' errors with it.
    """
    key, _ = _episode_key(seed, None, _NOISE_SALT)
    ramp = np.arange(1, horizon + 1) / horizon
    offsets = np.array(
        [_path_offset(key, int(t), int(s) // HOLD_STEPS) for t, s in zip(tracks, steps, strict=True)]
    )
    return sigma * offsets.reshape(-1, 1, 2) * ramp[None, :, None]


class FlippedIntent:
    """PRIVILEGED, degraded forecaster: the intent oracle flipped for a fraction `flip` of tracks (module)."""

    def __init__(self, flip: float, undecided: float = 0.5) -> None:
        if not 0.0 <= float(flip) <= 1.0:
            raise ValueError(f"FlippedIntention: flip must be a probability in [0, 1], got {flip}")
        self.flip = float(flip)
        self.oracle = IntentOracle(undecided)
        self.spec = self.oracle.spec
        self._gen: np.random.Generator | None = None
        self._key = 0
        self._draws: dict[int, float] = {}

    def bind(self, env: gym.Env) -> None:
        """Hand the oracle the env."""
        self.oracle.bind(env)

    def reset(self, seed: int | None) -> None:
        """Draw this episode's key (the tracks' draws follow from it)."""
        self._key, self._gen = _episode_key(seed, self._gen, _FLIP_SALT)
        self._draws = {}
        self.oracle.reset(seed)

    def _draw(self, track: int) -> float:
        if track not in self._draws:
            self._draws[track] = _flip_draw(self._key, track)
        return self._draws[track]

    def forecast(self, inputs: ForecastInput) -> Forecast:
        """The oracle's intent with the flipped tracks' decided values inverted (undecided stays 0.5)."""
        truth = self.oracle.forecast(inputs)
        if inputs.tracks is None:
            raise ValueError("FlippedIntention needs the observation's pedestrian tracks")
        values = []
        for value in (truth.intention, truth.intent):
            value = np.array(value, dtype=np.float32)
            for k in np.flatnonzero(inputs.present):
                if value[k] in (0.0, 1.0) and self._draw(int(inputs.tracks[k])) < self.flip:
                    value[k] = 1.0 - value[k]
            values.append(value)
        return replace(truth, intention=values[0], intent=values[1])


class NoisyOraclePaths:
    """PRIVILEGED, degraded forecaster: the path oracle with a horizon-growing error of scale `sigma`."""

    def __init__(self, sigma: float, hold_steps: int = HOLD_STEPS, **oracle: Any) -> None:
        if not (np.isfinite(sigma) and float(sigma) >= 0.0):
            raise ValueError(f"NoisyPaths: sigma must be a finite distance >= 0 (m), got {sigma}")
        if not (isinstance(hold_steps, int) and hold_steps >= 1):
            raise ValueError(f"NoisyPaths: hold_steps must be an integer >= 1, got {hold_steps!r}")
        self.sigma = float(sigma)
        self.hold_steps = hold_steps
        self.oracle = PathOracle(**oracle)
        self.spec = self.oracle.spec
        steps = self.spec.horizon
        self._ramp = (np.arange(1, steps + 1, dtype=np.float32) / steps)[:, None]  # (T, 1)
        self._gen: np.random.Generator | None = None
        self._key = 0
        self._period = -1
        self._held: dict[int, np.ndarray] = {}
        """Each present track's error of the current hold period."""
        self._error: np.ndarray | None = None

    @property
    def rollouts(self) -> int:
        """Rollouts the oracle has run so far."""
        return self.oracle.rollouts

    def bind(self, env: gym.Env) -> None:
        """Hand the oracle the env."""
        self.oracle.bind(env)

    def reset(self, seed: int | None) -> None:
        """Reset the oracle and draw this episode's key."""
        self._key, self._gen = _episode_key(seed, self._gen, _NOISE_SALT)
        self._period, self._held = -1, {}
        self.oracle.reset(seed)

    def _errors(self, inputs: ForecastInput) -> np.ndarray | None:
        """(N, T, 2) error of this step's present tracks (None when nothing is shifted)."""
        present = np.flatnonzero(inputs.present)
        if not present.size or self.sigma == 0.0:
            return None
        if inputs.tracks is None:
            raise ValueError("NoisyPaths needs the observation's pedestrian tracks")
        period = inputs.step // self.hold_steps
        if period != self._period:  # a track's error is drawn once per hold period, not once per step
            self._period, self._held = period, {}
        offsets = np.zeros((inputs.present.shape[0], 1, 2), np.float32)
        for k in present:
            track = int(inputs.tracks[k])
            if track not in self._held:
                self._held[track] = self.sigma * _path_offset(self._key, track, period)
            offsets[k, 0] = self._held[track]
        return offsets * self._ramp[None]  # (K, T, 2); zero in absent slots

    def forecast(self, inputs: ForecastInput) -> Forecast:
        """The oracle's paths of the present slots shifted by their track's error of this hold period."""
        truth = self.oracle.forecast(inputs)
        self._error = self._errors(inputs)
        if self._error is None:
            return truth
        return replace(truth, paths=truth.paths + self._error[:, None])

    def forecast_plans(self, inputs: ForecastInput) -> np.ndarray:
        """Each plan's true paths shifted by the same error (so plans stay comparable)."""
        plans = self.oracle.forecast_plans(inputs)
        return plans if self._error is None else plans + self._error[None]


class FlippedIntention(ForecastObservation):
    """PRIVILEGED, degraded: `FlippedIntent` in the one forecast wrapper."""

    privileged: ClassVar[bool] = True
    """Built on the ground truth: a point on the accuracy-to-value curve, never a deployable predictor."""

    def __init__(self, env: gym.Env, flip: float) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, flip=flip)
        super().__init__(env, FlippedIntent(flip), f"oracle-flip={flip:g}")
        self.flip = float(flip)


class NoisyPaths(ForecastObservation):
    """PRIVILEGED, degraded: `NoisyOraclePaths` in the one forecast wrapper."""

    privileged: ClassVar[bool] = True
    """Built on the ground truth: a point on the accuracy-to-value curve, never a deployable predictor."""

    def __init__(self, env: gym.Env, sigma: float, hold_steps: int = HOLD_STEPS, **oracle: Any) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, sigma=sigma, hold_steps=hold_steps, **oracle)
        super().__init__(env, NoisyOraclePaths(sigma, hold_steps, **oracle), f"oracle-noise={sigma:g}")
        self.sigma = float(sigma)
        self.hold_steps = hold_steps
