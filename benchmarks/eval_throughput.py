"""`crossing-eval` episodes per second at 1 and 2 local workers, and peak memory, in one run.

Runs the same task list (every built-in scenario × every policy × `--episodes`) once per worker count,
checks that the records are identical, and prints episodes/s and the peak resident memory of the
process and of its worker processes.

    python benchmarks/eval_throughput.py [--episodes 2] [--workers 1 2]
"""

from __future__ import annotations

import argparse
import resource
import time

from agents import POLICIES
from agents.evaluate import make_tasks, run_tasks
from scenarios import list_scenarios


def peak_rss_mib() -> tuple[float, float]:
    """Peak resident set size (MiB) of this process and of its largest finished child."""
    own = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    children = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    return own, children


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--episodes", type=int, default=2, help="episodes per scenario and policy")
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2], help="worker counts to compare")
    args = parser.parse_args()
    if args.episodes < 1 or min(args.workers) < 1:
        parser.error("--episodes and --workers must be >= 1")
    tasks = make_tasks(sorted(list_scenarios()), list(POLICIES), args.episodes, base_seed=2024)
    reference = None
    for workers in args.workers:
        start = time.perf_counter()
        records = run_tasks(tasks, workers=workers, show_progress=False)
        elapsed = time.perf_counter() - start
        same = "reference" if reference is None else ("identical" if records == reference else "DIFFERENT")
        reference = reference or records
        own, child = peak_rss_mib()
        print(
            f"workers={workers}: {len(tasks)} episodes in {elapsed:6.1f} s "
            f"= {len(tasks) / elapsed:5.2f} episodes/s"
            f"  (records {same}; peak RSS main {own:.0f} MiB, largest worker {child:.0f} MiB)",
            flush=True,
        )


if __name__ == "__main__":
    main()
