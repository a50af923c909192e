"""`crossing-eval` without --out keeps every run in its own dated folder; --out stays exact."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from crossing_eval.cli import DEFAULT_OUT, main

ARGS = ["--scenarios", "zebra_case1", "--episodes", "1", "--no-progress", "--policies", "yielding"]


def _runs(parent: Path) -> list[Path]:
    return sorted(p for p in parent.iterdir() if p.is_dir() and not p.is_symlink())


def test_a_second_run_keeps_the_first_and_latest_points_at_the_newest(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(ARGS) == 0
    assert main([*ARGS[:-1], "constant_speed"]) == 0
    parent = tmp_path / DEFAULT_OUT
    first, second = _runs(parent)
    for run, policy in ((first, "yielding"), (second, "constant_speed")):
        assert json.loads((run / "results.json").read_text())["settings"]["policies"] == [policy]
    assert (parent / "latest").resolve() == second.resolve()
    out = capsys.readouterr().out
    assert f"{DEFAULT_OUT}/latest points at it" in " ".join(out.split())
    # a run that fails before its first episode leaves no empty dated folder behind
    with pytest.raises(SystemExit):
        main([*ARGS[:-1], "no_such_policy"])
    assert main([*ARGS[:-1], "tests.crossing_eval.plugin_policies:RaisesInReset"]) == 2
    assert _runs(parent) == [first, second]
    # --out is exact: no dated folder inside it, no latest beside it
    exact = tmp_path / "mine"
    assert main([*ARGS, "--out", str(exact)]) == 0
    assert (exact / "results.json").is_file() and not (tmp_path / "latest").exists()
