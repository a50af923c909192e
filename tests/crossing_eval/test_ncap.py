"""NCAP-style scoring (issue 22 item 3): avoidance and impact speed per car-speed bin of ncap_* scenarios."""

from __future__ import annotations

import math

import pytest

from crossing_eval.ncap import ncap_markdown, ncap_rows
from crossing_eval.tasks import EpisodeRecord, EpisodeTask, run_episode


def _record(scenario: str, policy: str, speed_ms: float, impact_ms: float | None) -> EpisodeRecord:
    result = {"pedestrian_collisions": int(impact_ms is not None), "max_impact_speed": impact_ms}
    return EpisodeRecord(EpisodeTask(scenario, policy, 0, 0), result, [], [], initial_speed=speed_ms)


def test_bins_avoidance_and_impact_speed() -> None:
    records = [
        _record("ncap_cpna", "constant_speed", 25 / 3.6, 24 / 3.6),
        _record("ncap_cpna", "constant_speed", 28 / 3.6, 28 / 3.6),
        _record("ncap_cpna", "constant_speed", 55 / 3.6, None),
        _record("ncap_cpna", "yielding", 55 / 3.6, None),
        _record("zebra_case1", "yielding", 40 / 3.6, 10.0),  # not an NCAP scenario: left out
    ]
    rows = ncap_rows(records)
    assert [(r[0], r[1], r[2], r[3]) for r in rows] == [
        ("ncap_cpna", "constant_speed", "20-30", 2),
        ("ncap_cpna", "constant_speed", "50-60", 1),
        ("ncap_cpna", "yielding", "50-60", 1),
    ]
    assert rows[0][4] == 0.0 and rows[0][5] == pytest.approx(26.0)
    assert rows[1][4] == 1.0 and math.isnan(rows[1][5])
    assert "| ncap_cpna | constant_speed | 20-30 | 2 | 0.00 | 26.0 |" in ncap_markdown(records)
    assert ncap_markdown(records[-1:]) == ""


def test_records_carry_the_drawn_car_speed() -> None:
    tasks = [EpisodeTask("ncap_cpna", "constant_speed", e, 100 + e) for e in range(3)]
    speeds = {run_episode(t).initial_speed for t in tasks}
    assert all(5.5 <= s <= 16.8 for s in speeds) and len(speeds) == 3  # drawn per seed from 20-60 km/h
