"""Learned policies as data: the numpy actor equals SB3's greedy action, and a policy file cannot run code."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from agents.mlp import FORMAT, MLPPolicy, PolicyFileError, export_sb3, load_mlp
from crossing_env import ENV_ID
from crossing_env.observation import BASE_KEYS


@pytest.fixture(scope="module")
def trained(tmp_path_factory: pytest.TempPathFactory) -> tuple[object, object, Path]:
    """A tiny SB3 PPO with VecNormalize statistics gathered over a few hundred steps, and its export."""
    pytest.importorskip("stable_baselines3", reason="optional extra 'rl' not installed")
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    def make() -> gym.Env:
        return gym.wrappers.FilterObservation(gym.make(ENV_ID, scenario="busy_zebra"), list(BASE_KEYS))

    venv = VecNormalize(DummyVecEnv([make]), gamma=0.99)
    model = PPO("MultiInputPolicy", venv, n_steps=128, batch_size=64, seed=0, device="cpu")
    model.learn(256)
    path = export_sb3(model, venv, tmp_path_factory.mktemp("mlp") / "policy.npz")
    return model, venv, path


def test_numpy_actor_equals_sb3_greedy_action(trained):
    model, venv, path = trained
    policy = MLPPolicy(path)
    env = gym.make(ENV_ID, scenario="busy_zebra")
    obs, _ = env.reset(seed=5)
    diffs = []
    for _ in range(60):
        filtered = {k: obs[k] for k in BASE_KEYS}
        mine = policy(obs)  # extra keys in the observation are ignored: the file names its keys
        theirs, _ = model.predict(
            venv.normalize_obs({k: v[None] for k, v in filtered.items()}), deterministic=True
        )
        diffs.append(abs(float(mine[0]) - float(np.clip(theirs[0, 0], -1, 1))))
        assert mine.shape == (1,) and mine.dtype == np.float32
        obs, *_ = env.step(mine)
    assert max(diffs) < 1e-5


def test_policy_file_is_plain_data(trained, tmp_path):
    _, _, path = trained
    with np.load(path, allow_pickle=False) as data:  # would raise on any pickled object
        assert str(data["format"]) == FORMAT
        assert all(data[name].dtype != object for name in data.files)
    assert load_mlp(path).keys == tuple(sorted(BASE_KEYS))


def test_a_pickled_or_foreign_file_is_refused_with_its_name(tmp_path):
    pickled = tmp_path / "evil.npz"
    np.savez(pickled, format=np.array(FORMAT), payload=np.array([object()], dtype=object))
    with pytest.raises(PolicyFileError, match=r"evil\.npz"):
        load_mlp(pickled)
    other = tmp_path / "other.npz"
    np.savez(other, format=np.array("something-else"))
    with pytest.raises(PolicyFileError, match=r"other\.npz.*'format'"):
        load_mlp(other)
