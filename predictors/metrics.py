"""Error metrics of trajectory predictions on Social-GAN windows (the protocol every score here uses).

Windows: 8 observed, 12 predicted positions, 0.4 s apart; a pedestrian must be present in all 20 frames;
windows with >= 2 such pedestrians. Metrics in metres:

* ``k1``: most-likely prediction (learned models feed back the Gaussian means; CVM-S's most likely path is
  CVM's);
* ``ped20``: best-of-20 *per pedestrian*, ADE and FDE minimised separately (Social-STGCNN, Trajectron++);
* ``scene20``: best-of-20 *per scene* (Social-GAN ``evaluate_model.py``): per window the sample whose summed
  error over the window's pedestrians is smallest, ADE and FDE minimised separately;
* ``es``: energy score of the 20 samples (Gneiting & Raftery 2007; Shahroudi et al. 2024), per pedestrian on
  the flattened 24-dimensional future, averaged; the fair estimate (pairs ``i != j``), which is unbiased
  for the score of the distribution the samples come from. A strictly proper scoring rule: it rewards a
  spread only as far as the truth falls inside it, whatever the spread was tuned for. Lower is better.

The tables built from them (every predictor on every test scene) are ``python -m studies.evaluate``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import torch

from predictors.data import SCENES, Windows, iterate_batches

EVAL_SCENES: tuple[str, ...] = (*SCENES, "sdd")
"""The test scenes: the five ETH/UCY leave-one-out scenes and SDD."""
METRICS: tuple[str, ...] = ("k1", "ped20", "scene20", "es")
"""The scores :func:`evaluate_one` returns, each as ``[ADE, FDE]`` (``es``: ``[score, 0]``)."""

Predictor = Callable[[torch.Tensor, torch.Tensor, int, torch.Generator], tuple[torch.Tensor, torch.Tensor]]
"""``(obs, seq_start_end, k, generator) -> (most_likely (N, 12, 2), samples (k, N, 12, 2))``."""


def errors(pred: torch.Tensor, fut: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Per-pedestrian ADE and FDE, ``pred (..., N, 12, 2)`` against ``fut (N, 12, 2)``."""
    d = (pred - fut).norm(dim=-1)
    return d.mean(dim=-1), d[..., -1]


def scene_min(err: torch.Tensor, seq_start_end: torch.Tensor) -> torch.Tensor:
    """Per window, the smallest over samples of the summed error ``err (S, N)``; returns ``(W,)`` sums."""
    sizes = seq_start_end[:, 1] - seq_start_end[:, 0]
    group = torch.repeat_interleave(torch.arange(len(sizes)), sizes)
    sums = err.new_zeros(err.shape[0], len(sizes)).index_add_(1, group, err)
    return sums.min(dim=0).values


def energy_score(samples: torch.Tensor, fut: torch.Tensor) -> torch.Tensor:
    """Per-pedestrian energy score ``E|X - y| - E|X - X'|/2`` of ``samples (S, N, T, 2)`` against ``fut``.

    Fair sample estimate over the flattened ``T * 2`` trajectory: the pair term averages the ``S (S - 1)``
    pairs ``i != j``. The V-statistic form (``i = j`` included) shrinks the pair term by ``(S - 1) / S`` and
    so penalises spread samples; the fair form is unbiased for any ``S``. A point forecast (``S = 1`` or
    identical samples) scores its Euclidean distance to the true future.
    """
    x = samples.permute(1, 0, 2, 3).flatten(2)  # (N, S, T*2)
    y = fut.flatten(1)[:, None]  # (N, 1, T*2)
    s = x.shape[1]
    spread = torch.cdist(x, x, compute_mode="donot_use_mm_for_euclid_dist").sum(dim=(1, 2))  # zero diagonal
    pair = spread / (s * (s - 1)) if s > 1 else torch.zeros_like(spread)
    return (x - y).norm(dim=-1).mean(dim=1) - 0.5 * pair


@torch.no_grad()
def evaluate_one(
    predictor: Predictor, w: Windows, num_samples: int, seed: int, batch_peds: int = 256
) -> dict[str, list[float]]:
    """ADE/FDE of one predictor on one window set for every metric in :data:`METRICS`."""
    gen = torch.Generator().manual_seed(seed)
    acc = {m: np.zeros(2) for m in METRICS}
    n = 0
    for b in iterate_batches(w, batch_peds):
        ml, samples = predictor(b.obs, b.seq_start_end, num_samples, gen)
        ade1, fde1 = errors(ml, b.fut)
        ade_s, fde_s = errors(samples, b.fut)
        acc["k1"] += [float(ade1.sum()), float(fde1.sum())]
        acc["ped20"] += [float(ade_s.min(0).values.sum()), float(fde_s.min(0).values.sum())]
        acc["scene20"] += [
            float(scene_min(ade_s, b.seq_start_end).sum()),
            float(scene_min(fde_s, b.seq_start_end).sum()),
        ]
        acc["es"] += [float(energy_score(samples, b.fut).sum()), 0.0]
        n += b.obs.shape[0]
    return {m: [float(v) for v in acc[m] / max(n, 1)] for m in METRICS}
