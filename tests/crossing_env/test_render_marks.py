"""Readable frames (issue 26): the ego marked, a caption, intention tags that never overlap, a collision
marker."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from crossing_env import ENV_ID, CrossingEnv
from crossing_env.render import COLOURS, TopDownRenderer
from scenarios.config import EgoConfig, PedestrianConfig, PedestrianSpawn, ScenarioConfig, TrafficConfig


def _mask(frame: np.ndarray, colour: tuple[int, int, int]) -> np.ndarray:
    return np.all(frame == np.array(colour, np.uint8), axis=-1)


def _texts(renderer: TopDownRenderer) -> list[str]:
    """Record every string the renderer writes (both fonts)."""
    seen: list[str] = []
    for name in ("font", "label_font"):
        font = getattr(renderer, name)

        class Recording:
            def __init__(self, inner):
                self.inner = inner

            def render(self, text, *args, **kwargs):
                seen.append(text)
                return self.inner.render(text, *args, **kwargs)

            def __getattr__(self, attr):
                return getattr(self.inner, attr)

        setattr(renderer, name, Recording(font))
    return seen


def test_the_ego_is_outlined_and_labelled_and_the_caption_names_scenario_and_time():
    env = gym.make(ENV_ID, scenario="zebra_case1", render_mode="rgb_array")
    env.reset(seed=1)
    env.step(np.zeros(1, np.float32))
    base = env.unwrapped
    base.render()
    seen = _texts(base._renderer)
    frame = env.render()
    ego = np.argwhere(_mask(frame, COLOURS["ego"]))
    (top, left), (bottom, right) = ego.min(axis=0), ego.max(axis=0)
    ring = frame[top - 2 : bottom + 3, left - 2 : right + 3]
    assert _mask(ring, COLOURS["ego_outline"]).sum() > 2 * (right - left)  # the white outline
    assert "ego" in seen
    assert any(t.startswith("zebra_case1") and "t   0.1 s" in t for t in seen), seen


def test_video_caption_adds_policy_and_seed():
    env = gym.make(ENV_ID, scenario="zebra_case1")
    env.reset(seed=1)
    renderer = TopDownRenderer(env.unwrapped.config, caption="policy yielding   seed 7")
    seen = _texts(renderer)
    renderer.draw(env.unwrapped.world)
    assert any(t.startswith("zebra_case1   policy yielding   seed 7   t") for t in seen), seen


def test_intention_tags_never_overlap_and_stay_in_the_frame():
    """A crowd at the zebra: tags (and the ego's) are pairwise disjoint, inside the frame, off every ring."""
    pytest.importorskip("predictors.intention")
    from crossing_env.render import ShowPredictions
    from predictors.intention import QLBIntention

    env = ShowPredictions(QLBIntention(gym.make(ENV_ID, scenario="busy_zebra", render_mode="rgb_array")))
    env.reset(seed=3)
    tags = 0
    for step in range(70):
        env.step(np.array([-0.2 if step > 30 else 0.0], np.float32))
        if step % 10 == 9:
            env.render()
            renderer = env.unwrapped._renderer
            rects = renderer._labels
            tags += len(rects) - 1
            for i, a in enumerate(rects):
                assert 0 <= a.left and a.right <= renderer.width and 0 <= a.top
                assert a.bottom <= renderer.height
                assert all(not a.colliderect(b) for b in rects[i + 1 :])
    assert tags > 5


def test_a_collision_is_marked_until_the_end():
    spawn = PedestrianSpawn(x=75.0, side="south", crossing_x=75.0, critical_gap=0.0, desired_speed=1.4)
    scenario = ScenarioConfig(
        ego=EgoConfig(x=30.0, speed=12.0),
        pedestrians=PedestrianConfig(spawns=(spawn,), spawn_rate=0),
        traffic=TrafficConfig(flow_per_lane=0),
    )
    env = CrossingEnv(scenario=scenario, render_mode="rgb_array")
    env.reset(seed=0)
    before = None
    for _ in range(200):
        _, _, term, _, info = env.step(np.zeros(1, np.float32))
        if term:
            break
        before = env.render()
    assert info["crashed"]
    after = env.render()
    assert before is not None and _mask(before, COLOURS["collision"]).sum() == 0
    assert _mask(after, COLOURS["collision"]).sum() > 200  # the ring, the cross and the banner
    assert np.array_equal(env.render(), after)  # still there on the held frame
    env.reset(seed=0)  # a new episode forgets it
    assert _mask(env.render(), COLOURS["collision"]).sum() == 0
