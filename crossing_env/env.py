"""`crossing_env/Crossing-v0`: drive the ego car through a pedestrian crossing.

The env is a thin template around `World`: `reset` builds the world from a scenario with the env's RNG;
`step` applies the action → advances the world → observes → computes named reward terms →
terminated (collision, end of road) / truncated (scenario duration), both Python bools.

Change logs:
    - Reward terms (`crossing_env.reward`) use the evaluation's yield, TTC and braking definitions; new
      `time` and `near_miss` terms; `failing_to_yield` counts `crossing-eval`'s violated obligations.
    - `info` carries the keys other Gymnasium tools read (`INFO_KEYS`): `crashed` (highway-env),
      `passed_crossing`, `is_success` (SB3's callbacks), `cost` and `costs` (constrained RL, as in
      Safety-Gymnasium and MetaDrive; `crossing_env.safety.step_costs`) and `speed`.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from crossing_env.observation import ObservationBuilder
from crossing_env.reward import RewardTerms
from crossing_env.safety.step import COST_TERMS, step_costs
from crossing_env.types import CrossingObs, GroundTruth, StepReturn
from crossing_env.world import World
from scenarios import load_scenario, scenario_from_dict, validate_scenario
from scenarios.config import EgoConfig, EnvConfig, ScenarioConfig
from scenarios.overrides import apply_overrides, env_config_from_dict

END_OF_ROAD_MARGIN = 10.0
"""The episode terminates when the ego's centre is this close to the end of the road (m)."""

INFO_KEYS: tuple[str, ...] = (
    "ground_truth",
    "rewards",
    "time",
    "crashed",
    "collisions",
    "passed_crossing",
    "is_success",
    "cost",
    "costs",
    "speed",
)
"""Keys of the `info` dict of `reset` and `step` (docs/environment.md, "info"):

- ``ground_truth``: the world's `GroundTruth` (for metrics only; the step's safety quantities attached);
- ``rewards``: the named reward terms (``{}`` after `reset`);
- ``time``: simulation time (s);
- ``crashed``: bool, an ego collision began in this step (highway-env's name);
- ``collisions``: one dict per ego collision that began in this step: ``kind`` ('pedestrian', 'vehicle' or
  'static'), ``at_fault`` (bool, nuPlan's rule: `crossing_env.collision_fault`), ``contact_type`` (nuPlan's
  class), ``other_id`` and ``relative_speed`` (m/s); ``()`` when none;
- ``passed_crossing``: bool, the ego's rear is past the crossing's far edge (the conflict area's x_max);
- ``is_success``: bool, ``passed_crossing`` with no collision and no violated yield obligation so far in
  the episode (SB3's ``Monitor``/``EvalCallback`` read it at the episode's end);
- ``cost``: float ≥ 0, the step's safety cost for constrained RL: the sum of ``costs``;
- ``costs``: the unweighted indicators ``cost`` sums (`crossing_env.safety.step_costs`: ``collision``,
  ``failing_to_yield``, ``near_miss``); all 0.0 after `reset`;
- ``speed``: float, the ego's speed (m/s).
"""


def resolve_scenario(
    scenario: str | os.PathLike[str] | ScenarioConfig | Mapping[str, Any] | None,
    overrides: Mapping[str, Any] | None = None,
) -> ScenarioConfig:
    """A validated scenario config, then dotted-key `overrides` (`scenarios.overrides`) applied.

    `scenario` is a built-in name, a TOML path, a config object, a dict shaped like a scenario file, or
    None (the default).

    Config objects and dicts built in Python go through the same schema checks as files, so a bad value
    fails here with the field's name instead of misbehaving later.
    """
    if scenario is None or (isinstance(scenario, (str, Path)) and str(scenario) == "default"):
        cfg = ScenarioConfig()
    elif isinstance(scenario, ScenarioConfig):
        cfg = validate_scenario(scenario)
    elif isinstance(scenario, Mapping):
        cfg = scenario_from_dict(scenario, "<scenario dict>")
    else:
        cfg = load_scenario(scenario)
    return apply_overrides(cfg, overrides) if overrides else cfg


def action_to_acceleration(action: np.ndarray | float, ego: EgoConfig) -> np.ndarray:
    """Map normalised actions in [−1, 1] to accelerations: −1 → −max_deceleration, +1 → max_acceleration.

    The two halves are scaled separately so that 0 always means "hold speed". Works on batches.
    """
    u = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
    return np.where(u >= 0, u * ego.max_acceleration, u * ego.max_deceleration)


