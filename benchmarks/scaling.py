"""How the cost of one step grows with the number of pedestrians, against PySocialForce, in one run.

Ours: a full `World.step` (cars with IDM, pymunk physics, social force for every pedestrian, decisions,
history). Peer: PySocialForce's `Simulator.step` (pedestrians only, numba-accelerated, no obstacles),
with the same number of pedestrians walking along a corridor. Install it with `pip install -e ".[bench]"`.

Two crowds, each simulator running its own model of them: *singles* (no groups: PySocialForce's
cheapest configuration) and *pairs* (everyone walks with a companion: PySocialForce adds its group
coherence, repulsion and gaze forces, as in its README example; ours makes companions wait for and go
with each other). The issue's reference figures for the peer, about 1,200 / 220 / 28 steps/s, match
PySocialForce with pairs; without groups it is about three times faster at 10 and 50 pedestrians.

    python benchmarks/scaling.py [--seconds 5] [--counts 10 50 200]
"""

from __future__ import annotations

import argparse
import logging
import time

import numpy as np

from crossing_env.world import World
from scenarios.config import PedestrianConfig, PedestrianSpawn, RoadConfig, ScenarioConfig, TrafficConfig


def crowd_scenario(count: int, seed: int = 0, pairs: bool = False) -> ScenarioConfig:
    """`count` pedestrians spread along both sidewalks near the crossing, most of them crossing.

    With `pairs`, pedestrians 2k and 2k + 1 are companions: same sidewalk and intention, 0.8 m apart.
    """
    rng = np.random.default_rng(seed)
    xs = rng.uniform(60.0, 180.0, size=count)
    if pairs:
        xs[1::2] = xs[0::2][: count // 2] + 0.8
    spawns = tuple(
        PedestrianSpawn(
            x=float(x),
            side="south" if k % 2 == 0 else "north",
            crosses=bool(k % 3 != 0),
            group=k if pairs and 2 * k + 1 < count else -1,
        )
        for x, k in ((x, i // 2 if pairs else i) for i, x in enumerate(xs))
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


def ours(count: int, seconds: float, pairs: bool = False, chunk: int = 100) -> tuple[float, float]:
    """Steps per second of the full world, and the mean number of pedestrians walking while timed.

    Pedestrians finish their trips, so the world is rebuilt (untimed) every `chunk` steps (10 s) to
    keep the crowd at the requested size.
    """
    steps, elapsed, alive = 0, 0.0, []
    seed = 0
    while elapsed < seconds:
        world = World(crowd_scenario(count, seed, pairs), np.random.default_rng(seed))
        world.step(0.0)
        start = time.perf_counter()
        for _ in range(chunk):
            world.step(0.0)
        elapsed += time.perf_counter() - start
        steps += chunk
        alive.append(int(world.pedestrians.active.sum()))
        seed += 1
    return steps / elapsed, float(np.mean(alive))


def peer(count: int, seconds: float, pairs: bool = False) -> float | None:
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
    groups = None
    if pairs:
        state[1::2, 0] = state[0::2, 0][: count // 2] + 0.8
        state[1::2, 1] = state[0::2, 1][: count // 2]
        groups = [[2 * k, 2 * k + 1] for k in range(count // 2)]
    state[:, 4] = state[:, 0] + 200.0
    state[:, 5] = state[:, 1]
    # No obstacles: PySocialForce samples line obstacles into points (10 per metre), which would make
    # kerbs along the corridor cost it far more than our analytic kerb force.
    sim = psf.Simulator(state, groups=groups)
    return rate(lambda: sim.step(1), seconds)


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--seconds", type=float, default=5.0, help="wall time per measurement")
    parser.add_argument("--counts", type=int, nargs="+", default=[10, 50, 200], help="pedestrian counts")
    args = parser.parse_args()
    print(f"{'crowd':>6} {'pedestrians':>11} {'ours steps/s':>13} {'PySocialForce':>14} {'ratio':>7}")
    for pairs in (False, True):
        for count in args.counts:
            our_rate, alive = ours(count, args.seconds, pairs)
            peer_rate = peer(count, args.seconds, pairs)
            ratio = f"{our_rate / peer_rate:6.1f}x" if peer_rate else "    n/a"
            peer_text = f"{peer_rate:14.1f}" if peer_rate else f"{'not installed':>14}"
            crowd = "pairs" if pairs else "single"
            print(
                f"{crowd:>6} {count:>11} {our_rate:13.1f} {peer_text} {ratio}"
                f"   (ours: {alive:.0f} walking at chunk end)"
            )
    print("target: ours >= 5x PySocialForce at 50 and 200 pedestrians (ours includes cars and physics)")


if __name__ == "__main__":
    main()
