"""crossing-env: a Gymnasium environment for driving through pedestrian crossings.

Importing the package registers `crossing_env/Crossing-v0`::

    import gymnasium as gym
    import crossing_env  # noqa: F401  (registers the env)

    env = gym.make("crossing_env/Crossing-v0", scenario="zebra_case1")
"""

from __future__ import annotations

import gymnasium as gym

from crossing_env.env import CrossingEnv, acceleration_to_action, action_to_acceleration
from crossing_env.types import GroundTruth, PedState
from crossing_env.world import World
from scenarios import list_scenarios
from scenarios.config import (
    BehaviourConfig,
    CrosswalkConfig,
    EgoConfig,
    EnvConfig,
    IDMConfig,
    ObservationConfig,
    PedestrianConfig,
    PedestrianSpawn,
    RewardConfig,
    RoadConfig,
    ScenarioConfig,
    SignalConfig,
    SocialForceConfig,
    TrafficConfig,
    VehicleSpawn,
)

ENV_ID = "crossing_env/Crossing-v0"


def scenarios() -> dict[str, str]:
    """Built-in scenario names with a one-line description each."""
    return list_scenarios()


if ENV_ID not in gym.registry:
    # No max_episode_steps: the env truncates itself at the scenario's duration, whatever dt is.
    gym.register(id=ENV_ID, entry_point="crossing_env.env:CrossingEnv")

__all__ = [
    "ENV_ID",
    "BehaviourConfig",
    "CrossingEnv",
    "CrosswalkConfig",
    "EgoConfig",
    "EnvConfig",
    "GroundTruth",
    "IDMConfig",
    "ObservationConfig",
    "PedState",
    "PedestrianConfig",
    "PedestrianSpawn",
    "RewardConfig",
    "RoadConfig",
    "ScenarioConfig",
    "SignalConfig",
    "SocialForceConfig",
    "TrafficConfig",
    "VehicleSpawn",
    "World",
    "acceleration_to_action",
    "action_to_acceleration",
    "scenarios",
]
