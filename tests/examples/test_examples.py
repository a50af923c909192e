"""Smoke test of the Stable-Baselines3 PPO example: a few hundred steps of training and one scored episode."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3", reason="stable-baselines3 (test extra) not installed")

REPO = Path(__file__).resolve().parents[2]


def test_ppo_example_trains_and_evaluates(tmp_path: Path) -> None:
    model = tmp_path / "ppo.zip"
    env = dict(os.environ, PYTHONPATH=str(REPO), OMP_NUM_THREADS="1")
    proc = subprocess.run(
        [
            sys.executable,
            str(REPO / "examples" / "ppo_crossing.py"),
            "--timesteps",
            "256",
            "--n-steps",
            "128",
            "--batch-size",
            "64",
            "--eval-episodes",
            "1",
            "--scenario",
            "zebra_case1",
            "--save",
            str(model),
        ],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "trained PPO for 256 steps" in proc.stdout
    assert "eval 1 episodes: collision rate" in proc.stdout
    assert model.is_file() and model.stat().st_size > 1000
    assert model.with_suffix(".vecnormalize.pkl").is_file()


def test_ppo_example_rejects_bad_timesteps(tmp_path: Path) -> None:
    proc = subprocess.run(
        [sys.executable, str(REPO / "examples" / "ppo_crossing.py"), "--timesteps", "-5"],
        cwd=tmp_path,
        env=dict(os.environ, PYTHONPATH=str(REPO)),
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert proc.returncode == 2
    assert "'-5'" in proc.stderr
