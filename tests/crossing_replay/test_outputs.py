"""crossing-replay never overwrites a file it did not write."""

from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("rerun")
from crossing_replay.cli import main

ARGS = ["record", "--scenario", "zebra_case1", "--policy", "constant", "--steps", "2"]


def test_record_refuses_to_overwrite_a_foreign_file(tmp_path: Path, capsys) -> None:
    out = tmp_path / "thesis.rrd"
    out.write_text("my thesis, misnamed")
    assert main([*ARGS, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert str(out) in err and "not replaced" in err and err.count("\n") == 1
    assert out.read_text() == "my thesis, misnamed"
    assert [p.name for p in tmp_path.iterdir()] == ["thesis.rrd"]


def test_record_replaces_its_own_recording_and_log(tmp_path: Path) -> None:
    out, log = tmp_path / "ep.rrd", tmp_path / "ep.json"
    assert main([*ARGS, "--out", str(out), "--save-log", str(log)]) == 0
    assert main([*ARGS, "--out", str(out), "--save-log", str(log)]) == 0
    log.write_text("notes")
    assert main([*ARGS, "--out", str(out), "--save-log", str(log)]) == 2
    assert log.read_text() == "notes"
