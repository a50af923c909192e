from __future__ import annotations

import copy
import dataclasses

import gymnasium as gym

import crossing_env
from crossing_env.types import CollisionEvent
from crossing_replay.episode_log import ground_truth_digest


def _ground_truth_with_background_collision():
    env = gym.make(crossing_env.ENV_ID, scenario="zebra_case1").unwrapped
    _, info = env.reset(seed=0)
    event = CollisionEvent(
        time=1.0, kind="pedestrian", other_id=3, position=(10.0, 2.0), relative_speed=4.5, compliant=True
    )
    gt = info["ground_truth"]
    return dataclasses.replace(gt, extras={**gt.extras, "background_collisions": (event,)})


def test_digest_is_stable_for_equal_states_holding_event_objects() -> None:
    """Extras holding event tuples are object arrays for numpy: their bytes are pointers, not content."""
    a = _ground_truth_with_background_collision()
    b = copy.deepcopy(a)
    assert ground_truth_digest(a) == ground_truth_digest(b)
    moved = dataclasses.replace(
        a,
        extras={
            **a.extras,
            "background_collisions": (dataclasses.replace(a.extras["background_collisions"][0], other_id=4),),
        },
    )
    assert ground_truth_digest(moved) != ground_truth_digest(a)
