"""The conventional `info` keys: crashed, passed_crossing, is_success, cost (and costs), speed.

The cost is the metrics' own per-step safety terms, unweighted: checked step by step against
`EpisodeMetrics` on recorded episodes (a collision, failures to yield and near misses).
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from agents import make_policy
from crossing_env import ENV_ID, CrossingEnv
from crossing_env.env import INFO_KEYS
from crossing_env.safety import COST_TERMS, EpisodeMetrics
from crossing_eval.tasks import episode_seed
from scenarios.config import EgoConfig, PedestrianConfig, PedestrianSpawn, ScenarioConfig, TrafficConfig


def _collision_scenario() -> ScenarioConfig:
    """A pedestrian walks onto the road in front of an ego holding 12 m/s (test_env's collision case)."""
    spawn = PedestrianSpawn(x=75.0, side="south", crossing_x=75.0, critical_gap=0.0, desired_speed=1.4)
    return ScenarioConfig(
        ego=EgoConfig(x=30.0, speed=12.0),
        pedestrians=PedestrianConfig(spawns=(spawn,), spawn_rate=0),
        traffic=TrafficConfig(flow_per_lane=0),
    )


def _record(env: gym.Env, seed: int, policy_name: str | None) -> list[dict]:
    """The infos of one episode (reset first), driven by a registered policy or by holding speed."""
    base = env.unwrapped
    obs, info = env.reset(seed=seed)
    policy = make_policy(policy_name, scenario=base.scenario, dt=base.config.dt) if policy_name else None
    infos, done = [info], False
    while not done:
        action = np.zeros(1, np.float32) if policy is None else np.asarray(policy(obs), np.float32).reshape(1)
        obs, _, terminated, truncated, info = env.step(action)
        infos.append(info)
        done = terminated or truncated
    return infos


def _check_types(info: dict) -> None:
    assert tuple(info) == INFO_KEYS
    for key in ("crashed", "passed_crossing", "is_success"):
        assert type(info[key]) is bool, key
    for key in ("cost", "speed", "time"):
        assert type(info[key]) is float, key
    assert tuple(info["costs"]) == COST_TERMS
    assert all(type(v) is float and v >= 0.0 for v in info["costs"].values())
    assert info["cost"] == sum(info["costs"].values()) >= 0.0


def _assert_cost_is_the_metrics_terms(infos: list[dict], dt: float, scenario: ScenarioConfig) -> dict:
    """Step by step: each cost term equals the increment of the metric that counts it; returns the totals."""
    metrics = EpisodeMetrics(scenario, dt)
    before = metrics.result()
    totals = dict.fromkeys(COST_TERMS, 0.0)
    for info in infos[1:]:
        metrics.update(info["ground_truth"])
        after = metrics.result()
        collisions = (after.pedestrian_collisions + after.vehicle_collisions) - (
            before.pedestrian_collisions + before.vehicle_collisions
        )
        expected = {
            "collision": 1.0 if collisions else 0.0,
            "failing_to_yield": float(after.yield_violations - before.yield_violations),
            "near_miss": round((after.serious_conflict_time - before.serious_conflict_time) / dt),
        }
        assert info["costs"] == expected, (info["time"], info["costs"], expected)
        assert info["crashed"] == bool(collisions)
        for k, v in info["costs"].items():
            totals[k] += v
        before = after
    result = metrics.result()
    assert totals["failing_to_yield"] == result.yield_violations
    assert totals["near_miss"] * dt == pytest.approx(result.serious_conflict_time)
    assert totals["collision"] == float(result.collision)
    return totals


def test_reset_and_step_infos_have_the_conventional_keys_with_python_types():
    env = gym.make(ENV_ID, scenario="zebra_case1")
    infos = _record(env, seed=3, policy_name="yielding")
    for info in infos:
        _check_types(info)
    assert infos[0]["cost"] == 0.0 and not infos[0]["crashed"] and not infos[0]["is_success"]
    assert infos[0]["speed"] == pytest.approx(env.unwrapped.scenario.ego.speed)
    for info in infos:
        gt = info["ground_truth"]
        assert info["speed"] == pytest.approx(float(np.hypot(*gt.ego_velocity)))


def test_cost_equals_the_metrics_safety_terms_on_a_recorded_episode():
    """zebra_case1 at constant speed: failures to yield, each counted once in cost and metrics."""
    env = gym.make(ENV_ID, scenario="zebra_case1")
    base = env.unwrapped
    violations = 0.0
    for ep in range(2):
        infos = _record(env, episode_seed(2024, "zebra_case1", ep), "constant_speed")
        totals = _assert_cost_is_the_metrics_terms(infos, base.config.dt, base.scenario)
        violations += totals["failing_to_yield"]
        clean = totals["failing_to_yield"] == 0 and totals["collision"] == 0
        assert infos[-1]["is_success"] is (infos[-1]["passed_crossing"] and clean)
        if not clean:
            assert not any(i["is_success"] for i in infos)
    assert violations > 0


def test_a_collision_is_crashed_and_costs_one_and_never_a_success():
    scenario = _collision_scenario()
    env = CrossingEnv(scenario=scenario)
    infos = _record(env, seed=0, policy_name=None)
    totals = _assert_cost_is_the_metrics_terms(infos, env.config.dt, env.scenario)
    last = infos[-1]
    assert last["crashed"] is True and last["costs"]["collision"] == 1.0 and last["cost"] >= 1.0
    assert totals["collision"] == 1.0 and totals["near_miss"] > 0  # the approach was a near miss first
    assert sum(i["crashed"] for i in infos) == 1
    assert not any(i["is_success"] for i in infos)
    # The collision is told apart: a pedestrian hit with the moving car's front, at fault.
    assert [len(i["collisions"]) for i in infos] == [int(i["crashed"]) for i in infos]
    (hit,) = last["collisions"]
    assert hit["kind"] == "pedestrian" and hit["at_fault"] is True
    assert hit["contact_type"] in {"active_front", "stopped_track"} and hit["relative_speed"] > 0.0


def test_passing_cleanly_is_a_success_once_the_rear_is_past_the_crossing():
    """the ego drives through; success from the step its rear clears the crossing."""
    scenario = ScenarioConfig(
        ego=EgoConfig(x=30.0, speed=12.0),
        pedestrians=PedestrianConfig(spawn_rate=0),
        traffic=TrafficConfig(flow_per_lane=0),
    )
    env = CrossingEnv(scenario=scenario)
    infos = _record(env, seed=0, policy_name=None)
    for info in infos:
        gt = info["ground_truth"]
        rear = gt.ego_position[0] - 0.5 * gt.ego_size[0]
        assert info["passed_crossing"] is bool(rear >= gt.conflict_area.x_max)
        assert info["is_success"] is info["passed_crossing"]
        assert info["cost"] == 0.0
    assert infos[-1]["is_success"] and not infos[0]["is_success"]
