"""The external-style forecaster of examples/my_predictor.py: one flag plugs it into crossing-eval."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from crossing_eval.provenance import sha256
from predictors.data import default_data_root
from predictors.forecast import ForecastInput

REPO = Path(__file__).resolve().parents[2]
NAME = "examples.my_predictor:Forecaster"


def test_crossing_eval_runs_the_example_from_the_project_folder(tmp_path: Path) -> None:
    # The user's command, in a fresh process with two workers: the module is found in the current folder.
    exe = shutil.which("crossing-eval") or pytest.skip("crossing-eval is not installed in this environment")
    out = tmp_path / "out"
    argv = ["--predictor", NAME, "--policies", "predictive_yielding", "--scenarios", "zebra_case1"]
    proc = subprocess.run(
        [exe, *argv, "--episodes", "2", "--workers", "2", "--no-progress", "--out", str(out)],
        cwd=REPO,
        env={k: v for k, v in os.environ.items() if k != "PYTHONPATH"},
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    assert "predictive_yielding" in proc.stdout
    doc = json.loads((out / "results.json").read_text())
    assert all(f"trajectory:{NAME}" in e["predictors"] for e in doc["episodes"])
    assert doc["settings"]["provenance"]["files"]["examples/my_predictor.py"] == sha256(
        REPO / "examples" / "my_predictor.py"
    )


def test_the_example_samples_around_its_mode_and_the_same_seed_repeats() -> None:
    from examples.my_predictor import Forecaster

    history = np.cumsum(np.full((3, 8, 2), [0.5, 0.0], np.float32), axis=1)  # walking east at 1.25 m/s
    inputs = ForecastInput(history, np.ones(3, bool), None, None, {}, 0)
    forecaster = Forecaster()
    forecaster.reset(7)
    first = forecaster.forecast(inputs)
    forecaster.reset(7)
    again = forecaster.forecast(inputs)
    np.testing.assert_array_equal(first.paths, again.paths)
    np.testing.assert_allclose(first.mode[:, -1], history[:, -1] + 12 * np.array([0.5, 0.0]))
    ends = first.paths[:, :, -1] - history[:, None, -1]  # (N, S, 2) displacements over 4.8 s
    angles = np.degrees(np.arctan2(ends[..., 1], ends[..., 0]))
    assert 2.0 < angles.std() < 40.0  # a spread of headings around straight on
    assert first.paths.shape == (3, 12, 12, 2)


def test_the_shipped_constants_are_what_the_fit_gives() -> None:
    import examples.my_predictor as example

    if not (default_data_root() / "eth_ucy").is_dir():
        pytest.skip("ETH/UCY data not found (set CROSSING_DATA)")
    heading, median, sigma = example.fit()
    assert round(heading, 2) == example.HEADING_SIGMA_DEG
    assert round(median, 4) == example.LOG_SPEED_MEDIAN
    assert round(sigma, 3) == example.LOG_SPEED_SIGMA
