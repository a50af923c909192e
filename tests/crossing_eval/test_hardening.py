"""crossing-eval hardening (issue 16): errors before the first episode, whole output folders, reports."""

from __future__ import annotations

import csv
import json
import math
import pickle
from pathlib import Path

import pytest

import crossing_eval.cli as cli
from crossing_common.folders import write_marker
from crossing_eval.compare import compare, load_run
from crossing_eval.compare import main as compare_main
from crossing_eval.report import scenario_labels
from crossing_eval.runners import EpisodeFailed, RayConnectionError, check_ray_address, run_tasks
from crossing_eval.statistics import censored_delay, newcombe_difference
from crossing_eval.tasks import EpisodeTask
from scenarios import BUILTIN_DIR, ScenarioError, load_scenario

TINY = ["--scenarios", "occluded_parked_car", "--policies", "yielding,constant_speed", "--episodes", "1"]
TINY += ["--predictor", "none", "--intention", "none", "--workers", "1", "--no-progress"]


@pytest.fixture(scope="module")
def first_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("runs") / "a"
    assert cli.main([*TINY, "--out", str(out)]) == 0
    return out


def test_run_writes_reports_and_one_missing_value_convention(first_run: Path, capsys) -> None:
    for name in ("report.md", "table.txt", "per_scenario.csv", "summary.csv", "episodes.csv", "results.json"):
        assert (first_run / name).is_file(), name
    table = (first_run / "table_full.txt").read_text()
    assert "delay s (censored)" in table and "constant_speed" in table
    assert "delay s" in (first_run / "table.txt").read_text()  # the headline table
    report = (first_run / "report.md").read_text()
    assert "## occluded_parked_car" in report and "| constant_speed |" in report
    rows = list(csv.DictReader((first_run / "per_scenario.csv").open()))
    assert [(r["scenario"], r["policy"]) for r in rows] == [
        ("occluded_parked_car", "yielding"),
        ("occluded_parked_car", "constant_speed"),
    ]
    crashed = next(r for r in rows if r["policy"] == "constant_speed")
    assert crashed["collision_rate"] == "1.0" and crashed["pass_rate"] == "0.0"
    assert crashed["mean_delay"] == ""  # undefined → empty cell, in every CSV
    assert float(crashed["censored_mean_delay"]) == load_scenario("occluded_parked_car").duration
    for name in ("per_scenario.csv", "summary.csv", "episodes.csv"):
        assert "nan" not in (first_run / name).read_text().lower(), name


def test_rerun_replaces_the_folder_whole(first_run: Path, tmp_path: Path) -> None:
    out = tmp_path / "b"
    (out / "worst").mkdir(parents=True)
    (out / "results.json").write_text("{}")
    (out / "worst" / "99_stale.json").write_text("{}")
    write_marker(out, "crossing-eval")  # an earlier run's folder: every file listed in its marker
    assert cli.main([*TINY, "--policies", "yielding", "--out", str(out)]) == 0
    assert not (out / "worst" / "99_stale.json").exists()
    assert [p.name for p in tmp_path.iterdir()] == ["b"], "staging folder left behind"


def test_interrupted_write_leaves_the_previous_results(first_run: Path, tmp_path: Path, monkeypatch) -> None:
    out = tmp_path / "c"
    out.mkdir()
    (out / "results.json").write_text('{"old": true}')
    write_marker(out, "crossing-eval")
    records = run_tasks(
        [EpisodeTask("zebra_case1", "constant_speed", 0, 1), EpisodeTask("zebra_case1", "yielding", 0, 1)],
        show_progress=False,
    )

    def write_then_interrupt(records, summary, settings, folder, references):
        (folder / "results.json").write_text("{}")
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "run_tasks", lambda *a, **k: records)
    monkeypatch.setattr(cli, "write_outputs", write_then_interrupt)
    with pytest.raises(KeyboardInterrupt):
        cli.main([*TINY, "--out", str(out)])
    assert sorted(p.name for p in out.iterdir()) == [".crossing-output.json", "results.json"]
    assert (out / "results.json").read_text() == '{"old": true}'
    assert [p.name for p in tmp_path.iterdir()] == ["c"]


