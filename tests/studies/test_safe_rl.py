"""Steps to safety: the first checkpoint that matches `yielding`, each checkpoint only where still needed."""

from __future__ import annotations

import types
from pathlib import Path

import pytest

import studies.safe_rl as safe_rl


def _record(scenario: str, policy: str, collision: bool, violations: int) -> types.SimpleNamespace:
    result = {
        "collision": collision,
        "yield_obligations": 10,
        "yield_violations": violations,
        "delay": 1.0,
        "passed_crossing": True,
    }
    task = types.SimpleNamespace(scenario=scenario, policy=policy)
    return types.SimpleNamespace(task=task, result=result)


def test_steps_to_safety_takes_the_first_safe_checkpoint_and_skips_reached_scenarios(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    folder = tmp_path / "shielded" / "seed_0"
    folder.mkdir(parents=True)
    for n in (0, 10000, 20000):
        (folder / f"step_{n}.policy.npz").write_bytes(b"")
    # "a" is safe from the start; "b" collides until 10,000 steps; "c" never matches the compliance.
    unsafe = {("b", 0)}
    calls: list[tuple[int, list[str], int]] = []

    def evaluate(specs: list[str], scenarios: list[str], episodes: int, seed: int, workers: int) -> list:
        step = int(specs[0].rsplit("step_", 1)[1].split(".")[0])
        calls.append((step, list(scenarios), episodes))
        return [
            _record(s, specs[0], (s, step) in unsafe, 3 if s == "c" else 0)
            for s in scenarios
            for _ in range(episodes)
        ]

    monkeypatch.setattr(safe_rl, "_evaluate", evaluate)
    monkeypatch.setattr(safe_rl, "_duration", lambda scenario: 30.0)
    reference = {s: {"collisions": 0, "compliance": 1.0} for s in "abc"}
    first = safe_rl.steps_to_safety(tmp_path, "shielded", 0, ["a", "b", "c"], 45, 1, reference)
    assert first == {"a": 0, "b": 10000, "c": None}
    assert calls == [(0, ["a", "b", "c"], 45), (10000, ["b", "c"], 45), (20000, ["c"], 45)]
