"""crossing_replay stays split by job: no module grows past about 500 lines."""

from __future__ import annotations

from pathlib import Path

import crossing_replay

MAX_LINES = 500


def test_no_replay_module_exceeds_the_limit() -> None:
    folder = Path(crossing_replay.__file__).parent
    sizes = {p.name: len(p.read_text(encoding="utf-8").splitlines()) for p in folder.glob("*.py")}
    assert {name: n for name, n in sizes.items() if n > MAX_LINES} == {}
