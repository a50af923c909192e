"""Stable-Baselines3 accepts the env: its checker, Python bools, and why its shape warnings are benign."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest

from crossing_env import ENV_ID

sb3 = pytest.importorskip("stable_baselines3", reason="optional extra 'rl' not installed")
from stable_baselines3.common.env_checker import check_env  # noqa: E402

BENIGN = (
    "is an image but its `dtype`",  # (K, 8, 2) / (K, 12, 2) float boxes: SB3 guesses "image" from 3 dims
    "is an image but the upper and lower bounds",
    "minimal resolution for an image",
    "has an unconventional shape",  # (K, 8) / (M, 7) boxes
)
"""SB3's shape heuristics. Benign for `MultiInputPolicy`: `is_image_space` needs uint8, so every key goes
through `nn.Flatten` in `CombinedExtractor` (asserted below), never a CNN."""


def _check(env: gym.Env) -> None:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env)
    unexpected = [str(w.message) for w in caught if not any(b in str(w.message) for b in BENIGN)]
    assert not unexpected


def test_sb3_check_env_bare():
    _check(gym.make(ENV_ID).unwrapped)


def test_sb3_check_env_with_both_prediction_wrappers():
    from predictors.intention import QLBIntention
    from predictors.trajectory_wrapper import TrajectoryPrediction

    _check(TrajectoryPrediction(QLBIntention(gym.make(ENV_ID))))


def test_shape_warnings_are_benign_every_key_is_flattened():
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.preprocessing import is_image_space

    env = gym.make(ENV_ID)
    assert not any(is_image_space(s) for s in env.observation_space.spaces.values())
    model = PPO("MultiInputPolicy", env, n_steps=64, batch_size=64, device="cpu")
    extractors = model.policy.features_extractor.extractors
    assert set(extractors) == set(env.observation_space.spaces)
    assert all(isinstance(m, torch.nn.Flatten) for m in extractors.values())


def test_terminated_and_truncated_are_python_bools_under_time_limit():
    env = gym.make(ENV_ID, scenario="zebra_case1", max_episode_steps=5)  # TimeLimit truncates at 5
    env.reset(seed=0)
    for _ in range(5):
        _, reward, terminated, truncated, _ = env.step(np.zeros(1, np.float32))
        assert type(terminated) is bool and type(truncated) is bool and type(reward) is float
    assert truncated


@pytest.mark.slow
def test_async_vector_env_with_torch_wrapper_does_not_hang_under_fork():
    """The default (fork) start: the children run torch on one thread instead of hanging in its pool."""
    code = (
        "import gymnasium as gym, numpy as np, crossing_env\n"
        "from predictors.trajectory_wrapper import TrajectoryPrediction\n"
        "envs = gym.make_vec(crossing_env.ENV_ID, num_envs=2, vectorization_mode='async',"
        " wrappers=[TrajectoryPrediction], vector_kwargs={'context': 'fork'})\n"
        "obs, _ = envs.reset(seed=0)\n"
        "for _ in range(3): obs, *_ = envs.step(np.zeros((2, 1), np.float32))\n"
        "assert obs['predicted_paths'].shape[0] == 2\n"
        "envs.close()\n"
        "print('ok')\n"
    )
    proc = subprocess.Popen(
        [sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        start_new_session=True,
    )  # fmt: skip
    try:
        out, err = proc.communicate(timeout=240)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)  # the hung workers too
        proc.communicate()
        pytest.fail("async vector env with TrajectoryPrediction hung under fork")
    assert proc.returncode == 0, err[-2000:]
    assert "ok" in out
