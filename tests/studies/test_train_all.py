from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from predictors.checkpoints import checkpoint_meta, load_model
from studies import train_all
from studies.seed_table import budget_table, val_table


def _train_all_args(data_root: Path, out: Path, logs: Path) -> list[str]:
    """One-epoch `studies.train_all` arguments on the tiny data root."""
    return ["--data", str(data_root), "--out-dir", str(out), "--log-dir", str(logs), "--epochs", "1"]


def test_train_all_runs_in_parallel_and_reports_a_failed_run(
    data_root: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    out, logs = tmp_path / "w", tmp_path / "logs"
    args = [*_train_all_args(data_root, out, logs), "--jobs", "2"]
    # hotel has no data in this root: that run fails, the other two still finish
    assert train_all.main([*args, "--models", "s-cgru,lstm", "--scenes", "eth,hotel"]) == 1
    printed = capsys.readouterr().out
    for name in ("s-cgru_eth", "lstm_eth"):
        assert load_model(out / f"{name}.pt").config.kind == name.split("_")[0]
        assert "epoch 1: train nll" in (logs / f"{name}.log").read_text()
        assert f"{name}.pt: epochs 1" in printed
    assert "s-cgru_hotel: FAILED" in printed and "lstm_hotel: FAILED" in printed
    assert not (out / "s-cgru_hotel.pt").exists()
    assert "Traceback" in (logs / "s-cgru_hotel.log").read_text()  # the failed run's log says why
    assert train_all.main([*args, "--models", "transformer"]) == 2
    assert "transformer" in capsys.readouterr().err


def test_train_all_repeats_runs_per_seed(data_root: Path, tmp_path: Path) -> None:
    out = tmp_path / "w"
    args = _train_all_args(data_root, out, tmp_path / "logs")
    assert train_all.main([*args, "--models", "lstm", "--scenes", "eth", "--seeds", "3,4"]) == 0
    assert [checkpoint_meta(out / f"seed{k}" / "lstm_eth.pt")["seed"] for k in (3, 4)] == [3, 4]
    row = budget_table(out).splitlines()[2]
    assert row.startswith("| lstm | 2 | 0 | 1–1 | 1–1 |")  # two one-epoch runs, neither stopped early
    val = [checkpoint_meta(out / f"seed{k}" / "lstm_eth.pt")["val_ade"] for k in (3, 4)]
    row = val_table(out).splitlines()[2]
    assert row == f"| lstm | eth | {np.mean(val):.3f} ± {np.std(val, ddof=1):.3f} | 2 |"
    assert train_all.main([*args, "--seeds", "one"]) == 2
