from __future__ import annotations

from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces

from predictors.checkpoints import WEIGHTS_DIR
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
    """Speed is measured in benchmarks/predictors.py; here only the cache's correctness."""
    base = FakePedEnv(n_present=K)
    env = TrajectoryPrediction(base)
    env.reset(seed=0)
    obs = base._obs()
    rng = np.random.default_rng(1)
    moved = {**obs, "pedestrian_history": obs["pedestrian_history"] + rng.normal(0, 0.3, (K, 1, 2))}
    a = env.observation(obs)["predicted_paths"].copy()
    hits = env.cache_hits
    b = env.observation(moved)["predicted_paths"].copy()
    c = env.observation(moved)["predicted_paths"]
    assert not np.array_equal(a, b)  # a new history gives a new prediction
    np.testing.assert_array_equal(b, c)
    assert env.cache_hits == hits + 1


@needs_weights
@pytest.mark.parametrize("model", ["s-cgru", "s-lstm_eth", "cvm"])
def test_translated_and_reordered_history_reuses_shifted_paths(model: str) -> None:
    """The ego moved (a common translation) and the slots were re-sorted: the cached paths, reordered and
    shifted, equal a fresh prediction (the models are translation- and permutation-equivariant)."""
    chosen = model if model in ("s-cgru", "cvm") else WEIGHTS_DIR / f"{model}.pt"
    base = FakePedEnv(n_present=K - 3)
    env = TrajectoryPrediction(base, model=chosen)
    env.reset(seed=0)
    obs = base._obs()
    obs["pedestrian_history"][: K - 3] *= 0.3  # a tight crowd, so the social pooling matters
    first = env.observation(obs)["predicted_paths"].copy()
    assert (env.cache_hits, env.cache_misses) == (0, 2)  # reset's observation, then this one
    perm = np.r_[np.random.default_rng(0).permutation(K - 3), np.arange(K - 3, K)]
    shift = np.array([-3.7, 1.25], np.float32)
    moved = {
        "pedestrians": obs["pedestrians"][perm],
        "pedestrian_history": np.where(
            obs["pedestrians"][perm, :1, None] > 0.5, obs["pedestrian_history"][perm] + shift, 0.0
        ).astype(np.float32),
    }
    reused = env.observation(moved)["predicted_paths"]
    assert env.cache_hits == 1
    fresh = TrajectoryPrediction(FakePedEnv(n_present=K - 3), model=chosen).observation(moved)[
        "predicted_paths"
    ]
    np.testing.assert_allclose(reused, fresh, atol=1e-4, rtol=0)
    np.testing.assert_allclose(reused[: K - 3], first[perm[: K - 3]] + shift, atol=1e-5, rtol=0)
    assert np.all(reused[K - 3 :] == 0.0)


@needs_weights
def test_changed_history_is_recomputed() -> None:
    base = FakePedEnv(n_present=K)
    env = TrajectoryPrediction(base)
    env.reset(seed=0)
    obs = base._obs()
    a = env.observation(obs)["predicted_paths"].copy()
    hits, misses = env.cache_hits, env.cache_misses
    for change in (1e-3, 0.05):  # one pedestrian's newest sample moves: just above the tolerance, and more
        hist = obs["pedestrian_history"].copy()
        hist[3, -1] += change
        hist += np.float32(2.0)  # plus a common translation, which alone would be reused
        b = env.observation({**obs, "pedestrian_history": hist})["predicted_paths"]
        fresh = TrajectoryPrediction(FakePedEnv(n_present=K)).observation({**obs, "pedestrian_history": hist})
        np.testing.assert_allclose(b, fresh["predicted_paths"], atol=1e-4, rtol=0)
        assert not np.allclose(b[3], a[3] + 2.0, atol=1e-5)
    assert env.cache_misses == misses + 2 and env.cache_hits == hits
    # a pedestrian leaving changes the window: recomputed too
    fewer = {**obs, "pedestrians": obs["pedestrians"].copy()}
    fewer["pedestrians"][5, 0] = 0.0
    env.observation(fewer)
    assert env.cache_misses == misses + 3


def test_match_translated_rejects_ambiguous_and_accepts_exact() -> None:
    from predictors.trajectory_wrapper import match_translated

    rng = np.random.default_rng(3)
    ref = rng.normal(size=(5, 8, 2)).astype(np.float32)
    perm = np.array([2, 0, 4, 1, 3])
    got = match_translated(ref[perm] + np.float32(7.5), ref)
    assert got is not None
    np.testing.assert_array_equal(got[0], perm)
    np.testing.assert_allclose(got[1], [7.5, 7.5], atol=1e-5)
    assert match_translated(ref[:4], ref) is None  # different count
    twin = ref.copy()
    twin[1] = twin[0]  # two identical histories: no unique reordering
    assert match_translated(twin[[1, 0, 2, 3, 4]], twin) is not None  # identity still matches
    bent = ref.copy()
    bent[2, 3] += 2e-4
    assert match_translated(bent, ref) is None
