"""Output folders replaced whole, only when they are a tool's own earlier output, one run at a time.

A run writes into a staging folder beside the target and swaps it in at the end, so an interrupted run
leaves either the previous folder untouched or the complete new one, never a mix of both and never a
temporary file inside the target. On Linux the swap is one atomic ``renameat2(RENAME_EXCHANGE)``;
elsewhere two renames (the old folder is kept aside until the second one has succeeded).

What is guaranteed:

* **Nothing of the user's is deleted.** Every committed folder holds a marker file (`MARKER_NAME`, JSON)
  naming the tool that wrote it and listing every file it wrote. An existing target is replaced only when
  it is empty or when its marker lists every file in it; a folder without a marker (even one holding a
  ``results.json``), with an unreadable marker, or with any file its marker does not list is refused.
* **One run per folder.** A run holds an exclusive lock (``flock`` on ``.NAME.lock`` beside the target)
  from the moment it claims the folder until it commits or discards; a second run on the same target is
  refused at once with a message naming the folder, and touches nothing.
* **Stale staging folders** (``.NAME.staging-*``, left by a run killed with SIGKILL) are removed only by a
  run that holds the lock, i.e. when no live run can own them.
* **Unusable targets fail before any work**: a file, a read-only folder, an unwritable parent, or the
  working folder itself is a clear `OutputFolderError`, with nothing left behind.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import errno
import json
import os
import shutil
import stat
import sys
import tempfile
from pathlib import Path
from typing import Any

try:
    import fcntl
except ImportError:  # pragma: no cover - not on POSIX
    fcntl = None  # type: ignore[assignment]

MARKER_NAME = ".crossing-output.json"
"""The marker file of every output folder the tools write: ``{"tool": ..., "files": [...]}``."""
_STAGING = ".{name}.staging-"
_OLD = ".{name}.old-"
_LOCK = ".{name}.lock"
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


def _files_in(folder: Path) -> list[str]:
    """Every file (and symlink) under `folder`, as sorted POSIX paths relative to it; folders are left out."""
    out = []
    for root, dirs, files in os.walk(folder):
        rel = Path(root).relative_to(folder)
        out.extend((rel / f).as_posix() for f in files)
        out.extend((rel / d).as_posix() for d in dirs if (Path(root) / d).is_symlink())
    return sorted(out)


def read_marker(folder: str | os.PathLike[str]) -> dict[str, Any] | None:
    """The marker of an output folder (``tool``, ``files``), or None when it has none or it is unreadable."""
    path = Path(folder) / MARKER_NAME
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if (
        not isinstance(doc, dict)
        or not isinstance(doc.get("tool"), str)
        or not isinstance(doc.get("files"), list)
        or not all(isinstance(f, str) for f in doc["files"])
    ):
        return None
    return doc


def write_marker(folder: str | os.PathLike[str], tool: str, files: list[str] | None = None) -> Path:
    """Write the marker of `folder`: `tool` and `files` (default: every file now in it). Returns its path."""
    folder = Path(folder)
    listed = sorted(f for f in (_files_in(folder) if files is None else files) if f != MARKER_NAME)
    path = folder / MARKER_NAME
    path.write_text(json.dumps({"tool": tool, "files": listed}, indent=1) + "\n", encoding="utf-8")
    return path


def foreign_files(folder: str | os.PathLike[str], tool: str | None = None) -> list[str] | None:
    """Files in `folder` that its marker does not list (None: no usable marker, or another `tool`'s).

    An empty folder has no foreign files.
    """
    folder = Path(folder)
    present = [f for f in _files_in(folder) if f != MARKER_NAME]
    marker = read_marker(folder)
    if marker is None:
        return None if present or (folder / MARKER_NAME).exists() else []
    if tool is not None and marker["tool"] != tool:
        return None
    listed = set(marker["files"])
    return [f for f in present if f not in listed]


def _default_tool() -> str:
    return Path(sys.argv[0]).name or "crossing-env"


class FolderLock:
    """An exclusive, non-blocking lock on output target `target` (``flock`` on ``.NAME.lock`` beside it).

    The lock file is deleted on release; acquiring re-checks that the file locked is still the one at the
    path, so a release racing with a new run never lets two runs hold it.
    """

    def __init__(self, target: Path, tool: str) -> None:
        self.path = target.parent / _LOCK.format(name=target.name)
        self._fd: int | None = None
        if fcntl is None:  # pragma: no cover - not on POSIX
            return
        for _ in range(10):
            try:
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            except OSError as exc:
                raise OutputFolderError(f"{target}: cannot write there ({exc.strerror or exc})") from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as exc:
                holder = os.read(fd, 200).decode("utf-8", "replace").strip()
                os.close(fd)
                if exc.errno not in (errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK):
                    raise OutputFolderError(f"{target}: cannot lock it ({exc.strerror or exc})") from None
                who = f" ({holder})" if holder else ""
                raise OutputFolderError(
                    f"{target}: another run{who} is writing this folder; wait for it to finish or choose"
                    " another output folder"
                ) from None
            try:
                same = os.path.samestat(os.fstat(fd), os.stat(self.path))
            except FileNotFoundError:
                same = False
            if same:
                os.ftruncate(fd, 0)
                os.write(fd, f"{tool}, pid {os.getpid()}".encode())
                self._fd = fd
                return
            os.close(fd)  # released and deleted by its holder meanwhile: lock the new file
        raise OutputFolderError(f"{target}: cannot lock it (its lock file keeps changing)")

    @property
    def held(self) -> bool:
        """Whether this object still holds the lock."""
        return self._fd is not None

    def release(self) -> None:
        """Delete the lock file and release the lock (idempotent)."""
        if self._fd is None:
            return
        try:
            self.path.unlink(missing_ok=True)
        finally:
            os.close(self._fd)
            self._fd = None


class StagedFolder:
    """A staging folder for `target`, created beside it at once under an exclusive lock on the target.

    Use `path` for every file of the run, then `commit()` to swap it in, or `discard()` to drop it (either
    releases the lock; `discard` after `commit` is a no-op apart from that). An existing folder is replaced
    only if it is empty or its marker (`MARKER_NAME`) lists every file in it, so a mistyped ``--out``
    never swallows someone's folder. Also a context manager: discards on exit.
    """

    def __init__(self, target: str | os.PathLike[str], marker: str = "", tool: str | None = None) -> None:
        """Claim `target` for a run of `tool` (default: this program's name).

        `marker` names the file every output folder of this kind holds (e.g. ``results.json``); it is only
        used in messages.

        Raises:
            OutputFolderError: the target is unusable, not a replaceable output folder, or locked by
                another run.
        """
        self.target = Path(target).absolute()
        self.marker = marker
        self.tool = tool or _default_tool()
        self.path = Path()
        """The staging folder: every file of the run goes here."""
        self._staged = False
        t = self.target
        self._check_target()
        try:
            t.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise OutputFolderError(f"{t}: cannot write there ({exc.strerror or exc})") from None
        self._lock = FolderLock(t, self.tool)
        try:
            self._check_target()  # again, now that no other run can be committing
            self._remove_leftovers()
            self.path = Path(tempfile.mkdtemp(prefix=_STAGING.format(name=t.name), dir=t.parent))
            self._staged = True
            probe = self.path / ".write-test"
            probe.write_bytes(b"")
            probe.unlink()
            os.chmod(self.path, 0o777 & ~_umask())
        except BaseException as exc:
            if self._staged:
                shutil.rmtree(self.path, ignore_errors=True)
            self._lock.release()
            if isinstance(exc, OSError) and not isinstance(exc, OutputFolderError):
                raise OutputFolderError(f"{t}: cannot write there ({exc.strerror or exc})") from None
            raise

    def __enter__(self) -> StagedFolder:
        """The claimed folder; `discard()` runs on exit."""
        return self

    def __exit__(self, *exc: object) -> None:
        """Discard whatever was not committed and release the lock."""
        self.discard()

    def _check_target(self) -> None:
        """Raise `OutputFolderError` unless the target is missing, empty or a replaceable output folder."""
        t = self.target
        if not (t.exists() or t.is_symlink()):
            return
        if not t.is_dir() or t.is_symlink():
            raise OutputFolderError(f"{t}: exists and is not a folder")
        if Path.cwd().resolve().is_relative_to(t.resolve()):
            raise OutputFolderError(f"{t}: is the working folder or holds it; choose a new folder")
        if not _writable(t):
            raise OutputFolderError(f"{t}: is read-only; choose another folder or make it writable")
        foreign = foreign_files(t)
        if foreign is None:
            what = f"holds no {self.marker} with a " if self.marker else "holds no "
            raise OutputFolderError(
                f"{t}: exists, is not empty and {what}{MARKER_NAME} listing its files, so it is not an"
                " earlier run's output; choose a new or empty folder"
            )
        if foreign:
            shown = ", ".join(foreign[:3]) + (f" and {len(foreign) - 3} more" if len(foreign) > 3 else "")
            raise OutputFolderError(
                f"{t}: holds files no run wrote ({shown}); move them or choose a new or empty folder"
            )
        for sub in t.rglob("*"):
            if sub.is_dir() and not sub.is_symlink() and not _writable(sub):
                raise OutputFolderError(f"{t}: {sub.relative_to(t)} is read-only; cannot replace the folder")

    def _remove_leftovers(self) -> None:
        """Staging and old folders of a killed earlier run (called with the lock held: none is live)."""
        for pattern in (_STAGING, _OLD):
            for p in self.target.parent.glob(pattern.format(name=self.target.name) + "*"):
                shutil.rmtree(p, ignore_errors=True)

    def commit(self) -> None:
        """Write the marker, swap the staging folder in for the target, delete the previous content.

        Raises:
            OutputFolderError: the target changed since the run began (it now holds files no run wrote,
                or is no longer a folder); the target is then left as it is.
        """
        if not self._staged or not self._lock.held:
            raise OutputFolderError(f"{self.target}: this staged folder was already committed or discarded")
        write_marker(self.path, self.tool)
        t = self.target
        self._check_target()
        try:
            if not t.exists():
                os.replace(self.path, t)
            elif _exchange(self.path, t):
                shutil.rmtree(self.path, ignore_errors=True)  # now holds the previous content
            else:
                old = Path(tempfile.mkdtemp(prefix=_OLD.format(name=t.name), dir=t.parent))
                os.replace(t, old / "x")
                try:
                    os.replace(self.path, t)
                except BaseException:
                    os.replace(old / "x", t)
                    raise
                shutil.rmtree(old, ignore_errors=True)
        finally:
            self._staged = self.path.exists()
        self._lock.release()

    def discard(self) -> None:
        """Delete the staging folder (the target is left as it was) and release the lock."""
        if self._staged:
            shutil.rmtree(self.path, ignore_errors=True)
            self._staged = False
        self._lock.release()


def _writable(folder: Path) -> bool:
    """Writable by this process and not marked read-only (no owner write bit: respected even by root)."""
    return os.access(folder, os.W_OK | os.X_OK) and bool(folder.stat().st_mode & stat.S_IWUSR)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
