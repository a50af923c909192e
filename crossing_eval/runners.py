"""Running many episode tasks: in this process, a local process pool, or as Ray tasks.

Records come back in completion order and are sorted by (scenario, policy, episode) before they are
returned, so the results never depend on ``workers`` or the backend.
"""

from __future__ import annotations

import multiprocessing
import os
import pickle
import socket
import sys
import traceback
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import Any

from tqdm import tqdm

from crossing_eval.tasks import EpisodeRecord, EpisodeTask, run_episode

DEFAULT_RAY_TIMEOUT = 30.0
"""Seconds to wait for a Ray cluster at ``--address`` before giving up with a message."""


class EpisodeFailed(RuntimeError):
    """An episode raised in a worker; carries the task and the worker's error as text (always picklable)."""

    def __init__(self, task: EpisodeTask, error: str) -> None:
        self.task = task
        self.error = error
        super().__init__(
            f"episode {task.episode} of scenario {task.scenario!r} with policy {task.policy!r}"
            f" (seed {task.seed}) failed: {error}"
        )

    def __reduce__(self) -> tuple[type[EpisodeFailed], tuple[EpisodeTask, str]]:
        """Pickle by the constructor's arguments, so it crosses process and Ray boundaries whole."""
        return (type(self), (self.task, self.error))


class RayConnectionError(ConnectionError):
    """No Ray cluster answered at the given address within the timeout."""


def run_episode_guarded(task: EpisodeTask) -> EpisodeRecord:
    """`run_episode` whose errors always arrive whole in the parent process.

    An exception that pickles (e.g. `scenarios.ScenarioError`) is re-raised as is; one that does not (it
    would surface as a `BrokenProcessPool` with its message lost) becomes `EpisodeFailed` with its text.
    """
    try:
        return run_episode(task)
    except Exception as exc:
        try:
            pickle.loads(pickle.dumps(exc))
        except Exception:
            last = traceback.format_exception_only(type(exc), exc)[-1].strip()
            raise EpisodeFailed(task, last) from None
        raise


def default_workers() -> int:
    """CPUs this process may use (results do not depend on it)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not on Linux
        return max(1, os.cpu_count() or 1)


def _run_local(
    tasks: Sequence[EpisodeTask], workers: int, progress: Callable[[], None]
) -> list[EpisodeRecord]:
    if workers <= 1:
        out = []
        for t in tasks:
            out.append(run_episode(t))
            progress()
        return out
    records: list[EpisodeRecord] = []
    # forkserver, not fork: a forked child of a process that has run torch ops can hang in torch's
    # thread pool, and the predictor wrappers run torch.
    with ProcessPoolExecutor(
        max_workers=workers, mp_context=multiprocessing.get_context("forkserver")
    ) as pool:
        futures = [pool.submit(run_episode_guarded, t) for t in tasks]
        for fut in as_completed(futures):
            records.append(fut.result())
            progress()
    return records


def check_ray_address(address: str, timeout: float = DEFAULT_RAY_TIMEOUT) -> None:
    """Fail fast when nothing listens at a ``host:port`` or ``ray://host:port`` address.

    `ray.init` retries an unreachable address for minutes without a word; a plain TCP connect with a
    timeout tells the user at once. 'auto' (the address of a cluster started on this machine) is left
    to Ray.

    Raises:
        RayConnectionError: when the connection is refused or times out.
    """
    text = address.removeprefix("ray://")
    if address in ("auto", "") or ":" not in text:
        return
    host, _, port_text = text.rpartition(":")
    try:
        port = int(port_text)
    except ValueError:
        raise RayConnectionError(f"Ray address {address!r}: the port {port_text!r} is not a number") from None
    try:
        with socket.create_connection((host.strip("[]"), port), timeout=timeout):
            pass
    except OSError as exc:
        why = "timed out" if isinstance(exc, TimeoutError) else (exc.strerror or str(exc))
        raise RayConnectionError(
            f"no Ray cluster reachable at {address!r} ({why}, waited up to {timeout:g} s); start one with"
            " `ray start --head` or check the address"
        ) from None


def _run_ray(
    tasks: Sequence[EpisodeTask],
    address: str | None,
    workers: int,
    progress: Callable[[], None],
    timeout: float = DEFAULT_RAY_TIMEOUT,
) -> list[EpisodeRecord]:
    """Run the tasks as Ray tasks on an existing cluster (`address`) or a fresh local one."""
    # Imported here, not at the top: ray is an optional extra and slow to import.
    try:
        import ray
    except ImportError as exc:
        raise SystemExit(
            f"crossing-eval: --backend ray needs the optional extra: pip install 'crossing-env[ray]' ({exc})"
        ) from exc
    started = False
    if not ray.is_initialized():
        kwargs: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False}
        if address in (None, "", "local"):
            # A fresh instance we start ourselves: every Ray process inherits these, so token auth and
            # usage stats stay off consistently (see docs/scale-and-rl.md); users may override them.
            os.environ.setdefault("RAY_AUTH_MODE", "disabled")
            os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
            kwargs.update(address="local", num_cpus=max(1, workers), object_store_memory=100 * 2**20)
        else:
            check_ray_address(address, timeout)
            kwargs["address"] = address
        ray.init(**kwargs)
        started = True
    try:
        remote = ray.remote(num_cpus=1)(run_episode_guarded)
        pending = [remote.remote(t) for t in tasks]
        records: list[EpisodeRecord] = []
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            try:
                records.extend(ray.get(done))
            except ray.exceptions.RayTaskError as exc:
                # Ray wraps a task's exception; hand on the original (it pickled, see run_episode_guarded).
                cause = getattr(exc, "cause", None)
                if isinstance(cause, Exception):
                    raise cause from None
                raise
            progress()
        return records
    finally:
        if started:
            ray.shutdown()


def run_tasks(
    tasks: Sequence[EpisodeTask],
    workers: int = 1,
    backend: str = "local",
    address: str | None = None,
    show_progress: bool = True,
    ray_timeout: float = DEFAULT_RAY_TIMEOUT,
) -> list[EpisodeRecord]:
    """Run every task and return the records sorted by (scenario, policy, episode)."""
    bar = tqdm(total=len(tasks), desc="episodes", unit="ep", disable=not show_progress, file=sys.stderr)
    try:
        if backend == "ray":
            records = _run_ray(tasks, address, workers, bar.update, ray_timeout)
        else:
            records = _run_local(tasks, workers, bar.update)
    finally:
        bar.close()
    return sorted(records, key=lambda r: r.key)
