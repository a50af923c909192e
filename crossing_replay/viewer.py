"""The rerun viewer: the native executable shipped in the rerun-sdk wheel, and headless screenshots.

``open_viewer`` needs a display; `screenshot` runs the viewer headless, which needs a Vulkan driver (on a
CPU-only Linux box, Mesa's lavapipe from ``mesa-vulkan-drivers``).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any

from crossing_common.files import give_default_permissions
from crossing_replay.errors import PNG_HEADS, ReplayError, check_output


def viewer_executable() -> str | None:
    """Path of the native viewer shipped in the rerun-sdk wheel (`rerun_cli/rerun`), else `rerun` on PATH."""
    try:
        import rerun_cli

        exe = Path(rerun_cli.__file__).parent / "rerun"
        if exe.is_file():
            return str(exe)
    except ImportError:
        pass
    return shutil.which("rerun")


def open_viewer(path: Path) -> subprocess.Popen[bytes]:
    """Start the viewer on `path` in the background (it needs a display)."""
    exe = viewer_executable()
    if exe is None:
        raise ReplayError("--view: the rerun viewer binary was not found (is rerun-sdk installed?)")
    return subprocess.Popen([exe, str(path)], start_new_session=True)


def _shrink_png(src: Path, max_bytes: int) -> None:
    """Quantise (and if needed downscale) a PNG in place until it is under `max_bytes`."""
    from PIL import Image

    with Image.open(src) as im:
        image = im.convert("RGB")
    scale = 1.0
    while True:
        size = (max(1, int(image.width * scale)), max(1, int(image.height * scale)))
        small = image.resize(size, Image.Resampling.LANCZOS) if scale < 1.0 else image
        small.quantize(colors=256, method=Image.Quantize.MEDIANCUT).save(src, optimize=True)
        if src.stat().st_size <= max_bytes or scale < 0.2:
            return
        scale *= 0.8


def _connect(client_cls: Any, viewer: subprocess.Popen[bytes], port: int) -> Any:
    """A `client_cls` (`ViewerClient`) of the headless `viewer` once it answers (polled for up to ~30 s)."""
    for _ in range(150):
        if viewer.poll() is not None:
            raise ReplayError(f"viewer exited with code {viewer.returncode} (port {port} in use? no Vulkan?)")
        try:
            client = client_cls.connect(f"rerun+http://127.0.0.1:{port}/proxy")
            client.get_state()
            return client
        except Exception:  # the server is not up yet
            time.sleep(0.2)
    raise ReplayError(f"could not connect to the viewer on port {port}")


def _wait_for_file(path: str) -> None:
    """Wait up to ~10 s for the viewer to write `path` (it saves screenshots asynchronously)."""
    for _ in range(100):
        if os.path.exists(path) and os.path.getsize(path) > 0:
            return
        time.sleep(0.1)
    raise ReplayError("the viewer wrote no screenshot")


RRD_MAGIC = b"RRF2"
"""First bytes of a rerun recording file of the rerun-sdk this project pins."""


def verify_recording(path: str | os.PathLike[str], timeout: float = 60.0) -> None:
    """Check that `path` is a readable rerun recording before a viewer is started on it.

    Checks the magic bytes, then runs the shipped ``rerun rrd verify`` (it decodes every message).

    Raises:
        ReplayError: missing file, not a recording, or a recording that does not decode.
    """
    src = Path(path)
    if not src.is_file():
        raise ReplayError(f"recording not found: {src}")
    with src.open("rb") as fh:
        head = fh.read(len(RRD_MAGIC))
    if head != RRD_MAGIC:
        raise ReplayError(f"{src}: not a rerun recording (starts with {head!r}, expected {RRD_MAGIC!r})")
    exe = viewer_executable()
    if exe is None:
        return
    env = dict(os.environ, RERUN_ANALYTICS="0")
    try:
        proc = subprocess.run(
            [exe, "rrd", "verify", str(src)],
            capture_output=True,
            text=True,
            timeout=timeout,
            env=env,
            check=False,
        )
    except subprocess.TimeoutExpired:
        raise ReplayError(f"{src}: `rerun rrd verify` did not finish within {timeout:g} s") from None
    if proc.returncode != 0 or "1 file verified without error" not in proc.stdout + proc.stderr:
        lines = [ln.strip() for ln in (proc.stderr + proc.stdout).splitlines() if "rror" in ln]
        why = lines[0] if lines else f"rerun rrd verify exited with {proc.returncode}"
        raise ReplayError(f"{src}: corrupt recording ({why[:300]})")


def screenshot(
    rrd: str | os.PathLike[str],
    out: str | os.PathLike[str],
    time_s: float,
    size: tuple[int, int] = (1600, 900),
    port: int = 9877,
    max_bytes: int = 500_000,
    settle_s: float = 11.0,
) -> Path:
    """Screenshot of the whole viewer showing `rrd` at ``sim_time = time_s``, without a display.

    Runs the viewer headless (needs a Vulkan driver; on a CPU-only Linux box Mesa's lavapipe from
    ``mesa-vulkan-drivers``), drives it through the experimental `rerun.experimental.ViewerClient`, waits
    `settle_s` for the start-up notices to fade, then writes a PNG of at most `max_bytes` (atomically).
    """
    from rerun.experimental import ViewerClient

    src, dst = Path(rrd).resolve(), Path(out)
    verify_recording(src)
    if dst.suffix != ".png" or not dst.parent.is_dir():
        raise ReplayError(f"--out {str(dst)!r}: must be a .png in an existing folder")
    check_output(dst, PNG_HEADS, "a PNG image")
    exe = viewer_executable()
    if exe is None:
        raise ReplayError("the rerun viewer binary was not found (is rerun-sdk installed?)")
    env = dict(os.environ, CI="true", WGPU_BACKEND=os.environ.get("WGPU_BACKEND", "vulkan"))
    cmd = [
        exe,
        "--headless",
        "--hide-welcome-screen",
        "--window-size",
        f"{size[0]}x{size[1]}",
        "--port",
        str(port),
    ]
    viewer = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    fd, tmp = tempfile.mkstemp(prefix=f".{dst.name}.", suffix=".png", dir=dst.resolve().parent)
    os.close(fd)
    os.unlink(tmp)
    try:
        client = _connect(ViewerClient, viewer, port)
        client.open(str(src))
        time.sleep(settle_s)
        client.set_time("sim_time", duration=float(time_s), play_state="paused")
        time.sleep(1.0)
        client.save_screenshot(tmp)
        _wait_for_file(tmp)
        _shrink_png(Path(tmp), max_bytes)
        give_default_permissions(tmp)
        os.replace(tmp, dst)
    finally:
        viewer.terminate()
        try:
            viewer.wait(timeout=10)
        except subprocess.TimeoutExpired:
            viewer.kill()
        if os.path.exists(tmp):
            os.unlink(tmp)
    return dst
