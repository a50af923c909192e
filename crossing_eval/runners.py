"""Running many episode tasks: in this process, a local process pool, or as Ray tasks.

Records come back in completion order and are sorted by (scenario, policy, episode) before they are
returned, so the results never depend on ``workers`` or the backend.
"""

from __future__ import annotations

import gc
import itertools
import multiprocessing
import os
import pickle
import signal
import socket
import sys
import threading
import time
import traceback
from collections.abc import Callable, Iterable, Iterator, Sequence, Sized
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from contextlib import contextmanager
from typing import Any

from tqdm import tqdm

from crossing_common.processes import fork_is_safe
from crossing_eval.tasks import (
    EpisodeRecord,
    EpisodeTask,
    batches,
    heaviest_first,
    run_batch,
    run_episode,
    warm_up,
)
from rollout import ActionError

IN_FLIGHT_PER_WORKER = 2
"""Batches of tasks (`crossing_eval.tasks.batches`) submitted at a time per worker (lazy submission keeps
memory flat whatever ``--episodes`` is)."""
FIRST_EPISODE_LOOKAHEAD = 64
"""Tasks searched for one with the prediction wrappers, to warm up this process with before forking (and
handed to the workers slowest first)."""
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


def run_batch_guarded(batch: list[EpisodeTask]) -> list[EpisodeRecord]:
    """`run_batch` whose errors arrive as `run_episode_guarded`'s do, naming the episode that failed.

    A batch that raises is run again episode by episode, so the error comes from the task that raised it.
    """
    try:
        return run_batch(batch)
    except (Exception, SystemExit):  # a plug-in's sys.exit() too: it must not end the worker or the run
        return [run_episode_guarded(t) for t in batch]


class RayConnectionError(ConnectionError):
    """No Ray cluster answered at the given address within the timeout."""

    abandoned: bool = False
    """A `ray.init` call was left running in a background thread: the process should exit now."""


def _plugin_error(exc: BaseException) -> str:
    """One line for a plug-in's ``sys.exit()`` or a policy's answer that is not an action."""
    if isinstance(exc, SystemExit):
        return f"the policy or a predictor called sys.exit({exc.code!r})"
    return f"{type(exc).__name__}: {exc}"


def run_episode_guarded(task: EpisodeTask) -> EpisodeRecord:
    """`run_episode` whose errors always arrive whole in the parent process.

    An exception that pickles (e.g. `scenarios.ScenarioError`) is re-raised as is; one that does not (it
    would surface as a `BrokenProcessPool` with its message lost) becomes `EpisodeFailed` with its text, and
    so does a ``sys.exit()`` in a plug-in (in a pool worker it would reach the parent as its own exit).
    """
    try:
        return run_episode(task)
    except (SystemExit, ActionError) as exc:
        raise EpisodeFailed(task, _plugin_error(exc)) from None
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


WORKER_START_SECONDS = {"forkserver": 4.0, "fork": 0.3}
"""Rough CPU cost of starting one worker process. A forkserver worker imports the packages and loads the
env, the predictor models and the policies again: 3-5 s on a warm install, far more when the CPUs are
shared. A forked one starts with the parent's (the preflight's envs and models included); it only loads
the compiled kernels, which this process would otherwise load itself."""
EPISODE_SECONDS = 0.5
"""Rough mean CPU cost of one episode of the default table (0.07 s for constant speed, ~1 s for a yielding
policy under the prediction wrappers)."""


def pool_start_method() -> str:
    """How worker processes start: ``fork`` while this process has not imported torch, else ``forkserver``.

    A forked child of a process that has run torch ops can hang in torch's thread pool; the default run
    does not import torch (the shipped predictor and learned policy run without it), so its workers are
    forked from the preflight's process, with its imports, envs and models, in milliseconds.
    """
    return "fork" if fork_is_safe() else "forkserver"


def pool_pays_off(total: int | None, workers: int, method: str = "forkserver") -> bool:
    """Whether a pool of `workers` processes finishes `total` episodes sooner than this process alone.

    The pool saves about ``total * EPISODE_SECONDS * (1 - 1/workers)`` and costs the start-up of its
    workers (`WORKER_START_SECONDS` by start `method`); a small run
    (`crossing-eval --scenarios zebra_case1 --episodes 1`) with forkserver workers therefore runs in this
    process, with the envs and models the preflight already built. An unknown `total` uses the pool.
    The records are the same either way.
    """
    if workers <= 1:
        return False
    if total is None:
        return True
    return total * EPISODE_SECONDS * (workers - 1) > WORKER_START_SECONDS[method] * workers


