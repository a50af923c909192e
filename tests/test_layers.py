"""The package layers: every import, lazy ones included, runs from a higher layer to a lower one.

scenarios → simulator → predictors → agents → rollout → applications; `crossing_common` is plumbing
under all of them, `benchmarks/` and `examples/` sit on top. No two modules import each other.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

LAYERS: tuple[str, ...] = (
    "crossing_common",
    "scenarios",
    "crossing_env",
    "predictors",
    "agents",
    "rollout",
    "crossing_replay",
    "crossing_eval",
)
"""Bottom to top: a package may import only from packages before it (and itself)."""
TOP = ("benchmarks", "examples", "studies")


def _module_name(path: Path) -> str:
    parts = path.relative_to(REPO).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path) -> set[str]:
    """Project modules imported anywhere in the file (module level or inside functions)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.add(node.module)
            found.update(f"{node.module}.{alias.name}" for alias in node.names)
    return {name for name in found if name.split(".")[0] in LAYERS}


def _sources() -> dict[str, Path]:
    files = {}
    for package in (*LAYERS, *TOP):
        for path in sorted((REPO / package).rglob("*.py")):
            files[_module_name(path)] = path
    return files


SOURCES = _sources()


def _known(name: str) -> str | None:
    """The longest prefix of an imported name that is a module of the project."""
    while name:
        if name in SOURCES:
            return name
        name = name.rpartition(".")[0]
    return None


@pytest.mark.parametrize("module", sorted(SOURCES))
def test_imports_only_run_down(module: str) -> None:
    top = module.split(".")[0]
    rank = len(LAYERS) if top in TOP else LAYERS.index(top)
    upward = sorted(name for name in _imports(SOURCES[module]) if LAYERS.index(name.split(".")[0]) > rank)
    assert not upward, f"{module} imports from a higher layer: {upward}"


def test_no_two_modules_import_each_other() -> None:
    edges = {
        module: {_known(name) for name in _imports(path)} - {None, module} for module, path in SOURCES.items()
    }
    mutual = sorted(
        (a, b) for a, targets in edges.items() for b in targets if a < b and a in edges.get(b, set())
    )
    assert not mutual, f"modules importing each other: {mutual}"


def test_every_package_is_a_layer() -> None:
    packages = {p.parent.name for p in REPO.glob("*/__init__.py")}
    allowed = {*LAYERS, *TOP, "tests"}
    assert packages <= allowed, f"a package outside the layers: {packages - allowed}"
