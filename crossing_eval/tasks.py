"""Episode tasks and running one of them, in this process, a worker process or a Ray task.

Determinism: the seed of an episode depends only on (base seed, scenario name, episode index), via
`numpy.random.SeedSequence`, so every policy meets the same situations (a paired comparison; the policy
is deliberately not part of the seed) and a task gives the same record whatever process runs it.
Everything here is importable at module level, so process-pool workers can unpickle tasks and records.
"""

from __future__ import annotations

import multiprocessing
import sys
import zlib
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import rollout
from agents import policy_is_batched, policy_uses_predictors
from crossing_common import compile_ahead
from crossing_common.processes import fork_is_safe
from crossing_env.pedestrians.social_force import walk_step
from rollout import build_policy, make_env


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
    blind: bool = True
    """Tell the policy only the road, the crossing and its car (`agents.blind_scenario`), not the scenario's
    name, pedestrians or conflict; `crossing-eval --reveal-scenario` sets it False."""


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
    """Labels of the wrappers on (empty if none), e.g. ``["intention:qlb", "trajectory:s-cgru"]``."""
    final_ground_truth: Any = None
    """Last `GroundTruth` of the episode (lets the replay verify itself)."""
    episode_return: float = float("nan")
    """Sum of the env's rewards over the episode (`info['rewards']` terms)."""
    initial_speed: float = float("nan")
    """The ego's speed after reset (m/s); the NCAP-style table bins episodes by it."""
    score: dict[str, float] | None = None
    """The episode's score and its terms (`crossing_env.safety.score.EpisodeScore.as_dict`), set by
    `crossing_eval.scoring.attach_scores` once the reference driver's episode on the same seed is in."""

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
    blind: bool = True,
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
                        blind=blind,
                    )
                )
    return sorted(tasks, key=lambda t: (t.scenario, t.policy, t.episode))


_ENV_CACHE: dict[tuple[str, str, str], tuple[Any, list[str]]] = {}
"""Envs of this process by (scenario, predictor, intention): loading predictor models once per worker.

An env is reset with the task's seed before every episode, so the episodes it ran before (or a preflight
that only built it) never show in a record."""


def cached_env(scenario: str, intention: str = "none", predictor: str = "none") -> tuple[Any, list[str]]:
    """This process's env for (scenario, wrappers) and the wrapper labels, built on first use.

    Raises:
        rollout.WrapperError: a wrapper that cannot be built (nothing is cached then).
    """
    key = (scenario, predictor, intention)
    if key not in _ENV_CACHE:
        _ENV_CACHE[key] = make_env(scenario, intention=intention, predictor=predictor)
    return _ENV_CACHE[key]


def _cached_env(task: EpisodeTask) -> tuple[Any, list[str]]:
    return cached_env(task.scenario, task.intention, task.predictor)


_SPARE_ENVS: dict[tuple[str, str, str], list[Any]] = {}
"""More envs per `cached_env` key, for batches (`run_batch`): a batch steps one env per episode. Kept for
the `SPARE_KEYS` keys used last (an env with the prediction wrappers holds about 4 MB)."""

SPARE_KEYS = 2
"""Keys whose spare envs are kept: tasks come sorted by scenario, so a worker meets one scenario's two
wrapper settings in a row and builds their spares once; older ones are closed."""


def _batch_envs(task: EpisodeTask, n: int) -> tuple[list[Any], list[str]]:
    """`n` distinct envs for `task`'s scenario and wrappers: the cached one and spares, built on first use."""
    env, used = _cached_env(task)
    key = (task.scenario, task.predictor, task.intention)
    spares = _SPARE_ENVS.pop(key, [])
    _SPARE_ENVS[key] = spares  # the most recently used key last
    while len(spares) < n - 1:
        spares.append(make_env(task.scenario, intention=task.intention, predictor=task.predictor)[0])
    while len(_SPARE_ENVS) > SPARE_KEYS:
        for old in _SPARE_ENVS.pop(next(iter(_SPARE_ENVS))):
            old.close()
    return [env, *spares[: n - 1]], used


BATCH_EPISODES = 8
"""Episodes of one scenario, policy and wrappers stepped together at most (`batches`): the default run's 5
episodes make one batch; more per batch would spread little more and balance the workers worse."""


def batches(tasks: Iterable[EpisodeTask], size: int = BATCH_EPISODES) -> Iterator[list[EpisodeTask]]:
    """Runs of consecutive tasks with the same scenario, policy and wrappers, at most `size` long.

    Lazy: it reads one task past each batch, so a lazy task list stays lazy.
    """
    batch: list[EpisodeTask] = []
    for task in tasks:
        if batch and (len(batch) >= size or _batch_key(task) != _batch_key(batch[0])):
            yield batch
            batch = []
        batch.append(task)
    if batch:
        yield batch


def _batch_key(task: EpisodeTask) -> tuple[str, str, str, str, bool]:
    return task.scenario, task.policy, task.predictor, task.intention, task.blind


WARM_UP_STEPS = 40
"""Steps of a warm-up run (`warm_up`): enough to reach every compiled kernel an episode calls (all 27 of
the default run's kernels are loaded after 20 steps of a wrapped zebra episode); episodes run ~300."""


