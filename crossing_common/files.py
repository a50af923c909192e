"""Atomic file output: a crashed or interrupted run never leaves half a file behind.

Every writer of results, logs, figures, checkpoints and scenario files in the project goes through here.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


def give_default_permissions(path: str | os.PathLike[str]) -> None:
    """Give a `mkstemp` file (mode 0600) the usual mode of new files: 0666 minus the umask."""
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(path, 0o666 & ~umask)


@contextmanager
def atomic_output(path: str | os.PathLike[str], suffix: str = ".tmp") -> Iterator[Path]:
    """Yield a temporary path beside `path`; on success it replaces `path`, on an exception it is deleted.

    The temporary file lives in the target's folder (created if missing), so `os.replace` is atomic.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=suffix, dir=target.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        give_default_permissions(tmp)
        os.replace(tmp, target)
    finally:
        Path(tmp).unlink(missing_ok=True)


def write_text_atomic(path: str | os.PathLike[str], text: str) -> None:
    """Write UTF-8 `text` to `path` atomically."""
    with atomic_output(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def write_bytes_atomic(path: str | os.PathLike[str], data: bytes) -> None:
    """Write `data` to `path` atomically."""
    with atomic_output(path) as tmp:
        tmp.write_bytes(data)


class ForeignFileError(OSError):
    """An output path holds a file that the tool did not write; the message names it."""


def check_replaceable_file(path: str | os.PathLike[str], heads: tuple[bytes, ...], what: str) -> None:
    r"""Refuse to overwrite an existing `path` unless it starts like a file the tool writes.

    `heads` are the magic bytes of the tool's own output kind (e.g. ``b"RRF2"`` for a rerun recording,
    ``b"\x89PNG"`` for a PNG); a missing file, or one starting with any of them, may be replaced. A
    ``b"?"`` byte in a head matches any byte (MP4's ``????ftyp``).

    Raises:
        ForeignFileError: `path` is not a regular file, or it does not look like `what`.
    """
    p = Path(path)
    if not (p.exists() or p.is_symlink()):
        return
    if not p.is_file() or p.is_symlink():
        raise ForeignFileError(f"--out {str(p)!r}: exists and is not a regular file; not replaced")
    try:
        with p.open("rb") as fh:
            start = fh.read(max((len(h) for h in heads), default=0))
    except OSError as exc:
        raise ForeignFileError(f"--out {str(p)!r}: cannot read it ({exc.strerror or exc})") from None

    def matches(head: bytes) -> bool:
        return len(start) >= len(head) and all(h in (ord("?"), b) for h, b in zip(head, start, strict=False))

    if not any(matches(h) for h in heads):
        raise ForeignFileError(
            f"--out {str(p)!r}: exists and is not {what}, so this tool did not write it; not replaced"
            " (move it or choose another name)"
        )
