"""The adversary suite drives as its names say, and the episode score is not fooled by it."""

from __future__ import annotations

import numpy as np
import pytest

from agents import make_policy
from agents.adversaries import ADVERSARIES
from crossing_env.safety import EpisodeResult
from crossing_env.safety.score import episode_score
from rollout import RolloutSpec, build
from rollout.episode import frames, run_episode

SCENARIO = "zebra_case1"
SEED = 11


def _trace(policy: str) -> tuple[np.ndarray, np.ndarray, float]:
    """Ego x and speed at every frame, and the stop line's x."""
    run = build(RolloutSpec(scenario=SCENARIO, policy=policy))
    xs, vs, line = [], [], 0.0
    for f in frames(run.env, SEED, run.policy):
        gt = f.ground_truth
        xs.append(float(gt.ego_position[0]) + 0.5 * gt.ego_size[0])  # the front
        vs.append(float(gt.ego_velocity[0]))
        line = gt.conflict_area.stop_line_x
    run.env.close()
    return np.array(xs), np.array(vs), line


def _result(policy: str) -> EpisodeResult:
    run = build(RolloutSpec(scenario=SCENARIO, policy=policy))
    try:
        return EpisodeResult.from_dict(run_episode(run.env, SEED, policy=run.policy).result)
    finally:
        run.env.close()


def test_every_adversary_is_a_registered_policy() -> None:
    for name in ADVERSARIES:
        policy = make_policy(name, dt=0.1)
        policy.reset(seed=0)
        assert callable(policy)


def test_the_stopping_adversaries_stand_where_they_say() -> None:
    x, v, line = _trace("stop_far")
    assert v[-1] == pytest.approx(0.0, abs=0.05) and line - x[-1] >= 65.0
    x, v, line = _trace("stop_near")
    assert v[-1] == pytest.approx(0.0, abs=0.05) and -0.5 <= line - x[-1] <= 2.0
    x, v, line = _trace("stop_and_go")
    stood = np.count_nonzero(np.abs(v) < 0.1) * 0.1
    assert stood >= 2.0 and x[-1] > line + 50.0  # a token stop, then on its way


def test_the_speed_adversaries_drive_as_named() -> None:
    _, v, _ = _trace("crawl")
    assert v[-50:].max() <= 2.05 and v[-1] >= 1.95
    _, v, _ = _trace("full_throttle")
    assert v.max() > 13.9 + 3.0  # well over the limit


def test_a_never_passing_car_scores_zero_against_the_careful_driver() -> None:
    reference = _result("yielding")
    assert reference.passed_crossing
    for name in ("stop_far", "stop_near"):
        s = episode_score(_result(name), reference)
        assert s.progress == 0.0 and s.score == 0.0, name
    assert episode_score(reference, reference).score > 0.5
