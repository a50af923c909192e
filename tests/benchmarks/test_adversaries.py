"""The adversary benchmark: every shipped adversary scores below `yielding`, paired on the same seeds."""

from __future__ import annotations

import pytest

from agents.adversaries import ADVERSARIES
from benchmarks.adversaries import measure, misses, paired_difference, render_body


def test_every_adversary_scores_below_yielding_on_a_few_seeds() -> None:
    # A zebra with people crossing and an NCAP walker in the lane: where a token stop meets someone.
    data = measure(["zebra_case1", "ncap_cpla"], episodes=3, workers=1, progress=False)
    for scenario, cells in data["scenarios"].items():
        reference = cells["yielding"]["mean"]
        assert reference > 0.5, scenario
        for adversary in ADVERSARIES:
            assert cells[adversary]["mean"] < reference, (scenario, adversary, cells[adversary])
    text = render_body(data)
    assert "zebra_case1" in text and all(a in text for a in ADVERSARIES)
    assert len(misses(data)) == text.count("**!**") - 1  # the legend names the mark once


def test_the_paired_interval_is_taken_episode_by_episode() -> None:
    # The same offset on every seed: no spread, the interval is the mean itself.
    mean, lo, hi = paired_difference([0.1, 0.5, 0.2], [0.3, 0.7, 0.4])
    assert mean == pytest.approx(-0.2) and lo == hi == mean
    mean, lo, hi = paired_difference([0.0, 0.1, 0.5, 0.2], [0.9, 0.8, 0.7, 0.9])
    assert lo < mean < hi < 0.0
