"""crossing_env imports only highway-env's lanes (its env registry loads pyplot, pandas); all on request."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
CODE = """
import sys
import gymnasium as gym
import crossing_env
assert "pandas" not in sys.modules and "matplotlib.pyplot" not in sys.modules, "env registry imported"
assert "intersection-v0" not in gym.registry and "highway-v0" not in gym.registry, "placeholder left"
env = gym.make(crossing_env.ENV_ID, scenario="zebra_case1")
env.reset(seed=0)
from crossing_env.road import register_highway_envs
register_highway_envs()
assert "intersection-v0" in gym.registry and "highway-v0" in gym.registry
"""


def test_lanes_without_the_env_registry_and_the_registry_on_request() -> None:
    proc = subprocess.run([sys.executable, "-c", CODE], capture_output=True, text=True, cwd=REPO)
    assert proc.returncode == 0, proc.stderr[-2000:]


def test_highway_env_imported_first_keeps_its_envs() -> None:
    code = "import gymnasium as gym, highway_env, crossing_env; assert 'intersection-v0' in gym.registry"
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO)
    assert proc.returncode == 0, proc.stderr[-2000:]
