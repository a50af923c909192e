"""Fingerprints of the simulator's behaviour, to show that a refactor changed nothing.

Prints two hashes, each over every built-in scenario and a few seeds:

- `world`: random-action rollouts of the bare env, hashing the ground truth (bodies, states, collisions);
- `obs+reward`: the same rollouts, hashing every observation array, the named reward terms and the
  terminated/truncated flags.

Run it before and after a change; equal hashes mean bit-identical rollouts. Uses only public names.

    python benchmarks/fingerprint.py --seeds 3 --steps 200
"""

from __future__ import annotations

import argparse
import hashlib

import gymnasium as gym
import numpy as np

import crossing_env


def _update(h: hashlib._Hash, value: object) -> None:
    if isinstance(value, dict):
        for key in sorted(value):
            h.update(str(key).encode())
            _update(h, value[key])
    elif isinstance(value, (np.ndarray, np.generic, float, int, bool)):
        arr = np.ascontiguousarray(np.asarray(value, dtype=np.float64))
        h.update(arr.tobytes())
    else:
        h.update(repr(value).encode())


def fingerprint(seeds: int, steps: int) -> tuple[str, str]:
    """Hex digests (world, obs+reward) over every built-in scenario × `seeds` rollouts of `steps` steps."""
    world_hash = hashlib.sha256()
    obs_hash = hashlib.sha256()
    for name in sorted(crossing_env.scenarios()):
        env = gym.make(crossing_env.ENV_ID, scenario=name).unwrapped
        for seed in range(seeds):
            actions = np.random.default_rng(1000 + seed)
            obs, info = env.reset(seed=seed)
            _update(obs_hash, obs)
            for _ in range(steps):
                action = actions.uniform(-1.0, 1.0, size=(1,)).astype(np.float32)
                obs, reward, terminated, truncated, info = env.step(action)
                gt = info["ground_truth"]
                _update(obs_hash, obs)
                _update(obs_hash, info["rewards"])
                _update(obs_hash, [reward, terminated, truncated])
                _update(world_hash, gt.ego_position)
                _update(world_hash, gt.ego_velocity)
                _update(world_hash, gt.pedestrian_positions)
                _update(world_hash, gt.pedestrian_velocities)
                _update(world_hash, gt.pedestrian_states)
                _update(world_hash, gt.vehicle_positions)
                _update(world_hash, len(gt.collisions))
                if terminated or truncated:
                    break
        env.close()
    return world_hash.hexdigest()[:16], obs_hash.hexdigest()[:16]


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--seeds", type=int, default=3, help="rollouts per scenario (default: %(default)s)")
    parser.add_argument(
        "--steps", type=int, default=200, help="steps per rollout at most (default: %(default)s)"
    )
    args = parser.parse_args()
    world, obs = fingerprint(args.seeds, args.steps)
    print(f"world {world}")
    print(f"obs+reward {obs}")


if __name__ == "__main__":
    main()
