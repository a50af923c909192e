"""Oracle predictors: PRIVILEGED upper bounds that read the simulator's ground truth. Never a default.

They answer "how much could a perfect prediction be worth?" in the value-of-prediction table
(`crossing-eval --grid`, `--intention oracle`, `--predictor oracle`). They are observation wrappers that
read the unwrapped env's `World` when, and only when, someone wraps an env with them; the env's own
observation never carries ground truth, and the keys they add are the ones the real predictors add, so a
policy cannot tell them apart except by their accuracy.

- `OracleIntention` adds ``crossing_intention`` and ``crossing_intent`` (K,) with the same values (the
  first is the key every intention predictor fills, the second says the value is the intent to cross at
  all, not a near-term crossing probability): 1 for a pedestrian who truly intends to cross and
  has not crossed yet (states approaching / waiting / crossing), 0 for one who does not (or has already
  crossed), from the moment the intent was decided (`World.intent_decided_at`); before that the intent
  does not exist yet, and the slot gets ``undecided`` (0.5). Absent slots get 0.
- `OracleTrajectory` adds ``predicted_paths`` (K, 12, 2): each pedestrian's true next 12 positions at
  0.4 s, in the observation's frame (relative to the ego's current centre). The future depends on what the
  ego will do, so "true" is defined as the future of a copy of the world rolled forward with the ego
  holding its current speed (action 0): with a constant-speed ego the paths equal the recorded future
  exactly (tested). The copy carries its own copy of the random generator, so the rollout never changes
  the real episode. Cost: a rollout copies the world (the pymunk space dominates, about 0.1 s with a
  busy zebra's pools) and steps it 4.8 s ahead, so it runs every `refresh_steps` env steps (default 4 =
  0.4 s) and in between the cached rollout is read at the right time offset (exact for a constant-speed
  ego), or at once when a pedestrian appears that the cached rollout does not hold.
- **Plan-conditioned paths.** The pedestrians react to the car, so a future is only true for a given plan
  of the ego. `OracleTrajectory` also adds ``plan_paths`` (P, K, 12, 2): the same paths for each of the
  plans in ``plan_accelerations`` (P,) (m/s², each held over the 4.8 s horizon, the ego's speed kept
  within [0, speed limit]; default: go +1.5, keep 0, slow −2.5). The keep plan (0) reuses the
  ``predicted_paths`` rollout; each other plan costs one more rollout every `plan_refresh_steps` (default
  4, as the keep plan: the rollouts dominate an oracle episode's cost, but refreshing the plans every 8
  steps brought the chatter back on a signalised_red_light dev episode, 8 sign changes against 4). Between
  refreshes the cached plan rollouts are read at the time offset, exact only for an ego that followed
  that plan.
  `agents.predictive` scores the plans with them (`agents.plans`).
"""

from __future__ import annotations

import copy
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from crossing_env import physics
from crossing_env.observation import (
    HISTORY_INTERVAL,
    PEDESTRIAN_HISTORY_KEY,
    PEDESTRIANS_KEY,
    PointColumn,
)
from crossing_env.pedestrians.transitions import APPROACHING, CROSSING, WAITING
from predictors.forecast import Forecast, ForecastInput, ForecastSpec
from predictors.forecast_wrapper import PLAN_ACCELERATIONS_KEY, PLAN_PATHS_KEY, ForecastObservation

__all__ = [
    "PLAN_ACCELERATIONS_KEY",
    "PLAN_PATHS_KEY",
    "IntentOracle",
    "OracleIntention",
    "OracleTrajectory",
    "PathOracle",
    "rollout_pedestrians",
]
DEFAULT_PLANS: tuple[float, ...] = (1.5, 0.0, -2.5)
"""Default plans (m/s²): go (the yielding policy's `go_acceleration`), keep the speed, slow down
(its `comfortable_deceleration`, below the 3 m/s² hard-braking threshold)."""

PRED_LEN = 12
"""Predicted positions per pedestrian (the ETH/UCY protocol: 12, `HISTORY_INTERVAL` apart)."""


def _world(env: gym.Env) -> Any:
    world = getattr(env.unwrapped, "world", None)
    if world is None:
        raise RuntimeError("oracle predictors read the crossing_env world: call reset() first")
    return world


def _slots(env: gym.Env) -> np.ndarray:
    """Pool slot shown in each observation slot (−1 = empty)."""
    return env.unwrapped._observer.last_slots


