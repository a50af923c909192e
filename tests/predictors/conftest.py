"""Fixtures shared by the predictor tests."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from predictors import checkpoints
from predictors.checkpoints import WEIGHTS_DIR


@pytest.fixture
def shipped_copy(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A private 'shipped' folder holding one real checkpoint and its manifest."""
    folder = tmp_path / "weights"
    folder.mkdir()
    path = folder / "s-cgru_all.pt"
    shutil.copy(WEIGHTS_DIR / "s-cgru_all.pt", path)
    monkeypatch.setattr(checkpoints, "SHIPPED_DIR", folder.resolve())
    monkeypatch.setattr(checkpoints, "MANIFEST", folder / "manifest.json")
    checkpoints.update_manifest()
    return path
