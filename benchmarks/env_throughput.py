"""Env steps per second of Crossing-v0 against highway-env's intersection-v0, measured in one run.

Both envs run a random policy with no rendering, resets included. Machines here are noisy, so the two
envs are timed in alternating bursts (one burst each per round) and the ratio of the totals is what
matters, not the absolute numbers. The last line states whether bare Crossing-v0 meets the target ratio
(`--target`, 200x by default); the exit status is 0 either way unless `--check` is given.

    python benchmarks/env_throughput.py [--rounds 8] [--burst 1.0] [--scenario default] [--wrappers]
                                        [--target 200] [--check]
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings

import gymnasium as gym

import crossing_env  # noqa: F401  (registers Crossing-v0)

TARGET_RATIO = 200.0
"""Bare Crossing-v0 should run at least this many times as many steps per second as intersection-v0."""


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
    parser.add_argument(
        "--target",
        type=float,
        default=TARGET_RATIO,
        help="target ratio of bare Crossing-v0 to intersection-v0 (default: %(default)s)",
    )
    parser.add_argument("--check", action="store_true", help="exit with status 1 if the target is missed")
    args = parser.parse_args()
    if args.rounds < 1 or args.burst <= 0 or args.target <= 0:
        parser.error("--rounds must be >= 1, --burst > 0 and --target > 0")

    from crossing_env.road import register_highway_envs

    register_highway_envs()  # intersection-v0 (crossing_env imports only highway-env's lanes)

    timers = {"Crossing-v0": Timer(gym.make("crossing_env/Crossing-v0", scenario=args.scenario))}
    if args.wrappers:
        from rollout import INTENTION_WRAPPERS, NONE, TRAJECTORY_WRAPPERS, make_env

        for name in INTENTION_WRAPPERS:
            timers[f"Crossing-v0 + intention {name}"] = Timer(make_env(args.scenario, name, NONE)[0])
        for name in TRAJECTORY_WRAPPERS:
            timers[f"Crossing-v0 + predictor {name}"] = Timer(make_env(args.scenario, NONE, name)[0])
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
    ratio = timers["Crossing-v0"].rate / peer.rate
    met = ratio >= args.target
    print(
        f"scenario: {args.scenario}; bare Crossing-v0 / intersection-v0 = {ratio:.1f}x; "
        f"target >= {args.target:g}x: {'met' if met else 'NOT met'}"
    )
    if args.check and not met:
        sys.exit(1)


if __name__ == "__main__":
    main()
