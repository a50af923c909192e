"""Soak test: a million env steps (resets included) with resident memory that must stay flat.

Prints the RSS at every tenth of the run, then the growth from the end of the first tenth (warm-up) to the
end. Memory that grows with
the number of steps (a leak in the pools, the physics space or the history buffers) shows up here.

    python benchmarks/soak.py [--steps 1000000] [--scenario busy_zebra]
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np
import psutil

import crossing_env  # noqa: F401  (registers Crossing-v0)


def rss_mib() -> float:
    """Resident set size of this process in MiB."""
    return psutil.Process().memory_info().rss / 2**20


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--steps", type=int, default=1_000_000, help="env steps in total")
    parser.add_argument("--scenario", default="busy_zebra", help="scenario name or path")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    if args.steps < 10_000:
        parser.error(f"--steps must be at least 10000 to say anything about memory, got {args.steps}")

    env = gym.make("crossing_env/Crossing-v0", scenario=args.scenario)
    rng = np.random.default_rng(args.seed)
    env.reset(seed=args.seed)
    warmup = args.steps // 10  # allocator pools and caches fill during the first ~100k steps
    report_every = args.steps // 10
    episodes = 0
    start_rss = None
    start = time.perf_counter()
    for step in range(1, args.steps + 1):
        _, _, terminated, truncated, _ = env.step(rng.uniform(-1.0, 1.0, size=1).astype(np.float32))
        if terminated or truncated:
            episodes += 1
            env.reset()
        if step == warmup:
            start_rss = rss_mib()
            print(f"after warm-up ({warmup} steps): RSS {start_rss:.1f} MiB", flush=True)
        if step % report_every == 0:
            print(
                f"{step:>9} steps  {episodes:>6} episodes  RSS {rss_mib():7.1f} MiB  "
                f"{step / (time.perf_counter() - start):7.0f} steps/s",
                flush=True,
            )
    end_rss = rss_mib()
    print(
        f"start RSS {start_rss:.1f} MiB, end RSS {end_rss:.1f} MiB, growth {end_rss - start_rss:+.1f} MiB "
        f"over {args.steps - warmup} steps"
    )


if __name__ == "__main__":
    main()
