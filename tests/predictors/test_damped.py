from __future__ import annotations

import numpy as np
import pytest
import torch

from predictors.baselines import cvm
from predictors.damped import DampedCVM, tune
from predictors.data import Windows


def _walkers(n: int, damping: float, seed: int = 0) -> Windows:
    """``n`` lone-pair windows whose future speed is ``damping`` times the observed one."""
    rng = np.random.default_rng(seed)
    v = rng.normal(0.0, 0.4, (n, 1, 2))
    start = rng.normal(0.0, 5.0, (n, 1, 2))
    t_obs = np.arange(8)[None, :, None]
    t_fut = np.arange(1, 13)[None, :, None]
    obs = start + t_obs * v
    fut = obs[:, -1:] + t_fut * damping * v
    traj = np.concatenate([obs, fut], axis=1).astype(np.float32)
    sse = np.stack([np.arange(0, n, 2), np.arange(2, n + 1, 2)], axis=1).astype(np.int64)
    return Windows(traj, sse)


def test_undamped_without_spread_is_cvm() -> None:
    obs = torch.as_tensor(_walkers(6, 1.0).traj[:, :8])
    p = DampedCVM(1.0, 0.0)
    torch.testing.assert_close(p.predict(obs), cvm(obs))
    s = p.sample(obs, 4, torch.Generator().manual_seed(0))
    torch.testing.assert_close(s, cvm(obs)[None].expand(4, -1, -1, -1))


def test_samples_are_a_persistent_velocity_offset_with_the_given_spread() -> None:
    obs = torch.zeros(2000, 8, 2)
    s = DampedCVM(0.9, 0.07).sample(obs, 5, torch.Generator().manual_seed(1))
    steps = s / torch.arange(1, 13, dtype=s.dtype)[None, None, :, None]
    torch.testing.assert_close(steps, steps[:, :, :1].expand_as(steps))  # one offset for the horizon
    assert float(steps[:, :, 0].std()) == pytest.approx(0.07, rel=0.05)


def test_tune_recovers_the_damping_of_the_data() -> None:
    best, ade = tune(_walkers(400, 0.8))
    assert best.damping == 0.8
    assert best.spread == min(best.spread, 0.03)  # exact futures: the smallest spread wins
    best_fast, _ = tune(_walkers(400, 1.0))
    assert best_fast.damping == 1.0 and ade >= 0.0


def test_bad_parameters_are_refused() -> None:
    with pytest.raises(ValueError, match="damping"):
        DampedCVM(-0.1, 0.05)
    with pytest.raises(ValueError, match="spread"):
        DampedCVM(0.9, -1.0)
