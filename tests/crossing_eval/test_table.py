"""The table explains itself: no pooled-policy row, every column defined, speeding and separation shown,
close passes marked, plots without overlapping labels and with identical curves told apart."""

from __future__ import annotations

import csv
import dataclasses
import math
import sys
import types
from pathlib import Path

import pytest

from crossing_env.safety import EpisodeResult
from crossing_eval.outputs import _draw_min_ttc, _draw_safety_vs_efficiency, _write_summary_csv, dodge_offsets
from crossing_eval.report import per_scenario_rows, report_markdown
from crossing_eval.summary import (
    CLOSE_MARK,
    HEADLINE_COLUMNS,
    HEADLINE_WIDTH,
    TABLE_COLUMNS,
    format_table,
    summarise,
)
from crossing_eval.tasks import EpisodeRecord, EpisodeTask
from tests.crossing_env.safety.snapshots import Ped, make_gt, metrics

SCENARIO = "zebra_case1"


def _base() -> EpisodeResult:
    m = metrics()
    m.update(make_gt(0.1))
    return m.result()


def _records(per_policy: dict[str, list[dict]]) -> list[EpisodeRecord]:
    records = []
    for policy, changes in per_policy.items():
        for ep, kw in enumerate(changes):
            result = dataclasses.replace(_base(), **kw).as_dict()
            records.append(EpisodeRecord(EpisodeTask(SCENARIO, policy, ep, ep), result, [], []))
    return records


def _summarise(records: list[EpisodeRecord]) -> dict:
    """`summarise` with the reference driver's episode on every seed: the clean base episode."""
    seeds = sorted({(r.task.scenario, r.task.seed) for r in records})
    references = [
        EpisodeRecord(EpisodeTask(sc, "yielding", seed, seed), _base().as_dict(), [], [])
        for sc, seed in seeds
    ]
    return summarise(records, references)


def _cells(table: str, policy: str) -> dict[str, str]:
    """The row of `policy` in the fixed-width table, by header (cells are separated by 2+ spaces)."""
    lines = table.splitlines()
    widths = [len(d) for d in lines[1].split("  ")]
    starts = [sum(widths[:i]) + 2 * i for i in range(len(widths))]
    row = next(line for line in lines[2:] if line.startswith(policy + " "))
    return {c.header: row[s : s + w].strip() for c, s, w in zip(TABLE_COLUMNS, starts, widths, strict=True)}


RECORDS = {
    "ttc_brake": [
        # Passed 0.66 m from a pedestrian without ever being on a collision course (TTC inf).
        {"min_separation": 0.66, "min_ttc": math.inf, "max_drac_crossing": 111.0},
        {"min_separation": 2.5, "min_ttc": math.inf},
    ],
    "plugin_fast": [
        {"max_speed_over_limit": 6.1, "time_over_speed_limit": 4.0, "min_separation": 3.0, "min_ttc": 2.0},
        {"max_speed_over_limit": 5.0, "time_over_speed_limit": 2.0, "min_separation": 4.0, "min_ttc": 3.0},
    ],
}


def test_speeding_is_measured_from_the_ground_truth_against_the_scenario_limit():
    m = metrics()  # default road: speed limit 13.9 m/s
    for i, v in enumerate((10.0, 16.0, 15.0, 16.5, 12.0)):
        m.update(make_gt(0.1 * (i + 1), ego_x=30.0 + i, ego_v=v))
    r = m.result()
    assert r.max_speed_over_limit == pytest.approx(16.5 - 13.9)
    assert r.time_over_speed_limit == pytest.approx(0.3)
    assert EpisodeResult.from_dict(r.as_dict()) == r


def test_old_logs_without_the_speeding_fields_still_load():
    data = _base().as_dict()
    del data["max_speed_over_limit"], data["time_over_speed_limit"]
    old = EpisodeResult.from_dict(data)
    assert old.max_speed_over_limit == 0.0 and old.time_over_speed_limit == 0.0


def test_no_row_pools_policies_anywhere(tmp_path: Path):
    records = _records(RECORDS)
    summary = _summarise(records)
    assert set(summary) == {"per_policy", "per_scenario_policy", "world_health"}
    policies = list(RECORDS)
    table = format_table(summary, policies)
    rows = table.splitlines()[2 : 2 + len(policies)]
    assert [r.split()[0] for r in rows] == policies
    assert "overall" not in table
    report = report_markdown(summary, policies, {SCENARIO: SCENARIO}, {"episodes": 2})
    assert "overall" not in report and "pooled" not in report.split("## Definitions")[0].lower()
    _write_summary_csv(summary, policies, tmp_path)
    with (tmp_path / "summary.csv").open() as fh:
        assert [r["policy"] for r in csv.DictReader(fh)] == policies
    assert "world health: 0 background" in table