def acceleration_to_action(acceleration: np.ndarray | float, ego: EgoConfig) -> np.ndarray:
    """Inverse of `action_to_acceleration` (clipped to the feasible range), as float32."""
    a = np.asarray(acceleration, dtype=np.float64)
    u = np.where(a >= 0, a / ego.max_acceleration, a / ego.max_deceleration)
    return np.clip(u, -1.0, 1.0).astype(np.float32)


def _scalar_acceleration(action: float, ego: EgoConfig) -> float:
    """`action_to_acceleration` for one finite float, without numpy (the same float64 arithmetic)."""
    u = -1.0 if action < -1.0 else (1.0 if action > 1.0 else action)
    return u * ego.max_acceleration if u >= 0 else u * ego.max_deceleration


def check_action(action: Any) -> float:
    """The one real, finite number in `action` (a float, or an array of shape () or (1,)).

    Strings, booleans, complex numbers and other shapes are refused rather than coerced: a silently
    converted action hides a bug in the policy. Out-of-range values are accepted and clipped to [-1, 1]
    (Gymnasium's convention for Box actions, as its `ClipAction` wrapper does).

    Raises:
        ValueError: for anything that is not one finite real number.
    """
    if type(action) is np.ndarray and action.shape == (1,) and action.dtype.kind == "f":
        value = float(action[0])  # the common case, without building a new array
        if math.isfinite(value):
            return value
    wanted = "one finite real number (a float or an array of shape (1,)); values outside [-1, 1] are clipped"
    arr = np.asarray(action) if not isinstance(action, (str, bytes)) else None
    if arr is None or arr.dtype.kind not in "iuf" or arr.shape not in ((), (1,)):
        shape = "" if arr is None else f" (dtype {arr.dtype}, shape {arr.shape})"
        raise ValueError(f"action must be {wanted}; got {action!r}{shape}")
    value = float(arr.reshape(-1)[0])
    if not np.isfinite(value):
        raise ValueError(f"action must be {wanted}; got {action!r}")
    return value


