"""Issue 25 item 6: an address where something listens but no Ray cluster answers is exit 2 in time."""

from __future__ import annotations

import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

pytest.importorskip("ray")
REPO = Path(__file__).resolve().parents[2]


def _listener() -> tuple[socket.socket, int]:
    """A TCP server that accepts connections and answers nonsense (not Ray)."""
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(16)

    def serve() -> None:
        while True:
            try:
                conn, _ = srv.accept()
                conn.sendall(b"HTTP/1.0 200 OK\r\n\r\nnot ray")
            except OSError:
                return

    threading.Thread(target=serve, daemon=True).start()
    return srv, srv.getsockname()[1]


def test_a_listener_that_is_not_ray_fails_within_the_timeout(tmp_path: Path) -> None:
    srv, port = _listener()
    argv = ["--scenarios", "zebra_case1", "--episodes", "1", "--policies", "constant_speed", "--no-progress"]
    argv += ["--backend", "ray", "--address", f"127.0.0.1:{port}", "--ray-timeout", "3"]
    start = time.monotonic()
    try:
        proc = subprocess.run(
            [sys.executable, "-m", "crossing_eval.cli", *argv, "--out", str(tmp_path / "o")],
            capture_output=True,
            text=True,
            timeout=90,
            cwd=REPO,
        )
    finally:
        srv.close()
    took = time.monotonic() - start
    errors = [line for line in proc.stderr.splitlines() if line.startswith("crossing-eval: error:")]
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert len(errors) == 1 and "within 3 s" in errors[0] and "Traceback" not in proc.stderr
    assert took < 60, f"took {took:.0f} s"  # imports and the preflight, then at most the 3 s timeout
    assert not (tmp_path / "o").exists()
