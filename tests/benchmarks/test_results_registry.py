"""The results registry (issue 24): rendered tables equal their JSON; a stale table says so."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from benchmarks import results


@pytest.fixture(scope="module")
def fingerprint() -> str:
    return results.behaviour_fingerprint()


@pytest.mark.parametrize("name", sorted(results.ENTRIES))
def test_every_rendered_table_equals_its_json(name: str, fingerprint: str) -> None:
    entry = results.ENTRIES[name]
    assert results.committed_block(entry) == results.rendered_block(entry, fingerprint), (
        f"{entry.document.name}: the {name} block differs from {entry.json_path.name};"
        f" run `python -m benchmarks.results --render` (or re-measure: `python -m benchmarks.results {name}`)"
    )


def test_a_hand_edited_number_is_caught(tmp_path: Path, fingerprint: str) -> None:
    entry = results.ENTRIES["default_table"]
    doc = tmp_path / "doc.md"
    doc.write_text(entry.document.read_text(encoding="utf-8"), encoding="utf-8")
    edited = dataclasses.replace(entry, document=doc)
    assert results.committed_block(edited) == results.rendered_block(edited, fingerprint)
    text = doc.read_text(encoding="utf-8")
    block = results.committed_block(edited)
    i = next(k for k, ch in enumerate(block) if ch.isdigit() and k > block.index("```"))
    tampered = block[:i] + str((int(block[i]) + 1) % 10) + block[i + 1 :]
    doc.write_text(text.replace(block, tampered), encoding="utf-8")
    assert results.committed_block(edited) != results.rendered_block(edited, fingerprint)
    assert results.main(["--check"]) == 0  # the real documents are untouched


def test_a_table_measured_on_other_behaviour_is_marked_stale(tmp_path: Path) -> None:
    entry = results.ENTRIES["default_table"]
    data = json.loads(entry.json_path.read_text(encoding="utf-8"))
    assert results.stale_note(data, data["fingerprint"]) == ""
    note = results.stale_note(data, "0" * 16)
    assert note.startswith("> **Stale:**") and data["fingerprint"] in note and "default_table" in note


def test_fingerprint_is_deterministic(fingerprint: str) -> None:
    assert results.behaviour_fingerprint() == fingerprint
