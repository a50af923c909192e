"""Track ids in the observation (``pedestrian_tracks``): kept through short occlusions, renewed after long."""

from __future__ import annotations

import numpy as np
import pytest

from crossing_env import CrossingEnv
from crossing_env.observation import PEDESTRIAN_TRACKS_KEY, PEDESTRIANS_KEY, PedestrianColumn
from scenarios.config import (
    EnvConfig,
    ObservationConfig,
    PedestrianConfig,
    PedestrianSpawn,
    ScenarioConfig,
    TrafficConfig,
)

MEMORY = 1.0


def _env(memory: float = MEMORY) -> CrossingEnv:
    spawns = tuple(PedestrianSpawn(x=x, side="south", crosses=False) for x in (40.0, 45.0))
    scenario = ScenarioConfig(
        pedestrians=PedestrianConfig(spawns=spawns, spawn_rate=0, max_pedestrians=2),
        traffic=TrafficConfig(flow_per_lane=0),
    )
    env = CrossingEnv(scenario=scenario, config=EnvConfig(observation=ObservationConfig(track_memory=memory)))
    env.reset(seed=0)
    for _ in range(5):  # the spawns enter the world in the first steps
        env.step(np.array([-1.0], dtype=np.float32))
    return env


def _tracks_by_pool_slot(env: CrossingEnv, obs: dict) -> dict[int, int]:
    """{pool slot: track id} of the observed pedestrians."""
    slots = env._observer.last_slots
    return {int(p): int(obs[PEDESTRIAN_TRACKS_KEY][k]) for k, p in enumerate(slots) if p >= 0}


def _observe(env: CrossingEnv, dt: float = 0.1, hide: int | None = None) -> dict[int, int]:
    """Advance the clock by `dt`, optionally with pool slot `hide` out of sight, and observe."""
    world = env.world
    world.time += dt
    saved = world.pedestrians.position.copy()
    if hide is not None:
        world.pedestrians.position[hide] = (world.traffic.x[0] + 500.0, 0.0)  # beyond the perception range
    obs = env._observer.build(world)
    world.pedestrians.position[:] = saved
    return _tracks_by_pool_slot(env, obs)


def test_tracks_are_distinct_from_one_and_stable_while_observed():
    env = _env()
    first = _observe(env)
    assert sorted(first.values()) == [1, 2]
    for _ in range(20):
        assert _observe(env) == first


@pytest.mark.parametrize(("hidden_steps", "kept"), [(5, True), (9, True), (10, False), (25, False)])
def test_track_kept_through_a_short_occlusion_and_renewed_after_a_long_one(hidden_steps, kept):
    """Hidden for n steps of 0.1 s: last seen (n + 1) · 0.1 s before it reappears; the limit is 1 s."""
    env = _env()
    before = _observe(env)
    for _ in range(hidden_steps):
        during = _observe(env, hide=0)
        assert 0 not in during and during[1] == before[1]
    after = _observe(env)
    assert after[1] == before[1]
    if kept:
        assert after[0] == before[0]
    else:
        assert after[0] not in before.values()
        assert after[0] == 3  # the next id: ids are never reused


def test_a_pool_slot_reused_by_a_new_pedestrian_gets_a_new_track():
    env = _env()
    before = _observe(env)
    env.world.pedestrians.ids[0] = 1000  # the slot now holds someone else (spawning reuses free slots)
    after = _observe(env)
    assert after[0] not in before.values() and after[1] == before[1]


def test_padding_slots_hold_zero_and_tracks_restart_each_episode():
    env = _env()
    env.reset(seed=1)
    for _ in range(5):
        obs, *_ = env.step(np.array([-1.0], dtype=np.float32))
    present = obs[PEDESTRIANS_KEY][:, PedestrianColumn.PRESENCE] > 0.5
    tracks = obs[PEDESTRIAN_TRACKS_KEY]
    assert present.sum() == 2 and sorted(tracks[present].tolist()) == [1.0, 2.0]
    assert np.all(tracks[~present] == 0.0)
    assert obs[PEDESTRIAN_TRACKS_KEY].dtype == np.float32 and env.observation_space.contains(obs)


def test_track_memory_is_validated():
    with pytest.raises(ValueError, match="track_memory"):
        ObservationConfig(track_memory=-1.0)
