"""Cost of the privileged oracle predictors against the bare env and the S-CGRU wrapper, in one run.

The trajectory oracle copies the world and rolls it 4.8 s ahead every 0.4 s (`predictors.oracle`), so it
is the dear one; this prints env steps/s with a hold-speed ego for each wrapper on the same seeds, and the
ratio to the bare env (interleaved per seed, so machine noise hits every wrapper alike).

    python benchmarks/oracle_cost.py [--scenarios busy_zebra zebra_case1] [--seeds 3]
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

from rollout import NONE, make_env

WRAPPERS: dict[str, tuple[str, str]] = {
    "bare": (NONE, NONE),
    "oracle intention": ("oracle", NONE),
    "s-cgru paths": (NONE, "s-cgru"),
    "oracle paths": (NONE, "oracle"),
}
"""Row name → (intention, predictor) in `rollout`'s wrapper table."""


def _episode(env: gym.Env, seed: int) -> tuple[int, float]:
    hold = np.zeros(1, np.float32)
    env.reset(seed=seed)
    steps, done, t = 0, False, time.perf_counter()
    while not done:
        _, _, term, trunc, _ = env.step(hold)
        steps += 1
        done = term or trunc
    return steps, time.perf_counter() - t


def main() -> None:
    """Print steps/s per wrapper and scenario, and the ratio to the bare env."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", nargs="+", default=["busy_zebra", "zebra_case1"])
    parser.add_argument("--seeds", type=int, default=3)
    args = parser.parse_args()
    for sc in args.scenarios:
        envs = {name: make_env(sc, *wrappers)[0] for name, wrappers in WRAPPERS.items()}
        _episode(envs["bare"], 0)  # warm up (kernel loading)
        totals = {name: [0, 0.0] for name in envs}
        for seed in range(args.seeds):
            for name, env in envs.items():
                n, dt = _episode(env, seed)
                totals[name][0] += n
                totals[name][1] += dt
        bare = totals["bare"][0] / totals["bare"][1]
        for name, (n, dt) in totals.items():
            rate = n / dt
            print(
                f"{sc:14s} {name:17s} {rate:8.1f} steps/s  {1e3 / rate:6.2f} ms/step"
                f"  {bare / rate:6.1f}x bare"
            )


if __name__ == "__main__":
    main()
