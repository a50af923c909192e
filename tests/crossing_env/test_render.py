"""Readable frames (issue 16): scale, orientation as in rerun, night dimmed, predictions drawn."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from crossing_env import ENV_ID
from crossing_env.render import COLOURS, MIN_PED_PX, ShowPredictions


def _frame(scenario: str = "busy_zebra", steps: int = 40, **kwargs) -> tuple[np.ndarray, gym.Env]:
    env = gym.make(ENV_ID, scenario=scenario, render_mode="rgb_array", **kwargs)
    env.reset(seed=1)
    for _ in range(steps):
        env.step(np.array([-0.3], np.float32))
    return env.render(), env


def _mask(frame: np.ndarray, colour: tuple[int, int, int]) -> np.ndarray:
    return np.all(frame == np.array(colour, np.uint8), axis=-1)


def test_ego_is_drawn_with_y_down_like_the_rerun_view():
    frame, env = _frame(steps=1)
    rows = np.flatnonzero(_mask(frame, COLOURS["ego"]).any(axis=1))
    ego_y = env.unwrapped.world.traffic.y[0]
    centre_y = env.unwrapped.scenario.road.num_lanes * env.unwrapped.scenario.road.lane_width / 2
    assert ego_y < centre_y  # the ego drives in a forward lane, below the road's centre line in y ...
    assert rows.mean() < frame.shape[0] / 2  # ... which is drawn above the image centre (+y down)


def test_pedestrians_have_a_minimum_visible_size():
    frame, env = _frame(config={"render_extent": 200.0})  # 4 px per metre: a body would be ~1 px
    peds = env.unwrapped.world.pedestrians
    assert peds.active.any()
    state_pixels = (
        sum(_mask(frame, COLOURS[s]).sum() for s in COLOURS if not isinstance(s, str)) - 4 * np.pi * 25
    )  # the legend's four dots
    assert state_pixels >= 0.5 * np.pi * (MIN_PED_PX - 1) ** 2 * peds.active.sum()


def test_night_is_dimmed():
    day, _ = _frame(overrides={"night": False}, steps=5)
    night, _ = _frame(overrides={"night": True}, steps=5)
    body = slice(30, -30)  # leave out the overlay bands
    assert night[body].mean() < 0.7 * day[body].mean()


def test_predicted_paths_drawn_with_the_wrappers():
    pytest.importorskip("predictors.trajectory_wrapper")
    from predictors.trajectory_wrapper import TrajectoryPrediction

    env = gym.make(ENV_ID, scenario="busy_zebra", render_mode="rgb_array", config={"render_extent": 160.0})
    plain = env
    env = ShowPredictions(TrajectoryPrediction(env, model="cvm"))
    env.reset(seed=1)
    for _ in range(40):
        env.step(np.array([-0.3], np.float32))
    body = slice(30, -30)
    with_paths = _mask(env.render()[body], COLOURS["prediction"]).sum()
    without = _mask(plain.render()[body], COLOURS["prediction"]).sum()
    assert without == 0 and with_paths > 20
