"""StagedFolder: folders replaced whole, never a mix, never someone else's folder, one run at a time."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import pytest

from crossing_common.folders import (
    MARKER_NAME,
    OutputFolderError,
    StagedFolder,
    read_marker,
    write_marker,
)


def test_commit_replaces_the_whole_folder(tmp_path: Path) -> None:
    target = tmp_path / "out"
    (target / "worst").mkdir(parents=True)
    (target / "results.json").write_text("old")
    (target / "worst" / "stale.json").write_text("old")
    write_marker(target, "crossing-eval")
    staged = StagedFolder(target, marker="results.json", tool="crossing-eval")
    (staged.path / "results.json").write_text("new")
    assert (target / "results.json").read_text() == "old"  # untouched until the swap
    staged.commit()
    staged.discard()
    assert sorted(p.name for p in target.rglob("*")) == [MARKER_NAME, "results.json"]
    assert read_marker(target) == {"tool": "crossing-eval", "files": ["results.json"]}
    assert (target / "results.json").read_text() == "new"
    assert [p.name for p in tmp_path.iterdir()] == ["out"]


def test_discard_leaves_the_previous_folder(tmp_path: Path) -> None:
    target = tmp_path / "out"
    target.mkdir()
    (target / "results.json").write_text("old")
    write_marker(target, "crossing-eval")
    staged = StagedFolder(target, marker="results.json")
    (staged.path / "results.json").write_text("half")
    staged.discard()
    assert (target / "results.json").read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["out"]  # no staging folder, no lock file


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


def _tree(folder: Path) -> dict[str, str]:
    return {p.relative_to(folder).as_posix(): p.read_text() for p in folder.rglob("*") if p.is_file()}


@pytest.mark.parametrize("case", ["no_marker", "unlisted_file", "unlisted_in_sub", "bad_marker"])
def test_a_folder_with_files_no_run_wrote_is_never_replaced(tmp_path: Path, case: str) -> None:
    target = tmp_path / "out"
    (target / "sub").mkdir(parents=True)
    (target / "results.json").write_text("{}")  # looks like an earlier run's output ...
    if case != "no_marker":
        write_marker(target, "crossing-eval")
    if case == "unlisted_file":
        (target / "precious.txt").write_text("mine")  # ... but holds the user's own files
    if case == "unlisted_in_sub":
        (target / "sub" / "thesis.tex").write_text("mine")
    if case == "bad_marker":
        (target / MARKER_NAME).write_text("not json")
    before = _tree(target)
    with pytest.raises(OutputFolderError, match=re.escape(str(target))):
        StagedFolder(target, marker="results.json")
    assert _tree(target) == before
    assert [p.name for p in tmp_path.iterdir()] == ["out"]


def test_user_file_added_during_the_run_stops_the_commit(tmp_path: Path) -> None:
    target = tmp_path / "out"
    staged = StagedFolder(target, marker="results.json")
    staged.commit()
    staged = StagedFolder(target, marker="results.json")
    (staged.path / "results.json").write_text("new")
    (target / "precious.txt").write_text("mine")
    with pytest.raises(OutputFolderError, match=r"precious\.txt"):
        staged.commit()
    staged.discard()
    assert _tree(target) == {MARKER_NAME: (target / MARKER_NAME).read_text(), "precious.txt": "mine"}


def test_a_second_run_on_the_same_folder_is_refused_and_touches_nothing(tmp_path: Path) -> None:
    target = tmp_path / "out"
    first = StagedFolder(target, marker="results.json", tool="crossing-eval")
    (first.path / "results.json").write_text("first")
    expected = f"{target}: another run (crossing-eval, pid {os.getpid()})"
    with pytest.raises(OutputFolderError, match=re.escape(expected)):
        StagedFolder(target, marker="results.json", tool="crossing-eval")
    assert (first.path / "results.json").read_text() == "first"  # its staging folder survived
    first.commit()
    first.discard()
    assert (target / "results.json").read_text() == "first"
    second = StagedFolder(target, marker="results.json")  # the lock was released
    second.discard()
    assert [p.name for p in tmp_path.iterdir()] == ["out"]


def test_read_only_target_is_an_error_with_nothing_left_behind(tmp_path: Path) -> None:
    target = tmp_path / "out"
    staged = StagedFolder(target, marker="results.json")
    (staged.path / "results.json").write_text("old")
    staged.commit()
    target.chmod(0o555)
    try:
        with pytest.raises(OutputFolderError, match="read-only"):
            StagedFolder(target, marker="results.json")
        assert [p.name for p in tmp_path.iterdir()] == ["out"]
        assert (target / "results.json").read_text() == "old"
    finally:
        target.chmod(0o755)


def test_marker_lists_every_file_written(tmp_path: Path) -> None:
    with StagedFolder(tmp_path / "out", tool="crossing-replay") as staged:
        (staged.path / "worst").mkdir()
        (staged.path / "worst" / "a.json").write_text("{}")
        (staged.path / "b.csv").write_text("")
        staged.commit()
    doc = json.loads((tmp_path / "out" / MARKER_NAME).read_text())
    assert doc == {"tool": "crossing-replay", "files": ["b.csv", "worst/a.json"]}
