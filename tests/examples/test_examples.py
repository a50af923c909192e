"""Smoke test of the Stable-Baselines3 PPO recipe: a few hundred steps, its files, one scored episode."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3", reason="stable-baselines3 (test extra) not installed")

REPO = Path(__file__).resolve().parents[2]


def test_ppo_example_trains_logs_plots_and_evaluates(tmp_path: Path) -> None:
    out = tmp_path / "run"
    env = dict(os.environ, PYTHONPATH=str(REPO), OMP_NUM_THREADS="1")
    proc = subprocess.run(
        [
            sys.executable,
            str(REPO / "examples" / "ppo_crossing.py"),
            *("--timesteps", "512", "--n-envs", "2", "--n-steps", "128", "--batch-size", "64"),
            *("--bc-steps", "64", "--eval-every", "256", "--eval-episodes", "1"),
            *("--scenarios", "zebra_case1,midblock_jaywalker", "--out", str(out), "--no-progress"),
        ],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "trained PPO for 512 steps" in proc.stdout
    assert "warm start: imitated the yielding policy on 64 steps" in proc.stdout
    assert "collision rate [95% CI]" in proc.stdout and "mean return" in proc.stdout
    model = out / "model.zip"
    assert model.is_file() and model.stat().st_size > 1000
    assert (out / "model.vecnormalize.npz").is_file() and (out / "step_256.zip").is_file()
    assert not list(out.glob("*.pkl")), "statistics are data (npz), never pickle"
    assert (out / "learning_curve.png").stat().st_size > 1000
    header = (out / "episodes.csv").read_text().splitlines()[0]
    assert header == "step,scenario,return,collision,obligations,violations,delay,duration"
    assert (out / "progress.csv").is_file()


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
