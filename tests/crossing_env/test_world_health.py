"""A world a safety study can trust: lane-by-lane gaps, drivers who brake for people, bystanders, geometry."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from crossing_env.pedestrians.population import CarSnapshot
from crossing_env.pedestrians.transitions import CROSSING, LEAVING, WAITING, detour
from crossing_env.safety import EpisodeMetrics
from crossing_env.traffic import Traffic
from crossing_env.types import CollisionEvent
from crossing_env.world import World
from scenarios.config import (
    BehaviourConfig,
    BystanderConfig,
    EgoConfig,
    PedestrianConfig,
    PedestrianSpawn,
    RoadConfig,
    ScenarioConfig,
    TrafficConfig,
    VehicleSpawn,
    WaitingPlace,
)
from scenarios.loading import load_scenario

CALM = BehaviourConfig(
    decision_model="gap",
    turn_back_rate=0.0,
    hesitation_rate=0.0,
    running_rate=0.0,
    distraction_rate=0.0,
    jaywalk_rate=0.0,
)


def _group_at_kerb(far_car_gap: float) -> tuple[World, np.ndarray]:
    """Three friends waiting at the south kerb of a 7 m road; one car in the far lane `far_car_gap` s away."""
    spawns = tuple(
        PedestrianSpawn(x=119.0 + 0.7 * k, side="south", group=1, critical_gap=3.0, desired_speed=1.35)
        for k in range(3)
    )
    scenario = ScenarioConfig(
        ego=EgoConfig(speed=0.0, x=20.0),
        traffic=TrafficConfig(flow_per_lane=0.0),
        pedestrians=PedestrianConfig(spawns=spawns, spawn_rate=0.0, behaviour=CALM),
    )
    world = World(scenario, np.random.default_rng(3))
    peds = world.pedestrians
    world.step(0.0)
    peds.state[:3] = WAITING
    peds.position[:3] = peds.waypoint[:3]
    peds.velocity[:3] = 0.0
    line = float(peds.crossing_x[:3].max())
    # The far (north, −x) lane's car at 10 m/s: its front `far_car_gap` seconds from the group's lines.
    x = line + 10.0 * far_car_gap + 2.25
    cars = CarSnapshot(
        x=np.array([x]),
        direction=np.array([-1.0]),
        speed=np.array([10.0]),
        half_length=np.array([2.25]),
        boxes=np.zeros((0, 4)),
        lane=np.array([1]),
    )
    return world, cars


def test_group_does_not_step_out_in_front_of_a_far_lane_car_at_a_4_2_s_gap() -> None:
    """4.2 s is above every member's 3 s critical gap, but walking 7 m takes about 5.5 s."""
    world, cars = _group_at_kerb(4.2)
    peds = world.pedestrians
    for _ in range(10):  # one second of looks at the same car
        peds.step(world.time + 0.1, cars, None)
        world.time += 0.1
        assert not np.any(peds.state[:3] == CROSSING)


def test_group_goes_when_every_lane_is_free_long_enough() -> None:
    world, cars = _group_at_kerb(12.0)
    peds = world.pedestrians
    peds.step(world.time + 0.1, cars, None)
    assert np.all(peds.state[:3] == CROSSING)  # together


def test_a_group_decides_on_its_worst_member() -> None:
    """One member unsafe (a car in the near lane only covers its line): nobody in the group goes."""
    world, _ = _group_at_kerb(12.0)
    peds = world.pedestrians
    # A forward-lane car whose body will pass the first member's line in about 1 s.
    line0 = float(peds.crossing_x[0])
    cars = CarSnapshot(
        x=np.array([line0 - 10.0 - 2.25]),
        direction=np.array([1.0]),
        speed=np.array([10.0]),
        half_length=np.array([2.25]),
        boxes=np.zeros((0, 4)),
        lane=np.array([0]),
    )
    peds.crossing_x[1:3] = line0 + 30.0  # companions' lines are clear of that car for now
    peds.step(world.time + 0.1, cars, None)
    assert not np.any(peds.state[:3] == CROSSING)


