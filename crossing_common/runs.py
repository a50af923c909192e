"""Runs kept side by side: each run of a tool gets its own dated folder, and ``latest`` points at the newest.

As Hydra and Stable-Baselines3 keep runs, a second run never replaces the first unless the user names the
same folder on purpose (``--out``). Only what the tool made is ever touched: the run folder it claimed
(removed again only while still empty) and a ``latest`` symbolic link; a ``latest`` that is not a link
(a user's own file or folder) is left alone.
"""

from __future__ import annotations

import os
from datetime import datetime
from pathlib import Path

LATEST = "latest"
"""The symbolic link, in the parent folder, to the newest complete run."""
STAMP = "%Y-%m-%d_%H-%M-%S"
"""A run folder's name: its start time (local), ``-2``, ``-3``... appended when taken."""


def claim_run_folder(parent: str | os.PathLike[str], now: datetime | None = None) -> Path:
    """Create and return a new, empty run folder ``parent/<date_time>`` (the parent made if needed).

    Created with an exclusive ``mkdir``, so two runs started in the same second get different folders.

    Raises:
        OSError: the parent cannot be created or written (the message names it).
    """
    parent = Path(parent)
    parent.mkdir(parents=True, exist_ok=True)
    stamp = (now or datetime.now()).strftime(STAMP)
    for n in range(1, 1000):
        run = parent / (stamp if n == 1 else f"{stamp}-{n}")
        try:
            run.mkdir()
        except FileExistsError:
            continue
        return run
    raise FileExistsError(f"{parent}: no free run folder name for {stamp}")


def release_if_empty(run: str | os.PathLike[str]) -> None:
    """Remove a claimed run folder that is still empty (the run failed before writing anything)."""
    try:
        Path(run).rmdir()
    except OSError:  # not empty (the run's results) or already gone
        pass


def point_latest(run: str | os.PathLike[str]) -> str | None:
    """Point ``latest`` beside `run` at it (atomically); returns a note when that could not be done.

    An existing ``latest`` is replaced only when it is a symbolic link (one this tool made).
    """
    run = Path(run)
    link = run.parent / LATEST
    if os.path.lexists(link) and not link.is_symlink():
        return f"{link} is not a link this tool made; left as it is"
    tmp = run.parent / f".{LATEST}.{os.getpid()}"
    try:
        if tmp.is_symlink():
            tmp.unlink()
        tmp.symlink_to(run.name, target_is_directory=True)
        os.replace(tmp, link)
    except OSError as exc:  # no symbolic links here (some Windows setups)
        if tmp.is_symlink():
            tmp.unlink()
        return f"could not point {link} at {run.name} ({exc.strerror or exc})"
    return None
