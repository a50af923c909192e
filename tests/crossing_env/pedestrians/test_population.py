"""Pedestrians in the world (crossing_env.pedestrians.population): irrational acts at their rates, groups,
red light, distraction."""

from __future__ import annotations

import math
from collections import defaultdict

import numpy as np

from crossing_env.pedestrians.population import CarSnapshot
from crossing_env.pedestrians.transitions import CROSSING, WAITING
from crossing_env.world import World
from scenarios.config import (
    BehaviourConfig,
    CrosswalkConfig,
    EgoConfig,
    PedestrianConfig,
    PedestrianSpawn,
    ScenarioConfig,
    SignalConfig,
    TrafficConfig,
)
from tests.crossing_env.pedestrians.worlds import run_world as _run


# ------------------------------------------------------------------ pedestrians in the world
def _rate_scenario(**rates: float) -> ScenarioConfig:
    behaviour = BehaviourConfig(decision_model="qlb", **rates)  # type: ignore[arg-type]
    return ScenarioConfig(
        ego=EgoConfig(speed=0.0, x=20.0),
        traffic=TrafficConfig(flow_per_lane=0.0),
        pedestrians=PedestrianConfig(
            spawn_rate=45.0,
            cross_fraction=0.8,
            group_probability=0.0,
            max_pedestrians=160,
            behaviour=behaviour,
        ),
        duration=1000.0,
    )


def test_irrational_acts_happen_at_their_configured_rates() -> None:
    rates = {
        "distraction_rate": 0.2,
        "running_rate": 0.3,
        "hesitation_rate": 0.25,
        "turn_back_rate": 0.15,
        "jaywalk_rate": 0.2,
    }
    world, events = _run(_rate_scenario(**rates), seconds=260.0, seed=4)
    kinds: dict[str, set[int]] = defaultdict(set)
    for e in events:
        kinds[e.kind].add(e.pedestrian_id)
    spawned = world.pedestrians.next_id
    starters = kinds["start_crossing"]
    assert spawned > 150 and len(starters) > 120

    def close(count: int, n: int, rate: float) -> bool:  # within 3 binomial standard deviations
        return abs(count / n - rate) <= 3.0 * math.sqrt(rate * (1 - rate) / n)

    assert close(len(kinds["distracted"]), spawned, 0.2)
    assert close(len(kinds["run"] & starters), len(starters), 0.3)
    # Jaywalkers are a fraction of the pedestrians who intend to cross (those who reached a kerb).
    assert close(len(kinds["jaywalk"] & starters), len(starters), 0.2)
    # Hesitation and turning back happen during a crossing: count among those who got across.
    still = {int(world.pedestrians.ids[i]) for i in np.flatnonzero(world.pedestrians.state == CROSSING)}
    done = starters - still
    assert close(len(kinds["hesitate"] & done), len(done), 0.25)
    assert close(len(kinds["turn_back"] & done), len(done), 0.15)
    # Every act is a logged event of a known kind.
    assert set(kinds) <= {
        "distracted",
        "run",
        "hesitate",
        "turn_back",
        "jaywalk",
        "red_light",
        "start_crossing",
    }


def test_zero_rates_give_no_irrational_acts() -> None:
    zero = {
        "distraction_rate": 0.0,
        "running_rate": 0.0,
        "hesitation_rate": 0.0,
        "turn_back_rate": 0.0,
        "jaywalk_rate": 0.0,
        "red_light_rate": 0.0,
    }
    _, events = _run(_rate_scenario(**zero), seconds=40.0, seed=5)
    kinds = {e.kind for e in events}
    assert kinds == {"start_crossing"}


def test_turning_back_returns_to_the_start_kerb_and_crosses_again() -> None:
    spawn = PedestrianSpawn(x=118.0, side="south")
    scenario = _rate_scenario(turn_back_rate=1.0, hesitation_rate=0.0, running_rate=0.0, distraction_rate=0.0)
    scenario = ScenarioConfig(
        **{
            **scenario.__dict__,
            "pedestrians": PedestrianConfig(
                spawns=(spawn,), spawn_rate=0.0, behaviour=scenario.pedestrians.behaviour
            ),
        }
    )
    world = World(scenario, np.random.default_rng(6))
    seen: list[tuple[str, float]] = []
    min_y_after_turn = np.inf
    for _ in range(400):
        world.step(0.0)
        seen += [(e.kind, world.pedestrians.position[0, 1]) for e in world.pedestrians.events]
        if any(k == "turn_back" for k, _ in seen) and sum(k == "start_crossing" for k, _ in seen) == 1:
            min_y_after_turn = min(min_y_after_turn, world.pedestrians.position[0, 1])
    kinds = [k for k, _ in seen]
    assert kinds.count("turn_back") == 1 and kinds.count("start_crossing") == 2
    assert min_y_after_turn < world.geometry.kerb_south  # it went back onto its own (south) sidewalk
    assert world.pedestrians.position[0, 1] > world.geometry.kerb_north or not world.pedestrians.active[0]