def test_every_column_is_defined_in_the_report_with_the_censoring_rule():
    records = _records(RECORDS)
    summary = _summarise(records)
    report = report_markdown(summary, list(RECORDS), {SCENARIO: SCENARIO}, {"episodes": 2})
    definitions = report.split("## Definitions", 1)[1]
    for column in TABLE_COLUMNS:
        assert f"- **{column.header}**: " in definitions
        assert column.definition.strip()
    delay = next(c for c in TABLE_COLUMNS if c.key == "censored_mean_delay")
    assert "never reaches the target counts with a delay equal to its scenario's duration" in delay.definition
    assert "report.md" in format_table(summary, list(RECORDS))


def test_speeding_and_separation_columns():
    table = format_table(_summarise(_records(RECORDS)), list(RECORDS))
    fast = _cells(table, "plugin_fast")
    assert fast["over limit m/s"] == "6.10"
    assert fast["over limit s/ep"] == "3.00"
    assert fast["min sep m (min/p50)"] == "3.00/3.50"
    header, rows = per_scenario_rows(_summarise(_records(RECORDS)), {}, list(RECORDS))
    row = dict(zip(header, next(r for r in rows if r[1] == "plugin_fast"), strict=True))
    assert row["max_speed_over_limit_max"] == pytest.approx(6.1)
    assert row["time_over_speed_limit_mean"] == pytest.approx(3.0)
    assert row["min_separation_min"] == pytest.approx(3.0)


def test_a_close_pass_is_never_shown_as_no_conflict():
    """ttc_brake's 0.66 m pass with no collision course: the TTC cell is not a bare '-/-'."""
    table = format_table(_summarise(_records(RECORDS)), list(RECORDS))
    cells = _cells(table, "ttc_brake")
    assert cells["min sep m (min/p50)"] == f"0.66{CLOSE_MARK}/1.58"
    assert cells["minTTC p5/p50 s"] == f"-/-{CLOSE_MARK}"
    assert CLOSE_MARK not in "".join(_cells(table, "plugin_fast").values())


def test_a_real_close_pass_from_snapshots_is_marked():
    """A pedestrian 0.5 m beside the ego box, walking parallel: no collision course, separation 0.5 m."""
    m = metrics()
    for i in range(3):
        ped = Ped(1, (30.0 + i, 1.75 + 0.9 + 0.28 + 0.5), vel=(10.0, 0.0))
        m.update(make_gt(0.1 * (i + 1), ego_x=30.0 + i, peds=[ped]))
    r = m.result()
    assert r.min_ttc == math.inf and r.min_separation == pytest.approx(0.5)
    records = [EpisodeRecord(EpisodeTask(SCENARIO, "p", 0, 0), r.as_dict(), [], [])]
    cells = _cells(format_table(_summarise(records), ["p"]), "p")
    assert cells["minTTC p5/p50 s"].endswith(CLOSE_MARK)


def test_dodge_offsets_set_identical_points_apart():
    offsets = dodge_offsets([(11.7, 0.0), (11.7, 0.0), (0.2, 0.0), (0.21, 0.0), (20.5, 0.5)])
    assert offsets[0] != offsets[1] and offsets[2] != offsets[3]
    assert offsets[4] == 0.0
    assert dodge_offsets([]) == []


def test_plots_have_no_point_labels_and_identical_curves_are_named():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    twins = {
        "yielding": [{"min_ttc": 1.6}, {"min_ttc": 1.9}],
        "predictive_yielding": [{"min_ttc": 1.6}, {"min_ttc": 1.9}],
        "ttc_brake": [{"min_ttc": 4.2}, {"min_ttc": math.inf}],
    }
    records = _records(twins)
    summary = _summarise(records)
    names = list(twins)
    fig, ax = plt.subplots()
    _draw_safety_vs_efficiency(ax, summary, names)
    assert len(ax.texts) == 0  # names only in the legend: nothing can overlap
    assert [t.get_text().split(":")[0] for t in ax.get_legend().get_texts()] == names
    plt.close(fig)
    fig, ax = plt.subplots()
    _draw_min_ttc(ax, records, names)
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "same curve as yielding" in labels[1] and "same curve" not in labels[2]
    lines = ax.get_lines()[: len(names)]
    assert len({line.get_marker() for line in lines}) == len(names)
    assert lines[0].get_linewidth() > lines[1].get_linewidth()  # the earlier curve shows around the later
    plt.close(fig)


