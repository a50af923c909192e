from __future__ import annotations

import json
from pathlib import Path

import pytest

from studies import seed_table
from studies.seed_table import summary, table


def test_seed_table_reports_mean_sd_and_the_verdict() -> None:
    def run(model_ade: float) -> dict:
        res = {"s-cgru": {}, "dcvm": {}}
        for s in ("eth", "hotel", "univ", "zara1", "zara2"):
            res["s-cgru"][s] = {"k1": [model_ade, 1.0], "ped20": [model_ade / 2, 0.5], "es": [1.0, 0.0]}
            res["dcvm"][s] = {"k1": [0.50, 1.0], "ped20": [0.30, 0.5], "es": [1.0, 0.0]}
        return {"results": res}

    text, wins = table([run(0.40), run(0.42), run(0.44)], "s-cgru", "dcvm")
    assert "0.420 ± 0.020 (3)" in text and wins == 5  # 0.42 vs 0.50 at K=1, 0.21 vs 0.30 at best-of-20
    _, wins = table([run(0.30), run(0.70)], "s-cgru", "dcvm")
    assert wins == 0  # mean 0.50: no better at K=1, and the seed sd (0.28) swamps any difference
    rows = summary([run(0.40), run(0.42), run(0.44)], ["dcvm", "s-cgru"]).splitlines()
    assert rows[2].startswith("| dcvm | 0.500 / 1.000 | 0.300 / 0.500 |")  # no seed: no sd
    assert rows[3].startswith("| s-cgru | 0.420 ± 0.020 / 1.000 | 0.210 ± 0.010 / 0.500 |")


def test_seed_table_cli_names_a_model_missing_from_the_files(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    f = tmp_path / "seed0.json"
    f.write_text(json.dumps({"results": {"dcvm": {"eth": {"k1": [0.5, 1.0]}}}}))
    assert seed_table.main([str(f), "--models", "s-lstm"]) == 2
    assert "['s-lstm'] not in any file" in capsys.readouterr().err
    assert seed_table.main([str(tmp_path / "absent.json")]) == 2
