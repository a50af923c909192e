"""The rules' helpers in `agents.view`: their early returns give what the general path gives."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np

from agents.config import YieldingConfig
from agents.view import View, follow, parse_observation, stop_acceleration
from crossing_env.observation import VehicleColumn


def _batch(speeds: list[float]) -> View:
    """A real observation's view repeated over a batch, one ego speed per element."""
    obs, _ = gym.make("crossing_env/Crossing-v0", scenario="zebra_case1").reset(seed=0)
    view = parse_observation(obs)
    b = len(speeds)
    return dataclasses.replace(
        view,
        lead=(b,),
        speed=np.asarray(speeds, dtype=np.float64),
        vehicles=np.repeat(view.vehicles, b, axis=0),
    )


def test_a_stop_target_at_infinity_gives_what_the_general_path_gives() -> None:
    view = _batch([10.0, 10.0, 0.0])
    cfg = YieldingConfig()
    args = (cfg.comfortable_deceleration, cfg.stop_gain, cfg.ego.max_deceleration)
    none = stop_acceleration(view, np.full(3, np.inf), *args)  # the early return
    mixed = stop_acceleration(view, np.array([np.inf, 12.0, np.inf]), *args)  # the general path
    assert none.shape == (3,) and none.dtype == np.float64
    np.testing.assert_array_equal(none[[0, 2]], mixed[[0, 2]])
    assert np.isposinf(none).all() and mixed[1] == -(10.0**2) / (2 * 12.0)


def test_following_nobody_gives_what_the_general_path_gives() -> None:
    view = _batch([10.0, 10.0])
    veh = np.zeros((2, 2, len(VehicleColumn)))
    veh[:, 0, VehicleColumn.PRESENCE] = 1.0
    veh[:, 0, VehicleColumn.DX] = -20.0  # behind the ego in both elements
    veh[:, 0, VehicleColumn.LENGTH] = 4.5
    cfg = YieldingConfig()
    nobody = follow(dataclasses.replace(view, vehicles=veh), cfg)  # the early return
    lead = veh.copy()
    lead[1, 1] = lead[1, 0]
    lead[1, 1, VehicleColumn.DX] = 30.0  # a leader ahead in the second element only
    general = follow(dataclasses.replace(view, vehicles=lead), cfg)
    assert nobody.shape == (2,) and np.isposinf(nobody).all()
    assert general[0] == nobody[0] and np.isfinite(general[1])
