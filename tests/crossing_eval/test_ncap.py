"""NCAP-style scoring (issue 22 item 3): avoidance and impact speed per car-speed bin of ncap_* scenarios."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agents.policy import FunctionPolicy
from crossing_eval.ncap import ncap_markdown, ncap_rows
from crossing_eval.tasks import EpisodeRecord, EpisodeTask, episode_seed, run_episode
from rollout.build import RolloutSpec, build
from rollout.episode import run_episode as run_rollout


def _record(
    scenario: str, policy: str, speed_ms: float, impact_ms: float | None, outcome: str = ""
) -> EpisodeRecord:
    result = {
        "pedestrian_collisions": int(impact_ms is not None),
        "max_impact_speed": impact_ms,
        "ncap_outcome": outcome or ("impact" if impact_ms is not None else "avoided"),
    }
    return EpisodeRecord(EpisodeTask(scenario, policy, 0, 0), result, [], [], initial_speed=speed_ms)


def test_bins_outcomes_avoidance_of_the_tested_and_impact_speed() -> None:
    records = [
        _record("ncap_cpna", "constant_speed", 25 / 3.6, 24 / 3.6),
        _record("ncap_cpna", "constant_speed", 28 / 3.6, 28 / 3.6),
        _record("ncap_cpna", "constant_speed", 55 / 3.6, None),
        _record("ncap_cpna", "yielding", 55 / 3.6, None),
        _record("ncap_cpna", "yielding", 52 / 3.6, None, "outrun"),
        _record("ncap_cpna", "yielding", 51 / 3.6, None, "not tested"),
        _record("zebra_case1", "yielding", 40 / 3.6, 10.0),  # not an NCAP scenario: left out
    ]
    rows = ncap_rows(records)
    assert [(r.scenario, r.policy, r.band, r.episodes) for r in rows] == [
        ("ncap_cpna", "constant_speed", "20-30", 2),
        ("ncap_cpna", "constant_speed", "50-60", 1),
        ("ncap_cpna", "yielding", "50-60", 3),
    ]
    assert rows[0].avoidance == 0.0 and rows[0].impact_kmh == pytest.approx(26.0)
    assert rows[1].avoidance == 1.0 and math.isnan(rows[1].impact_kmh)
    # Outrunning is not avoiding, and an untested episode counts for nothing: 1 avoided of 2 tested.
    assert rows[2].counts == {"avoided": 1, "outrun": 1, "impact": 0, "not tested": 1}
    assert rows[2].tested == 2 and rows[2].avoidance == 0.5
    page = ncap_markdown(records)
    assert "| ncap_cpna | constant_speed | 20-30 | 2 | 0 | 0 | 2 | 0 | 0.00 | 26.0 |" in page
    assert "| ncap_cpna | yielding | 50-60 | 3 | 1 | 1 | 0 | 1 | 0.50 | - |" in page
    assert ncap_markdown(records[-1:]) == ""
    # Only untested episodes: no avoidance rate at all, never 1.00.
    (alone,) = ncap_rows([_record("ncap_cpfa", "stand", 40 / 3.6, None, "not tested")])
    assert math.isnan(alone.avoidance) and "| - |" in ncap_markdown(
        [_record("ncap_cpfa", "stand", 40 / 3.6, None, "not tested")]
    )


def _outcomes(scenario: str, action: float | None, policy: str = "constant_speed", n: int = 6) -> list[str]:
    """Outcomes of `n` episodes (base 9000) of `policy`, or of a constant action when `action` is given."""
    run = build(RolloutSpec(scenario=scenario, policy=policy))
    chosen = FunctionPolicy(lambda obs: np.full(1, action, np.float32)) if action is not None else run.policy
    try:
        return [
            run_rollout(run.env, episode_seed(9000, scenario, k), policy=chosen).result["ncap_outcome"]
            for k in range(n)
        ]
    finally:
        run.env.close()


@pytest.mark.parametrize("scenario", ["ncap_cpna", "ncap_cpfa", "ncap_cpnc"])
def test_episode_outcomes_of_careless_careful_and_absent_cars(scenario: str) -> None:
    assert set(_outcomes(scenario, None)) == {"impact"}  # holds its speed: hits the dummy
    assert set(_outcomes(scenario, None, policy="yielding")) == {"avoided"}
    assert set(_outcomes(scenario, -1.0, n=3)) == {"not tested"}  # brakes to a stand far back at once
    assert "avoided" not in _outcomes(scenario, 1.0)  # full throttle never avoids


def test_full_throttle_that_gets_past_the_dummy_is_outrun_not_avoided() -> None:
    # ncap_cpfa, base 9000, episode 12: full throttle passes 0.14 m from the dummy (found over 20 episodes).
    run = build(RolloutSpec(scenario="ncap_cpfa", policy="constant_speed"))
    full = FunctionPolicy(lambda obs: np.ones(1, np.float32))
    result = run_rollout(run.env, episode_seed(9000, "ncap_cpfa", 12), policy=full).result
    run.env.close()
    assert result["pedestrian_collisions"] == 0 and result["min_separation"] < 0.5
    assert result["ncap_outcome"] == "outrun"
    assert _counted_as_not_avoided(result)


def _counted_as_not_avoided(result: dict) -> bool:
    (row,) = ncap_rows(
        [EpisodeRecord(EpisodeTask("ncap_cpfa", "full", 0, 0), result, [], [], initial_speed=9.5)]
    )
    return row.avoidance == 0.0 and row.counts["outrun"] == 1


def test_non_dummy_scenarios_have_no_ncap_outcome() -> None:
    assert _outcomes("midblock_jaywalker", None, n=1) == [""]
    assert _outcomes("zebra_case1", None, n=1) == [""]


def test_records_carry_the_drawn_car_speed() -> None:
    tasks = [EpisodeTask("ncap_cpna", "constant_speed", e, 100 + e) for e in range(3)]
    speeds = {run_episode(t).initial_speed for t in tasks}
    assert all(5.5 <= s <= 16.8 for s in speeds) and len(speeds) == 3  # drawn per seed from 20-60 km/h
