"""The intention benchmark's scores on tiny hand-checked inputs."""

from __future__ import annotations

import math

import numpy as np

from benchmarks.intention import _row, brier, ece, roc_auc


def test_brier() -> None:
    y = np.array([1.0, 0.0, 1.0, 0.0])
    p = np.array([0.9, 0.2, 0.5, 0.0])
    assert math.isclose(brier(p, y), (0.01 + 0.04 + 0.25 + 0.0) / 4)
    assert math.isclose(brier(p, y, np.array([2.0, 0.0, 0.0, 1.0])), 0.02 / 3)


def test_roc_auc_counts_ties_as_one_half() -> None:
    y = np.array([1, 0, 1, 0])
    assert roc_auc(np.array([0.9, 0.1, 0.8, 0.2]), y) == 1.0
    assert roc_auc(np.array([0.1, 0.9, 0.2, 0.8]), y) == 0.0
    # Pairs (pos, neg): (0.6, 0.6) tie, (0.6, 0.2) win, (0.1, 0.6) loss, (0.1, 0.2) loss -> 1.5 / 4.
    assert roc_auc(np.array([0.6, 0.6, 0.1, 0.2]), y) == 0.375
    assert math.isnan(roc_auc(np.array([0.3, 0.4]), np.array([1, 1])))


def test_ece_by_hand() -> None:
    # Bin [0.1, 0.2): scores 0.1, 0.1, labels 0, 1 -> |0.1 - 0.5| = 0.4, share 1/2.
    # Bin [0.9, 1.0]: scores 0.9, 1.0, labels 1, 1 -> |0.95 - 1| = 0.05, share 1/2.
    p = np.array([0.1, 0.1, 0.9, 1.0])
    y = np.array([0.0, 1.0, 1.0, 1.0])
    assert math.isclose(ece(p, y), 0.5 * 0.4 + 0.5 * 0.05)
    assert ece(np.array([0.25, 0.25, 0.25, 0.25]), np.array([1.0, 0.0, 0.0, 0.0])) == 0.0


def test_bootstrap_row_brackets_the_point_values() -> None:
    rng = np.random.default_rng(0)
    episode = np.repeat(np.arange(6), 50)
    y = (rng.random(300) < 0.3).astype(np.float64)
    good = np.clip(y * 0.8 + 0.1 + rng.normal(0, 0.05, 300), 0, 1)
    row = _row({"good": good}, y, episode, 6, seed=1)
    for model in ("base rate", "good"):
        for point, lo, hi in row["models"][model].values():
            assert lo <= point + 1e-9 and point <= hi + 1e-9
    assert row["models"]["base rate"]["auc"][0] == 0.5
    assert row["models"]["good"]["brier_minus_base"][2] < 0.0  # beats the base rate, interval excludes 0
