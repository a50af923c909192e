"""The value-of-prediction grid: seeds are paired across rows, the table's arithmetic, the CLI option."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import pytest

from crossing_eval.grid import group_rows, make_grid_tasks, parse_grid
from crossing_eval.prediction_value import value_table
from crossing_eval.tasks import EpisodeRecord, EpisodeTask
from tests.crossing_eval.test_eval import run_cli

CHOICES = (("qlb", "classical", "none", "oracle"), ("s-cgru", "cvm", "none", "oracle"))


def test_grid_pairs_seeds_across_every_combination() -> None:
    spec = parse_grid(["intention=qlb,oracle", "predictor=cvm"], *CHOICES)
    assert spec.combinations() == [
        ("none", "none"),
        ("none", "cvm"),
        ("qlb", "none"),
        ("qlb", "cvm"),
        ("oracle", "none"),
        ("oracle", "cvm"),
    ]
    tasks = make_grid_tasks(["zebra_case1", "busy_zebra"], ["predictive_yielding", "ttc_brake"], 3, 7, spec)
    seeds: dict[tuple[str, int], set[int]] = {}
    rows: dict[tuple[str, str, str], int] = {}
    for t in tasks:
        seeds.setdefault((t.scenario, t.episode), set()).add(t.seed)
        rows[(t.policy, t.intention, t.predictor)] = rows.get((t.policy, t.intention, t.predictor), 0) + 1
    assert all(len(s) == 1 for s in seeds.values())  # one seed per (scenario, episode), whatever the row
    assert len({next(iter(s)) for s in seeds.values()}) == 6  # and different episodes differ
    assert rows == {
        **{("predictive_yielding", i, p): 6 for i, p in spec.combinations()},
        ("ttc_brake", "none", "none"): 6,
    }


@pytest.mark.parametrize(
    ("items", "needle"),
    [(["intention=psychic"], "'psychic'"), (["mood=none"], "'mood=none'"), (["predictor="], "no values")],
)
def test_parse_grid_rejects_bad_items(items: list[str], needle: str) -> None:
    with pytest.raises(ValueError, match=needle):
        parse_grid(items, *CHOICES)


def _record(
    intention: str, predictor: str, episode: int, delay: float, collision: bool = False
) -> EpisodeRecord:
    task = EpisodeTask("zebra_case1", "predictive_yielding", episode, 100 + episode, predictor, intention)
    result = {
        "collision": collision,
        "yield_compliant": 2,
        "yield_obligations": 2,
        "unneeded_stops": 1 if intention == "none" else 0,
        "passed_crossing": True,
        "delay": delay,
        "duration": 30.0,
        "hard_braking_events": 0,
        "min_ttc": None,
    }
    return EpisodeRecord(task=task, result=result, actions=[], predictors=[])


def test_value_table_differences_and_value_captured() -> None:
    none = [10.0, 12.0, 14.0, 16.0]
    recs = []
    for ep, d in enumerate(none):
        recs.append(_record("none", "none", ep, d))
        recs.append(_record("qlb", "none", ep, d - 2.0))  # saves 2 s in every episode
        recs.append(_record("oracle", "none", ep, d - 4.0, collision=ep == 0))  # saves 4 s, one collision
    table = {(r["intention"], r["predictor"]): r for r in value_table(group_rows(recs), n_resamples=200)}
    qlb, oracle = table[("qlb", "none")], table[("oracle", "none")]
    assert qlb["mean_delay"] == pytest.approx(11.0) and qlb["mean_delay_diff"] == pytest.approx(-2.0)
    assert qlb["mean_delay_diff_ci"] == pytest.approx((-2.0, -2.0))  # paired: the difference never varies
    assert qlb["value_captured"] == pytest.approx(0.5)
    assert qlb["value_captured_ci"] == pytest.approx((0.5, 0.5))
    assert qlb["unneeded_stops_diff"] == pytest.approx(-1.0)
    assert oracle["collision_rate_diff"] == pytest.approx(0.25)
    lo, hi = oracle["collision_rate_diff_ci"]
    assert lo == pytest.approx(0.0) and hi >= 0.25
    assert math.isnan(table[("none", "none")]["mean_delay_diff"])
    assert math.isnan(oracle["value_captured"])  # the oracle row is the bound itself


def test_value_captured_compares_each_row_with_its_own_oracle() -> None:
    """A trajectory predictor is measured against the path oracle, an intention model against the intent
    oracle; where the oracle is no faster than no prediction, the share is left out."""
    recs = []
    for ep, d in enumerate([10.0, 12.0, 14.0, 16.0]):
        recs.append(_record("none", "none", ep, d))
        recs.append(_record("qlb", "none", ep, d - 1.0))
        recs.append(_record("oracle", "none", ep, d - 4.0))
        recs.append(_record("none", "cvm", ep, d - 1.0))
        recs.append(_record("none", "oracle", ep, d + 1.0))  # the path oracle is slower
        recs.append(_record("oracle", "oracle", ep, d - 2.0))
        recs.append(_record("qlb", "cvm", ep, d - 1.0))
    table = {(r["intention"], r["predictor"]): r for r in value_table(group_rows(recs), n_resamples=100)}
    assert table[("qlb", "none")]["value_captured"] == pytest.approx(0.25)  # 1 of oracle / none's 4 s
    assert table[("qlb", "none")]["value_oracle"] == "oracle / none"
    assert math.isnan(table[("none", "cvm")]["value_captured"])  # none / oracle is not faster
    assert table[("qlb", "cvm")]["value_captured"] == pytest.approx(0.5)  # 1 of oracle / oracle's 2 s


def test_value_table_refuses_unpaired_rows() -> None:
    recs = [_record("none", "none", 0, 10.0), _record("none", "none", 1, 11.0)]
    recs += [_record("qlb", "none", 0, 9.0), _record("qlb", "none", 2, 9.0)]
    with pytest.raises(ValueError, match="different episodes"):
        value_table(group_rows(recs), n_resamples=50)


def test_cli_grid_writes_the_table(tmp_path: Path) -> None:
    out = tmp_path / "grid"
    proc = run_cli(
        "--grid", "intention=oracle", "--scenarios", "zebra_case1", "--policies", "predictive_yielding",
        "--episodes", "2", "--workers", "1", "--no-progress", "--out", str(out),
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert "| predictive_yielding | oracle | none | 2 |" in proc.stdout
    for name in ("value_of_prediction.md", "value_of_prediction.csv", "value_of_prediction.png"):
        assert (out / name).stat().st_size > 0
    with (out / "grid_episodes.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 4
    by_episode: dict[str, set[str]] = {}
    for r in rows:
        by_episode.setdefault(r["episode"], set()).add(r["seed"])
    assert all(len(s) == 1 for s in by_episode.values())


def test_cli_bad_grid_exits_2_and_writes_nothing(tmp_path: Path) -> None:
    out = tmp_path / "grid"
    proc = run_cli("--grid", "intention=psychic", "--out", str(out), timeout=60)
    assert proc.returncode == 2 and "'psychic'" in proc.stderr
    assert not out.exists()
