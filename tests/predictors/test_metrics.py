from __future__ import annotations

import math

import pytest
import torch

from predictors import metrics


def test_scene_min_matches_brute_force() -> None:
    g = torch.Generator().manual_seed(0)
    err = torch.rand(5, 7, generator=g)
    sse = torch.tensor([[0, 3], [3, 4], [4, 7]])
    got = metrics.scene_min(err, sse)
    want = torch.stack([err[:, s:e].sum(1).min() for s, e in sse.tolist()])
    torch.testing.assert_close(got, want)


def test_energy_score_of_a_point_is_its_distance_and_a_pair_matches_the_formula() -> None:
    fut = torch.zeros(1, 12, 2)
    point = torch.ones(3, 1, 12, 2)
    assert float(metrics.energy_score(point, fut)[0]) == pytest.approx(math.sqrt(24.0))
    pair = torch.stack([torch.ones(1, 12, 2), -torch.ones(1, 12, 2)])
    # E|X - y| = sqrt(24); E|X - X'| over the 4 ordered pairs = 2 * sqrt(96) / 4
    want = math.sqrt(24.0) - 0.5 * (2 * math.sqrt(96.0) / 4)
    assert float(metrics.energy_score(pair, fut)[0]) == pytest.approx(want, rel=1e-5)


def test_energy_score_prefers_the_true_spread_to_an_inflated_one() -> None:
    g = torch.Generator().manual_seed(0)
    fut = torch.randn(400, 12, 2, generator=g)
    right = torch.randn(20, 400, 12, 2, generator=g)
    wide = 3.0 * torch.randn(20, 400, 12, 2, generator=g)
    assert float(metrics.energy_score(right, fut).mean()) < float(metrics.energy_score(wide, fut).mean())