def test_the_safety_axis_is_the_score_so_breaking_yield_duties_without_a_collision_does_not_look_safe():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    duties = {"yield_obligations": 1}
    runs = {
        "careful": [{**duties, "yield_compliant": 1}, {**duties, "yield_compliant": 1}],
        "ignores_duties": [{**duties, "yield_violations": 1}, {**duties, "yield_violations": 1}],
    }
    summary = _summarise(_records(runs))
    assert all(summary["per_policy"][p]["collision_rate"] == 0.0 for p in runs)  # alike on collisions
    fig, ax = plt.subplots()
    _draw_safety_vs_efficiency(ax, summary, list(runs))
    careful, ignores = (float(c.lines[0].get_ydata()[0]) for c in ax.containers)
    assert ignores == 0.0 < careful
    assert "score" in ax.get_ylabel()
    plt.close(fig)


def test_drac_figures_stay_physical_near_contact():
    from crossing_eval.statistics import aggregate

    near_contact = [dataclasses.replace(_base(), max_drac_crossing=v) for v in (0.0, 2.0, 4.0, 422.9, 1257.2)]
    agg = aggregate(near_contact)
    assert agg["drac_conflict_rate"] == 0.6  # 4.0, 422.9 and 1257.2 exceed 3.35 m/s²
    assert agg["drac_crossing_p95"] == pytest.approx(9.81)  # capped at 1 g, not hundreds of m/s²
    assert agg["drac_crossing_mean"] > 300  # the uncapped mean the table no longer shows


def test_plots_drawn_in_a_child_process_are_written_and_a_failing_one_stops_the_outputs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    import crossing_eval.outputs as outputs

    monkeypatch.delitem(sys.modules, "torch", raising=False)  # the child is forked only without torch
    records = _records(RECORDS)
    summary = _summarise(records)
    outputs._plot(records, summary, list(RECORDS), tmp_path)
    pngs = sorted(p.name for p in tmp_path.glob("*.png"))
    assert pngs == ["min_ttc.png", "safety_vs_efficiency.png"]
    assert all((tmp_path / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for name in pngs)

    def broken(*args: object) -> None:
        raise ValueError("cannot draw")

    monkeypatch.setattr(outputs, "_draw_min_ttc", broken)  # the plot a forked child draws
    (tmp_path / "again").mkdir()
    with pytest.raises(RuntimeError, match=r"drawing min_ttc\.png failed"):
        outputs._plot(records, summary, list(RECORDS), tmp_path / "again")
    assert not (tmp_path / "again" / "min_ttc.png").exists()


def test_after_torch_the_plots_are_drawn_here_and_a_failing_one_raises_its_own_error(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    import crossing_eval.outputs as outputs

    monkeypatch.setitem(sys.modules, "torch", types.ModuleType("torch"))
    records = _records(RECORDS)
    summary = _summarise(records)

    def broken(*args: object) -> None:
        raise ValueError("cannot draw")

    monkeypatch.setattr(outputs, "_draw_min_ttc", broken)
    with pytest.raises(ValueError, match="cannot draw"):
        outputs._plot(records, summary, list(RECORDS), tmp_path)
    assert (tmp_path / "safety_vs_efficiency.png").is_file() and not (tmp_path / "min_ttc.png").exists()


def test_the_headline_table_fits_a_terminal_of_120_and_leads_with_the_score():
    records = _records(
        {
            "predictive_yielding": [{"min_separation": 0.4}, {"min_separation": 2.0}],
            "a_plugin_name_of_26_chars_": [{"min_separation": 3.0}, {"min_separation": 3.5}],
        }
    )
    summary = _summarise(records)
    policies = ["predictive_yielding", "a_plugin_name_of_26_chars_"]
    headline = format_table(summary, policies, HEADLINE_COLUMNS)
    assert max(len(line) for line in headline.splitlines()) <= HEADLINE_WIDTH < 120
    header = headline.splitlines()[0].split("  ")
    assert [h.strip() for h in header if h.strip()][:3] == ["policy", "n", "score [95% CI]"]
    for needle in ("ped. at fault", "yield compl.", "min sep p5 m", "pass rate", "delay s", "--full-table"):
        assert needle in headline, needle
    for jargon in ("PET", "DRAC", "minTTC", "unresolved"):  # in the full table, not the headline
        assert jargon not in headline and jargon in format_table(summary, policies), jargon
    row = next(line for line in headline.splitlines() if line.startswith("predictive_yielding "))
    assert f"0.48{CLOSE_MARK}" in row.split()  # the 5th percentile of (0.4, 2.0), marked: a close pass
    other = next(line for line in headline.splitlines() if line.startswith("a_plugin"))
    assert "3.02" in other.split()  # no episode closer than the clearance: no mark
    report = report_markdown(summary, policies, {SCENARIO: SCENARIO}, {"episodes": 2})
    assert "**min sep p5 m**" in report.split("## Definitions", 1)[1]
