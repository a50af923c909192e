"""The predictor benchmark script runs, and its shipped-checkpoint timing covers what it claims."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from predictors.checkpoints import WEIGHTS_DIR
from predictors.data import SCENES, default_data_root

ROOT = Path(__file__).resolve().parents[2]
DATA = default_data_root()


def test_script_named_like_the_package_still_imports_the_package() -> None:
    """``python benchmarks/predictors.py`` puts ``benchmarks/`` first on ``sys.path``; the script must
    not shadow the ``predictors`` package it measures."""
    done = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "predictors.py"), "--help"],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert "--batches" in done.stdout


def test_sibling_scripts_still_import_the_package() -> None:
    """A script run as ``python benchmarks/<name>.py`` has ``benchmarks/`` first on ``sys.path``; its
    ``import predictors.qlb`` (through crossing_env) must reach the package, not the benchmark."""
    code = (
        "import sys; sys.path.insert(0, 'benchmarks'); import predictors.qlb, predictors; "
        "print(predictors.__file__); print(predictors.qlb.__name__)"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120, check=False
    )
    assert done.returncode == 0, done.stderr
    first, second = done.stdout.split()
    assert Path(first) == ROOT / "predictors" / "__init__.py" and second == "predictors.qlb"


@pytest.mark.skipif(not (DATA / "eth_ucy").is_dir(), reason=f"shared data not found at {DATA}")
@pytest.mark.skipif(not (WEIGHTS_DIR / "s-cgru_eth.pt").is_file(), reason="shipped weights not built")
def test_shipped_latency_times_every_model_on_every_test_scene() -> None:
    from benchmarks.predictors import SHIPPED_KINDS, shipped_latency

    res = shipped_latency(DATA, per_scene=2, rounds=1)
    assert res is not None and list(res) == list(SCENES)
    for scene, r in res.items():
        assert r["batches"] == min(2, r["of"]) and 2 <= r["peds"] <= 256, scene
        times = r["times"]
        assert set(times) == set(SHIPPED_KINDS)
        assert all(len(v) == r["batches"] and min(v) > 0.0 for v in times.values())
