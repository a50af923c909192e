"""The one exception of the replay tools, shared by every module so the CLI can report it as bad input."""

from __future__ import annotations


class ReplayError(ValueError):
    """Bad input to the replay tools (file, field and value named in the message)."""