class RunInterrupted(Exception):
    """The run was stopped by SIGINT or SIGTERM; pending work was cancelled and the workers stopped.

    `exit_code` is the shell convention: 130 for SIGINT, 143 for SIGTERM.
    """

    def __init__(self, signum: int) -> None:
        self.signum = signum
        self.exit_code = 128 + signum
        name = signal.Signals(signum).name
        super().__init__(f"stopped by {name}: pending episodes cancelled, no output written")


def _ignore_sigint() -> None:
    """Worker initializer: Ctrl-C goes to the whole process group; only the parent handles it.

    SIGTERM gets its default action back: a forked worker inherits the parent's `stop_signals` handler.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


@contextmanager
def stop_signals() -> Iterator[None]:
    """Turn SIGINT and SIGTERM into `RunInterrupted` in the main thread (handlers restored afterwards)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: Any) -> None:
        raise RunInterrupted(signum)

    old = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, h in old.items():
            signal.signal(sig, h)


def _stop_pool(pool: ProcessPoolExecutor) -> None:
    """Cancel what has not started and stop the worker processes now (no orphans)."""
    pool.shutdown(wait=False, cancel_futures=True)
    for proc in list((getattr(pool, "_processes", None) or {}).values()):
        if proc.is_alive():
            proc.terminate()
    for proc in list((getattr(pool, "_processes", None) or {}).values()):
        proc.join(timeout=5)
        if proc.is_alive():
            proc.kill()


def _run_local(
    tasks: Iterable[EpisodeTask],
    workers: int,
    progress: Callable[[int], None],
    while_waiting: Callable[[], None] | None = None,
) -> list[EpisodeRecord]:
    if workers <= 1:
        out = []
        for batch in batches(tasks):
            done = run_batch_guarded(batch)
            out.extend(done)
            progress(len(done))
        return out
    records: list[EpisodeRecord] = []
    # A task list known in full goes to the pool slowest first, so the run does not end with one worker
    # on a long batch while the other waits; a lazy one only within the look-ahead below.
    todo = iter(heaviest_first(tasks) if isinstance(tasks, Sequence) else tasks)
    limit = IN_FLIGHT_PER_WORKER * workers
    # fork only while torch is not imported here (`pool_start_method`); the records are the same either way.
    method = pool_start_method()
    if method == "fork":
        # The first steps of an episode run here first, one with the prediction wrappers if any comes
        # soon: they load (on a fresh install: compile) the kernels once, and every forked worker starts
        # with them (instead of each loading them again, about 1 s of CPU apiece, or compiling them again,
        # tens of seconds). The episodes of the look-ahead then go to the workers, the slowest first.
        head = heaviest_first(list(itertools.islice(todo, FIRST_EPISODE_LOOKAHEAD)))
        if head:
            try:
                warm_up(head[0])
            except (SystemExit, ActionError) as exc:  # as a worker would report it
                raise EpisodeFailed(head[0], _plugin_error(exc)) from None
        todo = itertools.chain(head, todo)
    pending = batches(todo)
    pool = ProcessPoolExecutor(
        max_workers=workers,
        mp_context=multiprocessing.get_context(method),
        initializer=_ignore_sigint,
    )
    try:
        in_flight: set[Future[list[EpisodeRecord]]] = set()
        # Lazy submission: at most `limit` tasks wait in the pool, so memory stays flat however many there
        # are; records are sorted afterwards, so the order of completion never shows in the results.
        # The first submissions fork the workers. The objects that exist then stay out of the collector's
        # sweeps in the workers, so that those do not copy the shared pages they sit in (what `gc.freeze`
        # is documented for); this process collects them again afterwards.
        gc.freeze()
        try:
            for batch in itertools.islice(pending, limit):
                in_flight.add(pool.submit(run_batch_guarded, batch))
        finally:
            gc.unfreeze()
        if while_waiting is not None:
            while_waiting()
        while in_flight:
            done, in_flight = wait(in_flight, return_when=FIRST_COMPLETED)
            for fut in done:
                finished = fut.result()
                records.extend(finished)
                progress(len(finished))
            for batch in itertools.islice(pending, limit - len(in_flight)):
                in_flight.add(pool.submit(run_batch_guarded, batch))
    except BaseException:
        _stop_pool(pool)
        raise
    pool.shutdown(wait=True)
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


