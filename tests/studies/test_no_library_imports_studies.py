"""`studies/` sits on the top floor: no module of the library layers imports from it (lazy imports too)."""

from __future__ import annotations

import ast
from pathlib import Path

from tests.test_layers import LAYERS

REPO = Path(__file__).resolve().parents[2]


def _imports_studies(path: Path) -> list[str]:
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found += [a.name for a in node.names if a.name.split(".")[0] == "studies"]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            if node.module.split(".")[0] == "studies":
                found.append(node.module)
    return found


def test_no_library_module_imports_studies() -> None:
    offenders = {
        str(path.relative_to(REPO)): names
        for package in LAYERS
        for path in sorted((REPO / package).rglob("*.py"))
        if (names := _imports_studies(path))
    }
    assert not offenders, f"library modules importing studies: {offenders}"


def test_the_predictors_library_has_no_script_entry_point_but_crossing_train() -> None:
    """Issue 21: research and reproduction scripts live in studies/, not in the runtime library."""
    with_main = sorted(
        path.name for path in (REPO / "predictors").rglob("*.py") if "\ndef main(" in path.read_text("utf-8")
    )
    assert with_main == ["train.py"]