@pytest.mark.parametrize("car_x", [30.0, 40.0, 50.0, 60.0, 70.0])
def test_no_driver_drives_through_a_pedestrian_in_its_path(car_x: float) -> None:
    """A pedestrian who does not look crosses from the north into a non-yielding driver's lane."""
    scenario = ScenarioConfig(
        ego=EgoConfig(lane=0, speed=0.0, x=5.0),
        traffic=TrafficConfig(
            flow_per_lane=0.0,
            spawns=(VehicleSpawn(lane=0, x=car_x, speed=13.9, desired_speed=13.9, yields=False),),
        ),
        pedestrians=PedestrianConfig(
            spawns=(PedestrianSpawn(x=120.0, side="north", critical_gap=0.0, desired_speed=1.35),),
            spawn_rate=0.0,
            behaviour=CALM,
        ),
    )
    world = World(scenario, np.random.default_rng(0))
    contacts = 0
    for _ in range(150):
        world.step(0.0)
        contacts += len(world.background_collisions)
    assert contacts == 0
    assert world.pedestrians.state[0] in (LEAVING, 0)  # it got across


def test_drivers_brake_for_a_pedestrian_walking_into_their_lane_not_away_from_it() -> None:
    scenario = ScenarioConfig(
        traffic=TrafficConfig(
            flow_per_lane=0.0, spawns=(VehicleSpawn(lane=0, x=100.0, speed=12.0, yields=False),)
        ),
        pedestrians=PedestrianConfig(spawn_rate=0.0),
    )
    world = World(scenario, np.random.default_rng(0))
    tr = world.traffic
    pos = np.array([[125.0, 5.0]])  # in the oncoming lane, 25 m ahead of the car

    def acc(target_y: float, vy: float) -> float:
        a = tr.background_accelerations(
            pos,
            np.array([True]),
            False,
            False,
            np.array([[0.0, vy]]),
            np.array([CROSSING]),
            np.array([target_y]),
            np.array([0.28]),
        )
        return float(a[1])

    assert acc(-0.45, -1.35) < -3.0  # heading for the car's lane: brakes hard
    assert acc(7.45, 1.35) > 0.0  # walking away from it: drives on


def test_bystanders_carry_their_intent_in_the_ground_truth() -> None:
    scenario = load_scenario("bus_stop_zebra")
    world = World(scenario, np.random.default_rng(5))
    crossed_ids: set[int] = set()
    bystander_ids: set[int] = set()
    for _ in range(200):
        world.step(0.0)
        gt = world.ground_truth()
        assert np.all(~gt.intends_to_cross[gt.is_bystander])
        assert np.all(np.isfinite(gt.intent_decided_at)) and np.all(gt.intent_decided_at <= gt.time)
        bystander_ids |= set(gt.pedestrian_ids[gt.is_bystander].tolist())
        crossed_ids |= set(gt.pedestrian_ids[gt.pedestrian_states == CROSSING].tolist())
    assert len(bystander_ids) >= 9  # the people at the bus stop, the corner and the café at the start
    assert not bystander_ids & crossed_ids


def test_bystanders_stand_at_their_place_by_the_kerb() -> None:
    place = WaitingPlace(x=127.0, side="south", kind="bus_stop", kerb_distance=0.8, initial=4)
    scenario = ScenarioConfig(
        traffic=TrafficConfig(flow_per_lane=0.0),
        pedestrians=PedestrianConfig(
            spawn_rate=0.0, bystanders=BystanderConfig(places=(place,), dwell_mean=1e6)
        ),
    )
    world = World(scenario, np.random.default_rng(2))
    for _ in range(50):
        world.step(0.0)
    gt = world.ground_truth()
    assert gt.is_bystander.sum() == 4
    assert np.all(np.abs(gt.pedestrian_positions[:, 0] - 127.0) < 3.0)
    assert np.all((gt.pedestrian_positions[:, 1] < 0.0) & (gt.pedestrian_positions[:, 1] > -1.8))
    assert np.all(np.linalg.norm(gt.pedestrian_velocities, axis=1) < 0.3)


