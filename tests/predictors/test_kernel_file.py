"""The shipped S-CGRU's kernel file: the checkpoint's own arrays, used without torch, refused when stale."""

from __future__ import annotations

import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from predictors import checkpoints, trajectory_wrapper
from predictors.checkpoints import WEIGHTS_DIR, CheckpointError, load_model
from predictors.fast_inference import (
    KERNEL_ARRAYS,
    FastPredictor,
    kernel_file,
    load_kernel_file,
    save_kernel_file,
)
from predictors.trajectory_wrapper import TrajectoryPrediction
from tests.predictors.test_wrapper import FakePedEnv

SHIPPED = WEIGHTS_DIR / "s-cgru_all.pt"
REPO = Path(__file__).resolve().parents[2]


def _windows(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    start = rng.uniform(-8, 8, (n, 1, 2))
    vel = rng.uniform(-0.6, 0.6, (n, 1, 2))
    return (start + vel * np.arange(8)[None, :, None] + rng.normal(0, 0.05, (n, 8, 2))).astype(np.float32)


DERIVED_BY_BLAS = ("empty_soc",)
"""Kernel arrays computed with a matrix product when the file is written: their last bit depends on the CPU's
summation order (the file written on one machine, the test run on another differ by one float32 ulp), so
they are compared within float32 rounding; every other array is the checkpoint's own, bit for bit."""


def test_the_shipped_kernel_file_holds_the_checkpoints_arrays_bit_for_bit() -> None:
    from_torch = FastPredictor(load_model(SHIPPED))._kernel_args
    from_file = load_kernel_file(SHIPPED)
    assert from_file is not None, "the shipped kernel file is missing or stale: run save_kernel_file"
    assert len(from_file._kernel_args) == len(from_torch) == len(KERNEL_ARRAYS) + 3
    names = ("kind", *KERNEL_ARRAYS, "obs_len", "pred_len")
    for name, a, b in zip(names, from_file._kernel_args, from_torch, strict=True):
        if not isinstance(b, np.ndarray):
            assert a == b
            continue
        assert a.dtype == b.dtype and a.shape == b.shape, name
        if name in DERIVED_BY_BLAS:
            np.testing.assert_allclose(a, b, rtol=2e-7, atol=1e-7, err_msg=name)
        else:
            assert np.array_equal(a, b), name
    for n, seed in ((1, 0), (5, 1), (16, 2)):
        obs = _windows(n, seed)
        np.testing.assert_allclose(
            from_file.predict(obs), FastPredictor(load_model(SHIPPED)).predict(obs), rtol=0, atol=1e-4
        )


def test_the_wrapper_uses_the_kernel_file_and_loads_the_model_only_when_asked(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    env = TrajectoryPrediction(FakePedEnv(), model="s-cgru")
    assert env.forecaster._model is None  # no torch model built for the most-likely paths
    obs, _ = env.reset(seed=3)
    monkeypatch.setattr(trajectory_wrapper, "load_kernel_file", lambda path: None)
    reference = TrajectoryPrediction(FakePedEnv(), model="s-cgru")  # no kernel file: through torch
    assert reference.forecaster._model is not None
    ref, _ = reference.reset(seed=3)
    # The same model: equal up to the last bit of the BLAS-derived array (see DERIVED_BY_BLAS).
    np.testing.assert_allclose(obs["predicted_paths"], ref["predicted_paths"], rtol=0, atol=1e-4)
    assert env.model.config.kind == "s-cgru"  # still there on demand


def _copy_shipped(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """The shipped checkpoint and kernel file in a stand-in weights folder with its own manifest."""
    monkeypatch.setattr(checkpoints, "SHIPPED_DIR", tmp_path)
    monkeypatch.setattr(checkpoints, "MANIFEST", tmp_path / "manifest.json")
    pt = tmp_path / SHIPPED.name
    shutil.copy(SHIPPED, pt)
    shutil.copy(kernel_file(SHIPPED), kernel_file(pt))
    checkpoints.update_manifest()
    return pt


def test_a_stale_kernel_file_is_not_used(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    pt = _copy_shipped(tmp_path, monkeypatch)
    assert load_kernel_file(pt) is not None
    with np.load(kernel_file(pt), allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    arrays["source_sha256"] = np.str_("0" * 64)  # made from other bytes than this checkpoint's
    with kernel_file(pt).open("wb") as fh:
        np.savez(fh, **arrays)
    checkpoints.update_manifest()
    assert load_kernel_file(pt) is None  # the caller falls back to the checkpoint


def test_a_kernel_file_that_differs_from_the_manifest_is_refused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    pt = _copy_shipped(tmp_path, monkeypatch)
    with np.load(kernel_file(pt), allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    arrays["w_head"] = arrays["w_head"] * np.float32(1.01)
    with kernel_file(pt).open("wb") as fh:
        np.savez(fh, **arrays)
    with pytest.raises(CheckpointError, match="manifest"):
        load_kernel_file(pt)


def test_save_kernel_file_round_trips(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    pt = _copy_shipped(tmp_path, monkeypatch)
    kernel_file(pt).unlink()
    assert load_kernel_file(pt) is None
    assert save_kernel_file(pt) == kernel_file(pt)
    checkpoints.update_manifest()
    fast = load_kernel_file(pt)
    assert fast is not None
    obs = _windows(6, 4)
    assert np.array_equal(fast.predict(obs), FastPredictor(load_model(pt)).predict(obs))


COMPILE_ASIDE = """
from predictors.fast_inference import kernel_is_cached
from predictors.trajectory_wrapper import TrajectoryPrediction
from tests.predictors.test_wrapper import FakePedEnv
wrapper = TrajectoryPrediction(FakePedEnv(), model="s-cgru")
assert not kernel_is_cached(), "the cache folder was not empty"
compile_kernel = wrapper.kernel_to_compile()
assert compile_kernel is not None, "nothing to compile on an empty cache"
compile_kernel()
assert kernel_is_cached(), "the compiled kernel is not in the cache"
assert wrapper.kernel_to_compile() is None, "a cached kernel is offered for compiling again"
"""


def test_the_predictor_kernel_is_offered_for_compiling_only_while_it_is_not_cached(
    run_with_empty_numba_cache: Callable[[str], None],
) -> None:
    """`crossing_eval.tasks.warm_up` compiles it aside on a fresh install, never again once cached."""
    run_with_empty_numba_cache(COMPILE_ASIDE)


def test_the_cvm_has_no_kernel_to_compile() -> None:
    assert TrajectoryPrediction(FakePedEnv(), model="cvm").kernel_to_compile() is None
