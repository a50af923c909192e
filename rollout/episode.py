"""The one episode loop: reset the policy and the env with a seed, step until the end, score from the truth.

`frames` yields every frame (for recorders and videos); `run_episode` consumes them and returns an
`Episode`: the metrics (`crossing_env.safety.EpisodeMetrics`, fed the world's ground truth, never the
policy's view), the actions (enough to replay it), the return and the final ground truth. The same
(env, policy, seed) gives the same `Episode` in any process.
"""

from __future__ import annotations

import hashlib
import json
import sys
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

from agents import Policy
from crossing_env.safety import EpisodeMetrics
from crossing_env.types import GroundTruth


class ActionError(ValueError):
    """A policy returned something that is not an action (the message says what it returned)."""


def _describe(raw: Any) -> str:
    text = repr(raw)
    return text if len(text) <= 60 else text[:57] + "..."


def checked_action(raw: Any) -> np.ndarray:
    """`raw` as the env's action, float32 of shape (1,).

    An action is a real number or a real array of one element, finite. Strings, booleans, objects, several
    numbers and NaN or infinite values are refused, never coerced: a policy that returns ``"0.5"`` has a bug.

    Raises:
        ActionError: anything else, with what was returned.
    """
    if type(raw) is np.ndarray and raw.dtype.kind == "f" and raw.size == 1:  # the built-ins: the fast path
        action = raw.astype(np.float32, copy=False).reshape(1)
    elif isinstance(raw, (bool, np.bool_, str, bytes)):
        raise ActionError(f"the action must be a real number, got {_describe(raw)}")
    else:
        try:
            arr = np.asarray(raw)
        except Exception:  # an object numpy cannot read as an array
            raise ActionError(f"the action must be a real number, got {_describe(raw)}") from None
        if arr.dtype.kind not in "fiu" or arr.size != 1:
            raise ActionError(f"the action must be one real number, got {_describe(raw)}")
        action = arr.astype(np.float32).reshape(1)
    if not np.isfinite(action[0]):
        raise ActionError(f"the action must be finite, got {_describe(raw)}")
    return action


def checked_actions(raw: Any, n: int) -> np.ndarray:
    """A batched policy's actions, (n, 1) float32: `checked_action`'s rule for each of the `n` episodes.

    Raises:
        ActionError: not n real, finite numbers.
    """
    try:
        arr = np.asarray(raw)
    except Exception:
        raise ActionError(f"the actions must be {n} real numbers, got {_describe(raw)}") from None
    if arr.dtype.kind not in "fiu" or arr.size != n:
        raise ActionError(f"the actions must be {n} real numbers, got {_describe(raw)}")
    actions = arr.astype(np.float32).reshape(n, 1)
    if not np.isfinite(actions).all():
        raise ActionError(f"the actions must be finite, got {_describe(raw)}")
    return actions


@dataclass
class Frame:
    """One frame of an episode: what the policy saw and what was true."""

    step: int
    """Frame index (0 = after reset)."""
    observation: dict[str, np.ndarray]
    """The observation the policy saw (after the wrappers)."""
    ground_truth: GroundTruth
    """The world's true state."""
    slot_ids: np.ndarray
    """(K,) pedestrian id shown in each observation slot (−1 = empty), to attach predictions to people."""
    action: np.ndarray | None
    """Action that produced this frame (None for frame 0)."""
    reward: float = 0.0
    """Reward of the step that produced this frame (0 for frame 0)."""
    terminated: bool = False
    """The episode ended in a terminal state at this frame."""
    truncated: bool = False
    """The episode was cut at the time limit at this frame."""


@dataclass
class Episode:
    """What one episode gives: the scored result and what is needed to replay and verify it."""

    result: dict[str, Any]
    """`EpisodeResult.as_dict()` (JSON-safe)."""
    actions: list[float]
    """Actions given to `env.step`, in order."""
    episode_return: float
    """Sum of the env's rewards."""
    final_ground_truth: GroundTruth
    """Last ground truth (lets a replay check that it reproduced the episode)."""
    initial_speed: float = float("nan")
    """The ego's speed after reset (m/s): drawn per seed where a scenario's conflict sweeps it (NCAP)."""


def dynamics_digest(episode: Episode | Any) -> str:
    """Hash of what an episode did: its actions, its final state and whether the ego made contact.

    Registered results go stale on it (and on the figures each shows), never on the whole scored record: a
    field added to `EpisodeResult` changes no episode. Takes an `Episode` or anything with its ``actions``,
    ``final_ground_truth`` and ``result`` (`crossing_eval`'s records).
    """
    gt = episode.final_ground_truth
    digest = hashlib.sha256(json.dumps(list(episode.actions)).encode())
    state = (
        gt.time,
        gt.ego_position,
        gt.ego_velocity,
        gt.pedestrian_positions,
        gt.pedestrian_velocities,
        gt.pedestrian_states,
        gt.vehicle_positions,
        float(bool(episode.result["collision"])),
    )
    for value in state:
        digest.update(np.ascontiguousarray(np.asarray(value, dtype=np.float64)).tobytes())
    return digest.hexdigest()


