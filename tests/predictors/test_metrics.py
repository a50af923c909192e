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
    # E|X - y| = sqrt(24); fair E|X - X'| over the 2 ordered pairs i != j = sqrt(96) = 2 sqrt(24)
    assert float(metrics.energy_score(pair, fut)[0]) == pytest.approx(0.0, abs=1e-5)


def test_energy_score_is_the_fair_estimate_on_a_hand_computed_example() -> None:
    """Samples 0, 1 and 3 times the all-ones future, truth 0: every distance is a multiple of sqrt(24)."""
    fut = torch.zeros(1, 12, 2)
    samples = torch.stack([a * torch.ones(1, 12, 2) for a in (0.0, 1.0, 3.0)])
    to_truth = (0 + 1 + 3) / 3  # E|X - y| / sqrt(24)
    fair = to_truth - 0.5 * (2 * (1 + 3 + 2)) / 6  # pairs i != j: |0-1|, |0-3|, |1-3|, each twice
    v_statistic = to_truth - 0.5 * (2 * (1 + 3 + 2)) / 9  # i = j included (zeros on the diagonal)
    got = float(metrics.energy_score(samples, fut)[0])
    assert got == pytest.approx(fair * math.sqrt(24.0), rel=1e-6)
    assert got < v_statistic * math.sqrt(24.0)


def test_identical_samples_score_as_the_point_forecast() -> None:
    g = torch.Generator().manual_seed(1)
    fut = torch.randn(7, 12, 2, generator=g)
    point = torch.randn(7, 12, 2, generator=g)
    many = metrics.energy_score(point[None].expand(20, -1, -1, -1), fut)
    one = metrics.energy_score(point[None], fut)
    torch.testing.assert_close(many, one)
    torch.testing.assert_close(one, (point - fut).flatten(1).norm(dim=-1))


def test_the_fair_score_is_below_the_v_statistic_for_spread_samples() -> None:
    g = torch.Generator().manual_seed(2)
    fut = torch.randn(50, 12, 2, generator=g)
    samples = torch.randn(20, 50, 12, 2, generator=g)
    x = samples.permute(1, 0, 2, 3).flatten(2)
    v_statistic = (x - fut.flatten(1)[:, None]).norm(dim=-1).mean(1) - 0.5 * torch.cdist(x, x).mean((1, 2))
    fair = metrics.energy_score(samples, fut)
    assert bool((fair < v_statistic).all())
    # the two differ by exactly the pair term's factor S / (S - 1)
    torch.testing.assert_close(
        v_statistic - fair, 0.5 * torch.cdist(x, x).mean((1, 2)) / 19, rtol=1e-4, atol=1e-5
    )


def test_energy_score_prefers_the_true_spread_to_an_inflated_one() -> None:
    g = torch.Generator().manual_seed(0)
    fut = torch.randn(400, 12, 2, generator=g)
    right = torch.randn(20, 400, 12, 2, generator=g)
    wide = 3.0 * torch.randn(20, 400, 12, 2, generator=g)
    assert float(metrics.energy_score(right, fut).mean()) < float(metrics.energy_score(wide, fut).mean())
