"""Train Stable-Baselines3 PPO on `crossing_env/Crossing-v0` (dict observations) and evaluate it.

    python examples/ppo_crossing.py --timesteps 200000 --scenario zebra_case1 --save ppo_crossing.zip

PPO uses SB3's ``MultiInputPolicy`` (a ``CombinedExtractor`` flattens each Box of the Dict observation).
The observation holds positions up to ±500 m, so ``VecNormalize`` standardises it (rewards are left as they
are). Envs run in a ``DummyVecEnv``: on a 2-core machine ``SubprocVecEnv`` costs more to start than it
saves. After training, the greedy policy is scored with the same safety metrics as ``crossing-eval``
(collision rate, yield compliance, mean delay) on held-out seeds.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

# Heavy imports (torch, gymnasium, the env) happen inside the functions, so bad arguments fail fast.
ENV_ID = "crossing_env:crossing_env/Crossing-v0"
"""Module-qualified id: worker processes of a SubprocVecEnv import the module and find the id."""


@dataclass(frozen=True)
class Args:
    """Command-line settings (CleanRL style)."""

    timesteps: int = 50_000
    """Total environment steps of training."""
    scenario: str = "zebra_case1"
    """Built-in scenario name or scenario file."""
    n_envs: int = 1
    """Parallel environments in the DummyVecEnv."""
    n_steps: int = 1024
    """Rollout length per env and update (SB3 `n_steps`)."""
    batch_size: int = 64
    """Minibatch size (SB3 `batch_size`)."""
    seed: int = 0
    """Seed of PPO, the envs and the evaluation seeds."""
    eval_episodes: int = 5
    """Episodes of the trained policy scored with the safety metrics (0 = skip)."""
    save: Path | None = None
    """Where to save the trained model (``.zip``); nothing is saved by default."""


def parse_args(argv: list[str] | None = None) -> Args:
    """Parse the command line into `Args` (positive integers enforced; argparse exits with 2 otherwise)."""

    from crossing_common.cli import int_at_least

    positive, non_negative = int_at_least(1), int_at_least(0)
    d = Args()
    p = argparse.ArgumentParser(description="PPO (Stable-Baselines3) on crossing_env/Crossing-v0")
    p.add_argument("--timesteps", type=positive, default=d.timesteps, help="training environment steps")
    p.add_argument("--scenario", default=d.scenario, help="built-in scenario name or .toml file")
    p.add_argument("--n-envs", type=positive, default=d.n_envs, help="parallel envs (DummyVecEnv)")
    p.add_argument("--n-steps", type=positive, default=d.n_steps, help="rollout steps per env and update")
    p.add_argument("--batch-size", type=positive, default=d.batch_size, help="PPO minibatch size")
    p.add_argument("--seed", type=int, default=d.seed, help="random seed")
    p.add_argument("--eval-episodes", type=non_negative, default=d.eval_episodes, help="evaluation episodes")
    p.add_argument("--save", type=Path, default=None, help="save the trained model to this .zip")
    a = p.parse_args(argv)
    return Args(a.timesteps, a.scenario, a.n_envs, a.n_steps, a.batch_size, a.seed, a.eval_episodes, a.save)


def make_env(scenario: str) -> Any:
    """One monitored env (SB3 needs `Monitor` for episode statistics)."""
    import gymnasium as gym
    from stable_baselines3.common.monitor import Monitor

    import crossing_env  # noqa: F401 - registers the env id

    return Monitor(gym.make(ENV_ID, scenario=scenario))


def evaluate(model, vec_normalize, scenario: str, episodes: int, seed: int) -> dict:
    """Greedy rollouts scored with `crossing_env.safety` (the same figures as `crossing-eval`)."""
    import gymnasium as gym

    import crossing_env
    from crossing_env.safety import EpisodeMetrics
    from crossing_eval.statistics import aggregate

    env = gym.make(crossing_env.ENV_ID, scenario=scenario)
    base = env.unwrapped
    results = []
    for ep in range(episodes):
        obs, _ = env.reset(seed=10_000 + seed + ep)
        metrics = EpisodeMetrics(base.scenario, base.config.dt)
        done = False
        while not done:
            batch = {k: v[None] for k, v in obs.items()}
            if vec_normalize is not None:
                batch = vec_normalize.normalize_obs(batch)
            action, _ = model.predict(batch, deterministic=True)
            obs, _, terminated, truncated, info = env.step(np.asarray(action).reshape(1))
            metrics.update(info["ground_truth"])
            done = terminated or truncated
        results.append(metrics.result())
    env.close()
    return aggregate(results)


def main(argv: list[str] | None = None) -> int:
    """Train, optionally save, evaluate; prints the figures."""
    args = parse_args(argv)
    import torch

    torch.set_num_threads(1)
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from scenarios import load_scenario

    load_scenario(args.scenario)  # fail early with the scenario loader's clear message
    venv = DummyVecEnv([lambda: make_env(args.scenario) for _ in range(args.n_envs)])
    venv.seed(args.seed)
    venv = VecNormalize(venv, norm_obs=True, norm_reward=False)
    model = PPO(
        "MultiInputPolicy",
        venv,
        n_steps=args.n_steps,
        batch_size=min(args.batch_size, args.n_steps * args.n_envs),
        seed=args.seed,
        device="cpu",
        verbose=0,
    )
    t0 = time.perf_counter()
    model.learn(total_timesteps=args.timesteps)
    train_s = time.perf_counter() - t0
    print(f"trained PPO for {model.num_timesteps} steps in {train_s:.1f} s on {args.scenario}")
    if args.save is not None:
        model.save(args.save)
        venv.save(str(args.save.with_suffix(".vecnormalize.pkl")))
        print(f"saved {args.save} and its VecNormalize statistics")
    if args.eval_episodes:
        venv.training = False
        agg = evaluate(model, venv, args.scenario, args.eval_episodes, args.seed)
        lo, hi = agg["collision_ci95"]
        print(
            f"eval {agg['episodes']} episodes: collision rate {agg['collision_rate']:.2f}"
            f" [{lo:.2f}, {hi:.2f}],"
            f" yield compliance {agg['yield_compliance']:.2f} ({agg['yield_obligations']} obligations),"
            f" mean delay {agg['mean_delay']:.2f} s, pass rate {agg['pass_rate']:.2f}"
        )
    venv.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
