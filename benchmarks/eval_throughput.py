"""`crossing-eval` episodes per second at 1 and 2 local workers, and peak memory, in one run.

Runs the same task list (every built-in scenario × every policy × `--episodes`) once per worker count,
checks that the records are identical, and prints episodes/s and the peak resident memory of the
process with its worker processes (sampled every 0.2 s; needs psutil, in the `bench` extra).

    python benchmarks/eval_throughput.py [--episodes 2] [--workers 1 2]
"""

from __future__ import annotations

import argparse
import threading
import time

import psutil

from crossing_eval.plugins import default_policies
from crossing_eval.runners import run_tasks
from crossing_eval.tasks import make_tasks
from scenarios import list_scenarios


class TreeMemory:
    """Samples the summed resident memory of this process and all its descendants (workers) in a thread."""

    def __init__(self, interval: float = 0.2) -> None:
        self.interval = interval
        self.peak = 0.0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        me = psutil.Process()
        while not self._stop.is_set():
            total = 0
            for proc in [me, *me.children(recursive=True)]:
                try:
                    total += proc.memory_info().rss
                except psutil.Error:  # a worker exited between listing and reading
                    pass
            self.peak = max(self.peak, total / 2**20)
            self._stop.wait(self.interval)

    def __enter__(self) -> TreeMemory:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--episodes", type=int, default=2, help="episodes per scenario and policy")
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2], help="worker counts to compare")
    args = parser.parse_args()
    if args.episodes < 1 or min(args.workers) < 1:
        parser.error("--episodes and --workers must be >= 1")
    tasks = make_tasks(sorted(list_scenarios()), default_policies()[0], args.episodes, base_seed=2024)
    reference = None
    for workers in args.workers:
        with TreeMemory() as memory:
            start = time.perf_counter()
            records = run_tasks(tasks, workers=workers, show_progress=False)
            elapsed = time.perf_counter() - start
        same = "reference" if reference is None else ("identical" if records == reference else "DIFFERENT")
        reference = reference or records
        print(
            f"workers={workers}: {len(tasks)} episodes in {elapsed:6.1f} s "
            f"= {len(tasks) / elapsed:5.2f} episodes/s"
            f"  (records {same}; peak RSS of the process tree {memory.peak:.0f} MiB)",
            flush=True,
        )


if __name__ == "__main__":
    main()
