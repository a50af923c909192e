"""Social-force intensity update (crossing_env.pedestrians.force_update), seed Case 2."""

from __future__ import annotations

import numpy as np
import pytest

from crossing_env.pedestrians.force_update import irrational_neighbour_fraction, updated_ped_intensity
from crossing_env.pedestrians.population import PedestrianPopulation
from crossing_env.world import World
from scenarios.config import (
    BehaviourConfig,
    PedestrianConfig,
    ScenarioConfig,
)


# ------------------------------------------------------------------ seed Case 2
def test_irrational_neighbour_fraction_and_intensity_update() -> None:
    pos = np.array([[0.0, 0.0], [3.0, 0.0], [0.0, 4.0], [50.0, 0.0], [1.0, 1.0]])
    active = np.array([True, True, True, True, False])
    irrational = np.array([False, True, False, False, True])
    f = irrational_neighbour_fraction(pos, active, irrational, radius=10.0)
    np.testing.assert_allclose(f, [0.5, 0.0, 0.5, 0.0, 0.0])
    k = updated_ped_intensity(0.42, f)
    assert k[1] == pytest.approx(0.42) and k[3] == pytest.approx(0.42)
    assert k[0] > 0.42


def test_force_update_raises_intensity_near_irrational_pedestrians() -> None:
    behaviour = BehaviourConfig(
        decision_model="qlb", update_force_intensity=True, running_rate=0.5, jaywalk_rate=0.3
    )
    scenario = ScenarioConfig(pedestrians=PedestrianConfig(spawn_rate=40.0, behaviour=behaviour))
    world = World(scenario, np.random.default_rng(11))
    peds: PedestrianPopulation = world.pedestrians
    raised = 0
    for _ in range(300):
        world.step(0.0)
        base = scenario.pedestrians.social_force.ped_intensity
        if peds.irrational_now().any():
            raised += int(np.sum(peds.force_intensity[peds.active] > base + 1e-9))
        assert np.all(peds.force_intensity >= base - 1e-12)
    assert raised > 0
    off = World(
        ScenarioConfig(
            pedestrians=PedestrianConfig(
                spawn_rate=40.0, behaviour=BehaviourConfig(decision_model="qlb", running_rate=0.5)
            )
        ),
        np.random.default_rng(11),
    )
    for _ in range(100):
        off.step(0.0)
    assert np.all(off.pedestrians.force_intensity == scenario.pedestrians.social_force.ped_intensity)
