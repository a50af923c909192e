"""Runs kept side by side: a dated folder each, ``latest`` on the newest, nothing of the user's touched."""

from __future__ import annotations

from datetime import datetime
from pathlib import Path

from crossing_common.runs import LATEST, claim_run_folder, point_latest, release_if_empty

NOW = datetime(2026, 12, 8, 9, 30, 5)


def test_each_claim_is_a_new_empty_folder_even_within_one_second(tmp_path: Path):
    parent = tmp_path / "results"
    first = claim_run_folder(parent, NOW)
    second = claim_run_folder(parent, NOW)
    assert first.name == "2026-12-08_09-30-05" and second.name == "2026-12-08_09-30-05-2"
    assert first.is_dir() and second.is_dir() and list(first.iterdir()) == []


def test_latest_follows_the_newest_run_and_never_replaces_a_users_own(tmp_path: Path):
    first, second = claim_run_folder(tmp_path, NOW), claim_run_folder(tmp_path, NOW)
    (second / "results.json").write_text("{}")
    assert point_latest(first) is None
    assert point_latest(second) is None
    link = tmp_path / LATEST
    assert link.is_symlink() and (link / "results.json").is_file()
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # no temporary link left
    link.unlink()
    link.mkdir()
    (link / "mine.txt").write_text("keep")
    note = point_latest(second)
    assert note is not None and "left as it is" in note
    assert (link / "mine.txt").read_text() == "keep" and not link.is_symlink()


def test_only_an_empty_claimed_folder_is_released(tmp_path: Path):
    empty, full = claim_run_folder(tmp_path, NOW), claim_run_folder(tmp_path, NOW)
    (full / "results.json").write_text("{}")
    release_if_empty(empty)
    release_if_empty(full)
    release_if_empty(tmp_path / "never-there")
    assert not empty.exists() and (full / "results.json").is_file()
