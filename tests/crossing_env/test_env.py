from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import crossing_env
from crossing_env import ENV_ID, CrossingEnv, acceleration_to_action, action_to_acceleration
from crossing_env.reward import REWARD_TERMS
from scenarios.config import EgoConfig, PedestrianConfig, PedestrianSpawn, ScenarioConfig, TrafficConfig


def test_registered_and_check_env_passes_without_warnings():
    assert ENV_ID in gym.registry
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(gym.make(ENV_ID).unwrapped)


def test_make_vec_runs_four_envs():
    envs = gym.make_vec(ENV_ID, num_envs=4, vectorization_mode="sync")
    obs, _ = envs.reset(seed=3)
    assert obs["pedestrians"].shape == (4, 16, 8)
    for _ in range(30):
        obs, reward, _, _, _ = envs.step(envs.action_space.sample())
        assert reward.shape == (4,)
    envs.close()


def _rollout(seed: int, steps: int = 300) -> list:
    env = gym.make(ENV_ID, scenario=ScenarioConfig(pedestrians=PedestrianConfig(spawn_rate=20.0)))
    obs, info = env.reset(seed=seed)
    actions = np.random.default_rng(seed).uniform(-1, 1, size=(steps, 1)).astype(np.float32)
    trace = [(obs, info["ground_truth"])]
    for a in actions:
        obs, reward, term, trunc, info = env.step(a)
        trace.append((obs, reward, term, trunc, info["ground_truth"]))
        if term or trunc:
            obs, info = env.reset()
            trace.append((obs, info["ground_truth"]))
    return trace


def _equal(a, b) -> bool:
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_equal(a[k], b[k]) for k in a)
    if isinstance(a, tuple):
        return len(a) == len(b) and all(_equal(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, np.ndarray):
        return np.array_equal(a, b)
    return a == b


def test_same_seed_gives_identical_rollouts_and_different_seed_differs():
    a, b, c = _rollout(7), _rollout(7), _rollout(8)
    assert len(a) == len(b)
    assert all(_equal(x, y) for x, y in zip(a, b, strict=True))
    assert not all(_equal(x, y) for x, y in zip(a, c, strict=True))


@pytest.mark.parametrize("scenario_seed", range(3))
def test_observation_always_inside_space(scenario_seed):
    env = gym.make(ENV_ID, scenario=ScenarioConfig(pedestrians=PedestrianConfig(spawn_rate=40.0)))
    obs, _ = env.reset(seed=scenario_seed)
    assert env.observation_space.contains(obs)
    rng = np.random.default_rng(scenario_seed)
    seen_pedestrians = 0
    for _ in range(400):
        obs, _, term, trunc, _ = env.step(rng.uniform(-1, 1, size=1).astype(np.float32))
        assert env.observation_space.contains(obs), obs
        seen_pedestrians = max(seen_pedestrians, int(obs["pedestrians"][:, 0].sum()))
        if term or trunc:
            obs, _ = env.reset()
    assert seen_pedestrians > 0
    assert env.unwrapped._observer.out_of_range == 0  # raw values fitted the space; nothing was clipped


def test_reward_terms_named_and_summed():
    env = gym.make(ENV_ID)
    env.reset(seed=0)
    _, reward, _, _, info = env.step(np.array([1.0], dtype=np.float32))
    assert tuple(info["rewards"]) == REWARD_TERMS
    assert reward == pytest.approx(sum(info["rewards"].values()))
    assert info["rewards"]["progress"] > 0


def test_speeding_is_penalised_in_proportion_to_the_excess():
    scenario = ScenarioConfig(ego=EgoConfig(speed=16.0), pedestrians=PedestrianConfig(spawn_rate=0))
    env = CrossingEnv(scenario=scenario)
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.array([0.0], dtype=np.float32))
    excess = 16.0 - scenario.road.speed_limit
    assert info["rewards"]["speeding"] == pytest.approx(env.config.reward.speeding * excess)
    env.reset(seed=0, options={"scenario": ScenarioConfig(pedestrians=PedestrianConfig(spawn_rate=0))})
    _, _, _, _, info = env.step(np.array([0.0], dtype=np.float32))
    assert info["rewards"]["speeding"] == 0.0


def test_full_braking_counts_as_hard_braking():
    env = gym.make(ENV_ID)
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.array([-1.0], dtype=np.float32))
    assert info["ground_truth"].ego_acceleration == pytest.approx(-EgoConfig().max_deceleration)
    assert info["rewards"]["hard_braking"] < 0


def test_action_mapping_round_trip_and_halves():
    ego = EgoConfig()
    assert action_to_acceleration(0.0, ego) == 0.0
    assert action_to_acceleration(1.0, ego) == ego.max_acceleration
    assert action_to_acceleration(-1.0, ego) == -ego.max_deceleration
    acc = np.array([-8.0, -3.0, 0.0, 1.5, 3.0])
    np.testing.assert_allclose(action_to_acceleration(acceleration_to_action(acc, ego), ego), acc, rtol=1e-6)


def test_truncated_at_scenario_duration():
    env = CrossingEnv(scenario=ScenarioConfig(duration=2.0, traffic=TrafficConfig(flow_per_lane=0)))
    env.reset(seed=0)
    flags = [env.step(np.array([-1.0], dtype=np.float32))[2:4] for _ in range(20)]
    assert flags[18] == (False, False)
    assert flags[19] == (False, True)