def rollout_pedestrians(world: Any, steps: int, acceleration: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Roll a copy of `world` forward `steps` steps with the ego holding `acceleration` (m/s², default 0).

    The ego's speed is kept within [0, the road's speed limit] (the commanded acceleration is cut where
    the plan would leave it), so a plan is "accelerate to the limit" or "brake to a stop". Returns
    (ids, positions): (steps + 1, P) pedestrian ids per pool slot (−1 where inactive) and (steps + 1, P, 2)
    positions, index 0 being the current state. `world` itself is not touched.
    """
    # Share what never changes within an episode and the process-wide pymunk batch buffers (not copyable).
    memo = {id(x): x for x in (physics._SET_BUFFER, physics._GET_BUFFER, world.scenario, world.config)}
    memo[id(world.geometry)] = world.geometry
    sim = copy.deepcopy(world, memo)
    peds = sim.pedestrians
    cap = peds.capacity
    ids = np.full((steps + 1, cap), -1, dtype=np.int64)
    pos = np.zeros((steps + 1, cap, 2))
    limit = max(float(world.scenario.road.speed_limit), float(sim.traffic.speed[0]))
    dt = float(sim.dt)
    for s in range(steps + 1):
        if s and acceleration == 0.0:
            sim.step(0.0)
        elif s:
            v = float(sim.traffic.speed[0])
            sim.step(float(np.clip(acceleration, -v / dt, (limit - v) / dt)))
        act = peds.state != 0
        ids[s] = np.where(act, peds.ids, -1)
        pos[s] = peds.position
    return ids, pos


class IntentOracle:
    """PRIVILEGED forecaster: the true crossing intent of each slot (see the module docstring)."""

    def __init__(self, undecided: float = 0.5) -> None:
        if not 0.0 <= undecided <= 1.0:
            raise ValueError(f"OracleIntention: undecided must be a probability in [0, 1], got {undecided}")
        self.undecided = float(undecided)
        self.spec = ForecastSpec(paths=False, intent=True, privileged=True)
        self._env: gym.Env | None = None

    def bind(self, env: gym.Env) -> None:
        """Read the ground truth of `env` from now on."""
        self._env = env

    def reset(self, seed: int | None) -> None:
        """Nothing to forget: the truth is read afresh every step."""

    def forecast(self, inputs: ForecastInput) -> Forecast:
        """The true intent of each slot's pedestrian (undecided before the decision)."""
        assert self._env is not None, "bind(env) first"
        world = _world(self._env)
        peds = world.pedestrians
        slots = _slots(self._env)
        out = np.zeros(slots.shape[0], dtype=np.float32)
        present = slots >= 0
        p = slots[present]
        decided = world.intent_decided_at[p] <= world.time + 1e-9  # NaN (undecided) compares False
        state = peds.state[p]
        to_cross = peds.intends[p] & ((state == APPROACHING) | (state == WAITING) | (state == CROSSING))
        out[present] = np.where(decided, to_cross.astype(np.float32), np.float32(self.undecided))
        return Forecast(intention=out, intent=out.copy())


