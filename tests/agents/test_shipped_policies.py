"""The shipped learned policies: data files in the manifest, loaded without unpickling, acting in range."""

from __future__ import annotations

import json
import sys

import gymnasium as gym
import numpy as np

import crossing_eval.plugins as plugins
from agents import POLICIES, make_policy, policy_uses_predictors
from agents.mlp import MLPPolicy
from agents.registry import DEFAULT_LEARNED, SHIPPED_MANIFEST, SHIPPED_POLICIES
from agents.shield import ShieldedPolicy
from crossing_env import ENV_ID


def test_shipped_files_are_small_data_and_in_the_manifest():
    manifest = json.loads(SHIPPED_MANIFEST.read_text(encoding="utf-8"))
    for path in SHIPPED_POLICIES.values():
        assert path.is_file() and path.stat().st_size <= 2**20 and path.name in manifest
        with np.load(path, allow_pickle=False) as data:  # raises on any pickled object
            assert all(data[k].dtype != object for k in data.files)
    assert not list(SHIPPED_MANIFEST.parent.glob("*.zip")) and not list(SHIPPED_MANIFEST.parent.glob("*.pkl"))


def test_the_default_table_has_the_learned_policy_without_any_extra(monkeypatch):
    monkeypatch.setattr(plugins, "sb3_available", lambda: False)  # numpy only: no Stable-Baselines3 needed
    assert plugins.default_policies() == (list(POLICIES), None)
    assert DEFAULT_LEARNED in POLICIES


def test_shipped_policies_drive_through_the_shield_as_trained():
    env = gym.make(ENV_ID, scenario="zebra_case1")
    for name in SHIPPED_POLICIES:
        obs, _ = env.reset(seed=0)
        base = env.unwrapped
        policy = make_policy(name, scenario=base.scenario, dt=base.config.dt)
        assert not policy_uses_predictors(name)
        learned = policy.learned if isinstance(policy, ShieldedPolicy) else policy
        assert isinstance(learned, MLPPolicy)
        assert isinstance(policy, ShieldedPolicy) == learned.weights.shielded == (name == "ppo_shielded")
        policy.reset(0)
        actions = []
        for _ in range(40):
            a = policy(obs)
            assert a.shape == (1,) and a.dtype == np.float32 and -1.0 <= a[0] <= 1.0
            actions.append(float(a[0]))
            obs, *_ = env.step(a)
        assert np.ptp(actions) > 0, name  # it reacts to the observation


def test_acting_needs_neither_torch_nor_stable_baselines3():
    import subprocess

    code = (
        "import sys, gymnasium as gym, crossing_env\n"
        "from agents import make_policy\n"
        "env = gym.make(crossing_env.ENV_ID, scenario='busy_zebra'); obs, _ = env.reset(seed=1)\n"
        "p = make_policy('ppo_shielded', scenario=env.unwrapped.scenario, dt=0.1); p(obs)\n"
        "assert 'stable_baselines3' not in sys.modules, 'SB3 imported'\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stderr[-2000:]
