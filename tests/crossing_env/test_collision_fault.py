"""Collisions told apart by kind and fault (nuPlan's rule): the classes, the geometry, the world's events."""

from __future__ import annotations

import math

import numpy as np
import pytest

from crossing_env.collision_fault import (
    AT_FAULT_TYPES,
    STOPPED_SPEED,
    contact_type,
    front_touches_box,
    front_touches_disc,
    is_behind,
)
from crossing_env.world import World
from crossing_eval.tasks import episode_seed
from rollout import RolloutSpec, run_spec
from scenarios.config import EgoConfig, PedestrianConfig, ScenarioConfig, TrafficConfig, VehicleSpawn


def test_classes_follow_nuplans_order() -> None:
    # Ego stopped comes first, whatever else holds.
    assert contact_type(0.0, 5.0, False, False, True) == "stopped_ego"
    assert contact_type(STOPPED_SPEED, 0.0, True, True, True) == "stopped_ego"
    # Then a stopped or static other body.
    assert contact_type(5.0, 0.0, False, True, False) == "stopped_track"
    assert contact_type(5.0, 9.0, True, True, False) == "stopped_track"
    # Then an other body behind the ego, then one touching the front, else lateral.
    assert contact_type(5.0, 9.0, False, True, True) == "active_rear"
    assert contact_type(5.0, 1.0, False, False, True) == "active_front"
    assert contact_type(5.0, 1.0, False, False, False) == "active_lateral"
    assert AT_FAULT_TYPES == {"stopped_track", "active_front"}


def test_behind_is_measured_from_the_rear_axle() -> None:
    # Ego at the origin heading +x, 4 m long: the rear axle is 1.12 m behind the centre.
    assert is_behind(0.0, 0.0, 0.0, 4.0, -5.0, 0.0)
    assert not is_behind(0.0, 0.0, 0.0, 4.0, 5.0, 0.0)
    # 30 degrees off straight behind the axle is the boundary; a body beside the car is not behind.
    axle = -1.12
    assert is_behind(0.0, 0.0, 0.0, 4.0, axle - math.cos(math.radians(29)), math.sin(math.radians(29)))
    assert not is_behind(0.0, 0.0, 0.0, 4.0, axle - math.cos(math.radians(31)), math.sin(math.radians(31)))
    assert not is_behind(0.0, 0.0, 0.0, 4.0, 0.0, 2.0)
    # Heading −x mirrors it.
    assert is_behind(0.0, 0.0, math.pi, 4.0, 5.0, 0.0)


def test_front_edge_contact() -> None:
    # Ego 4 x 2 m at the origin heading +x: the front edge is x = 2, |y| <= 1.
    assert front_touches_disc(0.0, 0.0, 0.0, 4.0, 2.0, 2.25, 0.0, 0.3)  # in front, touching
    assert front_touches_disc(0.0, 0.0, 0.0, 4.0, 2.0, 1.9, 0.5, 0.3)  # a little inside the bonnet
    assert front_touches_disc(0.0, 0.0, 0.0, 4.0, 2.0, 2.1, 1.1, 0.3)  # at the corner
    assert not front_touches_disc(0.0, 0.0, 0.0, 4.0, 2.0, 0.0, 1.25, 0.3)  # beside the door
    assert not front_touches_disc(0.0, 0.0, 0.0, 4.0, 2.0, 1.0, 1.2, 0.3)  # side, behind the front edge
    assert front_touches_disc(0.0, 0.0, math.pi, 4.0, 2.0, -2.2, 0.0, 0.3)  # heading −x
    assert front_touches_box(0.0, 4.0, 1.0, 4.0, 4.5)  # car ahead straddles the front edge
    assert not front_touches_box(0.0, 4.0, 1.0, -4.0, 4.5)  # car behind


def _lane_world(ego_speed: float, other_x: float, other_speed: float) -> World:
    """An empty road: the ego at x = 50 and one car in its lane (no pedestrians, no arrivals)."""
    scenario = ScenarioConfig(
        ego=EgoConfig(speed=ego_speed, x=50.0),
        traffic=TrafficConfig(
            flow_per_lane=0.0,
            spawns=(VehicleSpawn(lane=0, x=other_x, speed=other_speed, desired_speed=other_speed),),
        ),
        pedestrians=PedestrianConfig(spawn_rate=0.0),
    )
    return World(scenario, np.random.default_rng(0))


def _first_collision(world: World, acceleration: float, steps: int = 40):
    for _ in range(steps):
        world.step(acceleration)
        if world.collisions:
            return world.collisions[0]
    raise AssertionError("no collision")


def test_a_standing_car_hit_from_behind_is_not_at_fault() -> None:
    world = _lane_world(ego_speed=0.0, other_x=44.0, other_speed=15.0)
    event = _first_collision(world, 0.0)
    assert event.kind == "vehicle"
    assert event.contact_type == "stopped_ego"
    assert event.at_fault is False


def test_a_moving_car_hit_from_behind_is_not_at_fault() -> None:
    world = _lane_world(ego_speed=3.0, other_x=44.0, other_speed=15.0)
    event = _first_collision(world, 0.0)
    assert (event.kind, event.contact_type, event.at_fault) == ("vehicle", "active_rear", False)


def test_driving_into_a_stopped_car_is_at_fault() -> None:
    world = _lane_world(ego_speed=12.0, other_x=70.0, other_speed=0.0)
    drivers = world.traffic.background_accelerations

    def stand_still(*args):  # the car ahead holds still (its driver model would creep at desired speed 0)
        acc = drivers(*args)
        acc[1:] = 0.0
        return acc

    world.traffic.background_accelerations = stand_still
    event = _first_collision(world, 0.0)
    assert (event.kind, event.contact_type, event.at_fault) == ("vehicle", "stopped_track", True)


def test_rear_ending_a_slower_car_is_at_fault() -> None:
    world = _lane_world(ego_speed=15.0, other_x=60.0, other_speed=3.0)
    event = _first_collision(world, 2.0)
    assert event.kind == "vehicle" and event.at_fault is True
    assert event.contact_type in {"active_front", "stopped_track"}  # the car ahead may brake to a stop


def test_careless_car_at_busy_zebra_crashes_into_vehicles_at_fault() -> None:
    """busy_zebra's careless-car collisions are rear-end crashes into cars ahead: vehicle, at fault.

    Base seed 9000 is one the project's tables never use (they use 2024, 7000 and others)."""
    seen = 0
    for k in range(12):
        result = run_spec(
            RolloutSpec(scenario="busy_zebra", policy="constant_speed"), episode_seed(9000, "busy_zebra", k)
        ).result
        if result["collision"]:
            seen += 1
            assert result["pedestrian_collisions"] == 0
            assert result["vehicle_collisions"] == result["vehicle_collisions_at_fault"] == 1
    assert seen >= 3


@pytest.mark.parametrize("scenario", ["ncap_cpfa", "children_running"])
def test_careless_car_hitting_a_child_or_adult_is_at_fault(scenario: str) -> None:
    hits = 0
    for k in range(6):
        result = run_spec(
            RolloutSpec(scenario=scenario, policy="constant_speed"), episode_seed(9000, scenario, k)
        )
        r = result.result
        hits += r["pedestrian_collisions"]
        assert r["pedestrian_collisions_at_fault"] == r["pedestrian_collisions"]
    assert hits >= 3