def _init_within(ray: Any, kwargs: dict[str, Any], timeout: float) -> None:
    """`ray.init(**kwargs)` that gives up after `timeout` seconds.

    Something that listens at the address but is not a Ray cluster makes `ray.init` retry for minutes; it
    runs in a daemon thread here, and when it has not returned in time the run stops with
    `RayConnectionError` (its ``abandoned`` flag tells the CLI to exit at once, as Ray's own threads may
    still be retrying).
    """
    outcome: dict[str, BaseException | None] = {}

    def target() -> None:
        try:
            ray.init(**kwargs)
            outcome["error"] = None
        except BaseException as exc:  # handed to the caller's thread below
            outcome["error"] = exc

    thread = threading.Thread(target=target, name="ray-init", daemon=True)
    thread.start()
    thread.join(timeout)
    if thread.is_alive():
        error = RayConnectionError(
            f"no Ray cluster answered at {kwargs['address']!r} within {timeout:g} s (--ray-timeout);"
            " something may listen there that is not a Ray cluster: check the address"
        )
        error.abandoned = True
        raise error
    if outcome.get("error") is not None:
        raise outcome["error"]  # type: ignore[misc]


def _run_ray(
    tasks: Iterable[EpisodeTask],
    address: str | None,
    workers: int,
    progress: Callable[[int], None],
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
        try:
            if "address" in kwargs and kwargs["address"] != "local":
                _init_within(ray, kwargs, timeout)
            else:
                ray.init(**kwargs)
        except RayConnectionError:
            raise
        except Exception as exc:  # e.g. something listens there but is not Ray, or no local cluster
            text = str(exc).strip().splitlines()
            raise RayConnectionError(
                f"cannot connect to a Ray cluster at {address or 'local'!r}"
                f" ({text[-1] if text else type(exc).__name__})"
            ) from None
        started = True
    try:
        remote = ray.remote(num_cpus=1)(run_batch_guarded)
        todo = batches(tasks)
        limit = IN_FLIGHT_PER_WORKER * max(1, workers)
        pending = [remote.remote(b) for b in itertools.islice(todo, limit)]
        records: list[EpisodeRecord] = []
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            pending.extend(remote.remote(b) for b in itertools.islice(todo, limit - len(pending)))
            try:
                finished = [r for batch in ray.get(done) for r in batch]
                records.extend(finished)
            except ray.exceptions.RayTaskError as exc:
                # Ray wraps a task's exception; hand on the original (it pickled, see run_episode_guarded).
                cause = getattr(exc, "cause", None)
                if isinstance(cause, Exception):
                    raise cause from None
                raise
            progress(len(finished))
        return records
    finally:
        if started:
            ray.shutdown()


HEARTBEAT_SECONDS = 30.0
"""Without the progress bar, one line on stderr at most this often, so a long run is visibly alive."""


class Heartbeat:
    """Counts finished episodes and prints ``episodes: done/total`` at most every `interval` seconds."""

    def __init__(self, total: int | None, interval: float = HEARTBEAT_SECONDS) -> None:
        self.total = total
        self.interval = interval
        self.done = 0
        self.start = self.last = time.monotonic()

    def update(self, n: int = 1) -> None:
        """`n` more episodes finished (the progress callback's signature)."""
        self.done += n
        now = time.monotonic()
        if now - self.last >= self.interval:
            self.last = now
            of = f"/{self.total}" if self.total is not None else ""
            print(f"episodes: {self.done}{of} done, {now - self.start:.0f} s", file=sys.stderr, flush=True)

    def close(self) -> None:
        """Nothing to release (the bar's interface)."""


def run_tasks(
    tasks: Iterable[EpisodeTask],
    workers: int = 1,
    backend: str = "local",
    address: str | None = None,
    show_progress: bool = True,
    ray_timeout: float = DEFAULT_RAY_TIMEOUT,
    total: int | None = None,
    while_waiting: Callable[[], None] | None = None,
) -> list[EpisodeRecord]:
    """Run every task and return the records sorted by (scenario, policy, episode).

    `tasks` may be a lazy iterable (then give `total` for the progress bar); at most
    ``IN_FLIGHT_PER_WORKER * workers`` of them are submitted at a time. `while_waiting` is work for this
    process while a local pool's workers run the first episodes (called once; e.g. imports the outputs
    need); it is not called without a pool.

    Raises:
        RunInterrupted: SIGINT or SIGTERM arrived; pending work is cancelled and the workers are stopped.
    """
    if total is None:
        total = len(tasks) if isinstance(tasks, Sized) else None
    bar: tqdm | Heartbeat = (
        tqdm(total=total, desc="episodes", unit="ep", file=sys.stderr) if show_progress else Heartbeat(total)
    )
    try:
        with stop_signals():
            try:
                if backend == "ray":
                    records = _run_ray(tasks, address, workers, bar.update, ray_timeout)
                else:
                    records = _run_local(tasks, workers, bar.update, while_waiting)
            except KeyboardInterrupt:  # SIGINT that arrived outside our handler's reach
                raise RunInterrupted(signal.SIGINT) from None
    finally:
        bar.close()
    return sorted(records, key=lambda r: r.key)