class PathOracle:
    """PRIVILEGED forecaster: each pedestrian's true next 12 positions, one sample of weight 1 (module)."""

    def __init__(
        self,
        refresh_steps: int = 4,
        plan_refresh_steps: int = 4,
        plan_accelerations: tuple[float, ...] = DEFAULT_PLANS,
    ) -> None:
        plans = tuple(float(a) for a in plan_accelerations)
        if not (isinstance(refresh_steps, int) and refresh_steps >= 1):
            raise ValueError(
                f"OracleTrajectory: refresh_steps must be an integer >= 1, got {refresh_steps!r}"
            )
        if not all(np.isfinite(plans)):
            raise ValueError(f"OracleTrajectory: plan accelerations must be finite, got {plans}")
        if not (isinstance(plan_refresh_steps, int) and plan_refresh_steps >= 1):
            raise ValueError(
                f"OracleTrajectory: plan_refresh_steps must be an integer >= 1, got {plan_refresh_steps!r}"
            )
        self.refresh_steps = refresh_steps
        self.plan_refresh_steps = plan_refresh_steps
        """Env steps between rollouts of the moving plans (each costs one rollout per refresh)."""
        self.plans = plans
        """Ego accelerations (m/s²) of the plans whose futures go into ``plan_paths`` (empty: no key)."""
        self.spec = ForecastSpec(plans=plans, privileged=True)
        self._env: gym.Env | None = None
        self._cache: tuple[int, np.ndarray, np.ndarray] | None = None  # (start step, ids, positions)
        self._plan_cache: dict[float, tuple[np.ndarray, np.ndarray]] = {}  # plan → (ids, positions)
        self._plan_start = 0
        self._keep: np.ndarray | None = None  # this step's keep-plan paths, for forecast_plans
        self.rollouts = 0
        """Rollouts run so far (each copies the world and steps it 4.8 s + refresh ahead)."""

    def bind(self, env: gym.Env) -> None:
        """Read the ground truth of `env` from now on."""
        self._env = env

    def reset(self, seed: int | None) -> None:
        """Forget the cached rollouts."""
        self._cache = None
        self._plan_cache = {}

    def _future(
        self, ids: np.ndarray, pos: np.ndarray, at: int, p: np.ndarray, ego: np.ndarray
    ) -> np.ndarray:
        """(n, 12, 2) positions of pool slots `p` read from a rollout at offset `at`, relative to the ego."""
        every = self._every
        rows = at + every * np.arange(1, PRED_LEN + 1)  # (12,)
        future = pos[rows][:, p]  # (12, n, 2)
        alive = ids[rows][:, p] == self._want[None, :]  # one who leaves keeps its last position
        for j in range(1, PRED_LEN):
            future[j] = np.where(alive[j][:, None], future[j], future[j - 1])
        return np.transpose(future - ego, (1, 0, 2)).astype(np.float32)

    def forecast(self, inputs: ForecastInput) -> Forecast:
        """The true future of the present slots under the keep plan (the ego holding its speed)."""
        assert self._env is not None, "bind(env) first"
        world = _world(self._env)
        slots = _slots(self._env)
        paths = np.zeros((slots.shape[0], PRED_LEN, len(PointColumn)), np.float32)
        self._present = np.flatnonzero(slots >= 0)
        self._keep = None
        if self._present.size:
            step = round(world.time / world.dt)
            self._every = round(HISTORY_INTERVAL / world.dt)
            self._step_now = step
            p = slots[self._present]
            self._p = p
            self._want = world.pedestrians.ids[p]
            cache = self._cache
            offset = -1 if cache is None else step - cache[0]
            if (
                cache is None
                or offset >= self.refresh_steps
                or offset < 0
                or not np.all(cache[1][offset, p] == self._want)
            ):
                ids, pos = rollout_pedestrians(world, PRED_LEN * self._every + self.refresh_steps - 1)
                self._cache = cache = (step, ids, pos)
                self.rollouts += 1
                offset = 0
            _, ids, pos = cache
            self._keep = self._future(ids, pos, offset, p, world.ego_position)
            paths[self._present] = self._keep
        return Forecast(paths=paths[:, None])

    def forecast_plans(self, inputs: ForecastInput) -> np.ndarray:
        """(P, N, 12, 2): the true future under each plan (called after `forecast` for the same step)."""
        assert self._env is not None, "bind(env) first"
        world = _world(self._env)
        out = np.zeros((len(self.plans), inputs.present.shape[0], PRED_LEN, len(PointColumn)), np.float32)
        if self._keep is None:
            return out
        p, want = self._p, self._want
        moving = [a for a in self.plans if a != 0.0]
        plan_offset = self._step_now - self._plan_start
        if moving and (
            not self._plan_cache
            or plan_offset >= self.plan_refresh_steps
            or plan_offset < 0
            or not all(np.all(c[0][plan_offset, p] == want) for c in self._plan_cache.values())
        ):
            # Each plan's world starts from the same state (and a copy of the same generator).
            steps = PRED_LEN * self._every + self.plan_refresh_steps - 1
            self._plan_cache = {a: rollout_pedestrians(world, steps, a) for a in moving}
            self._plan_start = self._step_now
            self.rollouts += len(moving)
            plan_offset = 0
        ego = world.ego_position
        for target, a in zip(out, self.plans, strict=True):
            target[self._present] = (
                self._keep if a == 0.0 else self._future(*self._plan_cache[a], plan_offset, p, ego)
            )
        return out


class OracleIntention(ForecastObservation):
    """PRIVILEGED: the true crossing intent as ``crossing_intention`` (`IntentOracle` in the one wrapper)."""

    privileged: ClassVar[bool] = True
    """Reads the ground truth: an upper bound for evaluation, never a sensor model."""

    def __init__(self, env: gym.Env, undecided: float = 0.5) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, undecided=undecided)
        space = env.observation_space
        if not isinstance(space, spaces.Dict) or PEDESTRIANS_KEY not in space.spaces:
            raise ValueError(f"OracleIntention needs a crossing_env Dict observation, got {space}")
        super().__init__(env, IntentOracle(undecided), "oracle")


class OracleTrajectory(ForecastObservation):
    """PRIVILEGED: the true next 12 positions as ``predicted_paths`` (`PathOracle` in the one wrapper)."""

    privileged: ClassVar[bool] = True
    """Reads the ground truth: an upper bound for evaluation, never a sensor model."""

    def __init__(
        self,
        env: gym.Env,
        refresh_steps: int = 4,
        plan_refresh_steps: int = 4,
        plan_accelerations: tuple[float, ...] = DEFAULT_PLANS,
    ) -> None:
        plans = tuple(float(a) for a in plan_accelerations)
        gym.utils.RecordConstructorArgs.__init__(
            self, refresh_steps=refresh_steps, plan_refresh_steps=plan_refresh_steps, plan_accelerations=plans
        )
        space = env.observation_space
        hist = space.spaces.get(PEDESTRIAN_HISTORY_KEY) if isinstance(space, spaces.Dict) else None
        if not isinstance(hist, spaces.Box) or len(hist.shape) != 3:
            raise ValueError(
                f"OracleTrajectory needs {PEDESTRIAN_HISTORY_KEY!r} (K, T, 2) in the observation, got {space}"
            )
        super().__init__(env, PathOracle(refresh_steps, plan_refresh_steps, plans), "oracle")

    @property
    def rollouts(self) -> int:
        """Rollouts the path oracle has run so far."""
        return self.forecaster.rollouts
