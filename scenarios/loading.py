"""Reading scenarios: built-in names and TOML files → validated `ScenarioConfig`.

TOML syntax is checked by `tomllib` (`tomli` on Python 3.10) and reported with file, line and column; the
content then goes through `scenarios.validation`. An empty file is an error, not the default scenario.
"""

from __future__ import annotations

import difflib
import os
import sys
from pathlib import Path

from scenarios.config import ScenarioConfig
from scenarios.errors import Problem, ScenarioError
from scenarios.validation import scenario_from_dict

if sys.version_info >= (3, 11):
    import tomllib as _toml
else:  # pragma: no cover - exercised only on Python 3.10
    try:
        import tomli as _toml
    except ModuleNotFoundError:
        _toml = None

BUILTIN_DIR: Path = Path(__file__).resolve().parent / "builtin"
"""Folder holding the built-in scenario files, one `<name>.toml` each."""


def parse_scenario(text: str, source: str = "<string>", *, default_name: str | None = None) -> ScenarioConfig:
    """Parse and validate TOML text.

    Raises:
        ScenarioError: on TOML syntax errors (with line and column) or invalid content.
    """
    if _toml is None:  # pragma: no cover - Python 3.10 without tomli
        raise ScenarioError(
            source, [Problem("", None, "reading TOML on Python 3.10 needs the 'tomli' package")]
        )
    try:
        data = _toml.loads(text)
    except (ValueError, RecursionError) as exc:  # TOMLDecodeError is a ValueError
        raise ScenarioError(source, [Problem("", None, f"invalid TOML: {exc}")]) from None
    if not data:
        raise ScenarioError(
            source,
            [Problem("", None, "empty scenario: give at least `name = ...` (or use the built-in 'default')")],
        )
    return scenario_from_dict(data, source, default_name=default_name)


def available_scenarios() -> list[str]:
    """Names of the built-in scenarios, sorted."""
    return sorted(p.stem for p in BUILTIN_DIR.glob("*.toml"))


def resolve_scenario_path(name_or_path: str | os.PathLike[str]) -> Path:
    """Map a built-in name or a file path onto a file; a bare name never falls back to the working directory.

    Raises:
        ScenarioError: for an unknown name or a missing file.
    """
    text = os.fspath(name_or_path)
    is_path = isinstance(name_or_path, os.PathLike) or text.endswith(".toml") or os.sep in text or "/" in text
    if is_path:
        path = Path(text)
        if not path.is_file():
            raise ScenarioError(str(path), [Problem("", None, "scenario file not found")])
        return path
    path = BUILTIN_DIR / f"{text}.toml"
    if not path.is_file():
        names = available_scenarios()
        hint = difflib.get_close_matches(text, names, n=1)
        msg = f"unknown scenario {text!r}" + (f" (did you mean {hint[0]!r}?)" if hint else "")
        msg += "; available: " + ", ".join(names) + " (or give a path to a .toml file)"
        raise ScenarioError("", [Problem("", None, msg)])  # no file to name: the name is the problem
    return path


def load_scenario(name_or_path: str | os.PathLike[str]) -> ScenarioConfig:
    """Load a built-in scenario by name (`"zebra_case1"`) or a scenario file by path.

    A file without a `name` key takes its file stem as the name.

    Raises:
        ScenarioError: for an unknown name, a missing or unreadable file, bad TOML or invalid content.
    """
    path = resolve_scenario_path(name_or_path)
    try:
        text = path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ScenarioError(str(path), [Problem("", None, f"not UTF-8 text: {exc}")]) from None
    except OSError as exc:
        raise ScenarioError(
            str(path), [Problem("", None, f"cannot read file: {exc.strerror or exc}")]
        ) from None
    return parse_scenario(text, str(path), default_name=path.stem)


def list_scenarios() -> dict[str, str]:
    """Built-in scenario names mapped to their one-line descriptions (each file is validated)."""
    return {name: load_scenario(name).description for name in available_scenarios()}
