"""StagedFolder: output folders replaced whole, never a mix, never someone else's folder."""

from __future__ import annotations

from pathlib import Path

import pytest

from crossing_common.folders import OutputFolderError, StagedFolder


def test_commit_replaces_the_whole_folder(tmp_path: Path) -> None:
    target = tmp_path / "out"
    (target / "worst").mkdir(parents=True)
    (target / "results.json").write_text("old")
    (target / "worst" / "stale.json").write_text("old")
    staged = StagedFolder(target, marker="results.json")
    (staged.path / "results.json").write_text("new")
    assert (target / "results.json").read_text() == "old"  # untouched until the swap
    staged.commit()
    staged.discard()
    assert sorted(p.name for p in target.rglob("*")) == ["results.json"]
    assert (target / "results.json").read_text() == "new"
    assert [p.name for p in tmp_path.iterdir()] == ["out"]


def test_discard_leaves_the_previous_folder(tmp_path: Path) -> None:
    target = tmp_path / "out"
    target.mkdir()
    (target / "results.json").write_text("old")
    staged = StagedFolder(target, marker="results.json")
    (staged.path / "results.json").write_text("half")
    staged.discard()
    assert (target / "results.json").read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["out"]


def test_new_target_and_leftovers_of_a_killed_run(tmp_path: Path) -> None:
    (tmp_path / ".out.staging-dead").mkdir()  # what SIGKILL would leave
    staged = StagedFolder(tmp_path / "sub" / "out", marker="results.json")
    staged.commit()
    assert (tmp_path / "sub" / "out").is_dir()
    StagedFolder(tmp_path / "out", marker="results.json").discard()
    assert not (tmp_path / ".out.staging-dead").exists()


@pytest.mark.parametrize("case", ["foreign", "file", "under_file", "cwd"])
def test_unusable_targets_fail_at_once(tmp_path: Path, case: str, monkeypatch) -> None:
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep")
    (tmp_path / "f").write_text("")
    monkeypatch.chdir(tmp_path / "mine")
    target = {
        "foreign": tmp_path / "mine",
        "file": tmp_path / "f",
        "under_file": tmp_path / "f" / "out",
        "cwd": Path("."),
    }[case]
    with pytest.raises(OutputFolderError):
        StagedFolder(target, marker="results.json")
    assert (tmp_path / "mine" / "notes.txt").read_text() == "keep"
