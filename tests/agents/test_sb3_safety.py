"""Model files cannot run code: crafted SB3 zips and statistics files load safely or fail clearly."""

from __future__ import annotations

import base64
import io
import json
import pickle
import zipfile
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")
from agents.sb3 import ModelFileError, SB3Policy, stats_candidates


class _Payload:
    """Unpickling this creates the file `sentinel`: the proof that a load ran code."""

    def __init__(self, sentinel: Path) -> None:
        self.sentinel = sentinel

    def __reduce__(self) -> tuple[object, tuple[str]]:
        return (exec, (f"open({str(self.sentinel)!r}, 'w').close()",))


def _copy_zip(src: Path, dst: Path, replace: dict[str, bytes]) -> Path:
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for name in zin.namelist():
            zout.writestr(name, replace.get(name, zin.read(name)))
    return dst


@pytest.fixture
def sentinel(tmp_path: Path) -> Path:
    return tmp_path / "code-ran"


def _evil_data(model: Path, sentinel: Path) -> bytes:
    with zipfile.ZipFile(model) as z:
        data = json.loads(z.read("data"))
    blob = base64.b64encode(pickle.dumps(_Payload(sentinel))).decode()
    for key in [k for k, v in data.items() if isinstance(v, dict) and ":serialized:" in v]:
        data[key][":serialized:"] = blob  # every pickled entry now runs code when unpickled
    return json.dumps(data).encode()


def _fresh(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(SB3Policy, "_CACHE", {})


def test_crafted_pickled_entries_in_a_zip_are_never_unpickled(
    sb3_zip, tmp_path, sentinel, monkeypatch
) -> None:
    _fresh(monkeypatch)
    evil = _copy_zip(sb3_zip, tmp_path / "evil.zip", {"data": _evil_data(sb3_zip, sentinel)})
    pol = SB3Policy(evil)  # loads: every pickled entry is replaced, none is unpickled
    assert not sentinel.exists()
    original = SB3Policy(sb3_zip)
    obs = {k: np.zeros(s.shape, np.float32) for k, s in original.model.observation_space.spaces.items()}
    assert np.array_equal(
        pol.model.predict(obs, deterministic=True)[0], original.model.predict(obs, deterministic=True)[0]
    )


def test_crafted_weights_in_a_zip_fail_clearly(sb3_zip, tmp_path, sentinel, monkeypatch) -> None:
    import torch

    _fresh(monkeypatch)
    buf = io.BytesIO()
    torch.save({"x": _Payload(sentinel)}, buf)
    evil = _copy_zip(sb3_zip, tmp_path / "evil.zip", {"policy.pth": buf.getvalue()})
    with pytest.raises(ModelFileError, match=r"evil\.zip: cannot load"):
        SB3Policy(evil)
    assert not sentinel.exists()


def test_not_a_model_is_a_clear_error(tmp_path, monkeypatch) -> None:
    _fresh(monkeypatch)
    bad = tmp_path / "bad.zip"
    bad.write_text("not a zip")
    with pytest.raises(ModelFileError, match=r"bad\.zip: not a Stable-Baselines3 model"):
        SB3Policy(bad)


@pytest.mark.parametrize("name", ["model.vecnormalize.pkl", "vec_normalize.pkl"])
def test_pickled_statistics_are_never_loaded(sb3_zip, tmp_path, sentinel, monkeypatch, name: str) -> None:
    _fresh(monkeypatch)
    model = _copy_zip(sb3_zip, tmp_path / "model.zip", {})
    (tmp_path / name).write_bytes(pickle.dumps(_Payload(sentinel)))
    with pytest.raises(ModelFileError, match=r"pickled statistics are never loaded"):
        SB3Policy(model)
    assert not sentinel.exists()


def test_crafted_npz_statistics_fail_clearly(sb3_zip, tmp_path, sentinel, monkeypatch) -> None:
    _fresh(monkeypatch)
    model = _copy_zip(sb3_zip, tmp_path / "model.zip", {})
    np.savez(
        stats_candidates(model)[0],
        norm_obs=np.array(True),
        norm_obs_keys=np.array([_Payload(sentinel)], dtype=object),
    )
    with pytest.raises(ModelFileError, match=r"model\.vecnormalize\.npz: not normalisation statistics"):
        SB3Policy(model)
    assert not sentinel.exists()


@pytest.mark.parametrize("name", ["model.vecnormalize.npz", "vec_normalize.npz"])
def test_both_statistics_names_are_found_and_reported(sb3_zip, tmp_path, monkeypatch, name: str) -> None:
    _fresh(monkeypatch)
    model = _copy_zip(sb3_zip, tmp_path / "model.zip", {})
    (tmp_path / name).write_bytes(stats_candidates(sb3_zip)[0].read_bytes())
    pol = SB3Policy(model)
    assert pol.stats is not None and pol.stats_file == tmp_path / name
