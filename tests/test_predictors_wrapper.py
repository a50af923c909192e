from __future__ import annotations

from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces

from predictors.train import WEIGHTS_DIR
from predictors.trajectory_wrapper import TrajectoryPrediction

K = 16


class FakePedEnv(gym.Env[dict, int]):
    """Pedestrians walking at constant velocity in the ego frame; slots K/2.. are padding."""

    metadata: ClassVar[dict[str, Any]] = {"render_modes": []}

    def __init__(self, n_present: int = K // 2) -> None:
        self.n_present = n_present
        self.observation_space = spaces.Dict(
            {
                "pedestrians": spaces.Box(-100.0, 100.0, (K, 5), np.float32),
                "pedestrian_history": spaces.Box(-100.0, 100.0, (K, 8, 2), np.float32),
            }
        )
        self.action_space = spaces.Discrete(2)
        self._t = 0

    def _obs(self) -> dict[str, np.ndarray]:
        peds = np.zeros((K, 5), np.float32)
        hist = np.zeros((K, 8, 2), np.float32)
        n = self.n_present
        peds[:n, 0] = 1.0
        rng = np.random.default_rng(42)
        start = rng.uniform(-10, 10, (n, 2))
        vel = rng.uniform(-0.5, 0.5, (n, 2))
        steps = self._t + np.arange(8)
        hist[:n] = (start[:, None] + steps[None, :, None] * vel[:, None]).astype(np.float32)
        return {"pedestrians": peds, "pedestrian_history": hist}

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        super().reset(seed=seed)
        self._t = 0
        return self._obs(), {}

    def step(self, action: int) -> tuple[dict, float, bool, bool, dict]:
        self._t += 1
        return self._obs(), 0.0, False, False, {}


needs_weights = pytest.mark.skipif(
    not (WEIGHTS_DIR / "s-cgru_all.pt").is_file(), reason="shipped default weights not built yet"
)


@needs_weights
def test_default_wrapper_adds_paths_inside_space() -> None:
    env = TrajectoryPrediction(FakePedEnv())
    obs, _ = env.reset(seed=0)
    assert obs in env.observation_space
    paths = obs["predicted_paths"]
    assert paths.shape == (K, 12, 2) and paths.dtype == np.float32
    assert np.all(paths[K // 2 :] == 0.0)
    hist = obs["pedestrian_history"][: K // 2]
    # walkers moving >= 0.2 m/step keep moving roughly along their velocity
    vel = hist[:, -1] - hist[:, -2]
    moving = np.linalg.norm(vel, axis=1) > 0.2
    progress = np.einsum("nd,nd->n", paths[: K // 2, -1] - hist[:, -1], vel)
    assert np.all(progress[moving] > 0.0)
    obs2, *_ = env.step(0)
    assert obs2 in env.observation_space
    assert not np.allclose(obs2["predicted_paths"], paths)


@needs_weights
def test_samples_are_seeded_by_reset() -> None:
    env = TrajectoryPrediction(FakePedEnv(), num_samples=4)
    a, _ = env.reset(seed=3)
    b, _ = env.reset(seed=3)
    c, _ = env.reset(seed=4)
    assert a["predicted_samples"].shape == (K, 4, 12, 2)
    np.testing.assert_array_equal(a["predicted_samples"], b["predicted_samples"])
    assert not np.array_equal(a["predicted_samples"], c["predicted_samples"])
    assert a in env.observation_space
    assert np.all(a["predicted_samples"][K // 2 :] == 0.0)


def test_cvm_wrapper_is_exact_and_empty_scene_works() -> None:
    env = TrajectoryPrediction(FakePedEnv(), model="cvm")
    obs, _ = env.reset(seed=0)
    hist = obs["pedestrian_history"][: K // 2]
    want = hist[:, -1:] + np.arange(1, 13)[None, :, None] * (hist[:, -1:] - hist[:, -2:-1])
    np.testing.assert_allclose(obs["predicted_paths"][: K // 2], want, rtol=1e-5, atol=1e-5)
    empty = TrajectoryPrediction(FakePedEnv(n_present=0), model="cvm")
    o, _ = empty.reset()
    assert np.all(o["predicted_paths"] == 0.0) and o in empty.observation_space


def test_bad_env_and_bad_path_errors(tmp_path: Any) -> None:
    class NoHistory(FakePedEnv):
        def __init__(self) -> None:
            super().__init__()
            self.observation_space = spaces.Dict({"pedestrians": spaces.Box(0, 1, (K, 5), np.float32)})

    with pytest.raises(ValueError, match="pedestrian_history"):
        TrajectoryPrediction(NoHistory(), model="cvm")
    bad = tmp_path / "bad.pt"
    bad.write_bytes(b"not a checkpoint")
    with pytest.raises(ValueError, match=r"bad\.pt"):
        TrajectoryPrediction(FakePedEnv(), model=bad)


@needs_weights
def test_unchanged_history_is_served_from_the_cache_identically() -> None:
    """Speed is measured in benchmarks/predictor_models.py; here only the cache's correctness."""
    base = FakePedEnv(n_present=K)
    env = TrajectoryPrediction(base)
    env.reset(seed=0)
    obs = base._obs()
    moved = {**obs, "pedestrian_history": obs["pedestrian_history"] + 0.3}
    a = env.observation(obs)["predicted_paths"].copy()
    b = env.observation(moved)["predicted_paths"].copy()
    c = env.observation(moved)["predicted_paths"]
    assert not np.array_equal(a, b)  # a new history gives a new prediction
    np.testing.assert_array_equal(b, c)
