from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from studies import fov_study
from studies.fov_study import mean_ci


def test_student_t_interval() -> None:
    m, h = mean_ci([1.0, 2.0, 3.0])
    assert m == pytest.approx(2.0)
    assert h == pytest.approx(4.302653 / math.sqrt(3.0), rel=1e-5)
    assert math.isnan(mean_ci([1.0])[1])


def test_fov_table_flags_distinguishable_optima_and_refuses_bad_input(capsys: pytest.CaptureFixture) -> None:
    def runs(*vals: float) -> list[dict[str, float]]:
        return [{"seed": i, "val_ade": v} for i, v in enumerate(vals)]

    res = {
        "fovs": [60.0, 360.0],
        "runs": {
            "eth": {"60.0": runs(0.40, 0.41, 0.42), "360.0": runs(0.50, 0.51, 0.52)},
            "hotel": {"60.0": runs(0.40, 0.50, 0.45), "360.0": runs(0.42, 0.52, 0.47)},
            "univ": {"60.0": runs(0.4)},
        },
        "cvm_val_ade": {"eth": 0.447},
    }
    rows = {line.split(" | ")[0]: line for line in fov_study.to_markdown(res).splitlines()}
    assert "| 60° | no | 85° |" in rows["| eth"]  # 0.41 ± 0.025 vs 0.51 ± 0.025: distinguishable
    assert "| 60° | yes | 75° |" in rows["| hotel"]  # spread of 0.05 between seeds: not
    assert "n/a (n < 2)" in rows["| univ"]
    assert rows["| eth"].endswith("| 0.447 |") and rows["| univ"].endswith("| – |")  # CVM's val ADE
    assert fov_study.main(["--scenes", "mars"]) == 2
    assert "mars" in capsys.readouterr().err


def test_fov_study_resume_keeps_other_scenes_and_refuses_another_budget(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    val = tmp_path / "data" / "eth_ucy" / "eth" / "val"
    val.mkdir(parents=True)
    rows = [f"{t * 10}\t{p}.0\t{0.4 * t + p:.3f}\t{p:.3f}" for t in range(20) for p in (1, 2)]
    (val / "a.txt").write_text("\n".join(rows) + "\n")
    save = tmp_path / "fov.json"
    run = {"seed": 0, "val_ade": 0.5, "val_fde": 1.0, "best_epoch": 1, "wall_s": 1.0}
    study = {"epochs": 4, "train_fraction": 0.25, "fovs": [60.0], "seeds": 1}
    study["runs"] = {"eth": {"60.0": [run]}, "hotel": {"60.0": [run]}}
    save.write_text(json.dumps(study))
    before = save.read_text()
    args = [
        "--scenes",
        "eth",
        "--fovs",
        "60",
        "--seeds",
        "1",
        "--data",
        str(tmp_path / "data"),
        "--save",
        str(save),
    ]
    assert fov_study.main([*args, "--epochs", "5"]) == 2
    assert "field 'epochs' is 4 there but 5 here" in capsys.readouterr().err
    assert save.read_text() == before  # nothing lost
    other = tmp_path / "other.json"
    other.write_text("[1, 2]")
    assert fov_study.main([*args[:-1], str(other), "--epochs", "4"]) == 2
    assert "not a field-of-view study" in capsys.readouterr().err and other.read_text() == "[1, 2]"
    assert fov_study.main([*args, "--epochs", "4"]) == 0  # every run already there: nothing trains
    saved = json.loads(save.read_text())
    assert set(saved["runs"]) == {"eth", "hotel"} and saved["cvm_val_ade"]["eth"] < 1e-5  # CV is exact here