@pytest.mark.parametrize("bad_out", ["/proc/x/y", "FILE/sub"])
def test_unwritable_out_fails_before_any_episode(bad_out: str, tmp_path: Path, capsys, monkeypatch) -> None:
    (tmp_path / "FILE").write_text("")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(cli, "run_tasks", lambda *a, **k: pytest.fail("episodes ran"))
    assert cli.main([*TINY, "--out", bad_out]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--out" in err and "Traceback" not in err


def test_foreign_folder_is_never_replaced(tmp_path: Path, capsys) -> None:
    (tmp_path / "notes.txt").write_text("mine")
    assert cli.main([*TINY, "--out", str(tmp_path)]) == 2
    assert "holds no results.json" in capsys.readouterr().err
    assert (tmp_path / "notes.txt").read_text() == "mine"


def test_invalid_scenario_file_fails_before_the_run(tmp_path: Path, capsys, monkeypatch) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "bad"\nduration = -3\n')
    empty = tmp_path / "empty.toml"
    empty.write_text("")
    monkeypatch.setattr(cli, "run_tasks", lambda *a, **k: pytest.fail("episodes ran"))
    for path, needle in ((bad, "duration = -3"), (empty, "empty scenario")):
        argv = [*TINY, "--scenarios", f"zebra_case1,{path}", "--workers", "2", "--out", str(tmp_path / "o")]
        assert cli.main(argv) == 2
        err = capsys.readouterr().err
        assert str(path) in err and needle in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()


def test_worker_errors_arrive_whole(tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "bad"\nduration = -3\n')
    with pytest.raises(ScenarioError, match="duration") as err:
        run_tasks([EpisodeTask(str(bad), "yielding", i, i) for i in range(2)], workers=2, show_progress=False)
    assert err.value.source == str(bad) and err.value.problems
    failed = EpisodeFailed(EpisodeTask("x", "yielding", 0, 1), "ValueError: boom")
    again = pickle.loads(pickle.dumps(failed))
    assert str(again) == str(failed) and "boom" in str(again)


def test_ray_address_is_checked_with_a_timeout() -> None:
    with pytest.raises(RayConnectionError, match=r"127\.0\.0\.1:1"):
        check_ray_address("127.0.0.1:1", timeout=2)
    with pytest.raises(RayConnectionError, match="not a number"):
        check_ray_address("ray://host:port", timeout=2)
    check_ray_address("auto")  # left to Ray


def test_custom_scenario_is_named_by_its_name_field(tmp_path: Path) -> None:
    path = tmp_path / "file_name.toml"
    text = (BUILTIN_DIR / "busy_zebra.toml").read_text()
    path.write_text(text.replace('name = "busy_zebra"', 'name = "my_zebra"'))
    assert scenario_labels([str(path), "busy_zebra"]) == {str(path): "my_zebra", "busy_zebra": "busy_zebra"}


def test_censored_delay_counts_episodes_that_never_pass() -> None:
    got = censored_delay([6.0, math.nan, math.nan], [True, False, False], 40.0)
    assert got == {
        "pass_rate": pytest.approx(1 / 3),
        "censored_mean_delay": pytest.approx(86 / 3),
        "censored_episodes": 2,
    }
    assert censored_delay([2.0], [True], 40.0)["censored_mean_delay"] == 2.0


def test_newcombe_difference_brackets_the_difference() -> None:
    diff, lo, hi = newcombe_difference(0, 20, 10, 20)
    assert diff == 0.5 and 0.0 < lo < 0.5 < hi <= 1.0
    diff, lo, hi = newcombe_difference(0, 5, 0, 5)
    assert diff == 0.0 and lo < 0.0 < hi  # no events is not certainty


def test_compare_prints_differences_with_intervals(first_run: Path, tmp_path: Path, capsys) -> None:
    doc = load_run(first_run)
    text = compare(doc, doc)
    assert "constant_speed" in text and "+0.00" in text and "(all)" in text
    flipped = json.loads(json.dumps(doc))
    for ep in flipped["episodes"]:
        ep["metrics"]["collision"] = not ep["metrics"]["collision"]
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / "results.json").write_text(json.dumps(flipped))
    assert compare_main([str(first_run), str(tmp_path / "b")]) == 0
    out = capsys.readouterr().out
    assert "1.00→0.00 -1.00" in out
    assert compare_main([str(first_run), str(tmp_path / "missing")]) == 2
    assert "results.json" in capsys.readouterr().err


@pytest.mark.ray
def test_ray_cli_fails_fast_on_an_unreachable_address(tmp_path: Path, capsys) -> None:
    pytest.importorskip("ray")
    argv = [*TINY, "--backend", "ray", "--address", "127.0.0.1:1", "--ray-timeout", "2"]
    assert cli.main([*argv, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "no Ray cluster reachable at '127.0.0.1:1'" in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()


def test_corrupt_predictor_weights_stop_the_run(tmp_path: Path, capsys, monkeypatch) -> None:
    from predictors import checkpoints

    folder = tmp_path / "weights"
    folder.mkdir()
    (folder / "s-cgru_all.pt").write_bytes(b"tampered")
    (folder / "manifest.json").write_text('{"s-cgru_all.pt": "0"}')
    monkeypatch.setattr(checkpoints, "SHIPPED_DIR", folder.resolve())
    monkeypatch.setattr(checkpoints, "MANIFEST", folder / "manifest.json")
    monkeypatch.setattr("predictors.trajectory_wrapper.WEIGHTS_DIR", folder)
    argv = [*TINY, "--policies", "yielding", "--predictor", "s-cgru", "--out", str(tmp_path / "o")]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert "does not match the manifest" in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()
