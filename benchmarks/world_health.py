"""World health: do background cars hit pedestrians when nobody controls the ego well?

Runs random-action ego episodes of each scenario (the ego's own behaviour is noise here; what is measured
is the world around it) and counts background car–pedestrian contacts: all of them, those with a
pedestrian who was crossing legally, and those with a legal pedestrian above 2 m/s relative speed (the
target is 0 of these). Rates per episode come with Wilson 95 % intervals (scipy.stats).

    python benchmarks/world_health.py [--episodes 100] [--seed 0] [--scenarios busy_zebra four_lane_arterial]
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np
from scipy.stats import binomtest

import crossing_env  # noqa: F401  (registers Crossing-v0)

HARM_SPEED = 2.0
"""Relative speed (m/s) above which a contact counts as harmful in the target."""


def wilson(k: int, n: int) -> tuple[float, float]:
    """Wilson 95 % interval of a proportion k/n."""
    ci = binomtest(k, n).proportion_ci(confidence_level=0.95, method="wilson")
    return float(ci.low), float(ci.high)


def run_scenario(scenario: str, episodes: int, seed: int) -> dict[str, object]:
    """Contacts over `episodes` random-ego episodes with seeds seed, seed + 1, ..."""
    env = gym.make("crossing_env/Crossing-v0", scenario=scenario)
    contacts: list[tuple[int, float, bool]] = []  # (episode, relative speed, legal)
    ego_hits = 0
    for episode in range(episodes):
        env.reset(seed=seed + episode)
        env.action_space.seed(seed + episode)
        done = False
        while not done:
            _, _, terminated, truncated, info = env.step(env.action_space.sample())
            done = terminated or truncated
            gt = info["ground_truth"]
            ego_hits += sum(c.kind == "pedestrian" for c in gt.collisions)
            for c in gt.extras["background_collisions"]:
                contacts.append((episode, c.relative_speed, c.compliant))
    env.close()
    harmful = [c for c in contacts if c[2] and c[1] > HARM_SPEED]
    return {
        "contacts": len(contacts),
        "legal": sum(c[2] for c in contacts),
        "harmful": len(harmful),
        "episodes_with_contact": len({c[0] for c in contacts}),
        "episodes_with_harm": len({c[0] for c in harmful}),
        "max_harm_speed": max((c[1] for c in harmful), default=float("nan")),
        "speeds": [round(c[1], 2) for c in contacts],
        "ego_pedestrian_hits": ego_hits,
    }


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--episodes", type=int, default=100, help="episodes per scenario")
    parser.add_argument("--seed", type=int, default=0, help="seed of the first episode")
    parser.add_argument("--scenarios", nargs="+", default=["busy_zebra", "four_lane_arterial"])
    args = parser.parse_args()
    if args.episodes < 1:
        parser.error("--episodes must be >= 1")
    print(
        f"{'scenario':22s} {'n':>4s} {'contacts':>8s} {'legal':>6s} {'legal>2m/s':>10s} "
        f"{'episodes w/ legal>2m/s [95% CI]':>32s} {'episodes w/ contact [95% CI]':>30s}"
    )
    total_harm = 0
    for scenario in args.scenarios:
        r = run_scenario(scenario, args.episodes, args.seed)
        n = args.episodes
        h, c = int(r["episodes_with_harm"]), int(r["episodes_with_contact"])
        lo_h, hi_h = wilson(h, n)
        lo_c, hi_c = wilson(c, n)
        total_harm += int(r["harmful"])
        print(
            f"{scenario:22s} {n:4d} {r['contacts']:8d} {r['legal']:6d} {r['harmful']:10d} "
            f"{h / n:12.3f} [{lo_h:.3f}, {hi_h:.3f}]      {c / n:8.3f} [{lo_c:.3f}, {hi_c:.3f}]"
        )
        print(
            f"{'':22s} contact speeds (m/s): {r['speeds'] or 'none'}; "
            f"max legal > 2 m/s: {np.round(r['max_harm_speed'], 2)}; "
            f"ego–pedestrian hits (random ego, not counted): {r['ego_pedestrian_hits']}"
        )
    verdict = "met" if total_harm == 0 else "NOT met"
    print(f"target: 0 contacts with legal pedestrians above {HARM_SPEED} m/s — {verdict} ({total_harm})")


if __name__ == "__main__":
    main()
