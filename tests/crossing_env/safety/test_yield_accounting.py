"""Honest yield accounting on whole episodes: obligations left open are unresolved, never compliant.

The drivers here are test harnesses that read the world directly (they are not shipped policies); the
metrics read the ground truth as `crossing-eval` does.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import gymnasium as gym
import numpy as np

from crossing_env import ENV_ID
from crossing_env.safety import EpisodeMetrics, EpisodeResult
from crossing_env.safety.yielding import VIOLATED, YieldTracker
from crossing_env.world import World
from crossing_eval.tasks import episode_seed
from rollout import RolloutSpec, run_spec

SEED_BASE = 31000
"""A base seed the project's tables never use (they use 2024 and 7000)."""


def _drive(
    scenario: str, seed: int, controller: Callable[[World], float], tracker: YieldTracker | None = None
) -> EpisodeResult:
    """One episode driven by `controller(world) -> acceleration (m/s²)`, scored from the ground truth.

    `tracker`, when given, follows the yield obligations too (to look at them per pedestrian).
    """
    env = gym.make(ENV_ID, scenario=scenario)
    base = env.unwrapped
    env.reset(seed=seed)
    ego = base.scenario.ego
    metrics = EpisodeMetrics(base.scenario, base.config.dt)
    done = False
    while not done:
        acc = controller(base.world)
        action = acc / ego.max_acceleration if acc >= 0 else acc / ego.max_deceleration
        _, _, terminated, truncated, info = env.step(np.array([action], dtype=np.float32))
        metrics.update(info["ground_truth"])
        if tracker is not None:
            tracker.update(info["ground_truth"])
        done = terminated or truncated
    env.close()
    return metrics.result()


def stop_far(distance: float = 70.0) -> Callable[[World], float]:
    """Brake gently to a stop with the front `distance` m before the stop line, then wait there for good."""

    def controller(world: World) -> float:
        front = float(world.traffic.x[0] + 0.5 * world.traffic.length[0])
        speed = float(world.traffic.speed[0])
        gap = world.conflict_area.stop_line_x - distance - front
        target = math.sqrt(2.0 * 2.5 * gap) if gap > 0.0 else 0.0
        return float(np.clip(2.0 * (target - speed), -8.0, 3.0))

    return controller


def stop_then_go(wait: float = 3.5) -> Callable[[World], float]:
    """Stop with the front 1 m before the stop line, stand `wait` s (long enough for a waiting pedestrian's
    obligation to close as declined), then drive off at full acceleration whatever happens."""
    stood = [0.0]

    def controller(world: World) -> float:
        if stood[0] >= wait:
            return 3.0
        front = float(world.traffic.x[0] + 0.5 * world.traffic.length[0])
        speed = float(world.traffic.speed[0])
        gap = world.conflict_area.stop_line_x - 1.0 - front
        if speed < 0.05 and gap < 1.0:
            stood[0] += world.dt
            return 0.0
        target = math.sqrt(2.0 * 2.5 * gap) if gap > 0.0 else 0.0
        return float(np.clip(2.0 * (target - speed), -8.0, 3.0))

    return controller


def _compliance(results: list[dict | EpisodeResult]) -> tuple[float, int, int]:
    rows = [r.as_dict() if isinstance(r, EpisodeResult) else r for r in results]
    met = sum(r["yield_compliant"] for r in rows)
    owed = sum(r["yield_obligations"] for r in rows)
    return met / owed, owed, sum(r["yield_unresolved"] for r in rows)


def test_stopping_far_and_waiting_leaves_obligations_unresolved_and_scores_below_yielding() -> None:
    far: list[EpisodeResult] = []
    careful: list[dict] = []
    for scenario in ("busy_zebra", "zebra_case1"):
        for k in range(4):
            seed = episode_seed(SEED_BASE, scenario, k)
            far.append(_drive(scenario, seed, stop_far()))
            careful.append(run_spec(RolloutSpec(scenario=scenario, policy="yielding"), seed).result)
    assert all(r.distance_travelled < 40.0 and not r.passed_crossing for r in far)  # it never came near
    assert all(r.yield_violations == 0 for r in far)  # nothing was broken ...
    far_compliance, far_owed, far_open = _compliance(far)
    assert far_open > 0 and far_owed > far_open  # ... but not everything owed was shown to be met
    for r in far:
        assert r.yield_obligations == r.yield_compliant + r.yield_violations + r.yield_unresolved
    careful_compliance, _, _ = _compliance(careful)
    assert far_compliance < careful_compliance
    assert far_compliance <= 1.0 - far_open / far_owed + 1e-12


def test_a_crash_before_the_crossing_leaves_its_obligations_unresolved() -> None:
    """busy_zebra's careless car rear-ends a car stopped for pedestrians: what it owed them is not met."""
    unresolved = 0
    for k in range(8):
        r = run_spec(
            RolloutSpec(scenario="busy_zebra", policy="constant_speed"),
            episode_seed(SEED_BASE, "busy_zebra", k),
        )
        m = r.result
        if m["collision"] and not m["passed_crossing"]:
            unresolved += m["yield_unresolved"]
            assert m["yield_compliant"] < m["yield_obligations"] or m["yield_obligations"] == 0
    assert unresolved > 0


def test_stop_briefly_then_go_into_a_reopened_obligation_is_a_violation() -> None:
    """A pedestrian declined the car's offer, then stepped onto the zebra as it pulled away: a violation.

    Found by running `stop_then_go` over 28 seeds of each zebra scenario at base 31000 (two such episodes
    in busy_zebra); before obligations reopened, this one recorded nothing against the car."""
    tracker = YieldTracker("zebra", 0.1)
    result = _drive("busy_zebra", episode_seed(SEED_BASE, "busy_zebra", 21), stop_then_go(), tracker)
    state = tracker.state
    reopened_then_broken = (state.status == VIOLATED) & (state.earlier_declined > 0)
    assert np.count_nonzero(reopened_then_broken) >= 1
    assert result.yield_violations >= np.count_nonzero(reopened_then_broken)
    assert result.yield_offers_declined >= np.count_nonzero(reopened_then_broken)
    assert (
        result.yield_obligations == result.yield_compliant + result.yield_violations + result.yield_unresolved
    )
