"""The shipped PPO policy: loads with its normalisation, acts in range, and is a default crossing-eval row."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import crossing_eval.plugins as plugins
from agents import POLICIES, make_policy, policy_uses_predictors
from agents.registry import SHIPPED_PPO
from agents.sb3 import stats_path
from crossing_env import ENV_ID


def test_shipped_files_are_small_and_paired():
    assert SHIPPED_PPO.is_file() and SHIPPED_PPO.stat().st_size <= 2 * 2**20
    assert stats_path(SHIPPED_PPO).is_file()


def test_ppo_is_in_the_default_table_only_with_the_rl_extra(monkeypatch):
    monkeypatch.setattr(plugins, "sb3_available", lambda: True)
    assert plugins.default_policies() == (list(POLICIES), None)
    monkeypatch.setattr(plugins, "sb3_available", lambda: False)
    policies, note = plugins.default_policies()
    assert "ppo" not in policies and "rl" in note


def test_shipped_ppo_drives():
    pytest.importorskip("stable_baselines3", reason="optional extra 'rl' not installed")
    env = gym.make(ENV_ID, scenario="zebra_case1")
    obs, _ = env.reset(seed=0)
    policy = make_policy("ppo")
    assert policy.stats is not None  # VecNormalize statistics loaded from beside the zip
    assert not policy_uses_predictors("ppo")
    actions = []
    for _ in range(30):
        a = policy(obs)
        assert a.shape == (1,) and a.dtype == np.float32 and -1.0 <= a[0] <= 1.0
        actions.append(float(a[0]))
        obs, *_ = env.step(a)
    assert np.ptp(actions) > 0  # it reacts to the observation, not a constant


def test_shipped_ppo_loads_without_a_training_optimizer():
    """Acting needs no Adam (building one imports torch._dynamo, ~2 s); its saved state is kept as is."""
    pytest.importorskip("stable_baselines3", reason="optional extra 'rl' not installed")
    from agents.sb3 import InferenceOnlyOptimizer

    policy = make_policy("ppo")
    optimizer = policy.model.policy.optimizer
    assert isinstance(optimizer, InferenceOnlyOptimizer)
    assert "param_groups" in optimizer.state_dict()  # the file's optimizer state, loaded untouched
    with pytest.raises(RuntimeError, match="to act"):
        optimizer.step()
