"""The oracle predictors equal the recorded truth, and never reach the normal observation."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import crossing_env  # noqa: F401 - registers the env
from crossing_env.pedestrians.transitions import LEAVING
from predictors.oracle import OracleIntention, OracleTrajectory

HOLD = np.zeros(1, dtype=np.float32)  # action 0: the ego holds its speed


def _env(wrapper: type[gym.ObservationWrapper], scenario: str = "busy_zebra") -> gym.Env:
    return wrapper(gym.make("crossing_env/Crossing-v0", scenario=scenario))


def test_oracle_paths_equal_the_recorded_future_with_a_constant_speed_ego() -> None:
    env = _env(OracleTrajectory)
    obs, _ = env.reset(seed=11)
    world = env.unwrapped.world
    checked = 0
    for _ in range(30):
        obs, *_ = env.step(HOLD)
    done = 30
    for start in (30, 31, 33):  # at a refresh and between refreshes (read from the cached rollout)
        while done < start:
            obs, *_ = env.step(HOLD)
            done += 1
        slots = env.unwrapped._observer.last_slots
        present = np.flatnonzero(slots >= 0)
        assert present.size, "the scene should show pedestrians"
        ids = world.pedestrians.ids[slots[present]].copy()
        ego0 = world.ego_position
        paths = obs["predicted_paths"][present].copy()
        # Record the real future with a new env run on the same seed and actions (no peeking at the oracle).
        replay = gym.make("crossing_env/Crossing-v0", scenario="busy_zebra")
        replay.reset(seed=11)
        for _ in range(start):
            replay.step(HOLD)
        w2 = replay.unwrapped.world
        for i in range(1, 13):
            for _ in range(4):
                replay.step(HOLD)
            for n, pid in enumerate(ids):
                slot = np.flatnonzero((w2.pedestrians.ids == pid) & (w2.pedestrians.state != 0))
                if slot.size:
                    want = (w2.pedestrians.position[slot[0]] - ego0).astype(np.float32)
                    np.testing.assert_array_equal(paths[n, i - 1], want)
                    checked += 1
    assert checked > 100
    assert env.rollouts >= 1


def test_oracle_rollout_does_not_change_the_episode() -> None:
    plain = gym.make("crossing_env/Crossing-v0", scenario="busy_zebra")
    oracle = _env(OracleTrajectory)
    a, _ = plain.reset(seed=5)
    b, _ = oracle.reset(seed=5)
    rng = np.random.default_rng(0)
    for _ in range(40):
        action = rng.uniform(-1, 1, 1).astype(np.float32)
        a, *_ = plain.step(action)
        b, *_ = oracle.step(action)
        for key in a:
            np.testing.assert_array_equal(a[key], b[key])
    assert set(b) - set(a) == {
        "predicted_paths",
        "predicted_samples",
        "sample_weights",
        "plan_paths",
        "plan_accelerations",
    }
    assert oracle.observation_space.contains(b)


def test_oracle_intention_is_the_true_intent() -> None:
    env = _env(OracleIntention)
    obs, _ = env.reset(seed=2)
    seen = {0.0: 0, 1.0: 0}
    for _ in range(150):
        obs, *_ = env.step(HOLD)
        world = env.unwrapped.world
        slots = env.unwrapped._observer.last_slots
        assert env.observation_space.contains(obs)
        np.testing.assert_array_equal(obs["crossing_intent"], obs["crossing_intention"])
        for k, p in enumerate(slots):
            if p < 0:
                assert obs["crossing_intention"][k] == 0.0
                continue
            truth = bool(world.pedestrians.intends[p]) and world.pedestrians.state[p] != LEAVING
            assert obs["crossing_intention"][k] == float(truth)
            seen[float(truth)] += 1
    assert seen[0.0] and seen[1.0]  # both kinds of pedestrian occur
    # The plain env never carries it.
    plain = gym.make("crossing_env/Crossing-v0").observation_space.spaces
    assert "crossing_intention" not in plain and "crossing_intent" not in plain


def test_oracle_intention_undecided_and_bad_arguments() -> None:
    env = _env(OracleIntention)
    env.reset(seed=2)
    for _ in range(20):
        obs, *_ = env.step(HOLD)
    env.unwrapped.world.intent_decided_at[:] = np.nan  # nobody has decided yet
    obs = env.observation(obs)
    slots = env.unwrapped._observer.last_slots
    assert np.all(obs["crossing_intention"][slots >= 0] == 0.5)
    with pytest.raises(ValueError, match="undecided"):
        _env(lambda e: OracleIntention(e, undecided=2.0))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="refresh_steps"):
        _env(lambda e: OracleTrajectory(e, refresh_steps=0))  # type: ignore[arg-type]
