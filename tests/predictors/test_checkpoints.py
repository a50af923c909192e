"""Checked weights (issue 16): manifest sums, non-finite and absurd weights, no silent overwrite."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
import torch

from predictors import checkpoints
from predictors.checkpoints import WEIGHTS_DIR, CheckpointError, load_model, save_checkpoint, sha256_file
from predictors.models import SocialRecurrent, default_config
from predictors.train import TrainConfig, main, output_path


def test_every_shipped_checkpoint_matches_the_manifest():
    manifest = json.loads((WEIGHTS_DIR / "manifest.json").read_text())
    assert set(manifest) == {p.name for p in checkpoints.shipped_files()}  # checkpoints and kernel files
    assert any(name.endswith(".kernel.npz") for name in manifest)
    for path in checkpoints.shipped_files():
        checkpoints.verify_shipped(path)


def test_flipped_bytes_in_a_shipped_checkpoint_are_refused(shipped_copy: Path):
    load_model(shipped_copy)  # intact: loads
    data = bytearray(shipped_copy.read_bytes())
    middle = len(data) // 2
    data[middle : middle + 64] = bytes(b ^ 0xFF for b in data[middle : middle + 64])
    shipped_copy.write_bytes(bytes(data))
    with pytest.raises(CheckpointError, match="does not match the manifest"):
        load_model(shipped_copy)


def test_an_unlisted_file_in_the_shipped_folder_is_refused(shipped_copy: Path):
    extra = shipped_copy.with_name("s-gru_all.pt")
    shutil.copy(shipped_copy, extra)
    with pytest.raises(CheckpointError, match=r"not in manifest\.json"):
        load_model(extra)


def _model() -> SocialRecurrent:
    torch.manual_seed(0)
    return SocialRecurrent(default_config("s-gru"))


@pytest.mark.parametrize(("value", "needle"), [(float("nan"), "non-finite"), (6e4, "magnitude 6")])
def test_non_finite_or_absurd_weights_are_refused_in_any_checkpoint(tmp_path: Path, value, needle):
    model = _model()
    with torch.no_grad():
        next(iter(model.parameters())).fill_(value)
    path = tmp_path / "bad.pt"
    save_checkpoint(path, model, {})
    with pytest.raises(CheckpointError, match=needle):
        load_model(path)
    good = tmp_path / "good.pt"
    save_checkpoint(good, _model(), {})
    assert isinstance(load_model(good), SocialRecurrent)


def test_code_running_pickles_are_still_refused(tmp_path: Path):
    class Boom:
        def __reduce__(self):
            return (print, ("pwned",))

    path = tmp_path / "evil.pt"
    torch.save({"x": Boom()}, path)
    with pytest.raises(ValueError, match="not a readable torch checkpoint"):
        load_model(path)


def test_training_writes_under_runs_and_never_over_a_shipped_file(tmp_path: Path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert output_path(TrainConfig(model="s-gru", scene="eth")) == Path("runs/s-gru_eth.pt")
    shipped = WEIGHTS_DIR / "s-cgru_all.pt"
    before = sha256_file(shipped)
    with pytest.raises(ValueError, match="--force"):
        output_path(TrainConfig(out=str(shipped)))
    assert output_path(TrainConfig(out=str(shipped), force=True)) == shipped
    assert main(["--out", str(shipped), "--epochs", "1"]) == 2
    assert "shipped checkpoint" in capsys.readouterr().err
    assert sha256_file(shipped) == before


def test_the_runtime_loaders_share_the_checkpoint_module() -> None:
    """Model loading lives in `predictors.checkpoints`; the trainer and the wrapper use that one function."""
    from predictors import train, trajectory_wrapper

    assert train.load_model is load_model and trajectory_wrapper.load_model is load_model
    assert train.WEIGHTS_DIR == trajectory_wrapper.WEIGHTS_DIR == WEIGHTS_DIR == checkpoints.SHIPPED_DIR


def test_install_refuses_a_bad_file_and_a_file_from_another_folder(tmp_path: Path) -> None:
    target = tmp_path / "m.pt"
    save_checkpoint(target, _model(), {"v": 1})
    before = target.read_bytes()
    bad = checkpoints.partial_path(target)
    bad.write_bytes(b"half a checkpoint")
    with pytest.raises(ValueError, match="not a readable torch checkpoint"):
        checkpoints.install_checkpoint(bad, target)
    assert target.read_bytes() == before and bad.exists()
    elsewhere = tmp_path / "other" / "m.pt"
    save_checkpoint(elsewhere, _model(), {})
    with pytest.raises(ValueError, match="must be in the folder"):
        checkpoints.install_checkpoint(elsewhere, target)
    assert target.read_bytes() == before
