"""The results registry (issue 24): rendered tables equal their JSON; a stale table says so."""

from __future__ import annotations

import dataclasses
import json
import subprocess
from pathlib import Path

import pytest

from benchmarks import results
from tests.conftest import data_root


@pytest.fixture(scope="module")
def fingerprint() -> str:
    return results.behaviour_fingerprint()


@pytest.mark.parametrize("name", sorted(results.ENTRIES))
def test_every_rendered_table_equals_its_json(name: str, fingerprint: str) -> None:
    entry = results.ENTRIES[name]
    if entry.fingerprint is results._predictors_fingerprint and not (data_root() / "eth_ucy").is_dir():
        pytest.skip(f"{name}'s fingerprint evaluates on ETH/UCY, not found at {data_root()}")
    assert results.committed_block(entry) == results.rendered_block(entry, fingerprint), (
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
def test_a_hand_edited_number_is_caught(name: str, tmp_path: Path, fingerprint: str) -> None:
    entry = results.ENTRIES[name]
    original = entry.document.read_text(encoding="utf-8")
    doc = tmp_path / "doc.md"
    doc.write_text(original, encoding="utf-8")
    edited = dataclasses.replace(entry, document=doc)
    assert results.committed_block(edited) == results.rendered_block(edited, fingerprint)
    block = results.committed_block(edited)
    i = next(k for k, ch in enumerate(block) if ch.isdigit() and k > block.index("```"))
    tampered = block[:i] + str((int(block[i]) + 1) % 10) + block[i + 1 :]
    doc.write_text(original.replace(block, tampered), encoding="utf-8")
    assert results.committed_block(edited) != results.rendered_block(edited, fingerprint)
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


def test_fingerprint_is_deterministic(fingerprint: str) -> None:
    assert results.behaviour_fingerprint.__wrapped__() == fingerprint  # recomputed, not the cached value


def test_one_measurement_feeds_both_predictor_blocks(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`predictors` and `predictors_summary` share a JSON: measured once, stored under the entry's own
    fingerprint (not the behaviour's), and each block goes stale when that fingerprint changes."""
    calls = []

    def fake_measure() -> dict[str, object]:
        calls.append(1)
        return {"value": 1.5}

    monkeypatch.setattr(results, "RESULTS_DIR", tmp_path)
    monkeypatch.setattr(results, "behaviour_fingerprint", lambda: "b" * 16)
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
        assert results.rendered_block(entry, "b" * 16).startswith("> **Stale:**")
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
