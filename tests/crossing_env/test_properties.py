"""Property tests: random scenarios and random actions never break the env's guarantees."""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from crossing_env import CrossingEnv
from scenarios.config import (
    BehaviourConfig,
    CrosswalkConfig,
    EgoConfig,
    PedestrianConfig,
    RoadConfig,
    ScenarioConfig,
    TrafficConfig,
)


@st.composite
def scenarios(draw) -> ScenarioConfig:
    lanes = draw(st.integers(1, 4))
    two_way = draw(st.booleans())
    length = draw(st.floats(120.0, 300.0))
    kind = draw(st.sampled_from(["zebra", "signalised", "none"]))
    rate = st.floats(0.0, 1.0)
    behaviour = BehaviourConfig(
        decision_model=draw(st.sampled_from(["gap", "qlb"])),
        distraction_rate=draw(rate),
        running_rate=draw(rate),
        hesitation_rate=draw(rate),
        turn_back_rate=draw(rate),
        jaywalk_rate=draw(rate),
        red_light_rate=draw(rate),
        phase_std=draw(st.floats(0.0, 1.5)),
    )
    return ScenarioConfig(
        road=RoadConfig(
            num_lanes=lanes, two_way=two_way, length=length, lane_width=draw(st.floats(2.8, 4.0))
        ),
        crossing=CrosswalkConfig(
            kind=kind, position=draw(st.floats(60.0, length - 40.0)), width=draw(st.floats(2.5, 6.0))
        ),
        ego=EgoConfig(x=draw(st.floats(5.0, 40.0)), speed=draw(st.floats(0.0, 18.0))),
        traffic=TrafficConfig(flow_per_lane=draw(st.floats(0.0, 1500.0)), yield_probability=draw(rate)),
        pedestrians=PedestrianConfig(
            spawn_rate=draw(st.floats(0.0, 60.0)),
            cross_fraction=draw(rate),
            group_probability=draw(rate),
            behaviour=behaviour,
        ),
        duration=20.0,
        night=draw(st.booleans()),
    )


def _car_pedestrian_overlaps(world) -> list[tuple[int, int]]:
    """(vehicle slot, pedestrian slot) pairs overlapping by more than 5 cm (ground-truth geometry)."""
    tr, peds = world.traffic, world.pedestrians
    pairs = []
    for v in np.flatnonzero(tr.active):
        d = np.abs(peds.position - np.array([tr.x[v], tr.y[v]]))
        gap = np.hypot(
            np.maximum(d[:, 0] - tr.length[v] / 2, 0.0), np.maximum(d[:, 1] - tr.width[v] / 2, 0.0)
        )
        pairs += [(int(v), int(p)) for p in np.flatnonzero(peds.active & (peds.radius - gap > 0.05))]
    return pairs


@settings(
    max_examples=max(5, settings().max_examples // 4),
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
@given(scenario=scenarios(), seed=st.integers(0, 2**31 - 1), data=st.data())
def test_random_scenarios_and_actions_keep_invariants(scenario, seed, data):
    env = CrossingEnv(scenario=scenario)
    obs, info = env.reset(seed=seed)
    actions = data.draw(st.lists(st.floats(-1.0, 1.0), min_size=60, max_size=120))
    hit_ids: set[int] = set()
    bg_hit_ids: set[int] = set()
    for a in actions:
        obs, reward, terminated, truncated, info = env.step(np.array([a], dtype=np.float32))
        assert env.observation_space.contains(obs)
        assert all(np.isfinite(v).all() for v in obs.values())
        assert np.isfinite(reward)
        gt = info["ground_truth"]
        assert np.isfinite(gt.pedestrian_positions).all() and np.isfinite(gt.pedestrian_velocities).all()
        hit_ids |= {c.other_id for c in gt.collisions if c.kind == "pedestrian"}
        bg_hit_ids |= {c.other_id for c in gt.extras["background_collisions"]}
        for vehicle, slot in _car_pedestrian_overlaps(env.world):
            pid = int(env.world.pedestrians.ids[slot])
            assert pid in (hit_ids if vehicle == 0 else bg_hit_ids), (
                "a pedestrian overlaps a car without a collision"
            )
        if terminated or truncated:
            break
    assert env._observer.out_of_range == 0, "raw observation values left the observation space"