def warm_up(task: EpisodeTask, steps: int = WARM_UP_STEPS) -> None:
    """Run the first `steps` steps of `task` and throw them away, to load the kernels in this process.

    It loads (on a fresh install: compiles) the numba kernels and the models here, so that workers forked
    from this process start with them. Cheaper than running the whole episode here first (a fraction of
    the time of a wrapped episode), and the episode itself then runs in a worker beside the others.
    Nothing carries over: every episode starts with `env.reset(seed)` and a fresh policy.

    On a fresh install the second core compiles too, in a forked child (only where fork is safe: no torch
    imported here): first the kernels the prediction wrappers offer (the trajectory predictor's is the
    largest), then the env's and the policy's kernels, last-called first (`crossing_common.compile_ahead`),
    while this process compiles them first-called first, on the first steps without the wrappers. Both
    save to numba's on-disk cache, so each loads what the other has compiled (only modules with no cache
    file yet, whose kernels have one signature each: `compile_ahead.ahead_of_time`); the wrapped steps then
    load the wrappers' kernels.
    """
    env, _ = _cached_env(task)

    def plain_steps() -> None:
        plain, _ = cached_env(task.scenario)
        policy = build_policy(task.policy, plain, blind=task.blind)
        rollout.run_episode(plain, task.seed, policy=policy, max_steps=steps)

    aside = _kernels_to_compile(env)
    env_cold = not compile_ahead.is_cached(walk_step)  # every step calls it: it stands for the env's
    if (aside is not None or env_cold) and fork_is_safe():
        fresh = compile_ahead.modules_without_cache() if env_cold else set()

        def compile_in_child() -> None:
            if aside is not None:
                aside()
            if fresh:
                signatures = compile_ahead.record_signatures(plain_steps)
                compile_ahead.compile_signatures(reversed(compile_ahead.ahead_of_time(signatures, fresh)))

        child = multiprocessing.get_context("fork").Process(target=compile_in_child, name="compile kernels")
        child.start()
        try:
            plain_steps()
        finally:
            child.join()  # whatever it did, the wrapped steps below compile what is still missing
    policy = build_policy(task.policy, env, blind=task.blind)
    rollout.run_episode(env, task.seed, policy=policy, max_steps=steps)


def _kernels_to_compile(env: Any) -> Callable[[], None] | None:
    """One call compiling the kernels the wrappers in `env`'s chain offer (see `warm_up`), or None.

    Outermost first; a wrapper offers a kernel only while numba's cache lacks it.
    """
    calls = []
    layer = env
    while isinstance(layer, gym.Wrapper):
        offer = getattr(layer, "kernel_to_compile", None)  # the wrapper's own: gymnasium forwards nothing
        call = offer() if callable(offer) else None
        if call is not None:
            calls.append(call)
        layer = layer.env
    if not calls:
        return None

    def compile_all() -> None:
        for call in calls:
            call()

    return compile_all


def heaviest_first(tasks: Sequence[EpisodeTask]) -> list[EpisodeTask]:
    """`tasks` with those under prediction wrappers first, otherwise in their order.

    They are the slowest (about 1 s each, against 0.1-0.7 s): a pool that starts the long episodes first
    does not end waiting on one.
    """
    return sorted(tasks, key=lambda t: t.predictor == "none" and t.intention == "none")


def run_episode(task: EpisodeTask) -> EpisodeRecord:
    """Run one episode with a fresh policy through `rollout`; same task, same record (in any process).

    Raises:
        rollout.WrapperError: a predictor that cannot be loaded (never evaluated silently without it).
    """
    env, used = _cached_env(task)
    policy = build_policy(task.policy, env, blind=task.blind)
    _one_torch_thread()
    return _record(task, rollout.run_episode(env, task.seed, policy=policy), used)


def run_batch(tasks: Sequence[EpisodeTask]) -> list[EpisodeRecord]:
    """The records of `tasks` (one batch of `batches`): the same records as `run_episode` of each.

    A policy that declares itself batched (`agents.policy_is_batched`) drives all the episodes in one call
    per step (`rollout.run_episodes`), which spreads its fixed cost per call; any other runs them one by one.

    Raises:
        ValueError: the tasks differ in scenario, policy or wrappers.
        rollout.WrapperError: a predictor that cannot be loaded (never evaluated silently without it).
    """
    if len({_batch_key(t) for t in tasks}) > 1:
        raise ValueError("a batch holds the episodes of one scenario, policy and wrappers")
    env, used = _cached_env(tasks[0])
    policy = build_policy(tasks[0].policy, env, blind=tasks[0].blind)
    if len(tasks) < 2 or not policy_is_batched(policy):
        return [run_episode(t) for t in tasks]
    envs, used = _batch_envs(tasks[0], len(tasks))
    _one_torch_thread()
    episodes = rollout.run_episodes(envs, [t.seed for t in tasks], policy)
    return [_record(t, e, used) for t, e in zip(tasks, episodes, strict=True)]


def _one_torch_thread() -> None:
    """One torch thread per process, where the env or the policy loaded torch.

    The shipped S-CGRU and the shipped learned policies run without it: importing torch for nothing costs
    1.5 s a process.
    """
    torch = sys.modules.get("torch")
    if torch is not None:
        torch.set_num_threads(1)


def _record(task: EpisodeTask, episode: rollout.Episode, used: list[str]) -> EpisodeRecord:
    return EpisodeRecord(
        task=task,
        result=episode.result,
        actions=episode.actions,
        predictors=list(used),
        final_ground_truth=episode.final_ground_truth,
        episode_return=episode.episode_return,
        initial_speed=episode.initial_speed,
    )
