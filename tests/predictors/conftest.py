"""Fixtures shared by the predictor tests."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from collections.abc import Callable
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


@pytest.fixture
def run_with_empty_numba_cache(tmp_path: Path) -> Callable[[str], None]:
    """Runs Python `code` in a fresh process whose numba cache folder is empty; fails on a non-zero exit."""

    def run(code: str) -> None:
        env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba"))
        repo = Path(__file__).resolve().parents[2]
        proc = subprocess.run([sys.executable, "-c", code], env=env, cwd=repo, capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr[-2000:]

    return run
