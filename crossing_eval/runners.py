"""Running many episode tasks: in this process, a local process pool, or as Ray tasks.

Records come back in completion order and are sorted by (scenario, policy, episode) before they are
returned, so the results never depend on ``workers`` or the backend.
"""

from __future__ import annotations

import multiprocessing
import os
import sys
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import Any

from tqdm import tqdm

from crossing_eval.tasks import EpisodeRecord, EpisodeTask, run_episode


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
        futures = [pool.submit(run_episode, t) for t in tasks]
        for fut in as_completed(futures):
            records.append(fut.result())
            progress()
    return records


def _run_ray(
    tasks: Sequence[EpisodeTask], address: str | None, workers: int, progress: Callable[[], None]
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
            kwargs["address"] = address
        ray.init(**kwargs)
        started = True
    try:
        remote = ray.remote(num_cpus=1)(run_episode)
        pending = [remote.remote(t) for t in tasks]
        records: list[EpisodeRecord] = []
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            records.extend(ray.get(done))
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
) -> list[EpisodeRecord]:
    """Run every task and return the records sorted by (scenario, policy, episode)."""
    bar = tqdm(total=len(tasks), desc="episodes", unit="ep", disable=not show_progress, file=sys.stderr)
    try:
        if backend == "ray":
            records = _run_ray(tasks, address, workers, bar.update)
        else:
            records = _run_local(tasks, workers, bar.update)
    finally:
        bar.close()
    return sorted(records, key=lambda r: r.key)
