"""Closed-loop release bounds: the sweep replaces only the bound, stops at the first failing bound, and the
policy releases more as the bound rises."""

from __future__ import annotations

import multiprocessing
from concurrent.futures import ProcessPoolExecutor

import gymnasium as gym
import numpy as np
import pytest

import crossing_env  # noqa: F401 - registers the env
from crossing_eval.runners import pool_start_method
from predictors.learned_intent_weights import CROSSING_INTENT_BOUND_KEY
from rollout import wrap
from studies.release_bounds import FixedBound, choose, passes, summarise, sweep


def _point(bound: float, collisions: int = 0, compliant: int = 100, obligations: int = 100) -> dict:
    return {"bound": bound, "collisions": collisions, "compliance": compliant / obligations}


def test_fixed_bound_replaces_the_published_bound_and_nothing_else() -> None:
    env, _ = wrap(gym.make("crossing_env/Crossing-v0", scenario="zebra_case1"), "learned", "none")
    plain, _ = env.reset(seed=3)
    fixed, _ = FixedBound(env, 0.37).reset(seed=3)
    assert fixed[CROSSING_INTENT_BOUND_KEY].tolist() == [np.float32(0.37)]
    assert plain[CROSSING_INTENT_BOUND_KEY][0] != np.float32(0.37)
    for key in plain:
        if key != CROSSING_INTENT_BOUND_KEY:
            np.testing.assert_array_equal(plain[key], fixed[key])
    assert FixedBound(env, 0.37).observation_space.contains(fixed)


def test_choice_is_the_last_pass_before_the_first_failure() -> None:
    points = [_point(0.1), _point(0.2), _point(0.3, compliant=98), _point(0.4)]
    assert choose(points, fallback=0.0) == 0.2
    assert choose([_point(0.1, collisions=1), _point(0.2)], fallback=0.015) == 0.015
    assert choose([_point(0.1), _point(0.2)], fallback=0.3) == 0.3  # never below the open-loop bound
    assert passes(_point(0.5, compliant=99)) and not passes(_point(0.5, compliant=989, obligations=1000))
    assert summarise(0.2, [])["compliance"] == 1.0
    assert np.isnan(summarise(0.2, [])["mean_duration"])


def test_a_higher_bound_releases_bus_waiters_without_breaking_compliance() -> None:
    """On `bus_stop_zebra` most people at the kerb wait for the bus: a bound of 1 releases everyone there that
    no duty holds, so the car passes sooner than at a bound of 0, and the people who do cross still get
    their stop (they step out, a visible duty)."""
    context = multiprocessing.get_context(pool_start_method())
    with ProcessPoolExecutor(1, mp_context=context) as pool:
        points = sweep("learned", ["bus_stop_zebra"], 3, pool, grid=(0.0, 1.0))
    assert [p["bound"] for p in points] == [0.0, 1.0]
    assert all(p["episodes"] == 3 and passes(p) for p in points)
    assert points[1]["mean_duration"] < points[0]["mean_duration"] - 2.0


def test_the_sweep_stops_at_the_first_failing_bound(monkeypatch: pytest.MonkeyPatch) -> None:
    """A failing bound ends the sweep: nothing above it is run."""
    import studies.release_bounds as rb

    class Pool:
        def map(self, fn: object, jobs: list) -> list:
            bound = jobs[0][2]
            bad = bound >= 0.2
            return [{"collision": False, "compliant": 0 if bad else 1, "obligations": 1, "duration": 1.0}]

    points = rb.sweep("learned", ["x"], 1, Pool(), grid=(0.1, 0.2, 0.3))  # type: ignore[arg-type]
    assert [p["bound"] for p in points] == [0.1, 0.2]
    assert rb.choose(points, 0.0) == 0.1


def test_a_kept_bound_steps_down_until_the_confirmation_episodes_pass_too() -> None:
    """Confirmation: other seeds, down the grid from the kept bound; the open-loop floor if none pass."""
    import studies.release_bounds as rb

    class Pool:
        def __init__(self, worst_passing: float) -> None:
            self.worst_passing, self.seeds = worst_passing, set()

        def map(self, fn: object, jobs: list) -> list:
            self.seeds.add(jobs[0][4])
            ok = jobs[0][2] <= self.worst_passing
            return [{"collision": False, "compliant": int(ok), "obligations": 1, "duration": 1.0}]

    pool = Pool(0.35)
    bound, points = rb.confirm("qlb", 0.4, 0.0, ["x"], 1, pool, grid=(0.3, 0.35, 0.4, 0.45))  # type: ignore[arg-type]
    assert bound == 0.35 and [p["bound"] for p in points] == [0.4, 0.35]
    assert pool.seeds == {rb.CONFIRM_SEED} and rb.CONFIRM_SEED != rb.SELECTION_SEED
    bound, points = rb.confirm("qlb", 0.1, 0.015, ["x"], 1, Pool(0.0), grid=(0.05, 0.1))  # type: ignore[arg-type]
    assert bound == 0.015 and [p["bound"] for p in points] == [0.1, 0.05]
