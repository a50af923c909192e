"""Tests of the episode score (`crossing_env.safety.score`) and the near-miss metric it reads."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from crossing_env.safety import EpisodeResult
from crossing_env.safety.score import (
    DEFAULT_SCORE,
    SCORE_TERMS,
    ScoreConfig,
    episode_score,
    free_flow_progress,
    makes_progress,
)
from tests.crossing_env.safety.snapshots import Ped, make_gt, metrics

FREE_FLOW = 10.0
"""Free-flow time (s) of the test episodes to the delay target."""


def _result(**kw: object) -> EpisodeResult:
    """A clean episode: reached the delay target at free flow, no conflict, nothing wrong.

    `target_time` sets the delay with it (free flow 10 s); nan = never got there.
    """
    m = metrics()
    m.update(make_gt(0.1))
    target = float(kw.pop("target_time", FREE_FLOW))  # type: ignore[arg-type]
    passed = math.isfinite(target)
    base = dataclasses.replace(
        m.result(),
        target_time=target,
        delay=target - FREE_FLOW if passed else math.nan,
        passed_crossing=passed,
        distance_travelled=200.0,
        max_deceleration=2.0,
    )
    return dataclasses.replace(base, **kw)  # type: ignore[arg-type]


REFERENCE = _result()


def test_a_clean_episode_at_free_flow_scores_one() -> None:
    s = episode_score(REFERENCE, REFERENCE)
    assert s.score == 1.0
    assert set(s.as_dict()) == set(SCORE_TERMS)
    assert all(0.0 <= v <= 1.0 for v in s.as_dict().values())


def test_a_never_passing_car_scores_zero_progress_and_zero() -> None:
    # Stopped 70 m back for good, perfect margins: nothing but progress shows it.
    waiting = _result(target_time=math.nan, passed_crossing=False, distance_travelled=20.0, min_ttc=math.inf)
    s = episode_score(waiting, REFERENCE)
    assert s.progress == 0.0 and s.progress_gate == 0.0 and s.score == 0.0
    assert s.ttc == 1.0 and s.near_miss_factor == 1.0  # its margins are perfect, and they do not save it


def test_a_collision_zeroes_the_score_whatever_the_margins() -> None:
    assert episode_score(_result(pedestrian_collisions_at_fault=1), REFERENCE).score == 0.0
    assert episode_score(_result(vehicle_collisions_at_fault=1), REFERENCE).score == 0.0
    # Not at fault (the ego stood, someone walked into it): not the ego's failure.
    assert episode_score(_result(pedestrian_collisions=1), REFERENCE).score == 1.0
    assert (
        episode_score(_result(static_collisions=1), REFERENCE).score == DEFAULT_SCORE.static_collision_factor
    )


def test_a_broken_yield_zeroes_and_an_open_one_halves() -> None:
    assert episode_score(_result(yield_violations=1, yield_obligations=1), REFERENCE).score == 0.0
    open_one = episode_score(_result(yield_unresolved=1, yield_obligations=1), REFERENCE)
    assert open_one.yield_gate == DEFAULT_SCORE.unresolved_factor
    assert open_one.score == DEFAULT_SCORE.unresolved_factor


def test_a_near_miss_sprint_scores_below_a_yielding_pass() -> None:
    # The sprint: past 11 s earlier than the careful driver, 0.006 m from a pedestrian at 72 km/h.
    yielding = _result(target_time=21.0, min_ttc=1.8, near_miss=0.05, max_deceleration=3.2)
    sprint = _result(target_time=8.0, min_ttc=math.inf, near_miss=0.997, max_speed_over_limit=6.1)
    ys, ss = episode_score(yielding, yielding), episode_score(sprint, yielding)
    assert ss.progress == 1.0  # faster than free flow earns no more than free flow
    assert ss.near_miss_factor < 0.01 and ss.speed_limit == 0.0
    assert ss.score < 0.01 < 0.75 < ys.score


def test_progress_is_against_free_flow_and_the_gate_against_the_reference() -> None:
    assert free_flow_progress(_result(target_time=40.0)) == 0.25
    assert free_flow_progress(_result(target_time=8.0)) == 1.0  # faster than free flow: capped
    assert free_flow_progress(_result(target_time=math.nan)) == 0.0
    # A policy that passes safely sooner than the careful reference gains: a better predictor can show.
    careful = _result(target_time=20.0)
    assert episode_score(_result(target_time=15.0), careful).score > episode_score(careful, careful).score
    # Waiting as long as the careful driver had to is never zeroed, nor is a car the reference could not
    # take past either, as long as it went a fifth as far.
    assert makes_progress(careful, careful)
    stuck = _result(target_time=math.nan, distance_travelled=100.0)
    assert makes_progress(_result(target_time=math.nan, distance_travelled=20.0), stuck)
    assert not makes_progress(_result(target_time=math.nan, distance_travelled=19.0), stuck)
    assert makes_progress(careful, stuck)  # got where the reference did not
    barely = _result(target_time=math.nan, distance_travelled=1.0)
    assert makes_progress(_result(target_time=math.nan, distance_travelled=0.0), barely)
    # Slower than a fifth of the reference's pace: no progress at all.
    assert not makes_progress(_result(target_time=101.0), careful)
    assert episode_score(_result(target_time=101.0), careful).score == 0.0
    with pytest.raises(ValueError, match="reference ran"):
        episode_score(REFERENCE, dataclasses.replace(REFERENCE, scenario="other"))


def test_margin_terms_follow_their_anchors() -> None:
    s = episode_score(_result(min_ttc=0.75, max_speed_over_limit=2.23 / 2, max_deceleration=6.025), REFERENCE)
    assert (
        s.ttc == pytest.approx(0.5)
        and s.speed_limit == pytest.approx(0.5)
        and s.comfort == pytest.approx(0.5)
    )
    expected = (5 * 1 + 5 * 0.5 + 4 * 0.5 + 2 * 0.5) / 16
    assert s.score == pytest.approx(expected)


@pytest.mark.parametrize(
    ("field", "value"),
    [("ttc_weight", -1.0), ("ttc_anchor", 0.0), ("min_progress", 1.5), ("emergency_deceleration", 3.0)],
)
def test_config_rejects_values_that_break_the_range(field: str, value: float) -> None:
    with pytest.raises(ValueError, match=field):
        ScoreConfig(**{field: value})


def test_random_episodes_score_in_the_unit_interval() -> None:
    rng = np.random.default_rng(0)
    for _ in range(200):
        kw = {
            "target_time": float(rng.choice([math.nan, rng.uniform(0.0, 60.0)])),
            "distance_travelled": float(rng.uniform(0.0, 240.0)),
            "min_ttc": float(rng.choice([math.inf, rng.uniform(0.0, 5.0)])),
            "near_miss": float(rng.uniform(0.0, 1.0)),
            "max_speed_over_limit": float(rng.uniform(0.0, 10.0)),
            "max_deceleration": float(rng.uniform(0.0, 10.0)),
            "yield_unresolved": int(rng.integers(0, 2)),
        }
        ref = _result(target_time=float(rng.choice([math.nan, rng.uniform(1.0, 60.0)])))
        terms = episode_score(_result(**kw), ref).as_dict()
        assert all(0.0 <= v <= 1.0 for v in terms.values()), terms


# ---------------------------------------------------------------------------------------------------------
# The near-miss metric (`EpisodeResult.near_miss`)
# ---------------------------------------------------------------------------------------------------------


def _near_miss(ego_v: float, ped_y: float) -> float:
    """One step with the ego (lane 0, y = 1.75, half width 0.9) beside a pedestrian at x = ego x."""
    m = metrics()
    m.update(make_gt(0.1, ego_x=120.0, ego_v=ego_v, peds=[Ped(1, (120.0, ped_y))]))
    return m.result().near_miss


def test_near_miss_is_proximity_times_speed_for_pedestrians_on_the_road() -> None:
    # Ego edge at y = 2.65; a disc of radius 0.28 centred at 3.93 is 1.0 m away: proximity 0.5.
    assert _near_miss(20.0, 3.93) == pytest.approx(0.5)
    assert _near_miss(50 / 3.6 / 2, 3.93) == pytest.approx(0.25)  # at half of 50 km/h, half as bad
    assert _near_miss(20.0, 2.936) == pytest.approx(0.997, abs=1e-3)  # 0.006 m at 72 km/h
    assert _near_miss(0.0, 2.936) == 0.0  # a standing car is not near-missing anyone
    assert _near_miss(20.0, 5.5) == 0.0  # farther than 2 m
    assert _near_miss(20.0, -0.5) == 0.0  # on the sidewalk, beside the road: not on the road
