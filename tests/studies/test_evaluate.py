from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch

from predictors.metrics import METRICS
from studies import evaluate
from tests.predictors.test_train import _write_scene


def _res(weights: str) -> dict[str, object]:
    cell = {"weights": weights, **{m: [0.5, 1.0] for m in METRICS}}
    return {"results": {"s-cgru": {"sdd": cell}}, "counts": {"sdd": [1, 2]}}


def test_dagger_footnote_only_when_a_cell_carries_it() -> None:
    assert "†" not in evaluate.to_markdown(_res("s-cgru_sdd.pt"))
    md = evaluate.to_markdown(_res("s-cgru_all.pt"))
    assert "0.50/1.00†" in md and "† SDD evaluated" in md


def test_unknown_variant_and_every_model_name_parse() -> None:
    assert "s-cgru+corr" in evaluate.ALL_MODELS and "dcvm" in evaluate.ALL_MODELS
    assert "sf-qlb" in evaluate.ALL_MODELS
    assert "k1-ref" in evaluate.ALL_MODELS and "s-cgru+persist" in evaluate.ALL_MODELS


def test_k1_reference_is_a_point_forecast_tuned_on_val(data_root: Path) -> None:
    pred, label = evaluate.make_predictor("k1-ref", "eth", Path("unused"), data_root)
    assert pred is not None and label == "cvm"  # synthetic walkers keep their speed: no damping helps
    w = evaluate.load_split(data_root, "eth", "test")
    obs = torch.as_tensor(w.traj[:, :8])
    sse = torch.as_tensor(w.seq_start_end)
    ml, samples = pred(obs, sse, 4, torch.Generator().manual_seed(0))
    torch.testing.assert_close(samples, ml[None].expand(4, -1, -1, -1))
    with pytest.raises(ValueError, match="data root"):
        evaluate.make_predictor("k1-ref", "eth", Path("unused"))


def test_evaluate_cli_json_on_synthetic_data(data_root: Path, capsys: pytest.CaptureFixture) -> None:
    rc = evaluate.main(
        ["--data", str(data_root), "--scenes", "eth", "--models", "cvm,cvm-s,kalman", "--json"]
    )
    assert rc == 0
    res = json.loads(capsys.readouterr().out)
    eth = res["results"]["cvm"]["eth"]
    # synthetic walkers move at constant velocity: CVM is exact up to the 1 mm rounding of the files
    assert eth["k1"][0] < 1e-2 and eth["ped20"][1] < 1e-2
    cs = res["results"]["cvm-s"]["eth"]
    assert cs["ped20"][0] <= cs["scene20"][0] + 1e-9  # per-pedestrian min can only be smaller
    assert evaluate.main(["--data", str(data_root), "--scenes", "mars"]) == 2


def test_evaluating_a_scene_alone_gives_the_full_runs_numbers(
    data_root: Path, capsys: pytest.CaptureFixture
) -> None:
    """Sample seeds follow the scene, not its place in ``--scenes`` (so runs can be split and merged)."""
    _write_scene(data_root / "eth_ucy" / "hotel" / "test", "h_test.txt", seed=5)
    runs = []
    for scenes in ("eth,hotel", "hotel"):
        args = ["--data", str(data_root), "--scenes", scenes, "--models", "cvm-s,kalman", "--json"]
        assert evaluate.main(args) == 0
        runs.append(json.loads(capsys.readouterr().out)["results"])
    for model in ("cvm-s", "kalman"):
        assert runs[0][model]["hotel"] == runs[1][model]["hotel"]
