from __future__ import annotations

from dataclasses import replace

import torch

from predictors.baselines import cvm
from predictors.social_force_predictor import SocialForcePredictor


def _pair(gap_y: float, v: float = 0.5) -> torch.Tensor:
    """Two pedestrians walking head-on along x (``v`` metres per 0.4 s step), ``gap_y`` apart laterally."""
    t = torch.arange(8, dtype=torch.float64)[:, None]
    a = torch.cat([-6.0 + v * t, torch.zeros_like(t)], dim=1)
    b = torch.cat([6.0 - v * t, torch.full_like(t, gap_y)], dim=1)
    return torch.stack([a, b]).float()


def test_lone_walker_without_forces_is_constant_velocity() -> None:
    obs = _pair(50.0)[:1]
    sse = torch.tensor([[0, 1]])
    got = SocialForcePredictor().predict(obs, sse)
    torch.testing.assert_close(got, cvm(obs), atol=1e-4, rtol=0)


def test_head_on_pair_is_deflected_and_zero_strength_is_not() -> None:
    obs, sse = _pair(0.3), torch.tensor([[0, 2]])
    sf = SocialForcePredictor()
    lateral = float((sf.predict(obs, sse)[1, :, 1] - sf.predict(obs, sse)[0, :, 1]).abs().max())
    free = replace(sf, force=replace(sf.force, base_strength=0.0))
    torch.testing.assert_close(free.predict(obs, sse), cvm(obs), atol=1e-4, rtol=0)
    assert lateral > 0.3 + 0.2  # the repulsion pushed them apart sideways


def test_windows_do_not_interact_and_samples_are_seeded() -> None:
    obs = torch.cat([_pair(0.3), _pair(0.3)])  # two identical windows in one batch
    sse = torch.tensor([[0, 2], [2, 4]])
    sf = SocialForcePredictor()
    alone = sf.predict(obs[:2], sse[:1])
    both = sf.predict(obs, sse)
    torch.testing.assert_close(both[:2], alone, atol=1e-4, rtol=0)
    torch.testing.assert_close(both[2:], alone, atol=1e-4, rtol=0)
    s1 = sf.sample(obs, sse, 3, torch.Generator().manual_seed(4))
    s2 = sf.sample(obs, sse, 3, torch.Generator().manual_seed(4))
    torch.testing.assert_close(s1, s2)
    flat = replace(sf, heading_std_deg=0.0).sample(obs, sse, 3, torch.Generator().manual_seed(4))
    torch.testing.assert_close(flat, both[None].expand(3, -1, -1, -1), atol=1e-4, rtol=0)


def test_qlb_raises_intensity_near_a_runner() -> None:
    walker = _pair(50.0)[0]
    runner = walker.clone()
    runner[:, 1] = 1.0
    runner[:, 0] = -6.0 + torch.arange(8) * 1.2  # 3 m/s, ends 5 m away: irrational by the proxy
    obs, sse = torch.stack([walker, runner]), torch.tensor([[0, 2]])
    sf = SocialForcePredictor(qlb=True)
    k_p = sf._setup(obs.double().numpy(), sse.numpy())[4]
    assert k_p[0] > sf.force.ped_intensity and k_p[1] == sf.force.ped_intensity
