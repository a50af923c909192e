"""Observation wrapper adding predicted pedestrian paths from a trained trajectory predictor.

Contract with the base env (keys and columns named in `crossing_env.observation`): its observation space
is a ``spaces.Dict`` with

* ``"pedestrians"`` ``(K, F)`` float32, column `PedestrianColumn.PRESENCE` a presence flag (1 present,
  0 padding);
* ``"pedestrian_history"`` ``(K, 8, 2)`` float32, each slot's last 8 positions `HISTORY_INTERVAL` (0.4 s)
  apart, oldest first, in the observation's (ego) frame, metres.

The wrapper adds ``"predicted_paths"`` ``(K, 12, 2)`` (most-likely path, same frame, zeros for absent slots)
and, with ``num_samples > 0``, ``"predicted_samples"`` ``(K, S, 12, 2)``. All present pedestrians form one
window, so the social pooling sees every present neighbour. Predictions are clipped to the declared bounds.
The most-likely path runs through :class:`~predictors.fast_inference.FastPredictor` (a numba-compiled
rollout, same numbers as the torch model to float32 rounding) to stay within the per-step budget; samples
run through the torch model.

Translation cache (without samples): the observation is in the ego frame, a pure translation of the world
frame that changes every env step as the ego moves, while the pedestrians' 0.4 s history only gains a sample
every ``0.4 / dt`` steps. Every model here is translation-equivariant (it sees displacements and relative
positions only: the input embedding takes ``p_t - p_{t-1}``, the pooling takes ``p_j - p_i`` and headings of
displacements, and the predicted positions are the last position plus predicted displacements; the CVM
likewise) and permutation-equivariant within the one window (pooling sums over neighbours). So when the
present histories equal, up to ``CACHE_TOLERANCE`` metres, the last *computed* ones shifted by one common
translation ``s`` (taken as the change of the mean last position) and possibly reordered (the env sorts
slots by distance to the moving ego), the paths are the computed ones reordered and shifted by ``s``; this
equals a fresh prediction up to float rounding. The comparison is always against the computed anchor, so
reuse never drifts. Any other change (a new sample, a pedestrian entering or leaving) recomputes.
Samples come from a private ``torch.Generator`` reseeded from the ``reset`` seed (seed 0 until the first
seeded reset), never from a global RNG.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from crossing_env.observation import PEDESTRIAN_HISTORY_KEY, PEDESTRIANS_KEY, PointColumn
from predictors.checkpoints import WEIGHTS_DIR, load_model
from predictors.constants import MODEL_KINDS, OBS_LEN, PRED_LEN
from predictors.fast_inference import FastPredictor, kernel_is_cached, load_kernel_file
from predictors.forecast import Forecast, ForecastInput, ForecastSpec
from predictors.forecast_wrapper import ForecastObservation

if TYPE_CHECKING:
    import torch

    from predictors.models import SocialRecurrent

# torch is imported only when a model must be loaded from its checkpoint or sampled (`_torch`): the
# most-likely paths of a shipped model come from its kernel file (`predictors.fast_inference`).
_FORKED = False
"""This process is a forked child (set by `_one_thread_after_fork`)."""


def _one_thread_after_fork() -> None:
    """In a forked child, run torch on one thread: its parent's thread pool does not survive `fork`.

    Without this, ``gym.make_vec(..., vectorization_mode="async", wrappers=[TrajectoryPrediction])``
    with the default ``fork`` start hangs silently in the children's first torch operation (the parent
    built a dummy env, which started torch's OpenMP pool). One thread per env worker is what a vector
    env wants anyway; spawn/forkserver children are not affected. A child that imports torch only later
    gets the same setting in `_torch`.
    """
    global _FORKED
    _FORKED = True
    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(1)


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_one_thread_after_fork)


def _torch() -> Any:
    """The torch module, imported on first use (one thread in a forked child, as `_one_thread_after_fork`)."""
    import torch

    if _FORKED:
        torch.set_num_threads(1)
    return torch


CACHE_TOLERANCE = 1e-4
"""Largest per-coordinate difference, metres, between a history and the cached one (after the common
translation) for which the cached paths are reused; float32 rounding of ego-frame values is ~1e-5 m."""


def match_translated(
    hist: np.ndarray, ref: np.ndarray, tol: float = CACHE_TOLERANCE
) -> tuple[np.ndarray, np.ndarray] | None:
    """``(perm, shift)`` with ``hist[k] == ref[perm[k]] + shift`` within ``tol`` for every row, or ``None``.

    ``hist``, ``ref``: ``(N, T, 2)`` histories. ``shift`` is the change of the mean last position (which is
    order-free), so a common translation plus a reordering of the rows is recognised in ``O(N^2 T)``.
    """
    if hist.shape != ref.shape:
        return None
    shift = hist[:, -1].mean(axis=0, dtype=np.float64) - ref[:, -1].mean(axis=0, dtype=np.float64)
    moved = ref + shift
    if np.abs(hist - moved).max() <= tol:
        return np.arange(len(hist)), shift
    dist = np.abs(hist[:, None] - moved[None]).max(axis=(2, 3))  # (N, N)
    perm = dist.argmin(axis=1)
    if dist[np.arange(len(hist)), perm].max() > tol or len(np.unique(perm)) != len(perm):
        return None
    return perm, shift


def model_path(model: str | Path) -> Path | None:
    """The checkpoint of ``"cvm"`` (None), a model kind (shipped ``<kind>_all.pt``) or a checkpoint path."""
    if isinstance(model, str) and model == "cvm":
        return None
    if isinstance(model, str) and model in MODEL_KINDS:
        return WEIGHTS_DIR / f"{model}_all.pt"
    return Path(model)


def resolve_model(model: str | Path) -> SocialRecurrent | str:
    """``"cvm"``, a model kind (shipped ``<kind>_all.pt``), or a checkpoint path → model (or ``"cvm"``)."""
    path = model_path(model)
    if path is None:
        return "cvm"
    _torch()  # one thread in a forked child, before the checkpoint imports torch
    return load_model(path)


class PathModel:
    """Forecaster of a trained path model, a checkpoint, or the CVM (see the module docstring).

    Args:
        model: ``"s-cgru"`` (default, shipped weights), another model kind, ``"cvm"``, or a checkpoint path.
        num_samples: number of sampled futures per pedestrian (0 = none: one path of weight 1, the most
            likely); with samples, the most likely path is the forecast's mode and the samples weigh equally.
    """

    def __init__(self, model: str | Path = "s-cgru", num_samples: int = 0) -> None:
        if num_samples < 0:
            raise ValueError(f"num_samples must be >= 0, got {num_samples}")
        self.num_samples = num_samples
        self.spec = ForecastSpec(samples=max(1, num_samples), mode=bool(num_samples), horizon=PRED_LEN)
        self._model_spec = model
        self._model: SocialRecurrent | str | None = None
        path = model_path(model)
        self._fast = load_kernel_file(path) if path is not None and not num_samples else None
        if self._fast is None:  # no kernel file (or samples wanted): the checkpoint, through torch
            self._model = resolve_model(model)
            self._fast = FastPredictor(self._model) if not isinstance(self._model, str) else None
        self._seed = 0
        self._gen: torch.Generator | None = None  # made on first use: sampling is the only user
        self._sse_cache: dict[int, torch.Tensor] = {}
        self._anchor: tuple[np.ndarray, np.ndarray] | None = None  # (history, paths) last computed
        self.cache_hits = 0
        """Calls served from the translation cache (see module docstring)."""
        self.cache_misses = 0
        """Calls that ran the predictor."""

    def kernel_to_compile(self) -> Callable[[], None] | None:
        """A call that compiles this predictor's kernel, where numba's on-disk cache lacks it.

        None where the kernel is cached or the predictor has none (CVM). The kernel is the largest of a run
        (seconds to compile): `crossing_eval.tasks.warm_up` compiles it in a second process while the env's
        kernels compile in the first.
        """
        if self._fast is None or kernel_is_cached():
            return None
        return self._fast.compile_kernel

    def reset(self, seed: int | None) -> None:
        """A seed reseeds the sampling generator so episodes are reproducible."""
        if seed is not None:
            self._seed = int(seed)
            if self._gen is not None:
                self._gen.manual_seed(self._seed)

    @property
    def model(self) -> SocialRecurrent | str:
        """The torch model (or ``"cvm"``), loaded from the checkpoint on first use."""
        if self._model is None:
            self._model = resolve_model(self._model_spec)
        return self._model

    @property
    def _generator(self) -> torch.Generator:
        """The sampling generator, seeded with the last reset's seed (0 before any)."""
        if self._gen is None:
            self._gen = _torch().Generator().manual_seed(self._seed)
        return self._gen

    def _predict(self, hist: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        if self._fast is not None and not self.num_samples:
            return self._fast.predict(hist), None  # compiled kernel: no torch dispatch on the hot path
        return self._predict_torch(hist)

    def _predict_torch(self, hist: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        torch = _torch()
        with torch.inference_mode():
            return self._predict_inference(torch, hist)

    def _predict_inference(self, torch: Any, hist: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        from predictors.baselines import cvm, cvm_samples

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

    def forecast(self, inputs: ForecastInput) -> Forecast:
        """Predict the paths of the present slots (one window: the pooling sees every present neighbour)."""
        present = np.flatnonzero(inputs.present)
        n, xy = inputs.present.shape[0], len(PointColumn)
        paths = np.zeros((n, PRED_LEN, xy), np.float32)
        samples = np.zeros((n, self.num_samples, PRED_LEN, xy), np.float32) if self.num_samples else None
        if len(present):
            hist = inputs.history[present]
            match = None
            if samples is None and self._anchor is not None:
                match = match_translated(hist, self._anchor[0])
            if match is not None:
                perm, shift = match
                p, s = (self._anchor[1][perm] + shift).astype(np.float32), None
                self.cache_hits += 1
            else:
                p, s = self._predict(hist)
                self.cache_misses += 1
                if samples is None:
                    self._anchor = (hist, p)
            paths[present] = p
            if samples is not None and s is not None:
                samples[present] = s
        if samples is None:
            return Forecast(paths=paths[:, None])
        return Forecast(paths=samples, mode=paths)


class TrajectoryPrediction(ForecastObservation):
    """Add ``predicted_paths`` (and optionally ``predicted_samples``): a `PathModel` in the one wrapper.

    Args:
        env: env whose observation space follows the contract in the module docstring.
        model: ``"s-cgru"`` (default, shipped weights), another model kind, ``"cvm"``, or a checkpoint path.
        num_samples: number of sampled futures per pedestrian (0 = none).
    """

    def __init__(self, env: gym.Env, model: str | Path = "s-cgru", num_samples: int = 0) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, model=str(model), num_samples=num_samples)
        space = env.observation_space
        if not isinstance(space, spaces.Dict) or PEDESTRIANS_KEY not in space.spaces:
            raise ValueError(
                f"TrajectoryPrediction needs a Dict observation space with {PEDESTRIANS_KEY!r}, got {space}"
            )
        hist = space.spaces.get(PEDESTRIAN_HISTORY_KEY)
        xy = len(PointColumn)
        if not isinstance(hist, spaces.Box) or len(hist.shape) != 3 or hist.shape[1:] != (OBS_LEN, xy):
            raise ValueError(
                f"observation {PEDESTRIAN_HISTORY_KEY!r} must be a Box (K, {OBS_LEN}, {xy}), got {hist}"
            )
        super().__init__(env, PathModel(model, num_samples), str(model))

    @property
    def cache_hits(self) -> int:
        """Calls served from the translation cache."""
        return self.forecaster.cache_hits

    @property
    def cache_misses(self) -> int:
        """Calls that ran the predictor."""
        return self.forecaster.cache_misses

    @property
    def model(self) -> SocialRecurrent | str:
        """The torch model (or ``"cvm"``)."""
        return self.forecaster.model
