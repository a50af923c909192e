from __future__ import annotations

import pytest
import torch

from predictors.baselines import KalmanConfig, cvm, cvm_samples, kalman_predict, kalman_samples
from predictors.data import default_data_root, load_split, to_batch

DATA = default_data_root()


def _line(n: int = 5, v: tuple[float, float] = (0.4, -0.2)) -> torch.Tensor:
    t = torch.arange(8, dtype=torch.float32)
    start = torch.randn(n, 1, 2, generator=torch.Generator().manual_seed(3))
    return start + t[None, :, None] * torch.tensor(v)


def test_cvm_extrapolates_last_displacement() -> None:
    obs = _line()
    obs[:, -1] += torch.tensor([0.1, 0.0])  # last displacement differs from the earlier ones
    pred = cvm(obs)
    vel = obs[:, -1] - obs[:, -2]
    torch.testing.assert_close(pred[:, 0], obs[:, -1] + vel)
    torch.testing.assert_close(pred[:, 11], obs[:, -1] + 12 * vel)


def test_cvm_s_zero_sigma_is_cvm_and_seeded() -> None:
    obs = _line()
    s0 = cvm_samples(obs, 4, torch.Generator().manual_seed(0), sigma_deg=0.0)
    torch.testing.assert_close(s0, cvm(obs)[None].expand(4, -1, -1, -1))
    a = cvm_samples(obs, 6, torch.Generator().manual_seed(7))
    b = cvm_samples(obs, 6, torch.Generator().manual_seed(7))
    c = cvm_samples(obs, 6, torch.Generator().manual_seed(8))
    torch.testing.assert_close(a, b)
    assert not torch.allclose(a, c)
    # heading noise keeps the speed
    speed = (a[:, :, 0] - obs[None, :, -1]).norm(dim=-1)
    torch.testing.assert_close(speed, (obs[:, -1] - obs[:, -2]).norm(dim=-1).expand(6, -1))


def test_kalman_recovers_noiseless_line_and_samples_spread() -> None:
    obs = _line()
    pred = kalman_predict(obs, KalmanConfig(meas_std=1e-3, accel_std=1e-3))
    torch.testing.assert_close(pred, cvm(obs), atol=2e-2, rtol=0)
    s = kalman_samples(obs, 1000, torch.Generator().manual_seed(0))
    assert s.shape == (1000, 5, 12, 2)
    spread = s.std(dim=0)
    assert bool((spread[:, -1] > spread[:, 0]).all())  # uncertainty grows with the horizon
    torch.testing.assert_close(s.mean(dim=0), kalman_predict(obs), atol=0.3, rtol=0)


@pytest.mark.skipif(not (DATA / "eth_ucy").is_dir(), reason=f"shared data not found at {DATA}")
def test_cvm_on_eth_matches_reference() -> None:
    b = to_batch(load_split(DATA, "eth", "test"))
    err = (cvm(b.obs) - b.fut).norm(dim=-1)
    assert round(float(err.mean()), 2) == 1.00  # prediction.md §2 [measured]: 1.00/2.23
    assert round(float(err[:, -1].mean()), 2) == 2.23
