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


def test_an_exported_residual_offset_runs_in_crossing_eval_as_trained(trained, tmp_path):
    """The registry's shielded policy from a file with ``residual_offset`` asks for the rule's acceleration
    plus scale × clip(offset + SB3's greedy action), capped by the envelope, at every step."""
    from dataclasses import replace

    from agents.config import YieldingConfig
    from agents.registry import mlp_policy, scenario_settings
    from agents.shield import YieldingShield
    from agents.view import parse_observation
    from crossing_env.env import acceleration_to_action

    model, venv, _ = trained
    path = export_sb3(
        model, venv, tmp_path / "offset.npz", shielded=True, residual_scale=2.0, residual_offset=1.0
    )
    assert load_mlp(path).residual_offset == 1.0
    env = gym.make(ENV_ID, scenario="busy_zebra")
    obs, _ = env.reset(seed=5)
    base = env.unwrapped
    policy = mlp_policy(path, base.scenario, base.config.dt)
    policy.reset(5)
    cfg = replace(YieldingConfig(), **scenario_settings(base.scenario), dt=base.config.dt)
    reference = YieldingShield(cfg)
    requests = []
    for _ in range(120):
        theirs, _ = model.predict(
            venv.normalize_obs({k: obs[k][None] for k in BASE_KEYS}), deterministic=True
        )
        residual = float(np.clip(1.0 + np.clip(theirs[0, 0], -1, 1), -1, 1))
        rule, bound = reference.rule_and_limit(parse_observation(obs))
        wanted = np.clip(rule[0] + 2.0 * residual, -cfg.ego.max_deceleration, cfg.ego.max_acceleration)
        expected = acceleration_to_action(np.array([min(wanted, bound[0])]), cfg.ego).reshape(1)
        mine = policy(obs)
        np.testing.assert_allclose(mine, expected, atol=1e-5)
        requests.append(residual)
        obs, _, terminated, truncated, _ = env.step(mine)
        if terminated or truncated:
            break
    assert min(requests) < 1.0  # the actor's own action mattered somewhere, not only the offset


def test_a_file_without_an_offset_reads_as_no_offset(trained, tmp_path):
    _, _, path = trained
    with np.load(path, allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files if k != "residual_offset"}
    old = tmp_path / "old.npz"
    np.savez(old, **arrays)
    assert load_mlp(old).residual_offset == 0.0
