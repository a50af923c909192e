"""Shared fixtures: headless pygame, the data folder, Hypothesis profiles.

Hypothesis profiles (`HYPOTHESIS_PROFILE` picks one; `CI=true` picks `ci`):

- `ci`: derandomized (the same examples on every run and every clone) with a fixed budget, no example
  database, so the suite is green on every fresh clone or red on every one;
- `dev` (default locally): random examples, the same budget;
- `fuzz`: deep local fuzzing, 20x the examples: `HYPOTHESIS_PROFILE=fuzz python -m pytest tests -k fuzz`.

Property tests scale their own budgets from the loaded profile's `max_examples`.
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, settings

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

settings.register_profile(
    "ci", derandomize=True, database=None, max_examples=100, deadline=None, print_blob=True
)
settings.register_profile("dev", max_examples=100, deadline=None)
settings.register_profile(
    "fuzz", max_examples=2000, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
settings.load_profile(
    os.environ.get("HYPOTHESIS_PROFILE") or ("ci" if os.environ.get("CI", "").lower() == "true" else "dev")
)

REPO = Path(__file__).resolve().parents[1]


def data_root() -> Path:
    """`CROSSING_DATA` or `<repo>/../shared/data`."""
    return Path(os.environ.get("CROSSING_DATA", REPO.parent / "shared" / "data"))


@pytest.fixture
def eth_ucy_root() -> Path:
    root = data_root() / "eth_ucy"
    if not root.is_dir():
        pytest.skip(f"ETH/UCY data not found at {root} (set CROSSING_DATA)")
    return root


@pytest.fixture(scope="session")
def sb3_zip(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An (untrained) SB3 PPO saved with its VecNormalize statistics beside it, as the recipe saves."""
    pytest.importorskip("stable_baselines3", reason="optional extra 'rl' not installed")
    import gymnasium as gym
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from crossing_env import ENV_ID

    out = tmp_path_factory.mktemp("sb3")
    venv = VecNormalize(DummyVecEnv([lambda: gym.make(ENV_ID)]))
    venv.reset()
    for _ in range(20):
        venv.step(np.zeros((1, 1), np.float32))  # some statistics to save
    model = PPO("MultiInputPolicy", venv, n_steps=32, batch_size=32, seed=0, device="cpu")
    model.save(out / "model.zip")
    from agents.sb3 import save_stats

    save_stats(venv, out / "model.vecnormalize.npz")
    return out / "model.zip"


@pytest.fixture
def run_with_empty_numba_cache(tmp_path: Path) -> Callable[[str], None]:
    """Runs Python `code` in a fresh process whose numba cache folder is empty; fails on a non-zero exit."""

    def run(code: str) -> None:
        env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba"))
        proc = subprocess.run([sys.executable, "-c", code], env=env, cwd=REPO, capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr[-2000:]

    return run