def test_groups_cross_together() -> None:
    spawns = (
        PedestrianSpawn(x=112.0, side="south", group=7, critical_gap=3.0),
        PedestrianSpawn(x=108.0, side="south", group=7, critical_gap=9.0),  # arrives later, more careful
        PedestrianSpawn(x=111.0, side="north", group=8),
        PedestrianSpawn(x=110.0, side="north", group=8),
        PedestrianSpawn(x=109.0, side="north", group=8),
    )
    behaviour = BehaviourConfig(
        decision_model="qlb", hesitation_rate=0.0, turn_back_rate=0.0, distraction_rate=0.0
    )
    # Busy, but not so busy that no gap lets a group clear both lanes (lane by lane, at walking speed)
    # within a minute: at 900 cars/h per lane it hardly ever comes.
    scenario = ScenarioConfig(
        traffic=TrafficConfig(flow_per_lane=300.0),
        pedestrians=PedestrianConfig(spawns=spawns, spawn_rate=0.0, behaviour=behaviour),
    )
    for seed in range(3):
        _, events = _run(scenario, seconds=60.0, seed=seed)
        start = {e.pedestrian_id: e.time for e in events if e.kind == "start_crossing"}
        assert len(start) == 5
        assert start[0] == start[1]
        assert start[2] == start[3] == start[4]


def _signal_scenario(red_light_rate: float) -> ScenarioConfig:
    behaviour = BehaviourConfig(decision_model="qlb", red_light_rate=red_light_rate, jaywalk_rate=0.0)
    return ScenarioConfig(
        crossing=CrosswalkConfig(
            kind="signalised",
            width=8.0,
            signal=SignalConfig(pedestrian_green=10.0, pedestrian_red=70.0, offset=10.0),
        ),
        ego=EgoConfig(speed=0.0, x=20.0),
        traffic=TrafficConfig(flow_per_lane=0.0),
        pedestrians=PedestrianConfig(
            spawn_rate=40.0,
            cross_fraction=1.0,
            group_probability=0.0,
            max_pedestrians=96,
            spawn_extent=12.0,
            behaviour=behaviour,
        ),
    )


def test_nobody_crosses_on_red_when_the_rate_is_zero() -> None:
    world, events = _run(_signal_scenario(0.0), seconds=65.0, seed=7)
    assert not any(e.kind in ("red_light", "start_crossing") for e in events)  # 65 s of red from t = 0
    assert int((world.pedestrians.state == WAITING).sum()) > 10  # many are waiting at the kerb


def test_red_light_violators_cross_at_the_configured_rate() -> None:
    _, events = _run(_signal_scenario(1.0), seconds=30.0, seed=7)
    red = {e.pedestrian_id for e in events if e.kind == "red_light"}
    starts = {e.pedestrian_id for e in events if e.kind == "start_crossing"}
    assert len(red) > 10 and red == starts
    world = World(_signal_scenario(0.3), np.random.default_rng(8))
    peds, red, arrived = world.pedestrians, set(), set()
    for _ in range(650):  # 65 s of red
        world.step(0.0)
        arrived |= {int(i) for i in peds.ids[peds.state == WAITING]}
        red |= {e.pedestrian_id for e in peds.events if e.kind == "red_light"}
    assert len(arrived) > 25
    assert abs(len(red) / len(arrived) - 0.3) <= 3.0 * math.sqrt(0.3 * 0.7 / len(arrived))


def test_same_seed_same_pedestrians() -> None:
    behaviour = BehaviourConfig(decision_model="qlb", update_force_intensity=True, phase_std=0.8)
    scenario = ScenarioConfig(
        pedestrians=PedestrianConfig(spawn_rate=40.0, spawn_extent=10.0, behaviour=behaviour)
    )
    runs = []
    for _ in range(2):
        world, events = _run(scenario, seconds=30.0, seed=9)
        runs.append((world.pedestrians.position.copy(), world.pedestrians.force_intensity.copy(), events))
    np.testing.assert_array_equal(runs[0][0], runs[1][0])
    np.testing.assert_array_equal(runs[0][1], runs[1][1])
    assert runs[0][2] == runs[1][2] and len(runs[0][2]) > 5
    other, _ = _run(scenario, seconds=30.0, seed=10)
    assert not np.array_equal(other.pedestrians.position, runs[0][0])


def test_distracted_pedestrian_takes_a_gap_an_attentive_one_refuses() -> None:
    spawns = (
        PedestrianSpawn(x=120.0, side="south", critical_gap=6.0, distracted=False),
        PedestrianSpawn(x=120.0, side="north", critical_gap=6.0, distracted=True),
    )
    behaviour = BehaviourConfig(
        decision_model="gap", turn_back_rate=0.0, hesitation_rate=0.0, running_rate=0.0
    )
    scenario = ScenarioConfig(
        ego=EgoConfig(speed=0.0, x=20.0),
        traffic=TrafficConfig(flow_per_lane=0.0),
        pedestrians=PedestrianConfig(spawns=spawns, spawn_rate=0.0, behaviour=behaviour),
    )
    world = World(scenario, np.random.default_rng(12))
    peds = world.pedestrians
    world.step(0.0)  # spawns both
    peds.state[:2] = WAITING  # put them at their kerb points, about to decide
    peds.position[:2] = peds.waypoint[:2]
    peds.velocity[:2] = 0.0
    # A car in the north (−x) lane 5 s from the lines: under the attentive pedestrian's 6 s critical gap;
    # the distracted one (critical gap x 0.7, view 1 s late), for whom it is the near lane, takes it. The
    # south-lane car is 12 s away, far enough for either to clear its lane.
    x = peds.crossing_x[:2]
    cars = CarSnapshot(
        x=np.array([x[0] - 120.0 - 2.25, x[1] + 50.0 + 2.25]),
        direction=np.array([1.0, -1.0]),
        speed=np.array([10.0, 10.0]),
        half_length=np.array([2.25, 2.25]),
        boxes=np.zeros((0, 4)),
        lane=np.array([0, 1]),
    )
    peds.step(world.time + 0.1, cars, None)
    assert peds.state[0] == WAITING and peds.state[1] == CROSSING
