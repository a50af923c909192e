from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
import torch

from predictors import evaluate
from predictors.fov_study import mean_ci


def test_energy_score_of_a_point_is_its_distance_and_a_pair_matches_the_formula() -> None:
    fut = torch.zeros(1, 12, 2)
    point = torch.ones(3, 1, 12, 2)
    assert float(evaluate.energy_score(point, fut)[0]) == pytest.approx(math.sqrt(24.0))
    pair = torch.stack([torch.ones(1, 12, 2), -torch.ones(1, 12, 2)])
    # E|X - y| = sqrt(24); E|X - X'| over the 4 ordered pairs = 2 * sqrt(96) / 4
    want = math.sqrt(24.0) - 0.5 * (2 * math.sqrt(96.0) / 4)
    assert float(evaluate.energy_score(pair, fut)[0]) == pytest.approx(want, rel=1e-5)


def test_energy_score_prefers_the_true_spread_to_an_inflated_one() -> None:
    g = torch.Generator().manual_seed(0)
    fut = torch.randn(400, 12, 2, generator=g)
    right = torch.randn(20, 400, 12, 2, generator=g)
    wide = 3.0 * torch.randn(20, 400, 12, 2, generator=g)
    assert float(evaluate.energy_score(right, fut).mean()) < float(evaluate.energy_score(wide, fut).mean())


def _res(weights: str) -> dict[str, object]:
    cell = {"weights": weights, **{m: [0.5, 1.0] for m in evaluate.METRICS}}
    return {"results": {"s-cgru": {"sdd": cell}}, "counts": {"sdd": [1, 2]}}


def test_dagger_footnote_only_when_a_cell_carries_it() -> None:
    assert "†" not in evaluate.to_markdown(_res("s-cgru_sdd.pt"))
    md = evaluate.to_markdown(_res("s-cgru_all.pt"))
    assert "0.50/1.00†" in md and "† SDD evaluated" in md


def test_unknown_variant_and_every_model_name_parse() -> None:
    assert "s-cgru+corr" in evaluate.ALL_MODELS and "dcvm" in evaluate.ALL_MODELS
    assert "sf-qlb" in evaluate.ALL_MODELS


def test_student_t_interval() -> None:
    m, h = mean_ci([1.0, 2.0, 3.0])
    assert m == pytest.approx(2.0)
    assert h == pytest.approx(4.302653 / math.sqrt(3.0), rel=1e-5)
    assert math.isnan(mean_ci([1.0])[1])


def test_simulated_windows_follow_the_sgan_filter() -> None:
    import numpy as np

    from predictors.sim_transfer import windows_from_tracks

    # a walks frames 0..24, b frames 3..22, c only frames 0..10: windows need 20 frames of >= 2 pedestrians
    tracks = {
        1: {f: np.array([0.1 * f, 0.0]) for f in range(25)},
        2: {f: np.array([0.0, 0.1 * f]) for f in range(3, 23)},
        3: {f: np.array([1.0, 1.0]) for f in range(11)},
    }
    w = windows_from_tracks(tracks)
    assert w.num_windows == 1 and w.num_peds == 2  # only the window starting at frame 3
    assert np.allclose(w.traj[0, :, 0], 0.1 * np.arange(3, 23), atol=1e-6)
    assert windows_from_tracks({}).num_windows == 0


def test_fov_table_flags_distinguishable_optima_and_refuses_bad_input(capsys: pytest.CaptureFixture) -> None:
    from predictors import fov_study

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
    from predictors import fov_study

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
