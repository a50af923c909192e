"""Env steps per second of Crossing-v0 against highway-env's intersection-v0, measured in one run.

Both envs run a random policy with no rendering, resets included. Machines here are noisy, so the two
envs are timed in alternating bursts (one burst each per round) and the ratio of the totals is what
matters, not the absolute numbers.

    python benchmarks/env_throughput.py [--rounds 8] [--burst 1.0] [--scenario default] [--wrappers]
"""

from __future__ import annotations

import argparse
import time
import warnings

import gymnasium as gym

import crossing_env  # noqa: F401  (registers Crossing-v0)


class Timer:
    """Accumulates random-policy steps and wall time of one env across bursts."""

    def __init__(self, env: gym.Env, seed: int = 0) -> None:
        self.env = env
        env.reset(seed=seed)
        env.action_space.seed(seed)
        # Random actions drawn up front: sampling a Box costs tens of microseconds, which would be timed
        # as part of the env step.
        self.actions = [env.action_space.sample() for _ in range(4096)]
        # Untimed warm-up: a first step compiles (or loads from numba's disk cache) the kernels it uses.
        for action in self.actions[:20]:
            env.step(action)
        env.reset(seed=seed)
        self.steps = 0
        self.seconds = 0.0
        self.episodes = 0

    def burst(self, seconds: float) -> None:
        """Step for about `seconds`."""
        start = time.perf_counter()
        while time.perf_counter() - start < seconds:
            for _ in range(10):
                action = self.actions[self.steps % len(self.actions)]
                _, _, terminated, truncated, _ = self.env.step(action)
                self.steps += 1
                if terminated or truncated:
                    self.episodes += 1
                    self.env.reset()
        self.seconds += time.perf_counter() - start

    @property
    def rate(self) -> float:
        """Steps per second so far."""
        return self.steps / self.seconds


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--rounds", type=int, default=8, help="alternating rounds")
    parser.add_argument("--burst", type=float, default=1.0, help="seconds per env per round")
    parser.add_argument("--scenario", default="default", help="Crossing-v0 scenario name or path")
    parser.add_argument(
        "--wrappers", action="store_true", help="also time Crossing-v0 with each predictor wrapper"
    )
    args = parser.parse_args()
    if args.rounds < 1 or args.burst <= 0:
        parser.error("--rounds must be >= 1 and --burst > 0")

    import highway_env  # noqa: F401  (registers intersection-v0)

    timers = {"Crossing-v0": Timer(gym.make("crossing_env/Crossing-v0", scenario=args.scenario))}
    if args.wrappers:
        from predictors.registry import available_wrappers

        for name, wrap in available_wrappers().items():
            timers[f"Crossing-v0 + {name}"] = Timer(
                wrap(gym.make("crossing_env/Crossing-v0", scenario=args.scenario))
            )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # intersection-v0 warns that it is out of date
        peer = Timer(gym.make("intersection-v0"))
        for _ in range(args.rounds):
            peer.burst(args.burst)
            for timer in timers.values():
                timer.burst(args.burst)
    for name, timer in timers.items():
        print(
            f"{name:40s} {timer.rate:9.1f} steps/s ({timer.episodes} episodes)  "
            f"ratio to intersection-v0: {timer.rate / peer.rate:6.1f}x"
        )
    print(f"{'highway-env intersection-v0':40s} {peer.rate:9.1f} steps/s ({peer.episodes} episodes)")
    print(f"scenario: {args.scenario}; target for bare Crossing-v0: >= 100x")


if __name__ == "__main__":
    main()