def test_terminates_at_end_of_road():
    scenario = ScenarioConfig(ego=EgoConfig(x=200.0, speed=15.0), pedestrians=PedestrianConfig(spawn_rate=0))
    env = CrossingEnv(scenario=scenario)
    env.reset(seed=0)
    for _ in range(40):
        _, _, term, trunc, info = env.step(np.array([0.0], dtype=np.float32))
        if term:
            break
    assert term and not trunc
    assert info["ground_truth"].ego_position[0] >= scenario.road.length - 10.0


def test_collision_terminates_with_penalty():
    spawn = PedestrianSpawn(x=75.0, side="south", crossing_x=75.0, critical_gap=0.0, desired_speed=1.4)
    scenario = ScenarioConfig(
        ego=EgoConfig(x=30.0, speed=12.0),
        pedestrians=PedestrianConfig(spawns=(spawn,), spawn_rate=0),
        traffic=TrafficConfig(flow_per_lane=0),
    )
    env = CrossingEnv(scenario=scenario)
    env.reset(seed=0)
    for _ in range(200):
        _, _, term, _, info = env.step(np.array([0.0], dtype=np.float32))
        if term:
            break
    gt = info["ground_truth"]
    assert term and gt.collisions and gt.collisions[0].kind == "pedestrian"
    assert info["rewards"]["collision"] < 0


def test_pedestrian_pool_smaller_than_the_observation_slots():
    """Two pedestrians at most, sixteen slots: both fill a slot each, the rest stay empty (no read past
    the pool in the compiled slot filling)."""
    spawns = tuple(PedestrianSpawn(x=x, side="south", crosses=False) for x in (40.0, 45.0))
    scenario = ScenarioConfig(
        pedestrians=PedestrianConfig(spawns=spawns, spawn_rate=0, max_pedestrians=2),
        traffic=TrafficConfig(flow_per_lane=0),
    )
    env = CrossingEnv(scenario=scenario)
    obs, _ = env.reset(seed=0)
    for _ in range(5):
        obs, *_ = env.step(np.array([0.0], dtype=np.float32))
    assert env.observation_space.contains(obs)
    present = obs["pedestrians"][:, 0]
    assert present.tolist() == [1.0, 1.0] + [0.0] * (len(present) - 2)


def test_rgb_array_render_and_bad_render_mode():
    env = gym.make(ENV_ID, render_mode="rgb_array")
    env.reset(seed=0)
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
    assert frame.std() > 0
    with pytest.raises(ValueError, match="render_mode"):
        CrossingEnv(render_mode="video")


def test_bad_action_rejected():
    env = CrossingEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([np.nan], dtype=np.float32))


def test_scenarios_listing_exposed():
    assert callable(crossing_env.scenarios)


def test_bad_config_objects_fail_with_the_field_named():
    from scenarios import ScenarioError
    from scenarios.config import EnvConfig, ObservationConfig

    with pytest.raises(ScenarioError, match="ego"):
        CrossingEnv(scenario=ScenarioConfig(ego=EgoConfig(lane=1)))  # a lane towards -x
    with pytest.raises(ValueError, match="dt"):
        EnvConfig(dt=0.0)
    with pytest.raises(ValueError, match="dt"):
        EnvConfig(dt=0.3)  # does not divide the 0.4 s history cadence
    with pytest.raises(ValueError, match="history_length"):
        ObservationConfig(history_length=0)


def test_long_scenarios_are_not_cut_by_a_step_cap():
    from scenarios.config import EnvConfig

    scenario = ScenarioConfig(
        duration=60.0, ego=EgoConfig(speed=0.0), pedestrians=PedestrianConfig(spawn_rate=0)
    )
    env = gym.make(ENV_ID, scenario=scenario, config=EnvConfig(dt=0.05))
    env.reset(seed=0)
    steps = 0
    while True:
        _, _, term, trunc, info = env.step(np.array([-1.0], dtype=np.float32))
        steps += 1
        if term or trunc:
            break
    assert trunc and steps == 1200 and info["time"] == pytest.approx(60.0)


def test_history_holds_nothing_from_before_a_pedestrian_came_into_view():
    """A pedestrian walking behind a parked van: its first visible history must not reveal its hidden path."""
    env = gym.make(ENV_ID, scenario="occluded_parked_car")
    obs, _ = env.reset(seed=0)
    observer = env.unwrapped._observer
    world = env.unwrapped.world
    seen_before: set[int] = set()
    appeared = 0
    for _ in range(300):
        ids = {int(world.pedestrians.ids[s]) for s in observer.last_slots if s >= 0}
        for k, slot in enumerate(observer.last_slots):
            if slot < 0:
                continue
            pid = int(world.pedestrians.ids[slot])
            if pid not in seen_before:  # first frame this pedestrian is observed
                appeared += 1
                hist = obs["pedestrian_history"][k]
                assert np.allclose(hist, hist[-1:], atol=1e-6) or world.time < 0.45, hist
        seen_before |= ids
        obs, _, term, trunc, _ = env.step(np.array([-0.2], dtype=np.float32))
        if term or trunc:
            break
    assert appeared > 0
