"""The one exception of the replay tools (reported by the CLI as bad input), and the overwrite guard.

No replay command overwrites a file it did not write: an existing ``--out`` is replaced only when it starts
like the kind of file the command writes (`check_output`).
"""

from __future__ import annotations

import os

from crossing_common.files import ForeignFileError, check_replaceable_file


class ReplayError(ValueError):
    """Bad input to the replay tools (file, field and value named in the message)."""


RRD_HEADS = (b"RRF2", b"RRF0", b"RRIO")
"""How rerun recordings start."""
PNG_HEADS = (b"\x89PNG",)
VIDEO_HEADS = (b"GIF87a", b"GIF89a", b"????ftyp")
LOG_HEADS = (b'{\n "format"',)
"""How episode logs written by `save_episode_log` start."""


def check_output(path: str | os.PathLike[str], heads: tuple[bytes, ...], what: str) -> None:
    """Refuse to overwrite an existing `path` that the tools did not write (see `check_replaceable_file`).

    Raises:
        ReplayError: `path` exists and does not start like `what`.
    """
    try:
        check_replaceable_file(path, heads, what)
    except ForeignFileError as exc:
        raise ReplayError(str(exc)) from None
