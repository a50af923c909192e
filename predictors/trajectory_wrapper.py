"""Observation wrapper adding predicted pedestrian paths from a trained trajectory predictor.

Contract with the base env: its observation space is a ``spaces.Dict`` with

* ``"pedestrians"`` ``(K, F)`` float32, column 0 a presence flag (1 present, 0 padding);
* ``"pedestrian_history"`` ``(K, 8, 2)`` float32, each slot's last 8 positions 0.4 s apart, oldest first,
  in the observation's (ego) frame, metres.

The wrapper adds ``"predicted_paths"`` ``(K, 12, 2)`` (most-likely path, same frame, zeros for absent slots)
and, with ``num_samples > 0``, ``"predicted_samples"`` ``(K, S, 12, 2)``. All present pedestrians form one
window, so the social pooling sees every present neighbour. Predictions are clipped to the declared bounds.
The most-likely path runs through :class:`~predictors.fast_inference.FastPredictor` (NumPy, same numbers as
the torch model) to stay within the per-step budget; samples run through the torch model. Without samples,
an observation whose present slots and histories equal the previous call's reuses the previous paths
(exact; helps when the env steps faster than the 0.4 s history spacing).
Samples come from a private ``torch.Generator`` reseeded from the ``reset`` seed (seed 0 until the first
seeded reset), never from a global RNG.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from gymnasium import spaces

from predictors.baselines import cvm, cvm_samples
from predictors.data import OBS_LEN, PRED_LEN
from predictors.fast_inference import FastPredictor
from predictors.models import MODEL_KINDS, SocialRecurrent
from predictors.train import WEIGHTS_DIR, load_model

MAX_STEP = 3.0
"""Largest displacement per 0.4 s step assumed when bounding predictions, metres (clipped beyond)."""


def resolve_model(model: str | Path) -> SocialRecurrent | str:
    """``"cvm"``, a model kind (shipped ``<kind>_all.pt``), or a checkpoint path → model (or ``"cvm"``)."""
    if isinstance(model, str) and model == "cvm":
        return "cvm"
    if isinstance(model, str) and model in MODEL_KINDS:
        return load_model(WEIGHTS_DIR / f"{model}_all.pt")
    return load_model(Path(model))


class TrajectoryPrediction(gym.ObservationWrapper, gym.utils.RecordConstructorArgs):
    """Add ``predicted_paths`` (and optionally ``predicted_samples``) to a dict observation.

    Args:
        env: env whose observation space follows the contract in the module docstring.
        model: ``"s-cgru"`` (default, shipped weights), another model kind, ``"cvm"``, or a checkpoint path.
        num_samples: number of sampled futures per pedestrian (0 = none).
    """

    def __init__(self, env: gym.Env, model: str | Path = "s-cgru", num_samples: int = 0) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, model=str(model), num_samples=num_samples)
        gym.ObservationWrapper.__init__(self, env)
        space = env.observation_space
        if not isinstance(space, spaces.Dict) or "pedestrians" not in space.spaces:
            raise ValueError(
                f"TrajectoryPrediction needs a Dict observation space with 'pedestrians', got {space}"
            )
        hist = space.spaces.get("pedestrian_history")
        if not isinstance(hist, spaces.Box) or len(hist.shape) != 3 or hist.shape[1:] != (OBS_LEN, 2):
            raise ValueError(f"observation 'pedestrian_history' must be a Box (K, {OBS_LEN}, 2), got {hist}")
        if num_samples < 0:
            raise ValueError(f"num_samples must be >= 0, got {num_samples}")
        self.num_slots = hist.shape[0]
        self.num_samples = num_samples
        self.model = resolve_model(model)
        self._fast = FastPredictor(self.model) if isinstance(self.model, SocialRecurrent) else None
        bound = float(max(np.abs(hist.low).max(), np.abs(hist.high).max())) + PRED_LEN * MAX_STEP
        self.bound = np.float32(bound) if np.isfinite(bound) else np.float32(np.finfo(np.float32).max)
        new = dict(space.spaces)
        new["predicted_paths"] = spaces.Box(
            -self.bound, self.bound, (self.num_slots, PRED_LEN, 2), np.float32
        )
        if num_samples:
            new["predicted_samples"] = spaces.Box(
                -self.bound, self.bound, (self.num_slots, num_samples, PRED_LEN, 2), np.float32
            )
        self.observation_space = spaces.Dict(new)
        self._generator = torch.Generator().manual_seed(0)
        self._sse_cache: dict[int, torch.Tensor] = {}
        self._last: tuple[np.ndarray, np.ndarray] | None = None  # (present slots, history) of the last call
        self._last_paths: np.ndarray | None = None

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        """Reset the env; a seed also reseeds the sampling generator so episodes are reproducible."""
        if seed is not None:
            self._generator.manual_seed(int(seed))
        return super().reset(seed=seed, options=options)

    @torch.inference_mode()
    def _predict(self, hist: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        obs = torch.from_numpy(np.ascontiguousarray(hist, dtype=np.float32))
        n = obs.shape[0]
        sse = self._sse_cache.get(n)
        if sse is None:
            sse = self._sse_cache.setdefault(n, torch.tensor([[0, n]]))
        if isinstance(self.model, str):
            paths = cvm(obs)
            samples = cvm_samples(obs, self.num_samples, self._generator) if self.num_samples else None
        else:
            assert self._fast is not None
            paths = torch.from_numpy(self._fast.predict(obs.numpy()))
            samples = (
                self.model.sample(obs, sse, self.num_samples, self._generator) if self.num_samples else None
            )
        out_s = None if samples is None else samples.permute(1, 0, 2, 3).numpy()
        return paths.numpy(), out_s

    def observation(self, observation: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Predict the paths of the present pedestrian slots (batched over the slots)."""
        present = np.flatnonzero(np.asarray(observation["pedestrians"])[:, 0] > 0.5)
        paths = np.zeros((self.num_slots, PRED_LEN, 2), np.float32)
        samples = (
            np.zeros((self.num_slots, self.num_samples, PRED_LEN, 2), np.float32)
            if self.num_samples
            else None
        )
        if len(present):
            hist = np.asarray(observation["pedestrian_history"])[present]
            last = self._last
            if (
                samples is None
                and last is not None
                and self._last_paths is not None
                and np.array_equal(last[0], present)
                and np.array_equal(last[1], hist)
            ):
                # Unchanged 0.4 s history (env steps faster than the history spacing): reuse, exactly.
                p, s = self._last_paths, None
            else:
                p, s = self._predict(hist)
                self._last, self._last_paths = (present, hist.copy()), p
            paths[present] = np.nan_to_num(p)
            if samples is not None and s is not None:
                samples[present] = np.nan_to_num(s)
        out = dict(observation)
        out["predicted_paths"] = np.clip(paths, -self.bound, self.bound)
        if samples is not None:
            out["predicted_samples"] = np.clip(samples, -self.bound, self.bound)
        return out
