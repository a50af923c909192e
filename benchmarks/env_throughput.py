"""Env steps per second of Crossing-v0 against highway-env's intersection-v0, measured in one run.

Both envs run a random policy with no rendering, resets included. Machines here are noisy, so the
figure that matters is the ratio printed at the end, not the absolute numbers.

    python benchmarks/env_throughput.py [--seconds 10] [--scenario default]
"""

from __future__ import annotations

import argparse
import time
import warnings

import gymnasium as gym
import numpy as np

import crossing_env  # noqa: F401  (registers Crossing-v0)


def steps_per_second(env: gym.Env, seconds: float, seed: int = 0) -> tuple[float, int]:
    """Random-policy steps per second over roughly `seconds` of wall time (resets included)."""
    env.reset(seed=seed)
    env.action_space.seed(seed)
    steps, episodes = 0, 0
    start = time.perf_counter()
    while time.perf_counter() - start < seconds:
        for _ in range(20):
            _, _, terminated, truncated, _ = env.step(env.action_space.sample())
            steps += 1
            if terminated or truncated:
                episodes += 1
                env.reset()
    return steps / (time.perf_counter() - start), episodes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=10.0, help="wall time per env")
    parser.add_argument("--scenario", default="default", help="Crossing-v0 scenario name or path")
    parser.add_argument("--wrappers", action="store_true", help="also time Crossing-v0 with each predictor wrapper")
    args = parser.parse_args()

    ours = gym.make("crossing_env/Crossing-v0", scenario=args.scenario)
    ours_sps, ours_eps = steps_per_second(ours, args.seconds)
    print(f"Crossing-v0 ({args.scenario}): {ours_sps:9.1f} steps/s ({ours_eps} episodes)")
    rows = [("Crossing-v0", ours_sps)]
    if args.wrappers:
        from predictors.registry import available_wrappers

        for name, wrap in available_wrappers().items():
            sps, _ = steps_per_second(wrap(gym.make("crossing_env/Crossing-v0", scenario=args.scenario)), args.seconds)
            print(f"Crossing-v0 + {name}: {sps:9.1f} steps/s")
            rows.append((f"+ {name}", sps))

    import highway_env  # noqa: F401  (registers intersection-v0)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # intersection-v0 warns that it is out of date
        peer = gym.make("intersection-v0")
        peer_sps, peer_eps = steps_per_second(peer, args.seconds)
    print(f"highway-env intersection-v0: {peer_sps:9.1f} steps/s ({peer_eps} episodes)")
    print(f"ratio Crossing-v0 / intersection-v0: {ours_sps / peer_sps:.1f}x (target >= 100x)")
    np.set_printoptions(precision=1)


if __name__ == "__main__":
    main()
