from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from predictors import evaluate
from predictors.models import SocialRecurrent, default_config
from predictors.train import WEIGHTS_DIR, checkpoint_meta, load_model, main, save_checkpoint


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
    assert not list(out.parent.glob("*.tmp"))


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


def _train_all_args(data_root: Path, out: Path, logs: Path) -> list[str]:
    """One-epoch `predictors.train_all` arguments on the tiny data root."""
    return ["--data", str(data_root), "--out-dir", str(out), "--log-dir", str(logs), "--epochs", "1"]


def test_train_all_runs_in_parallel_and_reports_a_failed_run(
    data_root: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    from predictors import train_all

    out, logs = tmp_path / "w", tmp_path / "logs"
    args = [*_train_all_args(data_root, out, logs), "--jobs", "2"]
    # hotel has no data in this root: that run fails, the other two still finish
    assert train_all.main([*args, "--models", "s-cgru,lstm", "--scenes", "eth,hotel"]) == 1
    printed = capsys.readouterr().out
    for name in ("s-cgru_eth", "lstm_eth"):
        assert load_model(out / f"{name}.pt").config.kind == name.split("_")[0]
        assert "epoch 1: train nll" in (logs / f"{name}.log").read_text()
        assert f"{name}.pt: epochs 1" in printed
    assert "s-cgru_hotel: FAILED" in printed and "lstm_hotel: FAILED" in printed
    assert not (out / "s-cgru_hotel.pt").exists()
    assert "Traceback" in (logs / "s-cgru_hotel.log").read_text()  # the failed run's log says why
    assert train_all.main([*args, "--models", "transformer"]) == 2
    assert "transformer" in capsys.readouterr().err


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


def test_scene_min_matches_brute_force() -> None:
    g = torch.Generator().manual_seed(0)
    err = torch.rand(5, 7, generator=g)
    sse = torch.tensor([[0, 3], [3, 4], [4, 7]])
    got = evaluate.scene_min(err, sse)
    want = torch.stack([err[:, s:e].sum(1).min() for s, e in sse.tolist()])
    torch.testing.assert_close(got, want)


def test_evaluate_cli_json_on_synthetic_data(data_root: Path, capsys: pytest.CaptureFixture) -> None:
    rc = evaluate.main(
        ["--data", str(data_root), "--scenes", "eth", "--models", "cvm,cvm-s,kalman", "--json"]
    )
    assert rc == 0
    res = json.loads(capsys.readouterr().out)
    eth = res["results"]["cvm"]["eth"]
    # synthetic walkers move at constant velocity: CVM is exact up to the 1 mm rounding of the files
    assert eth["k1"][0] < 1e-2 and eth["ped20"][1] < 1e-2
    cs = res["results"]["cvm-s"]["eth"]
    assert cs["ped20"][0] <= cs["scene20"][0] + 1e-9  # per-pedestrian min can only be smaller
    assert evaluate.main(["--data", str(data_root), "--scenes", "mars"]) == 2


def test_evaluating_a_scene_alone_gives_the_full_runs_numbers(
    data_root: Path, capsys: pytest.CaptureFixture
) -> None:
    """Sample seeds follow the scene, not its place in ``--scenes`` (so runs can be split and merged)."""
    _write_scene(data_root / "eth_ucy" / "hotel" / "test", "h_test.txt", seed=5)
    runs = []
    for scenes in ("eth,hotel", "hotel"):
        args = ["--data", str(data_root), "--scenes", scenes, "--models", "cvm-s,kalman", "--json"]
        assert evaluate.main(args) == 0
        runs.append(json.loads(capsys.readouterr().out)["results"])
    for model in ("cvm-s", "kalman"):
        assert runs[0][model]["hotel"] == runs[1][model]["hotel"]


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


def test_seed_table_reports_mean_sd_and_the_verdict() -> None:
    from predictors.seed_table import summary, table

    def run(model_ade: float) -> dict:
        res = {"s-cgru": {}, "dcvm": {}}
        for s in ("eth", "hotel", "univ", "zara1", "zara2"):
            res["s-cgru"][s] = {"k1": [model_ade, 1.0], "ped20": [model_ade / 2, 0.5], "es": [1.0, 0.0]}
            res["dcvm"][s] = {"k1": [0.50, 1.0], "ped20": [0.30, 0.5], "es": [1.0, 0.0]}
        return {"results": res}

    text, wins = table([run(0.40), run(0.42), run(0.44)], "s-cgru", "dcvm")
    assert "0.420 ± 0.020 (3)" in text and wins == 5  # 0.42 vs 0.50 at K=1, 0.21 vs 0.30 at best-of-20
    _, wins = table([run(0.30), run(0.70)], "s-cgru", "dcvm")
    assert wins == 0  # mean 0.50: no better at K=1, and the seed sd (0.28) swamps any difference
    rows = summary([run(0.40), run(0.42), run(0.44)], ["dcvm", "s-cgru"]).splitlines()
    assert rows[2].startswith("| dcvm | 0.500 / 1.000 | 0.300 / 0.500 |")  # no seed: no sd
    assert rows[3].startswith("| s-cgru | 0.420 ± 0.020 / 1.000 | 0.210 ± 0.010 / 0.500 |")


def test_seed_table_cli_names_a_model_missing_from_the_files(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    from predictors import seed_table

    f = tmp_path / "seed0.json"
    f.write_text(json.dumps({"results": {"dcvm": {"eth": {"k1": [0.5, 1.0]}}}}))
    assert seed_table.main([str(f), "--models", "s-lstm"]) == 2
    assert "['s-lstm'] not in any file" in capsys.readouterr().err
    assert seed_table.main([str(tmp_path / "absent.json")]) == 2


def test_train_all_repeats_runs_per_seed(data_root: Path, tmp_path: Path) -> None:
    from predictors import train_all

    out = tmp_path / "w"
    args = _train_all_args(data_root, out, tmp_path / "logs")
    assert train_all.main([*args, "--models", "lstm", "--scenes", "eth", "--seeds", "3,4"]) == 0
    assert [checkpoint_meta(out / f"seed{k}" / "lstm_eth.pt")["seed"] for k in (3, 4)] == [3, 4]
    from predictors.seed_table import budget_table, val_table

    row = budget_table(out).splitlines()[2]
    assert row.startswith("| lstm | 2 | 0 | 1–1 | 1–1 |")  # two one-epoch runs, neither stopped early
    val = [checkpoint_meta(out / f"seed{k}" / "lstm_eth.pt")["val_ade"] for k in (3, 4)]
    row = val_table(out).splitlines()[2]
    assert row == f"| lstm | eth | {np.mean(val):.3f} ± {np.std(val, ddof=1):.3f} | 2 |"
    assert train_all.main([*args, "--seeds", "one"]) == 2