def slot_ids(env: gym.Env) -> np.ndarray:
    """(K,) ids of the pedestrians in the observation's slots at the last observation (−1 = empty)."""
    base = env.unwrapped
    observer = getattr(base, "_observer", None)
    slots = getattr(observer, "last_slots", None)
    if slots is None or base.world is None:
        return np.zeros(0, dtype=np.int64)
    ids = base.world.pedestrians.ids
    return np.where(slots >= 0, ids[np.maximum(slots, 0)], -1).astype(np.int64)


def frames(
    env: gym.Env,
    seed: int,
    policy: Policy | None = None,
    actions: Sequence[float] | np.ndarray | None = None,
    max_steps: int | None = None,
) -> Iterator[Frame]:
    """Reset (policy first, then env) with `seed` and step with `policy` or the logged `actions`.

    Stops at termination, truncation, `max_steps`, or the end of `actions`.

    Raises:
        ValueError: not exactly one of `policy` and `actions`.
    """
    if (policy is None) == (actions is None):
        raise ValueError("an episode needs exactly one of policy and actions")
    if policy is not None:
        policy.reset(seed=seed)
    obs, info = env.reset(seed=seed)
    yield Frame(0, obs, info["ground_truth"], slot_ids(env), None)
    limit = len(actions) if actions is not None else sys.maxsize
    if max_steps is not None:
        limit = min(limit, max_steps)
    step = 0
    while step < limit:
        if actions is not None:
            action = np.asarray(actions[step], dtype=np.float32).reshape(1)
        else:
            action = checked_action(policy(obs))  # type: ignore[misc]
        obs, reward, terminated, truncated, info = env.step(action)
        step += 1
        yield Frame(
            step, obs, info["ground_truth"], slot_ids(env), action, float(reward), terminated, truncated
        )
        if terminated or truncated:
            break


def run_episode(
    env: gym.Env,
    seed: int,
    policy: Policy | None = None,
    actions: Sequence[float] | np.ndarray | None = None,
    max_steps: int | None = None,
) -> Episode:
    """Run one episode (see `frames`) and score it from the ground truth."""
    base = env.unwrapped
    metrics = EpisodeMetrics(base.scenario, base.config.dt)
    taken: list[float] = []
    episode_return = 0.0
    gt: GroundTruth | None = None
    initial_speed = float("nan")
    for frame in frames(env, seed, policy, actions, max_steps):
        gt = frame.ground_truth
        if frame.step == 0:
            initial_speed = float(np.hypot(*gt.ego_velocity))
        if frame.action is None:
            continue
        taken.append(float(frame.action[0]))
        episode_return += frame.reward
        metrics.update(gt)
    assert gt is not None  # frame 0 always comes
    return Episode(metrics.result().as_dict(), taken, episode_return, gt, initial_speed)


def run_episodes(
    envs: Sequence[gym.Env], seeds: Sequence[int], policy: Policy, max_steps: int | None = None
) -> list[Episode]:
    """Episode ``i`` of ``envs[i]`` with ``seeds[i]``, the policy acting for all of them in one batched call.

    For a policy that declares ``batched = True`` (`agents.policy_is_batched`): it keeps its memory per
    batch position and gives each element the action it would give alone, so every `Episode` equals
    `run_episode` (env ``i``, seed ``i``) bit for bit. One call per step for the whole batch spreads the
    policy's fixed cost per call (array set-up, small-array arithmetic) over the episodes. Episodes end at
    their own step: an element that has ended keeps showing the policy its last observation (so the batch
    positions stay put), and its actions are dropped. Reset with ``seeds[0]`` (a batched policy draws
    nothing at random).

    Raises:
        ValueError: ``envs`` and ``seeds`` differ in length, or are empty.
    """
    if len(envs) != len(seeds) or not envs:
        raise ValueError(f"one seed per env: got {len(envs)} env(s) and {len(seeds)} seed(s)")
    if len(envs) == 1:
        return [run_episode(envs[0], seeds[0], policy=policy, max_steps=max_steps)]
    policy.reset(seed=seeds[0])
    n = len(envs)
    metrics = [EpisodeMetrics(env.unwrapped.scenario, env.unwrapped.config.dt) for env in envs]
    last: list[Any] = []
    truth: list[GroundTruth] = []
    for env, seed in zip(envs, seeds, strict=True):
        obs, info = env.reset(seed=seed)
        last.append(obs)
        truth.append(info["ground_truth"])
    initial = [float(np.hypot(*gt.ego_velocity)) for gt in truth]
    taken: list[list[float]] = [[] for _ in range(n)]
    returns = [0.0] * n
    running = list(range(n))
    keys = list(last[0])
    limit = sys.maxsize if max_steps is None else max_steps
    step = 0
    while running and step < limit:
        batch = {key: np.stack([obs[key] for obs in last]) for key in keys}
        actions = checked_actions(policy(batch), n)
        step += 1
        still = []
        for i in running:
            action = actions[i].reshape(1)
            obs, reward, terminated, truncated, info = envs[i].step(action)
            last[i] = obs
            truth[i] = info["ground_truth"]
            taken[i].append(float(action[0]))
            returns[i] += float(reward)
            metrics[i].update(truth[i])
            if not (terminated or truncated):
                still.append(i)
        running = still
    return [
        Episode(metrics[i].result().as_dict(), taken[i], returns[i], truth[i], initial[i]) for i in range(n)
    ]
