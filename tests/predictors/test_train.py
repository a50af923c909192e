from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from predictors import checkpoints, train
from predictors.checkpoints import WEIGHTS_DIR, checkpoint_meta, load_model, save_checkpoint, sha256_file
from predictors.models import SocialRecurrent, default_config
from predictors.train import main


def _write_scene(folder: Path, name: str, seed: int, frames: int = 40) -> None:
    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True, exist_ok=True)
    lines = []
    starts = rng.uniform(0, 10, (4, 2))
    vel = rng.normal(0, 0.4, (4, 2))
    for t in range(frames):
        for p in range(4):
            x, y = starts[p] + vel[p] * t
            lines.append(f"{t * 10}\t{p + 1}.0\t{x:.3f}\t{y:.3f}")
    (folder / name).write_text("\n".join(lines) + "\n")


@pytest.fixture
def data_root(tmp_path: Path) -> Path:
    root = tmp_path / "data"
    for split, seed in (("train", 0), ("val", 1), ("test", 2)):
        _write_scene(root / "eth_ucy" / "eth" / split, f"a_{split}.txt", seed)
    return root


def test_train_cli_writes_loadable_checkpoint(data_root: Path, tmp_path: Path) -> None:
    out = tmp_path / "w" / "m.pt"
    rc = main(
        ["--model", "s-gru", "--scene", "eth", "--epochs", "2", "--data", str(data_root), "--out", str(out)]
    )
    assert rc == 0
    model = load_model(out)
    assert model.config.kind == "s-gru"
    meta = checkpoint_meta(out)
    assert meta["scene"] == "eth" and meta["epochs_run"] == 2 and len(meta["history"]) == 2
    assert meta["best_epoch"] in (1, 2)
    assert [f.name for f in out.parent.iterdir()] == ["m.pt"]  # no temporary file left behind


