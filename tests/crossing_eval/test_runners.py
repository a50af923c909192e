"""crossing-eval's runner: lazy task submission, clean stops on SIGINT/SIGTERM."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from collections.abc import Iterator

import psutil
import pytest

from crossing_eval.runners import (
    FIRST_EPISODE_LOOKAHEAD,
    IN_FLIGHT_PER_WORKER,
    RunInterrupted,
    _run_local,
    run_tasks,
)
from crossing_eval.tasks import BATCH_EPISODES, EpisodeTask


def _tasks(n: int, consumed: list[int]) -> Iterator[EpisodeTask]:
    for i in range(n):
        consumed[0] += 1
        yield EpisodeTask("zebra_case1", "constant_speed", i, i)


def test_tasks_are_submitted_lazily_and_results_do_not_change() -> None:
    consumed, seen = [0], []
    workers = 2

    def progress(n: int) -> None:
        for _ in range(n):
            seen.append(consumed[0] - len(seen) - 1)  # tasks taken but not yet finished

    records = _run_local(_tasks(10, consumed), workers, progress)
    assert len(records) == 10 and consumed[0] == 10
    # At most the in-flight batches (and the one task read past them), or the look-ahead for the episode a
    # forking run starts with here.
    assert max(seen) <= max(IN_FLIGHT_PER_WORKER * workers * BATCH_EPISODES + 1, FIRST_EPISODE_LOOKAHEAD)
    serial = run_tasks(list(_tasks(10, [0])), workers=1, show_progress=False)
    assert [r.key for r in sorted(records, key=lambda r: r.key)] == [r.key for r in serial]
    assert [r.result for r in sorted(records, key=lambda r: r.key)] == [r.result for r in serial]


SCRIPT = """
import sys
from crossing_eval.runners import RunInterrupted, run_tasks
from crossing_eval.tasks import EpisodeTask
tasks = (EpisodeTask("busy_zebra", "yielding", i, i) for i in range(100000))
try:
    run_tasks(tasks, workers=2, show_progress=False, total=100000)
except RunInterrupted as exc:
    print(exc, file=sys.stderr)
    sys.exit(exc.exit_code)
"""


@pytest.mark.parametrize(("sig", "code"), [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_a_signal_stops_the_run_within_seconds(sig: int, code: int) -> None:
    proc = subprocess.Popen([sys.executable, "-c", SCRIPT], stderr=subprocess.PIPE, text=True)
    time.sleep(8)
    deadline = time.monotonic() + 60  # a loaded machine: the first episode runs here before the pool
    while not (children := psutil.Process(proc.pid).children(recursive=True)) and time.monotonic() < deadline:
        time.sleep(0.5)  # children: the workers (and a forkserver and resource tracker, without fork)
    assert children, "the pool had not started"
    t0 = time.monotonic()
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == code, err
    assert time.monotonic() - t0 < 15
    assert "Traceback" not in err and err.strip().count("\n") == 0 and "stopped by" in err
    _, alive = psutil.wait_procs(children, timeout=10)
    assert not alive, f"orphaned processes: {[p.pid for p in alive]}"


def test_run_interrupted_carries_the_shell_exit_code() -> None:
    assert RunInterrupted(signal.SIGINT).exit_code == 130
    assert RunInterrupted(signal.SIGTERM).exit_code == 143


def test_heartbeat_without_the_progress_bar(capsys) -> None:
    from crossing_eval.runners import Heartbeat

    beat = Heartbeat(total=3, interval=0.0)
    beat.update()
    beat.update()
    lines = capsys.readouterr().err.splitlines()
    assert [line.split(",")[0] for line in lines] == ["episodes: 1/3 done", "episodes: 2/3 done"]
    quiet = Heartbeat(total=3, interval=3600.0)
    quiet.update()
    assert capsys.readouterr().err == ""  # at most one line per interval
