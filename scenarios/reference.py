"""The field reference `docs/scenarios.md`, generated from the config dataclasses' docstrings.

The docstrings in `scenarios/config.py` are the one source; this renders them with each field's type,
default and allowed range (`VALUE_RULES`), and a test keeps the committed file in sync. Regenerate with
``python -m scenarios.reference docs/scenarios.md``.
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import inspect
import sys
from collections.abc import Sequence

from crossing_common.files import write_text_atomic
from scenarios import config as config_module
from scenarios.ranges import VALUE_RULES

TOP_LEVEL = ("ScenarioConfig", "EnvConfig")
"""Where the reference starts: the scenario file's tables, then the env's config."""


def field_docs(cls: type) -> dict[str, str]:
    """Each field's docstring (the string literal after its annotation), read from the class source."""
    tree = ast.parse(inspect.getsource(cls))
    body = tree.body[0].body  # type: ignore[attr-defined]
    out: dict[str, str] = {}
    for stmt, nxt in zip(body, [*body[1:], None], strict=True):
        if (
            isinstance(stmt, ast.AnnAssign)
            and isinstance(stmt.target, ast.Name)
            and isinstance(nxt, ast.Expr)
            and isinstance(nxt.value, ast.Constant)
            and isinstance(nxt.value.value, str)
        ):
            out[stmt.target.id] = " ".join(nxt.value.value.split())
    return out


def _classes() -> list[type]:
    """Config dataclasses reachable from the top-level ones, in first-use order."""
    seen: list[type] = []

    def visit(cls: type) -> None:
        if cls in seen:
            return
        seen.append(cls)
        for f in dataclasses.fields(cls):
            for name in config_module.__dict__:
                sub = getattr(config_module, name)
                if dataclasses.is_dataclass(sub) and isinstance(sub, type) and name in str(f.type):
                    visit(sub)

    for name in TOP_LEVEL:
        visit(getattr(config_module, name))
    return seen


def _default(f: dataclasses.Field[object]) -> str:
    if f.default is not dataclasses.MISSING:
        value = f.default
    elif f.default_factory is not dataclasses.MISSING:
        value = f.default_factory()
    else:
        return "required"
    if dataclasses.is_dataclass(value):
        return "(table)"
    if value == ():
        return "[]"
    return f"`{value!r}`".replace("|", "\\|")


def reference_markdown() -> str:
    """The whole of ``docs/scenarios.md``."""
    lines = [
        "# Scenario and env configuration reference",
        "",
        "Generated from the docstrings in `scenarios/config.py` by `python -m scenarios.reference"
        " docs/scenarios.md`; do not edit by hand (a test checks it is in sync).",
        "",
        "A scenario file's top-level keys are `ScenarioConfig`'s fields; nested tables are the classes below"
        " (`[pedestrians.behaviour]` is a `BehaviourConfig`). The same dotted names work as one-line"
        ' overrides: `gym.make("crossing_env/Crossing-v0", scenario="busy_zebra",'
        ' overrides={"pedestrians.spawn_rate": 12.0})`. `EnvConfig` is given as `config=` (an object or a'
        ' dict such as `{"dt": 0.05}`).',
    ]
    for cls in _classes():
        docs = field_docs(cls)
        lines += ["", f"## `{cls.__name__}`", "", " ".join((cls.__doc__ or "").split()), ""]
        lines += ["| field | type | default | allowed | meaning |", "|---|---|---|---|---|"]
        for f in dataclasses.fields(cls):
            rule = VALUE_RULES.get((cls, f.name))
            allowed = rule.allowed.removeprefix("must be ").replace("|", "\\|") if rule is not None else ""
            tp = str(f.type).replace("|", "or")
            doc = docs.get(f.name, "").replace("|", "\\|")
            lines.append(f"| `{f.name}` | `{tp}` | {_default(f)} | {allowed} | {doc} |")
    return "\n".join(lines) + "\n"


def main(argv: Sequence[str] | None = None) -> int:
    """Write the reference to a file (or print it)."""
    parser = argparse.ArgumentParser(
        prog="python -m scenarios.reference", description=__doc__.splitlines()[0]
    )
    parser.add_argument("path", nargs="?", help="file to write (default: print to stdout)")
    args = parser.parse_args(argv)
    text = reference_markdown()
    if args.path:
        write_text_atomic(args.path, text)
    else:
        sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
