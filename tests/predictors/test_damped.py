from __future__ import annotations

import numpy as np
import pytest
import torch

from predictors.baselines import cvm
from predictors.damped import DampedCVM, tune, tune_k1
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


def test_tune_k1_picks_the_damping_of_the_data_for_the_most_likely_path() -> None:
    best, ade = tune_k1(_walkers(400, 0.83))
    assert best.damping == pytest.approx(0.83) and best.spread == 0.0 and ade < 1e-5
    cvm_wins, _ = tune_k1(_walkers(400, 1.0))
    assert cvm_wins.damping == 1.0  # plain CVM is a candidate, and wins on undamped walkers


def test_tune_k1_ignores_the_spread_that_best_of_20_rewards() -> None:
    """Noisy futures: best-of-20 may prefer another damping, K = 1 takes the one closest in mean."""
    w = _walkers(600, 0.9, seed=3)
    rng = np.random.default_rng(4)
    w.traj[:, 8:] += np.cumsum(rng.normal(0.0, 0.05, w.traj[:, 8:].shape), axis=1).astype(np.float32)
    best, ade = tune_k1(w)
    obs, fut = torch.as_tensor(w.traj[:, :8]), torch.as_tensor(w.traj[:, 8:])
    for d in (best.damping - 0.05, best.damping + 0.05):
        other = float((DampedCVM(min(d, 1.0), 0.0).predict(obs) - fut).norm(dim=-1).mean())
        assert other >= ade - 1e-6
