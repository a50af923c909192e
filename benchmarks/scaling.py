"""How the cost of one step grows with the number of pedestrians, against PySocialForce, in one run.

Ours: a full `World.step` (cars with IDM, pymunk physics, social force for every pedestrian, decisions,
history). Peer: PySocialForce's `Simulator.step` (pedestrians only, numba-accelerated), with the same
number of pedestrians walking along a corridor. Install the peer with `pip install -e ".[bench]"`.

    python benchmarks/scaling.py [--seconds 5] [--counts 10 50 200]
"""

from __future__ import annotations

import argparse
import logging
import time

import numpy as np

from crossing_env.config import PedestrianConfig, PedestrianSpawn, RoadConfig, ScenarioConfig, TrafficConfig
from crossing_env.world import World


def crowd_scenario(count: int, seed: int = 0) -> ScenarioConfig:
    """`count` pedestrians spread along both sidewalks near the crossing, most of them crossing."""
    rng = np.random.default_rng(seed)
    spawns = tuple(
        PedestrianSpawn(x=float(x), side="south" if i % 2 == 0 else "north", crosses=bool(i % 3 != 0))
        for i, x in enumerate(rng.uniform(60.0, 180.0, size=count))
    )
    return ScenarioConfig(
        road=RoadConfig(length=400.0),
        pedestrians=PedestrianConfig(spawns=spawns, spawn_rate=0.0, max_pedestrians=count),
        traffic=TrafficConfig(flow_per_lane=600.0),
    )


def rate(step, seconds: float) -> float:
    """Calls per second of `step` over about `seconds` of wall time."""
    step()
    n, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        for _ in range(5):
            step()
        n += 5
    return n / (time.perf_counter() - start)


def ours(count: int, seconds: float, chunk: int = 100) -> tuple[float, float]:
    """Steps per second of the full world, and the mean number of pedestrians walking while timed.

    Pedestrians finish their trips, so the world is rebuilt (untimed) every `chunk` steps (10 s) to
    keep the crowd at the requested size.
    """
    steps, elapsed, alive = 0, 0.0, []
    seed = 0
    while elapsed < seconds:
        world = World(crowd_scenario(count, seed), np.random.default_rng(seed))
        world.step(0.0)
        start = time.perf_counter()
        for _ in range(chunk):
            world.step(0.0)
        elapsed += time.perf_counter() - start
        steps += chunk
        alive.append(int(world.pedestrians.active.sum()))
        seed += 1
    return steps / elapsed, float(np.mean(alive))


def peer(count: int, seconds: float) -> float | None:
    """Steps per second of PySocialForce with `count` pedestrians, or None if it is not installed."""
    try:
        logging.disable(logging.CRITICAL)  # PySocialForce logs at DEBUG level on import
        import pysocialforce as psf
    except ImportError:
        return None
    rng = np.random.default_rng(0)
    state = np.zeros((count, 6))
    state[:, 0] = rng.uniform(0.0, 120.0, count)
    state[:, 1] = rng.uniform(0.0, 10.0, count)
    state[:, 2] = 1.3
    state[:, 4] = state[:, 0] + 200.0
    state[:, 5] = state[:, 1]
    sim = psf.Simulator(state)  # pedestrians only: its line obstacles become thousands of points
    return rate(lambda: sim.step(1), seconds)


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--seconds", type=float, default=5.0, help="wall time per measurement")
    parser.add_argument("--counts", type=int, nargs="+", default=[10, 50, 200], help="pedestrian counts")
    args = parser.parse_args()
    print(f"{'pedestrians':>11} {'ours steps/s':>13} {'PySocialForce':>14} {'ratio':>7}")
    for count in args.counts:
        our_rate, alive = ours(count, args.seconds)
        peer_rate = peer(count, args.seconds)
        ratio = f"{our_rate / peer_rate:6.1f}x" if peer_rate else "    n/a"
        peer_text = f"{peer_rate:14.1f}" if peer_rate else f"{'not installed':>14}"
        print(f"{count:>11} {our_rate:13.1f} {peer_text} {ratio}   (ours: {alive:.0f} walking at chunk end)")
    print("target: ours >= 5x PySocialForce at 50 and 200 pedestrians (ours includes cars and physics)")


if __name__ == "__main__":
    main()
