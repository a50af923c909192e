from __future__ import annotations

from pathlib import Path

import pytest

from tests.predictors.test_train import _write_scene


@pytest.fixture
def data_root(tmp_path: Path) -> Path:
    """A tiny ETH/UCY-shaped data root: scene ``eth`` with one synthetic file per split."""
    root = tmp_path / "data"
    for split, seed in (("train", 0), ("val", 1), ("test", 2)):
        _write_scene(root / "eth_ucy" / "eth" / split, f"a_{split}.txt", seed)
    return root
