"""The tools' output folders: user files are never deleted, and one run at a time writes a folder."""

from __future__ import annotations

from pathlib import Path

import pytest

from crossing_common.folders import MARKER_NAME, StagedFolder, read_marker

cli = pytest.importorskip("crossing_eval.cli")

TINY = ["--scenarios", "zebra_case1", "--policies", "constant_speed", "--episodes", "1"]
TINY += ["--predictor", "none", "--intention", "none", "--workers", "1", "--no-progress"]


def _tree(folder: Path) -> dict[str, str]:
    files = (p for p in folder.rglob("*") if p.is_file())
    return {p.relative_to(folder).as_posix(): p.read_text(errors="replace") for p in files}


def test_eval_refuses_a_results_folder_holding_user_files(tmp_path: Path, capsys, monkeypatch) -> None:
    out = tmp_path / "out"
    (out / "sub").mkdir(parents=True)
    (out / "results.json").write_text("{}")
    (out / "precious.txt").write_text("mine")
    (out / "sub" / "thesis.tex").write_text("mine")
    monkeypatch.setattr(cli, "run_tasks", lambda *a, **k: pytest.fail("episodes ran"))
    assert cli.main([*TINY, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(out) in err
    assert _tree(out) == {"results.json": "{}", "precious.txt": "mine", "sub/thesis.tex": "mine"}
    assert [p.name for p in tmp_path.iterdir()] == ["out"]


def test_eval_marks_its_folder_and_replaces_only_that(tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert cli.main([*TINY, "--out", str(out)]) == 0
    marker = read_marker(out)
    assert marker is not None
    assert sorted(marker["files"]) == sorted(f for f in _tree(out) if f != MARKER_NAME)
    assert cli.main([*TINY, "--out", str(out)]) == 0  # its own earlier output: replaced
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_eval_second_run_on_a_locked_folder_exits_2_and_touches_nothing(
    tmp_path: Path, capsys, monkeypatch
) -> None:
    out = tmp_path / "out"
    first = StagedFolder(out, marker="results.json", tool="crossing-eval")
    (first.path / "results.json").write_text("first")
    monkeypatch.setattr(cli, "run_tasks", lambda *a, **k: pytest.fail("episodes ran"))
    try:
        assert cli.main([*TINY, "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and str(out) in err and "another run" in err
        assert (first.path / "results.json").read_text() == "first"
    finally:
        first.discard()