def test_parked_cars_stand_in_the_parking_strip_not_on_the_sidewalk() -> None:
    scenario = load_scenario("occluded_parked_car")
    world = World(scenario, np.random.default_rng(0))
    tr = world.traffic
    boxes = tr.boxes(tr.active & tr.parked)
    assert boxes.shape[0] == 2
    walk = world.geometry.sidewalk_south
    assert np.all(boxes[:, 1] >= walk.y_max - 1e-9) and np.all(boxes[:, 3] <= 0.0)
    for _ in range(150):
        world.step(0.0)
        peds = world.pedestrians
        y = peds.position[peds.active, 1]
        assert not np.any((y > -scenario.road.parking_strip) & (y < 0.0) & _beside_parked(peds, tr))


def _beside_parked(peds: object, tr: Traffic) -> np.ndarray:
    x = peds.position[peds.active, 0]  # type: ignore[attr-defined]
    boxes = tr.boxes(tr.active & tr.parked)
    return np.any((x[:, None] > boxes[None, :, 0]) & (x[:, None] < boxes[None, :, 2]), axis=1)


def test_nobody_walks_beyond_the_outer_walkway_edges() -> None:
    scenario = load_scenario("busy_zebra")
    world = World(scenario, np.random.default_rng(1))
    south, north = world.geometry.walkway_bounds
    for _ in range(300):
        world.step(0.0)
        peds = world.pedestrians
        y = peds.position[peds.active, 1]
        r = peds.radius[peds.active]
        assert np.all((y - r >= south - 1e-9) & (y + r <= north + 1e-9))


def test_a_pedestrian_walks_round_a_car_standing_on_its_line() -> None:
    state = np.array([CROSSING])
    position = np.array([[120.0, 2.0]])
    waypoint = np.array([[120.0, 7.45]])
    box = np.array([[118.5, 2.6, 123.0, 4.4]])  # a car standing across the pedestrian's line
    detour(state, position, np.zeros((1, 2)), waypoint, np.array([0.28]), box)
    assert waypoint[0, 0] == pytest.approx(118.5 - 0.28 - 0.3)
    assert waypoint[0, 1] == 7.45
    waypoint2 = np.array([[120.0, 7.45]])
    detour(state, position, np.array([[0.0, 1.3]]), waypoint2, np.array([0.28]), box)  # still walking
    assert waypoint2[0, 0] == 120.0


def test_background_collisions_are_in_the_episode_result() -> None:
    scenario = ScenarioConfig()
    world = World(scenario, np.random.default_rng(0))
    metrics = EpisodeMetrics(scenario, 0.1)
    world.step(0.0)
    gt = world.ground_truth()
    metrics.update(gt)
    hit = CollisionEvent(
        time=0.2, kind="background", other_id=3, position=(120.0, 1.0), relative_speed=4.5, compliant=True
    )
    illegal = dataclasses.replace(hit, relative_speed=1.0, compliant=False)
    metrics.update(dataclasses.replace(gt, time=0.2, extras={**gt.extras, "background_collisions": (hit,)}))
    metrics.update(
        dataclasses.replace(gt, time=0.3, extras={**gt.extras, "background_collisions": (illegal,)})
    )
    result = metrics.result()
    assert result.background_collisions == 2
    assert result.background_collisions_legal == 1
    assert result.background_collision_max_speed == pytest.approx(4.5)
    assert not result.collision  # the ego was not involved


def test_parked_car_without_a_parking_strip_is_a_named_error() -> None:
    from scenarios.errors import ScenarioError
    from scenarios.validation import validate_scenario

    bad = ScenarioConfig(
        road=RoadConfig(parking_strip=0.0),
        traffic=TrafficConfig(spawns=(VehicleSpawn(lane=0, x=95.0, speed=0.0, parked=True),)),
    )
    with pytest.raises(ScenarioError, match=r"traffic\.spawns\[0\]\.parked"):
        validate_scenario(bad)
