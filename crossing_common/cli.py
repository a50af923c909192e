"""Shared argument types for the command-line tools: bad values fail with the value named, exit 2."""

from __future__ import annotations

import argparse
from collections.abc import Callable


def int_at_least(minimum: int) -> Callable[[str], int]:
    """An argparse `type` that accepts integers >= `minimum` and names the offending text otherwise."""
    wanted = "a positive integer" if minimum == 1 else f"an integer >= {minimum}"

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {wanted}, got {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"expected {wanted}, got {text!r}")
        return value

    return parse


def positive_float(text: str) -> float:
    """An argparse `type` for a finite number > 0, naming the offending text otherwise."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}") from None
    if not (value > 0 and value < float("inf")):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


class DefaultsHelpFormatter(argparse.HelpFormatter):
    """Help that shows each option's default, except where there is none to show (None, False, '')."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        default = action.default
        if "%(default)" in text or "default:" in text:
            return text
        if default is None or default is False or default is argparse.SUPPRESS or default == "":
            return text
        if action.option_strings or action.nargs in (argparse.OPTIONAL, argparse.ZERO_OR_MORE):
            shown = ",".join(map(str, default)) if isinstance(default, list | tuple) else "%(default)s"
            text += f" (default: {shown})"
        return text