class CrossingEnv(gym.Env[CrossingObs, np.ndarray]):
    """A car approaching a pedestrian crossing; the action is its normalised longitudinal acceleration.

    Action: shape (1,) in [−1, 1]; −1 is full braking (`EgoConfig.max_deceleration`), +1 full throttle
    (`EgoConfig.max_acceleration`), 0 holds speed (see `action_to_acceleration`). Values outside [−1, 1]
    are clipped; strings, complex numbers, NaN and other shapes raise `ValueError` (`check_action`).

    Observation: a Dict of float32 boxes (`crossing_env.observation`): ego state, K pedestrian slots
    (presence, position relative to the ego, world-frame velocity, on-crossing / waiting / on-road flags;
    the ego's heading is +x, so the frames differ by a translation only) with each slot's
    0.4 s position history, and M vehicle slots. Reward terms are reported in `info["rewards"]`; the
    world's ground truth (for metrics only) in `info["ground_truth"]`, with the step's safety quantities,
    computed once for the reward and reused by `EpisodeMetrics`, attached as its `safety`. `info` also has
    the keys other tools read (`INFO_KEYS`): ``crashed``, ``passed_crossing``, ``is_success``, ``cost``
    (with its terms in ``costs``) and ``speed``.
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 10}  # noqa: RUF012 - Gymnasium API

    def __init__(
        self,
        scenario: str | os.PathLike[str] | ScenarioConfig | None = None,
        config: EnvConfig | Mapping[str, Any] | None = None,
        render_mode: str | None = None,
        overrides: Mapping[str, Any] | None = None,
    ) -> None:
        """Build the env.

        Args:
            scenario: A built-in name, a TOML path, a `ScenarioConfig`, a dict shaped like a scenario file,
                or None for the default scenario.
            config: An `EnvConfig` or a dict of its fields, e.g. ``{"dt": 0.05}`` (validated).
            render_mode: None, "rgb_array" or "human".
            overrides: Dotted-key changes to the scenario, e.g. ``{"pedestrians.spawn_rate": 12.0}``.

        Raises:
            ScenarioError: for a bad scenario, override or config, naming the field, value and rule.
        """
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode={render_mode!r}; allowed: {self.metadata['render_modes']} or None")
        self.scenario = resolve_scenario(scenario, overrides)
        if isinstance(config, Mapping):
            config = env_config_from_dict(config)
        self.config = config or EnvConfig()
        self.render_mode = render_mode
        self.action_space = spaces.Box(low=-1.0, high=1.0, shape=(1,), dtype=np.float32)
        self._observer = ObservationBuilder(self.scenario, self.config.observation)
        self.observation_space = self._observer.space
        self.world: World | None = None
        self._reward_terms: RewardTerms | None = None
        self._renderer = None
        self._collided = False
        self._violated = False

    # ------------------------------------------------------------------ Gymnasium API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[CrossingObs, dict]:
        """Start a new episode; `options={"scenario": ...}` switches scenario for this and later episodes."""
        super().reset(seed=seed)
        if options and "scenario" in options:
            new = resolve_scenario(options["scenario"])
            if replace(new, name="", description="") != replace(self.scenario, name="", description=""):
                self.scenario = new
                self._observer = ObservationBuilder(new, self.config.observation)
                if self._observer.space != self.observation_space:
                    raise ValueError("options['scenario'] must keep the observation layout")
        self.world = World(self.scenario, self.np_random, self.config)
        self._reward_terms = RewardTerms(self.scenario, self.config.dt, self.config.reward)
        self._observer.reset()
        self._collided = self._violated = False
        gt = self.world.ground_truth()
        info = self._info(gt, {}, dict.fromkeys(COST_TERMS, 0.0))
        if self.render_mode == "human":
            self.render()
        return self._observer.build(self.world), info

    def step(self, action: np.ndarray) -> StepReturn:
        """Apply the ego acceleration for one `dt`."""
        if self.world is None:
            raise RuntimeError("call reset() before step()")
        accel = _scalar_acceleration(check_action(action), self.scenario.ego)
        world = self.world
        x_before = world.traffic.x[0]
        world.step(accel)
        gt = world.ground_truth()
        assert self._reward_terms is not None  # set with the world in reset()
        rewards = self._reward_terms(gt, float(world.traffic.x[0] - x_before))
        assert gt.safety is not None  # attached by the reward terms
        costs = step_costs(gt, gt.safety)
        self._collided = self._collided or bool(gt.collisions)
        self._violated = self._violated or gt.safety.yield_violations > 0
        terminated = bool(gt.collisions) or bool(
            world.traffic.x[0] >= self.scenario.road.length - END_OF_ROAD_MARGIN
        )
        truncated = (not terminated) and bool(world.time >= self.scenario.duration - 1e-9)
        info = self._info(gt, rewards, costs)
        if self.render_mode == "human":
            self.render()
        return self._observer.build(world), float(sum(rewards.values())), terminated, truncated, info

    def _info(self, gt: GroundTruth, rewards: dict[str, float], costs: dict[str, float]) -> dict[str, Any]:
        """The `info` dict (`INFO_KEYS`), with Python bools and floats."""
        rear = float(gt.ego_position[0]) - 0.5 * gt.ego_size[0]
        passed = bool(rear >= gt.conflict_area.x_max)
        return {
            "ground_truth": gt,
            "rewards": rewards,
            "time": gt.time,
            "crashed": bool(gt.collisions),
            "collisions": tuple(
                {
                    "kind": ev.kind,
                    "at_fault": bool(ev.at_fault),
                    "contact_type": ev.contact_type,
                    "other_id": int(ev.other_id),
                    "relative_speed": float(ev.relative_speed),
                }
                for ev in gt.collisions
            ),
            "passed_crossing": passed,
            "is_success": passed and not self._collided and not self._violated,
            "cost": float(sum(costs.values())),
            "costs": costs,
            "speed": float(abs(gt.ego_velocity[0])),
        }

    def render(self, observation: dict[str, np.ndarray] | None = None) -> np.ndarray | None:
        """Top-down frame: `rgb_array` returns it, `human` shows it in a window.

        `observation` (as `crossing_env.render.ShowPredictions` passes it) adds the predictor wrappers'
        predicted paths and intentions to the frame.
        """
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode")
            return None
        if self.world is None:
            raise RuntimeError("call reset() before render()")
        from crossing_env.render import TopDownRenderer

        if self._renderer is None:
            self._renderer = TopDownRenderer(self.config, human=self.render_mode == "human")
        frame = self._renderer.draw(self.world, observation)
        return frame if self.render_mode == "rgb_array" else None

    def close(self) -> None:
        """Release the window, if any."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
