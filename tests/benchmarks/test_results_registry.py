"""The results registry (issues 24 and 55): rendered tables equal their JSON; a stale table says so, and
only a change to what it shows makes it stale."""

from __future__ import annotations

import dataclasses
import json
import subprocess
from pathlib import Path

import pytest

from benchmarks import results
from tests.conftest import data_root


@pytest.mark.parametrize("name", sorted(results.ENTRIES))
def test_every_rendered_table_equals_its_json(name: str) -> None:
    entry = results.ENTRIES[name]
    if entry.fingerprint is results._predictors_fingerprint and not (data_root() / "eth_ucy").is_dir():
        pytest.skip(f"{name}'s fingerprint evaluates on ETH/UCY, not found at {data_root()}")
    assert results.committed_block(entry) == results.rendered_block(entry), (
        f"{entry.document.name}: the {name} block differs from {entry.json_path.name};"
        f" run `python -m benchmarks.results --render` (or re-measure: `python -m benchmarks.results {name}`)"
    )


TAMPERED = (
    "default_table",
    "first_result",
    "predictor_speed",
    *results.BENCHMARK_SCRIPTS,
    "predictor_compare",
)
"""Entries whose block shows a printed report in a code block: a digit in it is a measured figure."""


@pytest.mark.parametrize("name", TAMPERED)
def test_a_hand_edited_number_is_caught(name: str, tmp_path: Path) -> None:
    entry = results.ENTRIES[name]
    original = entry.document.read_text(encoding="utf-8")
    doc = tmp_path / "doc.md"
    doc.write_text(original, encoding="utf-8")
    edited = dataclasses.replace(entry, document=doc)
    assert results.committed_block(edited) == results.rendered_block(edited)
    block = results.committed_block(edited)
    i = next(k for k, ch in enumerate(block) if ch.isdigit() and k > block.index("```"))
    tampered = block[:i] + str((int(block[i]) + 1) % 10) + block[i + 1 :]
    doc.write_text(original.replace(block, tampered), encoding="utf-8")
    assert results.committed_block(edited) != results.rendered_block(edited)
    assert entry.document.read_text(encoding="utf-8") == original  # the real document is untouched


def test_the_committed_documents_pass_the_check() -> None:
    if not (data_root() / "eth_ucy").is_dir():
        pytest.skip(f"the predictor entries' fingerprint evaluates on ETH/UCY, not found at {data_root()}")
    assert results.main(["--check"]) == 0


@pytest.mark.parametrize("name", sorted(results.BENCHMARK_SCRIPTS))
def test_benchmarks_page_lists_each_script_with_its_registered_command(name: str) -> None:
    """The overview table of docs/benchmarks.md names the command the entry runs and stores."""
    script, args, _ = results.BENCHMARK_SCRIPTS[name]
    data = json.loads(results.ENTRIES[name].json_path.read_text(encoding="utf-8"))
    assert data["command"] == " ".join(["python", f"benchmarks/{script}", *args])
    row = next(
        line
        for line in results.ENTRIES[name].document.read_text(encoding="utf-8").splitlines()
        if line.startswith("|") and f"| `{name}` |" in line
    )
    assert f"{data['command']}`" in row


def test_a_script_report_keeps_its_options_and_the_load(monkeypatch: pytest.MonkeyPatch) -> None:
    calls = []

    def fake_run(cmd: list[str], **kwargs: object) -> subprocess.CompletedProcess[str]:
        calls.append(cmd)
        return subprocess.CompletedProcess(cmd, 0, stdout="12.5 steps/s\n", stderr="")

    monkeypatch.setattr(results.subprocess, "run", fake_run)
    monkeypatch.setattr(results.os, "getloadavg", lambda: (1.234, 0.0, 0.0))
    data = results._script_report("soak.py", "--scenario", "default")
    assert calls[0][1:] == [str(results.REPO / "benchmarks" / "soak.py"), "--scenario", "default"]
    assert data["command"] == "python benchmarks/soak.py --scenario default" and data["defaults"] is False
    assert data["load_average"] == 1.23 and data["output"] == "12.5 steps/s\n"
    block = results._render_script({**data, "commit": "c" * 40}, "soak")
    assert "`python benchmarks/soak.py --scenario default` on commit `cccccccccccc`" in block
    assert "(defaults)" not in block and "load average 1.2 at the start" in block
    assert block.endswith("```\n12.5 steps/s\n```")
    plain = results._script_report("predictors.py")
    assert "defaults" not in plain and "(defaults)" in results._script_block(
        {**plain, "commit": "c" * 40}, "x", ""
    )


