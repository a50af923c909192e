"""Tests of crossing_env.safety.step: the env computes the safety quantities once, the metrics reuse them."""

from __future__ import annotations

import dataclasses
import itertools
import json
import pickle

import gymnasium as gym
import numpy as np
import pytest

import crossing_env
from crossing_env.safety import EpisodeMetrics, MetricsConfig
from crossing_env.safety.step import SafetyMonitor, StepSafety
from crossing_env.safety.yielding import EMPTY_YIELD_STATE, YieldTracker
from tests.crossing_env.safety.snapshots import DT, Ped, make_gt


def _episode(scenario: str, seed: int, steps: int) -> list:
    env = gym.make(crossing_env.ENV_ID, scenario=scenario).unwrapped
    env.reset(seed=seed)
    actions = np.random.default_rng(seed)
    gts = []
    for _ in range(steps):
        _, _, terminated, truncated, info = env.step(actions.uniform(-1.0, 0.6, size=(1,)).astype(np.float32))
        gts.append(info["ground_truth"])
        if terminated or truncated:
            break
    env.close()
    return gts


def _run_metrics(gts: list, config: MetricsConfig | None = None) -> tuple[str, list[tuple[float, ...]]]:
    scenario = crossing_env.CrossingEnv(scenario="busy_zebra").scenario
    m = EpisodeMetrics(scenario, 0.1, config)
    steps = []
    for gt in gts:
        m.update(gt)
        steps.append((m.step_ttc, m.step_separation, m.step_drac))
    return json.dumps(m.result().as_dict(), sort_keys=True), steps


def test_env_attaches_the_step_quantities_once() -> None:
    gts = _episode("busy_zebra", 0, 60)
    assert all(isinstance(gt.safety, StepSafety) for gt in gts)
    # Consecutive steps chain: each step starts from the obligations the previous one ended with.
    for before, after in itertools.pairwise(gts):
        assert after.safety.yield_before is before.safety.yield_after


@pytest.mark.parametrize("scenario", ["busy_zebra", "zebra_case1", "signalised_red_light"])
def test_metrics_reusing_the_env_quantities_equal_metrics_computing_them(scenario: str) -> None:
    gts = _episode(scenario, 1, 400)
    stripped = [dataclasses.replace(gt) for gt in gts]  # same snapshots, no attached quantities
    assert all(gt.safety is None for gt in stripped)
    shared_result, shared_steps = _run_metrics(gts)
    own_result, own_steps = _run_metrics(stripped)
    assert shared_result == own_result
    assert np.array_equal(np.array(shared_steps), np.array(own_steps))


def test_metrics_with_other_thresholds_compute_their_own() -> None:
    gts = _episode("busy_zebra", 2, 300)
    strict = MetricsConfig(yield_deceleration=1.5, serious_ttc=3.0)
    assert not gts[0].safety.usable_by(YieldTracker("zebra", 0.1, strict))
    stripped = [dataclasses.replace(gt) for gt in gts]
    assert _run_metrics(gts, strict) == _run_metrics(stripped, strict)


def test_metrics_started_mid_episode_do_not_reuse_obligations() -> None:
    gts = _episode("busy_zebra", 3, 300)
    late = gts[100:]
    stripped = [dataclasses.replace(gt) for gt in late]
    assert _run_metrics(late) == _run_metrics(stripped)


def test_monitor_matches_the_functions_it_shares() -> None:
    monitor = SafetyMonitor("zebra", DT)
    assert monitor.yields.state is EMPTY_YIELD_STATE
    gt = make_gt(0.1, ego_x=116.0, acc=-4.0, peds=[Ped(1, (120.0, 1.0), (0.0, 1.3))])
    s = monitor(gt)
    assert gt.safety is s
    assert s.ego_in_conflict_area and s.hard_braking
    # ego front at 118.25 touches the crossing; pedestrian 1.75 m ahead of the front in x, inside the lane
    assert s.min_separation == pytest.approx(120.0 - 0.28 - 118.25)
    assert 0.0 < s.min_ttc < np.inf


def test_attached_quantities_are_not_state() -> None:
    gt = _episode("busy_zebra", 4, 30)[-1]
    copy = dataclasses.replace(gt)
    assert copy == gt  # equality ignores the attached quantities
    restored = pickle.loads(pickle.dumps(gt))
    assert restored.safety is None and restored == gt
