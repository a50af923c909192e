"""Scenario errors: every problem found in a file, each naming the field, the value and what is allowed.

`ScenarioError` pickles whole (it crosses process and Ray boundaries in `crossing-eval`'s workers).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

_MAX_REPR = 60


@dataclass(frozen=True)
class Problem:
    """One thing wrong with a scenario: where, what was found and what is allowed."""

    field: str
    """Dotted field path such as `traffic.spawns[0].lane`; empty for file-level problems (syntax, missing)."""
    value: Any
    """The offending value (`None` when the problem is not about a value)."""
    allowed: str
    """What is allowed instead, in words."""
    has_value: bool = True
    """Whether `value` is meaningful (a missing key has no value)."""

    def __str__(self) -> str:
        if not self.field:
            return self.allowed
        if not self.has_value:
            return f"{self.field}: {self.allowed}"
        return f"{self.field} = {_short_repr(self.value)}: {self.allowed}"


class ScenarioError(ValueError):
    """A scenario file or config that cannot be used; the message names file, field, value and rule."""

    def __init__(self, source: str, problems: list[Problem]) -> None:
        self.source = source
        """The file path (or `<string>` / `<config>`) the problems were found in; "" for an unknown name
        (no file to name)."""
        self.problems = tuple(problems)
        """Every problem found, in schema order."""
        if len(problems) == 1:
            message = f"{source}: {problems[0]}" if source else str(problems[0])
        else:
            lines = "\n".join(f"  - {p}" for p in problems)
            message = f"{source}: {len(problems)} problems:\n{lines}"
        super().__init__(message)

    def __reduce__(self) -> tuple[type[ScenarioError], tuple[str, list[Problem]]]:
        """Pickle by the constructor's arguments, so the error arrives whole from a worker process."""
        return (type(self), (self.source, list(self.problems)))


def _short_repr(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= _MAX_REPR else text[: _MAX_REPR - 1] + "…"