def test_a_table_measured_on_other_behaviour_is_marked_stale(tmp_path: Path) -> None:
    entry = results.ENTRIES["default_table"]
    data = json.loads(entry.json_path.read_text(encoding="utf-8"))
    assert results.stale_note(data, data["fingerprint"]) == ""
    note = results.stale_note(data, "0" * 16)
    assert note.startswith("> **Stale:**") and data["fingerprint"] in note and "default_table" in note


def test_fingerprint_is_deterministic() -> None:
    again = results.fingerprint_records.__wrapped__()  # recomputed, not the cached episodes
    assert results.dynamics_digest(again) == results.behaviour_fingerprint()
    entry = results.ENTRIES["default_table"]
    assert entry.current_fingerprint(again) == entry.current_fingerprint()


def test_one_measurement_feeds_both_predictor_blocks(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`predictors` and `predictors_summary` share a JSON: measured once, stored under the entry's own
    fingerprint (not the behaviour's), and each block goes stale when that fingerprint changes."""
    calls = []

    def fake_measure() -> dict[str, object]:
        calls.append(1)
        return {"value": 1.5}

    monkeypatch.setattr(results, "RESULTS_DIR", tmp_path)
    monkeypatch.setattr(results, "source_commit", lambda: "c" * 40)
    own = ["f" * 16]
    entries = {}
    for name in ("predictors", "predictors_summary"):
        doc = tmp_path / f"{name}.md"
        doc.write_text(f"# x\n<!-- results:{name} -->\nold\n<!-- /results:{name} -->\n", encoding="utf-8")
        entries[name] = dataclasses.replace(
            results.ENTRIES[name],
            measure=fake_measure,
            render=lambda d, tag=name: f"{tag}: {d['value']}",
            document=doc,
            fingerprint=lambda: own[0],
        )
    monkeypatch.setattr(results, "ENTRIES", entries)
    assert results.main(["predictors", "predictors_summary"]) == 0
    assert len(calls) == 1
    data = json.loads((tmp_path / "predictors.json").read_text(encoding="utf-8"))
    assert data["fingerprint"] == "f" * 16 and data["name"] == "predictors"
    assert results.committed_block(entries["predictors_summary"]) == "predictors_summary: 1.5"
    assert results.main(["--check"]) == 0
    own[0] = "0" * 16  # the weights or the evaluation changed: both blocks are now stale
    for entry in entries.values():
        assert results.rendered_block(entry).startswith("> **Stale:**")
    assert results.main(["--check"]) == 1


def test_a_new_empty_block_is_filled_and_read_back(tmp_path: Path) -> None:
    doc = tmp_path / "doc.md"
    doc.write_text("intro\n<!-- results:x -->\n<!-- /results:x -->\nafter\n", encoding="utf-8")
    entry = dataclasses.replace(results.ENTRIES["safe_rl_long"], name="x", document=doc)
    assert results.committed_block(entry) == ""
    assert results.write_block(entry, "| a |\n| b |")
    assert (
        doc.read_text(encoding="utf-8")
        == "intro\n<!-- results:x -->\n| a |\n| b |\n<!-- /results:x -->\nafter\n"
    )
    assert results.committed_block(entry) == "| a |\n| b |"
    assert not results.write_block(entry, "| a |\n| b |")


# ---------------------------------------------------------------------------------------------------------
# Issue 55: staleness follows what an entry shows
# ---------------------------------------------------------------------------------------------------------

SIMULATED = sorted(name for name, e in results.ENTRIES.items() if e.behaviour and e.fingerprint is None)
"""Entries stamped by the fingerprint episodes (the others carry their own fingerprint)."""


def _fingerprints(records: object) -> dict[str, str | None]:
    return {name: results.ENTRIES[name].current_fingerprint(records) for name in SIMULATED}


def test_an_added_episode_field_leaves_every_entry_current() -> None:
    """A new field in every episode's record (what a new collision kind or count does) moves no
    entry's fingerprint: neither what the episodes do nor any figure an entry shows changed."""
    records = results.fingerprint_records()
    widened = [
        dataclasses.replace(r, result={**r.result, "static_contacts_by_side": 3, "near_misses": [1.0]})
        for r in records
    ]
    assert _fingerprints(widened) == _fingerprints(records)


def test_a_changed_compliance_computation_makes_exactly_its_entries_stale(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The table's compliance with another denominator (obligations + 1): the entries that print
    `crossing-eval`'s table go stale, and no other."""
    records = results.fingerprint_records()
    before = _fingerprints(records)
    from crossing_eval import summary

    real = summary.aggregate

    def other_denominator(res: list[object]) -> dict[str, object]:
        agg = real(res)
        met = agg["yield_compliance"] * agg["yield_obligations"]
        agg["yield_compliance"] = met / (agg["yield_obligations"] + 1)
        return agg

    monkeypatch.setattr(summary, "aggregate", other_denominator)
    after = _fingerprints(records)
    moved = {name for name in SIMULATED if after[name] != before[name]}
    table = {name for name in SIMULATED if results.ENTRIES[name].figures is results.table_figures}
    assert table >= {"default_table", "default_table_summary", "first_result", "predictor_compare"}
    assert moved == table


def test_a_changed_per_episode_figure_moves_only_the_entries_that_show_it() -> None:
    """Each episode's obligation count one higher: every entry showing compliance goes stale (the table,
    the safe-RL scores), the discrimination report (which shows violations, not compliance) and the
    speed and memory scripts (which show no per-episode figure) stay current."""
    records = results.fingerprint_records()
    assert any(r.result["yield_obligations"] for r in records), "no fingerprint episode has an obligation"
    bumped = [
        dataclasses.replace(r, result={**r.result, "yield_obligations": r.result["yield_obligations"] + 1})
        for r in records
    ]
    before, after = _fingerprints(records), _fingerprints(bumped)
    moved = {name for name in SIMULATED if after[name] != before[name]}
    shows_compliance = {
        name
        for name in SIMULATED
        if results.ENTRIES[name].figures in (results.table_figures, results.safe_rl_figures)
    }
    assert "safe_rl" in shows_compliance and "default_table" in shows_compliance
    assert moved == shows_compliance


def test_what_the_episodes_do_moves_every_simulated_entry() -> None:
    """A different action in one episode (the world or a policy changed) makes every simulated entry
    stale, the speed and memory scripts included."""
    records = list(results.fingerprint_records())
    k = next(i for i, r in enumerate(records) if r.task.scenario == "busy_zebra")  # in every entry's set
    actions = records[k].actions
    records[k] = dataclasses.replace(records[k], actions=[*actions[:-1], actions[-1] + 0.5])
    before, after = _fingerprints(results.fingerprint_records()), _fingerprints(records)
    assert all(after[name] != before[name] for name in SIMULATED)


def test_a_new_scenario_stales_only_the_entries_that_run_every_scenario() -> None:
    """A new built-in scenario (its fingerprint episodes added) moves the entries that run every
    built-in scenario (the default table, discrimination, safe RL) and leaves the scripts that run their
    own worlds (the default road, crowds, two zebras) current."""
    records = list(results.fingerprint_records())
    without = [r for r in records if r.task.scenario != "ncap_cpnc"]  # as if ncap_cpnc were new
    before, after = _fingerprints(without), _fingerprints(records)
    moved = {name for name in SIMULATED if after[name] != before[name]}
    every = {name for name in SIMULATED if results.ENTRIES[name].scenarios is None}
    assert {"default_table", "discrimination", "safe_rl", "eval_throughput"} <= every
    assert {"env_throughput", "soak", "world_health", "sim_transfer"}.isdisjoint(every)
    assert moved == every


def test_every_named_scenario_is_built_in() -> None:
    from scenarios import list_scenarios

    for name in SIMULATED:
        assert set(results.ENTRIES[name].scenarios or ()) <= set(list_scenarios()), name


def test_the_value_study_stamps_its_figures_not_the_whole_record() -> None:
    from crossing_eval.value_v2 import episode_figures

    result = results.fingerprint_records()[0].result
    scenario = results.fingerprint_records()[0].task.scenario
    figures = episode_figures(result, scenario)
    assert episode_figures({**result, "a_new_count": 7}, scenario) == figures
    bumped = episode_figures({**result, "yield_obligations": result["yield_obligations"] + 1}, scenario)
    assert bumped["obligations"] == figures["obligations"] + 1


def _fake_registry(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, calls: list[str]) -> dict[str, object]:
    """Four entries in `tmp_path`: 'slow' (last cost 50 s), 'cheap' (5 s), 'unknown' (no cost recorded)
    and 'fresh' (current); each fake measurement appends its name to `calls`."""
    monkeypatch.setattr(results, "RESULTS_DIR", tmp_path)
    monkeypatch.setattr(results, "source_commit", lambda: "c" * 40)
    entries = {}
    for name, cost, fingerprint in (("slow", 50.0, "old"), ("cheap", 5.0, "old"), ("unknown", None, "old"),
                                    ("fresh", 1.0, "new")):  # fmt: skip
        doc = tmp_path / f"{name}.md"
        doc.write_text(f"<!-- results:{name} -->\nx\n<!-- /results:{name} -->\n", encoding="utf-8")
        stored = {"name": name, "commit": "b" * 40, "fingerprint": fingerprint, "value": 0}
        if cost is not None:
            stored["cost_seconds"] = cost
        (tmp_path / f"{name}.json").write_text(json.dumps(stored), encoding="utf-8")

        def fake_measure(name: str = name) -> dict[str, object]:
            calls.append(name)
            if name == "unknown" and calls.count("unknown") == 1 and "interrupt" in calls:
                raise KeyboardInterrupt
            return {"value": 1}

        entries[name] = results.Entry(
            name,
            "slow",
            fake_measure,
            lambda d: f"value {d['value']}",
            doc,
            fingerprint=lambda: "new",
        )
    monkeypatch.setattr(results, "ENTRIES", entries)
    return entries


def test_stale_regenerates_cheapest_first_and_resumes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    calls: list[str] = ["interrupt"]  # the first run is interrupted during 'unknown'
    entries = _fake_registry(tmp_path, monkeypatch, calls)
    assert [e.name for e in results.stale_order(list(entries.values()))] == ["cheap", "slow", "unknown"]
    with pytest.raises(KeyboardInterrupt):
        results.main(["--stale"])
    assert calls == ["interrupt", "cheap", "slow", "unknown"]
    err = capsys.readouterr().err
    assert "[1/3] cheap: measuring (last cost 5 s)" in err and "[2/3] slow: done in" in err
    for name in ("cheap", "slow"):  # written as each finished, and rendered
        data = json.loads((tmp_path / f"{name}.json").read_text(encoding="utf-8"))
        assert data["fingerprint"] == "new" and data["value"] == 1 and "cost_seconds" in data
        assert results.committed_block(entries[name]) == "value 1"
    assert json.loads((tmp_path / "unknown.json").read_text(encoding="utf-8"))["value"] == 0
    calls.clear()
    assert results.main(["--stale"]) == 0  # resumes: only what is still stale
    assert calls == ["unknown"]
    out = capsys.readouterr().out
    assert "fresh" in out and "stale" not in out.replace("--stale", "")
    calls.clear()
    results.main(["--stale"])
    assert calls == []  # everything current: nothing measured


def test_the_listing_shows_each_entry_last_cost(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    _fake_registry(tmp_path, monkeypatch, [])
    assert results.main([]) == 0
    lines = {line.split()[0]: line for line in capsys.readouterr().out.splitlines() if line.strip()}
    assert "stale" in lines["slow"] and "last cost 50 s" in lines["slow"]
    assert "last cost unknown" in lines["unknown"] and "current" in lines["fresh"]