def test_train_cli_bad_input_exits_nonzero(
    data_root: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    assert main(["--model", "transformer", "--data", str(data_root), "--out", str(tmp_path / "x.pt")]) == 2
    assert "transformer" in capsys.readouterr().err
    assert main(["--scene", "hotel", "--data", str(data_root), "--out", str(tmp_path / "x.pt")]) == 2
    assert "hotel" in capsys.readouterr().err


def test_train_rotation_augmentation_can_be_switched_off(
    data_root: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    base = ["--model", "lstm", "--scene", "eth", "--epochs", "1", "--data", str(data_root)]
    assert main([*base, "--out", str(tmp_path / "r1.pt")]) == 0
    assert main([*base, "--rotate", "0", "--out", str(tmp_path / "r0.pt")]) == 0
    assert checkpoint_meta(tmp_path / "r1.pt")["rotate"] == 1
    assert checkpoint_meta(tmp_path / "r0.pt")["rotate"] == 0
    w1 = load_model(tmp_path / "r1.pt").state_dict()
    w0 = load_model(tmp_path / "r0.pt").state_dict()
    assert any(not torch.equal(w1[k], w0[k]) for k in w1)  # same seed, different batches seen
    capsys.readouterr()
    assert main([*base, "--rotate", "2", "--out", str(tmp_path / "bad.pt")]) == 2
    assert "--rotate must be 0 or 1, got 2" in capsys.readouterr().err
    assert not (tmp_path / "bad.pt").exists()


def test_checkpoint_roundtrip_and_clear_errors(tmp_path: Path) -> None:
    m = SocialRecurrent(default_config("s-cgru"))
    path = tmp_path / "ok.pt"
    save_checkpoint(path, m, {"note": "x"})
    loaded = load_model(path)
    for (k, a), (_, b) in zip(m.state_dict().items(), loaded.state_dict().items(), strict=True):
        torch.testing.assert_close(a.half().float(), b, msg=k)

    corrupt = tmp_path / "corrupt.pt"
    corrupt.write_bytes(path.read_bytes()[:1000])
    with pytest.raises(ValueError, match=r"corrupt\.pt"):
        load_model(corrupt)

    foreign = tmp_path / "foreign.pt"
    torch.save({"weights": torch.zeros(3)}, foreign)
    with pytest.raises(ValueError, match=r"foreign\.pt.*format"):
        load_model(foreign)

    pickled = tmp_path / "pickled.pt"
    torch.save(m, pickled)  # a whole pickled module is refused by weights_only=True
    with pytest.raises(ValueError, match=r"pickled\.pt"):
        load_model(pickled)

    wrong = tmp_path / "wrong.pt"
    payload = torch.load(path, weights_only=True)
    payload["config"] = default_config("s-lstm").to_dict()
    torch.save(payload, wrong)
    with pytest.raises(ValueError, match=r"wrong\.pt.*s-lstm"):
        load_model(wrong)

    with pytest.raises(FileNotFoundError, match=r"nope\.pt"):
        load_model(tmp_path / "nope.pt")


def test_shipped_weights_load_and_are_small() -> None:
    files = sorted(WEIGHTS_DIR.glob("*.pt"))
    if not files:
        pytest.skip("no shipped weights yet")
    assert (WEIGHTS_DIR / "s-cgru_all.pt").is_file()
    assert sum(f.stat().st_size for f in files) < 10 * 2**20
    for f in files:
        assert f.stat().st_size < 600 * 2**10, f
        load_model(f)


class _RunsCode:
    """A pickle payload that would create a file when unpickled by a permissive loader."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (Path.touch, (self.marker,))


def test_checkpoint_that_tries_to_run_code_is_refused(tmp_path: Path) -> None:
    marker = tmp_path / "code-ran"
    evil = tmp_path / "evil.pt"
    torch.save({"format": "x", "payload": _RunsCode(marker)}, evil)
    with pytest.raises(ValueError, match=r"evil\.pt"):
        load_model(evil)
    assert not marker.exists()


def test_train_stops_early_without_val_progress(data_root: Path, tmp_path: Path) -> None:
    """With patience 1, a run stops at the first epoch that does not improve the val ADE."""
    out = tmp_path / "m.pt"
    args = [
        "--model",
        "lstm",
        "--scene",
        "eth",
        "--epochs",
        "30",
        "--data",
        str(data_root),
        "--out",
        str(out),
    ]
    assert main([*args, "--patience", "1", "--lr-plateau", "1", "--lr", "0.05"]) == 0
    meta = checkpoint_meta(out)
    vals = [h["val_ade"] for h in meta["history"]]
    assert meta["epochs_run"] < 30
    assert meta["epochs_run"] == meta["best_epoch"] + 1  # stopped right after the first non-improvement
    assert min(vals[:-1]) <= vals[-1]
    assert meta["patience"] == 1 and meta["lr_plateau"] == 1


def _force_args(data_root: Path, out: Path) -> list[str]:
    return ["--model", "lstm", "--scene", "eth", "--epochs", "3", "--data", str(data_root), "--out", str(out)]


@pytest.mark.parametrize("error", [RuntimeError("disk on fire"), KeyboardInterrupt()])
def test_force_over_a_shipped_checkpoint_that_fails_midway_changes_nothing(
    data_root: Path, shipped_copy: Path, monkeypatch: pytest.MonkeyPatch, error: BaseException
) -> None:
    """Issue 25: `crossing-train --force` used to write each epoch's best straight over the shipped file."""
    folder = shipped_copy.parent
    before = {f.name: f.read_bytes() for f in folder.iterdir()}
    real, calls = train.most_likely_ade, []

    def fail_in_epoch_two(*args, **kwargs):
        calls.append(1)
        if len(calls) == 2:  # epoch 1's checkpoint has been written by now
            raise error
        return real(*args, **kwargs)

    monkeypatch.setattr(train, "most_likely_ade", fail_in_epoch_two)
    with pytest.raises(type(error)):
        main([*_force_args(data_root, shipped_copy), "--force"])
    assert len(calls) == 2
    assert {f.name: f.read_bytes() for f in folder.iterdir()} == before  # file, manifest, nothing else
    load_model(shipped_copy)  # still matches its manifest entry


def test_force_over_a_shipped_checkpoint_that_fails_while_installing_changes_nothing(
    data_root: Path, shipped_copy: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A manifest that cannot be rewritten after the replace: the previous file is put back."""
    folder = shipped_copy.parent
    before = {f.name: f.read_bytes() for f in folder.iterdir()}

    def no_manifest(names=None):
        raise OSError("read-only manifest")

    monkeypatch.setattr(checkpoints, "update_manifest", no_manifest)
    with pytest.raises(OSError, match="read-only manifest"):
        main([*_force_args(data_root, shipped_copy), "--force"])
    assert {f.name: f.read_bytes() for f in folder.iterdir()} == before
    load_model(shipped_copy)


def test_force_replaces_a_shipped_checkpoint_and_its_manifest_entry(
    data_root: Path, shipped_copy: Path, capsys: pytest.CaptureFixture
) -> None:
    old_sum = sha256_file(shipped_copy)
    assert main(_force_args(data_root, shipped_copy)) == 2  # without --force: refused
    assert "shipped checkpoint" in capsys.readouterr().err and sha256_file(shipped_copy) == old_sum
    assert main([*_force_args(data_root, shipped_copy), "--force"]) == 0
    assert sorted(f.name for f in shipped_copy.parent.iterdir()) == ["manifest.json", "s-cgru_all.pt"]
    assert checkpoints.read_manifest() == {"s-cgru_all.pt": sha256_file(shipped_copy)}
    assert sha256_file(shipped_copy) != old_sum
    model = load_model(shipped_copy)  # passes the manifest check
    assert model.config.kind == "lstm" and checkpoint_meta(shipped_copy)["epochs_run"] == 3


def test_a_run_without_a_finite_val_ade_writes_nothing(
    data_root: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    out = tmp_path / "w" / "m.pt"
    out.parent.mkdir()
    out.write_bytes(b"previous")
    monkeypatch.setattr(train, "most_likely_ade", lambda *a, **k: (float("nan"), float("nan")))
    assert main(_force_args(data_root, out)) == 2
    assert "no epoch gave a finite val ADE" in capsys.readouterr().err
    assert [f.name for f in out.parent.iterdir()] == ["m.pt"] and out.read_bytes() == b"previous"
