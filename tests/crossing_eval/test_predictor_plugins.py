"""A user's predictor plugs into crossing-eval with one flag; a broken one is one line and exit 2."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from crossing_eval.cli import main
from crossing_eval.provenance import sha256
from rollout import wrappers
from rollout.wrappers import WrapperError, wrap

PLUGIN = "tests.crossing_eval.plugin_predictors"
ARGS = [
    "--scenarios",
    "zebra_case1",
    "--policies",
    "predictive_yielding",
    "--episodes",
    "1",
    "--workers",
    "1",
]


def test_a_plug_in_predictor_runs_and_the_results_name_it_and_its_file(tmp_path: Path) -> None:
    name = f"{PLUGIN}:Steady"
    assert main([*ARGS, "--no-progress", "--predictor", name, "--out", str(tmp_path / "out")]) == 0
    settings = json.loads((tmp_path / "out" / "results.json").read_text())["settings"]
    assert f"trajectory:{name}" in settings["predictors_used"]
    source = Path(__file__).with_name("plugin_predictors.py")
    assert settings["provenance"]["files"]["tests/crossing_eval/plugin_predictors.py"] == sha256(source)


@pytest.mark.parametrize(
    ("flag", "value", "said"),
    [
        ("--predictor", f"{PLUGIN}:RaisesInInit", "RuntimeError: weights.bin not found"),
        ("--predictor", f"{PLUGIN}:ReturnsNaN", "NaN"),
        ("--predictor", f"{PLUGIN}:WrongShape", r"shape \(16, 1, 12, 2\)"),
        ("--predictor", f"{PLUGIN}:RaisesInForecast", "IndexError: index 8 is out of bounds"),
        ("--predictor", f"{PLUGIN}:NoSpec", "spec"),
        ("--predictor", f"{PLUGIN}:NOT_CALLABLE", "not a forecaster class or factory"),
        ("--predictor", f"{PLUGIN}:Missing", "cannot load"),
        ("--predictor", "no_such_package.module:Forecaster", "No module named 'no_such_package'"),
        ("--intention", f"{PLUGIN}:Steady", "does not forecast intent"),
    ],
)
def test_a_broken_plug_in_is_one_line_naming_it_and_exit_2(
    flag: str, value: str, said: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    assert main([*ARGS, "--no-progress", flag, value, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("crossing-eval: error:"), err
    assert value in err[0] and __import__("re").search(said, err[0]), err[0]
    assert "Traceback" not in err[0] and not out.exists()


def test_an_installed_entry_point_is_a_predictor_name(monkeypatch: pytest.MonkeyPatch) -> None:
    import gymnasium as gym

    monkeypatch.setattr(wrappers, "installed_predictors", lambda: {"steady": f"{PLUGIN}:Steady"})
    env, used = wrap(gym.make("crossing_env/Crossing-v0", scenario="zebra_case1"), "none", "steady")
    obs, _ = env.reset(seed=0)
    present = obs["pedestrians"][:, 0] > 0.5
    assert used == ["trajectory:steady"]
    np.testing.assert_array_equal(obs["predicted_paths"][present, -1], obs["pedestrian_history"][present, -1])
    with pytest.raises(WrapperError, match="not one of"):
        wrap(gym.make("crossing_env/Crossing-v0", scenario="zebra_case1"), "none", "not-installed")


def test_a_plug_in_is_a_row_of_the_grid_beside_the_built_ins(tmp_path: Path) -> None:
    out = tmp_path / "grid"
    grid = f"predictor=cvm,{PLUGIN}:Steady"
    assert main([*ARGS, "--no-progress", "--grid", grid, "--out", str(out)]) == 0
    table = (out / "value_of_prediction.md").read_text()
    assert f"{PLUGIN}:Steady" in table and "cvm" in table
