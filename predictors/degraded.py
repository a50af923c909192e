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

from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

from crossing_env.observation import (
    CROSSING_INTENT_KEY,
    CROSSING_INTENTION_KEY,
    PEDESTRIAN_TRACKS_KEY,
    PEDESTRIANS_KEY,
    PREDICTED_PATHS_KEY,
    PedestrianColumn,
)
from predictors.oracle import PLAN_PATHS_KEY

__all__ = ["FlippedIntention", "NoisyPaths", "flip_draws", "path_errors"]

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


class FlippedIntention(gym.ObservationWrapper, gym.utils.RecordConstructorArgs):
    """PRIVILEGED, degraded: the oracle's intent flipped for a fraction `flip` of tracks (see the module)."""

    privileged: ClassVar[bool] = True
    """Built on the ground truth: a point on the accuracy-to-value curve, never a deployable predictor."""

    def __init__(self, env: gym.Env, flip: float) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, flip=flip)
        gym.ObservationWrapper.__init__(self, env)
        if not 0.0 <= float(flip) <= 1.0:
            raise ValueError(f"FlippedIntention: flip must be a probability in [0, 1], got {flip}")
        space = env.observation_space
        if not isinstance(space, gym.spaces.Dict) or CROSSING_INTENT_KEY not in space.spaces:
            raise ValueError("FlippedIntention wraps an env that has crossing_intent (the intention oracle)")
        self.flip = float(flip)
        self._gen: np.random.Generator | None = None
        self._key = 0
        self._draws: dict[int, float] = {}

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict]:
        """Reset the env and draw this episode's key (the tracks' draws follow from it)."""
        self._key, self._gen = _episode_key(seed, self._gen, _FLIP_SALT)
        self._draws = {}
        return super().reset(seed=seed, options=options)

    def _draw(self, track: int) -> float:
        if track not in self._draws:
            self._draws[track] = _flip_draw(self._key, track)
        return self._draws[track]

    def observation(self, observation: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The oracle's intent with the flipped tracks' decided values inverted (undecided stays 0.5)."""
        present = observation[PEDESTRIANS_KEY][:, PedestrianColumn.PRESENCE] > 0.5
        tracks = observation[PEDESTRIAN_TRACKS_KEY]
        result = dict(observation)
        for key in (CROSSING_INTENT_KEY, CROSSING_INTENTION_KEY):
            if key not in observation:
                continue
            value = observation[key].copy()
            for k in np.flatnonzero(present):
                if value[k] in (0.0, 1.0) and self._draw(int(tracks[k])) < self.flip:
                    value[k] = 1.0 - value[k]
            result[key] = value
        return result


class NoisyPaths(gym.ObservationWrapper, gym.utils.RecordConstructorArgs):
    """PRIVILEGED, degraded: the oracle's paths with a horizon-growing error of scale `sigma` (docstring)."""

    privileged: ClassVar[bool] = True
    """Built on the ground truth: a point on the accuracy-to-value curve, never a deployable predictor."""

    def __init__(self, env: gym.Env, sigma: float, hold_steps: int = HOLD_STEPS) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, sigma=sigma, hold_steps=hold_steps)
        gym.ObservationWrapper.__init__(self, env)
        if not (np.isfinite(sigma) and float(sigma) >= 0.0):
            raise ValueError(f"NoisyPaths: sigma must be a finite distance >= 0 (m), got {sigma}")
        if not (isinstance(hold_steps, int) and hold_steps >= 1):
            raise ValueError(f"NoisyPaths: hold_steps must be an integer >= 1, got {hold_steps!r}")
        space = env.observation_space
        if not isinstance(space, gym.spaces.Dict) or PREDICTED_PATHS_KEY not in space.spaces:
            raise ValueError("NoisyPaths wraps an env that has predicted_paths (the path oracle)")
        self.sigma = float(sigma)
        self.hold_steps = hold_steps
        self.bound = float(space.spaces[PREDICTED_PATHS_KEY].high.max())
        steps = space.spaces[PREDICTED_PATHS_KEY].shape[1]
        self._ramp = (np.arange(1, steps + 1, dtype=np.float32) / steps)[:, None]  # (T, 1)
        self._gen: np.random.Generator | None = None
        self._key = 0
        self._step = 0
        self._period = -1
        self._held: dict[int, np.ndarray] = {}
        """Each present track's error of the current hold period."""

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict]:
        """Reset the env, the step count and this episode's key."""
        self._key, self._gen = _episode_key(seed, self._gen, _NOISE_SALT)
        self._step = -1  # the reset's observation is step 0
        self._period, self._held = -1, {}
        return super().reset(seed=seed, options=options)

    def observation(self, observation: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The paths of the present slots shifted by their track's error of this hold period."""
        self._step += 1
        present = np.flatnonzero(observation[PEDESTRIANS_KEY][:, PedestrianColumn.PRESENCE] > 0.5)
        if not present.size or self.sigma == 0.0:
            return observation
        tracks = observation[PEDESTRIAN_TRACKS_KEY]
        period = self._step // self.hold_steps
        if period != self._period:  # a track's error is drawn once per hold period, not once per step
            self._period, self._held = period, {}
        offsets = np.zeros((observation[PREDICTED_PATHS_KEY].shape[0], 1, 2), np.float32)
        for k in present:
            track = int(tracks[k])
            if track not in self._held:
                self._held[track] = self.sigma * _path_offset(self._key, track, period)
            offsets[k, 0] = self._held[track]
        error = offsets * self._ramp[None]  # (K, T, 2); zero in absent slots
        result = dict(observation)
        for key in (PREDICTED_PATHS_KEY, PLAN_PATHS_KEY):
            if key in observation:
                result[key] = np.clip(observation[key] + error, -self.bound, self.bound).astype(np.float32)
        return result
