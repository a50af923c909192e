"""Helpers shared by the pedestrian tests: run a world with the ego holding its speed."""

from __future__ import annotations

import numpy as np

from crossing_env.types import BehaviourEvent
from crossing_env.world import World
from scenarios.config import ScenarioConfig


def run_world(scenario: ScenarioConfig, seconds: float, seed: int = 0) -> tuple[World, list[BehaviourEvent]]:
    """Run a world (the ego holds its speed) and return it with every behaviour event logged."""
    world = World(scenario, np.random.default_rng(seed))
    events = []
    for _ in range(round(seconds / world.dt)):
        world.step(0.0)
        events.extend(world.pedestrians.events)
    return world, events
