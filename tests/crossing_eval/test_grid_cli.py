"""`crossing-eval --grid` goes through the plain run's path: checks, staged output, errors (issue 21)."""

from __future__ import annotations

from pathlib import Path

import pytest

import crossing_eval.cli as cli
from crossing_common.folders import MARKER_NAME, read_marker

GRID = ["--grid", "intention=oracle", "--scenarios", "zebra_case1", "--policies", "predictive_yielding"]
GRID += ["--episodes", "1", "--workers", "1", "--no-progress"]


def test_grid_refuses_a_folder_it_did_not_write(tmp_path: Path, capsys, monkeypatch) -> None:
    out = tmp_path / "mine"
    out.mkdir()
    (out / "thesis.tex").write_text("mine")
    monkeypatch.setattr(cli, "run_tasks", lambda *a, **k: pytest.fail("episodes ran"))
    assert cli.main([*GRID, "--out", str(out)]) == 2
    assert "--out" in capsys.readouterr().err
    assert [p.name for p in out.iterdir()] == ["thesis.tex"] and (out / "thesis.tex").read_text() == "mine"


def test_grid_with_a_predictor_that_cannot_load_stops_before_any_episode(tmp_path: Path, monkeypatch) -> None:
    bad = tmp_path / "broken.pt"
    bad.write_text("not a model")
    monkeypatch.setattr(cli, "run_tasks", lambda *a, **k: pytest.fail("episodes ran"))
    argv = ["--grid", f"predictor={bad}", "--scenarios", "zebra_case1", "--policies", "predictive_yielding"]
    with pytest.raises(SystemExit) as exc:  # a grid value is checked as an argument: argparse's exit 2
        cli.main([*argv, "--out", str(tmp_path / "o")])
    assert exc.value.code == 2 and not (tmp_path / "o").exists()


def test_grid_output_is_staged_and_marked(tmp_path: Path) -> None:
    out = tmp_path / "grid"
    assert cli.main([*GRID, "--out", str(out)]) == 0
    marker = read_marker(out)
    assert marker["tool"] == "crossing-eval"
    assert "value_of_prediction.csv" in marker["files"] and "provenance.json" in marker["files"]
    assert sorted(p.name for p in out.iterdir()) == sorted([MARKER_NAME, *marker["files"]])
    assert cli.main([*GRID, "--out", str(out)]) == 0  # its own earlier output is replaced whole
    assert [p.name for p in tmp_path.iterdir()] == ["grid"], "no staging folder or lock left behind"


def test_grid_has_its_own_default_folder(monkeypatch) -> None:
    args = cli._parse(cli.build_parser(), GRID)
    assert args.out == Path(cli.DEFAULT_GRID_OUT)
