"""`crossing-eval --list`: every name the tool accepts, with one line each, so a newcomer need not guess.

Scenarios with their descriptions, policies with the first line of their docstring, predictors and
intention models with their summaries. Installed plug-ins (entry points) are listed by target, never
imported: listing names runs no one's code.
"""

from __future__ import annotations

import argparse
import shutil
import textwrap
from collections.abc import Iterable, Sequence
from typing import Any

import agents.registry as registry
import rollout.wrappers as wrappers
from rollout.wrappers import (
    DEGRADED_INTENTION,
    DEGRADED_PREDICTOR,
    INTENTION_WRAPPERS,
    NONE,
    TRAJECTORY_WRAPPERS,
)
from scenarios import list_scenarios

WIDTH = 100
"""Lines are wrapped to the terminal's width, at most this many columns."""


def _first_line(obj: Any) -> str:
    doc = (getattr(obj, "__doc__", None) or "").strip()
    return doc.splitlines()[0].rstrip(".").replace("`", "") if doc else ""


def _section(title: str, rows: Iterable[tuple[str, str]], width: int) -> list[str]:
    rows = list(rows)
    name_w = min(max(len(n) for n, _ in rows), 24)
    lines = [title]
    for name, text in rows:
        head = f"  {name.ljust(name_w)}  "
        body = textwrap.wrap(text, max(width - len(head), 30)) or [""]
        if len(head) > name_w + 4:  # a long name: its text on the next lines
            lines.append(head.rstrip())
            head = " " * (name_w + 4)
        lines.append(head + body[0])
        lines.extend(" " * (name_w + 4) + more for more in body[1:])
    return [*lines, ""]


def policy_rows() -> list[tuple[str, str]]:
    """(name, one line) of every policy name `make_policy` accepts now; defaults marked."""
    plugins = registry.installed_policies()
    rows = []
    for name in registry.policy_names():
        if name in plugins:
            text = f"installed plug-in ({plugins[name]})"
        else:
            text = _first_line(registry.policy_entry(name).factory)
        rows.append((name, f"{text} [in the default table]" if name in registry.POLICIES else text))
    return rows


def predictor_rows() -> list[tuple[str, str]]:
    """(name, one line) of every ``--predictor`` value."""
    rows = [(n, e.summary) for n, e in TRAJECTORY_WRAPPERS.items()]
    rows.append((f"{DEGRADED_PREDICTOR}=SIGMA", "the path oracle with an error of SIGMA m at 4.8 s"))
    rows.append(("PATH.pt", "a trajectory checkpoint file (predictors/train.py writes them)"))
    rows.extend((n, f"installed plug-in ({t})") for n, t in wrappers.installed_predictors().items())
    rows.append(("pkg.module:attr", "your own forecaster (README, 'Your own predictor')"))
    rows.append((NONE, "no path prediction"))
    return rows


def intention_rows() -> list[tuple[str, str]]:
    """(name, one line) of every ``--intention`` value."""
    rows = [(n, e.summary) for n, e in INTENTION_WRAPPERS.items()]
    rows.append((f"{DEGRADED_INTENTION}=Q", "the intention oracle, wrong for a share Q of pedestrians"))
    rows.append(("pkg.module:attr", "your own intent forecaster"))
    rows.append((NONE, "no intention prediction"))
    return rows


def format_listing(width: int | None = None) -> str:
    """The text `crossing-eval --list` prints."""
    width = min(WIDTH, shutil.get_terminal_size((WIDTH, 24)).columns) if width is None else width
    lines = [
        *_section(
            "scenarios (--scenarios NAME,...; or a scenario .toml file):", list_scenarios().items(), width
        ),
        *_section(
            "policies (--policies NAME,...; or pkg.module:attr, sb3:model.zip, mlp:policy.npz):",
            policy_rows(),
            width,
        ),
        *_section("path predictors (--predictor):", predictor_rows(), width),
        *_section("intention models (--intention):", intention_rows(), width),
    ]
    return "\n".join(lines).rstrip() + "\n"


class ListAction(argparse.Action):
    """``--list``: print `format_listing` and exit 0, whatever else is on the command line (as --help)."""

    def __init__(self, option_strings: Sequence[str], dest: str, **kwargs: Any) -> None:
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kwargs)

    def __call__(self, parser: argparse.ArgumentParser, *args: Any, **kwargs: Any) -> None:
        """Print the listing and exit."""
        print(format_listing(), end="")
        parser.exit(0)
