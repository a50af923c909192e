"""Episode tasks and running one of them, in this process, a worker process or a Ray task.

Determinism: the seed of an episode depends only on (base seed, scenario name, episode index), via
`numpy.random.SeedSequence`, so every policy meets the same situations (a paired comparison; the policy
is deliberately not part of the seed) and a task gives the same record whatever process runs it.
Everything here is importable at module level, so process-pool workers can unpickle tasks and records.
"""

from __future__ import annotations

import sys
import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from agents import make_policy, policy_uses_predictors
from crossing_env import ENV_ID
from crossing_env.safety import EpisodeMetrics


@dataclass(frozen=True)
class EpisodeTask:
    """One episode to run: everything a worker process (or Ray task) needs, picklable."""

    scenario: str
    """Built-in scenario name or path to a scenario file."""
    policy: str
    """Policy name or plug-in spec accepted by `agents.make_policy` (resolved in the worker)."""
    episode: int
    """Episode index within (scenario, policy)."""
    seed: int
    """Seed given to `env.reset`."""
    predictor: str = "none"
    """Trajectory predictor wrapper ('s-cgru', 'cvm', 'none', a checkpoint path, or the privileged 'oracle');
    only for policies that use predictors."""
    intention: str = "none"
    """Intention wrapper ('qlb', 'classical', 'none' or the privileged 'oracle'); only for policies that use
    predictors."""


@dataclass
class EpisodeRecord:
    """What a task returns: the metrics plus what is needed to replay the episode."""

    task: EpisodeTask
    """The task that produced it."""
    result: dict[str, Any]
    """`EpisodeResult.as_dict()` (JSON-safe)."""
    actions: list[float]
    """Actions given to `env.step`, for the replay log."""
    predictors: list[str]
    """Wrappers actually used (empty if none or unavailable)."""
    final_ground_truth: Any = None
    """Last `GroundTruth` of the episode (lets the replay verify itself)."""
    episode_return: float = float("nan")
    """Sum of the env's rewards over the episode (`info['rewards']` terms)."""

    @property
    def key(self) -> tuple[str, str, int]:
        """Sort key: (scenario, policy, episode)."""
        return self.task.scenario, self.task.policy, self.task.episode


def episode_seed(base_seed: int, scenario: str, episode: int) -> int:
    """Deterministic 32-bit seed of (base seed, scenario, episode); independent of policy and workers."""
    tag = zlib.crc32(Path(scenario).stem.encode("utf-8")) if scenario else 0
    ss = np.random.SeedSequence([int(base_seed) & 0xFFFFFFFF, tag, int(episode)])
    return int(ss.generate_state(1, dtype=np.uint32)[0])


def make_tasks(
    scenarios: Sequence[str],
    policies: Sequence[str],
    episodes: int,
    base_seed: int,
    predictor: str = "s-cgru",
    intention: str = "qlb",
) -> list[EpisodeTask]:
    """The sorted task list of a run; predictor settings only go to policies that use them."""
    tasks = []
    for sc in scenarios:
        for pol in policies:
            uses = policy_uses_predictors(pol)
            for ep in range(episodes):
                tasks.append(
                    EpisodeTask(
                        scenario=sc,
                        policy=pol,
                        episode=ep,
                        seed=episode_seed(base_seed, sc, ep),
                        predictor=predictor if uses else "none",
                        intention=intention if uses else "none",
                    )
                )
    return sorted(tasks, key=lambda t: (t.scenario, t.policy, t.episode))


_ENV_CACHE: dict[tuple[str, str, str], tuple[Any, list[str]]] = {}
"""Envs of this process by (scenario, predictor, intention): loading predictor models once per worker."""
_WARNED: set[str] = set()


def _warn_once(message: str) -> None:
    if message not in _WARNED:
        _WARNED.add(message)
        print(f"crossing-eval: {message}", file=sys.stderr)


def build_env(scenario: str, predictor: str = "none", intention: str = "none") -> tuple[Any, list[str]]:
    """The env for a scenario with the requested wrappers.

    Missing predictor modules are skipped with a message; the record then lists which wrappers were used.
    """
    env = gym.make(ENV_ID, scenario=scenario)
    used: list[str] = []
    if intention == "oracle":  # privileged upper bound (reads the world): only when asked for by name
        from predictors.oracle import OracleIntention

        env = OracleIntention(env)
        used.append("intention:oracle")
    elif intention != "none":
        # Imported here, not at the top: the predictor wrappers load torch, which `--help` must not wait for.
        try:
            from predictors import intention as intention_mod
        except ImportError as exc:
            _warn_once(f"intention wrapper unavailable ({exc}); running without crossing_intention")
        else:
            cls_name = "QLBIntention" if intention == "qlb" else "ClassicalIntention"
            cls = getattr(intention_mod, cls_name, None)
            if cls is None:
                _warn_once(f"predictors.intention has no {cls_name}; running without crossing_intention")
            else:
                env = cls(env)
                used.append(f"intention:{intention}")
    if predictor == "oracle":  # privileged upper bound (reads the world): only when asked for by name
        from predictors.oracle import OracleTrajectory

        env = OracleTrajectory(env)
        used.append("trajectory:oracle")
    elif predictor != "none":
        try:
            from predictors.trajectory_wrapper import TrajectoryPrediction  # torch-heavy: see above
        except ImportError as exc:
            _warn_once(f"trajectory wrapper unavailable ({exc}); running without predicted_paths")
        else:
            from predictors.checkpoints import CheckpointError

            try:
                env = TrajectoryPrediction(env, model=predictor)
                used.append(f"trajectory:{predictor}")
            except CheckpointError:
                raise  # corrupt or tampered weights: never evaluate silently without them
            except (OSError, ValueError, RuntimeError) as exc:
                _warn_once(f"trajectory predictor {predictor!r} failed to load ({exc}); running without it")
    return env, used


def _cached_env(task: EpisodeTask) -> tuple[Any, list[str]]:
    key = (task.scenario, task.predictor, task.intention)
    if key not in _ENV_CACHE:
        _ENV_CACHE[key] = build_env(task.scenario, task.predictor, task.intention)
    return _ENV_CACHE[key]


def run_episode(task: EpisodeTask) -> EpisodeRecord:
    """Run one episode with a fresh policy; same task, same record (in any process)."""
    # Imported here, not at the top, so that `--help` does not load torch; one thread per worker process.
    try:
        import torch

        torch.set_num_threads(1)
    except ImportError:  # pragma: no cover - torch is a hard dependency
        pass

    env, used = _cached_env(task)
    base = env.unwrapped
    policy = make_policy(task.policy, scenario=base.scenario, dt=base.config.dt)
    obs, info = env.reset(seed=task.seed)
    metrics = EpisodeMetrics(base.scenario, base.config.dt)
    actions: list[float] = []
    episode_return = 0.0
    done = False
    gt = info["ground_truth"]
    while not done:
        action = np.asarray(policy(obs), dtype=np.float32).reshape(1)
        actions.append(float(action[0]))
        obs, reward, terminated, truncated, info = env.step(action)
        episode_return += float(reward)
        gt = info["ground_truth"]
        metrics.update(gt)
        done = terminated or truncated
    return EpisodeRecord(
        task=task,
        result=metrics.result().as_dict(),
        actions=actions,
        predictors=used,
        final_ground_truth=gt,
        episode_return=episode_return,
    )
