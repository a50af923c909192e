"""Output folders replaced whole: a run writes into a staging folder beside the target and swaps it in.

An interrupted run then leaves either the previous folder untouched or the complete new one, never a
mix of both and never a temporary file inside the target. On Linux the swap is one atomic
``renameat2(RENAME_EXCHANGE)``; elsewhere two renames (the old folder is kept aside until the second
one has succeeded).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import shutil
import tempfile
from pathlib import Path

_STAGING = ".{name}.staging-"
_OLD = ".{name}.old-"
_RENAME_EXCHANGE = 2
_AT_FDCWD = -100


class OutputFolderError(OSError):
    """The output folder cannot be used; the message names the folder and why."""


def _exchange(a: Path, b: Path) -> bool:
    """Atomically swap two existing paths (Linux ``renameat2``); False where unsupported."""
    libc_name = ctypes.util.find_library("c")
    if libc_name is None:
        return False
    libc = ctypes.CDLL(libc_name, use_errno=True)
    fn = getattr(libc, "renameat2", None)
    if fn is None:
        return False
    rc = fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE)
    return rc == 0


class StagedFolder:
    """A staging folder for `target`, created beside it at once (so an unusable target fails early).

    Use `path` for every file of the run, then `commit()` to swap it in, or `discard()` to drop it.
    A folder that already exists is replaced only if it is empty or `is_ours(folder)` says it holds an
    earlier run's output, so a mistyped ``--out`` never swallows someone's folder.
    """

    def __init__(self, target: str | os.PathLike[str], marker: str) -> None:
        self.target = Path(target).absolute()
        self.marker = marker
        """A file name every output folder of this kind holds (e.g. ``results.json``)."""
        t = self.target
        if t.exists() or t.is_symlink():
            if not t.is_dir() or t.is_symlink():
                raise OutputFolderError(f"{t}: exists and is not a folder")
            if Path.cwd().resolve().is_relative_to(t.resolve()):
                raise OutputFolderError(f"{t}: is the working folder or holds it; choose a new folder")
            if any(t.iterdir()) and not (t / marker).is_file():
                raise OutputFolderError(
                    f"{t}: exists, is not empty and holds no {marker}, so it is not an earlier run's"
                    " output; choose a new or empty folder"
                )
        try:
            t.parent.mkdir(parents=True, exist_ok=True)
            self._remove_leftovers()
            self.path = Path(tempfile.mkdtemp(prefix=_STAGING.format(name=t.name), dir=t.parent))
            probe = self.path / ".write-test"
            probe.write_bytes(b"")
            probe.unlink()
        except OSError as exc:
            raise OutputFolderError(f"{t}: cannot write there ({exc.strerror or exc})") from None
        os.chmod(self.path, 0o777 & ~_umask())

    def _remove_leftovers(self) -> None:
        """Staging and old folders of a killed earlier run (SIGKILL skips the clean-up)."""
        for pattern in (_STAGING, _OLD):
            for p in self.target.parent.glob(pattern.format(name=self.target.name) + "*"):
                shutil.rmtree(p, ignore_errors=True)

    def commit(self) -> None:
        """Swap the staging folder in for the target; the previous content is then deleted."""
        t = self.target
        if not t.exists():
            os.replace(self.path, t)
            return
        if _exchange(self.path, t):
            shutil.rmtree(self.path, ignore_errors=True)  # now holds the previous content
            return
        old = Path(tempfile.mkdtemp(prefix=_OLD.format(name=t.name), dir=t.parent))
        os.replace(t, old / "x")
        try:
            os.replace(self.path, t)
        except BaseException:
            os.replace(old / "x", t)
            raise
        shutil.rmtree(old, ignore_errors=True)

    def discard(self) -> None:
        """Delete the staging folder; the target is left as it was."""
        shutil.rmtree(self.path, ignore_errors=True)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
