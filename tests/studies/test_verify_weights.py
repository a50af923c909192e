from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from predictors import checkpoints
from predictors.checkpoints import WEIGHTS_DIR
from studies import verify_weights


def test_every_shipped_checkpoint_verifies(capsys: pytest.CaptureFixture) -> None:
    assert verify_weights.main([]) == 0
    assert f"{len(checkpoints.shipped_files())} ok, 0 failed" in capsys.readouterr().out  # with kernel files


def test_a_changed_file_fails_and_update_records_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    folder = tmp_path / "weights"
    folder.mkdir()
    shutil.copy(WEIGHTS_DIR / "s-cgru_all.pt", folder / "s-cgru_all.pt")
    monkeypatch.setattr(checkpoints, "SHIPPED_DIR", folder.resolve())
    monkeypatch.setattr(checkpoints, "MANIFEST", folder / "manifest.json")
    assert verify_weights.main([]) == 1  # not in the (missing) manifest
    assert "not in manifest.json" in capsys.readouterr().err
    assert verify_weights.main(["--update"]) == 0
    assert verify_weights.main([]) == 0
    assert "1 ok, 0 failed" in capsys.readouterr().out
