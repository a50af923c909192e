"""Shared fixtures: headless pygame, the data folder."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

REPO = Path(__file__).resolve().parents[1]


def data_root() -> Path:
    """`CROSSING_DATA` or `<repo>/../shared/data`."""
    return Path(os.environ.get("CROSSING_DATA", REPO.parent / "shared" / "data"))


@pytest.fixture
def eth_ucy_root() -> Path:
    root = data_root() / "eth_ucy"
    if not root.is_dir():
        pytest.skip(f"ETH/UCY data not found at {root} (set CROSSING_DATA)")
    return root
