"""Crossing-intention wrappers (QLB, CBM): space, observation-only values, speed, benchmark maths."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from benchmarks.intention import brier, cautious_action, roc_auc
from crossing_env.env import CrossingEnv
from crossing_env.observation import PedestrianColumn
from crossing_env.pedestrians.quantum import disjunction_probabilities
from predictors.intention import (
    INTENT_HORIZON,
    ClassicalIntention,
    CrossingIntention,
    IntentionConfig,
    QLBIntention,
    crossing_intention,
    look_probability,
)
from predictors.learned_intent_weights import platt
from scenarios.config import PedestrianConfig, ScenarioConfig


def _env(spawn_rate: float = 20.0) -> CrossingEnv:
    return CrossingEnv(ScenarioConfig(pedestrians=PedestrianConfig(spawn_rate=spawn_rate)))


def _obs_with(
    peds: list[list[float]],
    speed: float = 8.0,
    stop_line: float = 40.0,
    vehicles: list[list[float]] | None = None,
) -> dict[str, np.ndarray]:
    """A hand-made observation: K = 16 slots, M = 8 vehicle slots (ego in lane 0, zebra)."""
    ped = np.zeros((16, 8), dtype=np.float32)
    ped[: len(peds)] = np.asarray(peds, dtype=np.float32)
    veh = np.zeros((8, 7), dtype=np.float32)
    if vehicles:
        veh[: len(vehicles)] = np.asarray(vehicles, dtype=np.float32)
    ego = np.array([speed, 0.0, stop_line, -stop_line - 10.0, 1.0, 1.0], dtype=np.float32)
    return {
        "ego": ego,
        "pedestrians": ped,
        "vehicles": veh,
        "pedestrian_history": np.zeros((16, 8, 2), np.float32),
    }


@pytest.mark.parametrize("cls", [QLBIntention, ClassicalIntention])
def test_space_and_values(cls: type[CrossingIntention]) -> None:
    env = cls(_env(), horizon=2.0)
    space = env.observation_space["crossing_intention"]
    assert space.shape == (16,) and space.dtype == np.float32
    obs, _ = env.reset(seed=3)
    seen_positive = False
    for _ in range(250):
        obs, *_ = env.step(cautious_action(obs))
        assert env.observation_space.contains(obs)
        p = obs["crossing_intention"]
        absent = obs["pedestrians"][:, 0] < 0.5
        assert np.all(p[absent] == 0.0)
        seen_positive |= bool(np.any(p > 0.5))
    assert seen_positive


def test_only_the_observation_is_used() -> None:
    env = QLBIntention(_env(), horizon=2.0)
    obs, _ = env.reset(seed=4)
    for _ in range(120):
        obs, *_ = env.step(cautious_action(obs))
    before = obs["crossing_intention"].copy()
    raw = {k: v for k, v in obs.items() if k != "crossing_intention"}
    # Scramble the hidden state of the world: the estimate from the same observation must not change.
    peds = env.unwrapped.world.pedestrians
    peds.intends[:] = ~peds.intends
    peds.critical_gap[:] = 100.0
    peds.phase[:] = 0.0
    np.testing.assert_array_equal(env.observation(raw)["crossing_intention"], before)


def test_qualitative_behaviour() -> None:
    env = ClassicalIntention(_env(), horizon=2.0)
    env.reset(seed=0)
    ego_y = 1.75  # lane 0 centre; the south kerb is 1.75 m below the ego, the north kerb 5.25 m above
    crossing = 40.0 + 3.0 + 2.0 + 2.25  # stop line + offset + half width + half ego length
    rows = [
        [1, crossing, -ego_y - 0.6, 0.0, 0.0, 0, 1, 0],  # 0: waiting at the south kerb, no traffic
        [1, crossing, -ego_y - 1.65, 1.3, 0.0, 0, 0, 0],  # 1: walking along the sidewalk at the crossing
        [1, crossing - 20.0, -ego_y - 1.65, -1.3, 0.0, 0, 0, 0],  # 2: walking away from the crossing
        [1, crossing, 0.0, 0.0, 1.3, 1, 0, 1],  # 3: on the road ahead
        [1, -10.0, 0.0, 0.0, 1.3, 0, 0, 1],  # 4: on the road behind the ego
        [1, crossing, 5.25 + 2.0, 0.0, 1.2, 0, 0, 0],  # 5: walking away from the road on the north side
    ]
    p = env.observation(_obs_with(rows, speed=0.0))["crossing_intention"]
    assert p[3] > 0.9 and p[4] == 0.0
    assert p[0] > 0.5 and p[0] > p[2] and p[0] > p[5]
    assert p[5] < 0.05
    # A fast car about to pass in front of the waiting pedestrian lowers its probability.
    car = [[1, crossing + 15.0, 3.5, -12.0, 0.0, 4.5, 1.8]]  # oncoming in lane 1, about 1 s from the line
    q = env.observation(_obs_with(rows, speed=0.0, vehicles=car))["crossing_intention"]
    assert q[0] < p[0] - 0.3
    # A longer horizon never lowers the probability.
    long = ClassicalIntention(_env(), horizon=4.0)
    long.reset(seed=0)
    r = long.observation(_obs_with(rows, speed=0.0))["crossing_intention"]
    assert np.all(r >= p - 1e-6)


def test_qlb_and_cbm_differ_only_in_interference() -> None:
    cfg = IntentionConfig()
    gaps = np.array([0.0, 3.0, 5.0, 5.5, 6.0, 8.0, np.inf])
    cbm = look_probability(gaps, "cbm", cfg)
    qlb = look_probability(gaps, "qlb", cfg)
    # CBM is the classical mixture; QLB is the heuristic-phase disjunction over the same belief.
    belief = (cbm - cfg.p_cross_unsafe) / (cfg.p_cross_safe - cfg.p_cross_unsafe)
    np.testing.assert_allclose(
        qlb, disjunction_probabilities(cfg.p_cross_safe, cfg.p_cross_unsafe, belief, None), atol=1e-12
    )
    np.testing.assert_allclose(
        disjunction_probabilities(cfg.p_cross_safe, cfg.p_cross_unsafe, belief, np.pi / 2), cbm, atol=1e-12
    )
    assert np.max(np.abs(qlb - cbm)) > 0.01
    assert np.all(np.diff(cbm) >= 0)


def test_bad_arguments_are_rejected() -> None:
    with pytest.raises(ValueError, match="horizon"):
        QLBIntention(_env(), horizon=0.0)
    with pytest.raises(ValueError, match="variant"):
        CrossingIntention(_env(), variant="quantum")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="Dict"):
        CrossingIntention(gym.make("CartPole-v1"))


def test_make_and_record_constructor_args() -> None:
    env = QLBIntention(_env(), horizon=4.0)
    assert env._saved_kwargs == {"horizon": 4.0, "config": None}  # RecordConstructorArgs
    assert env.horizon == 4.0 and env.variant == "qlb"
    assert ClassicalIntention(_env()).variant == "cbm"


def test_benchmark_metrics() -> None:
    y = np.array([0, 0, 1, 1, 0, 1], dtype=float)
    assert roc_auc(np.array([0.1, 0.2, 0.8, 0.9, 0.3, 0.7]), y) == 1.0
    assert roc_auc(np.array([0.9, 0.8, 0.1, 0.2, 0.7, 0.3]), y) == 0.0
    assert roc_auc(np.full(6, 0.5), y) == 0.5
    # One tie between a positive and a negative counts one half: 8.5 of 9 pairs.
    assert roc_auc(np.array([0.1, 0.2, 0.8, 0.9, 0.7, 0.7]), y) == pytest.approx(8.5 / 9)
    assert brier(y, y) == 0.0 and brier(1 - y, y) == 1.0


@pytest.mark.parametrize("wrapper", [QLBIntention, ClassicalIntention])
def test_the_wrappers_shared_parts_give_the_functions_own_values(wrapper: type[CrossingIntention]) -> None:
    # The wrapper computes the horizon-free parts once for both outputs; each must equal a separate call of
    # `crossing_intention`, bit for bit, on real observations with pedestrians about.
    env = wrapper(_env())
    obs, _ = env.reset(seed=3)
    compared = 0
    for _ in range(60):
        obs, *_ = env.step(np.zeros(1, dtype=np.float32))
        model = env.forecaster
        args = (env._scene, model.config, model._rates, model._red_rates)
        near = crossing_intention(obs, model.horizon, *args)
        raw = crossing_intention(obs, INTENT_HORIZON, *args, ahead_only=False)
        present = obs["pedestrians"][:, PedestrianColumn.PRESENCE] > 0.5
        np.testing.assert_array_equal(obs["crossing_intention"], near)
        intent = (platt(raw, model._calibration) * present).astype(np.float32)
        np.testing.assert_array_equal(obs["crossing_intent"], intent)
        compared += int(present.sum())
    assert compared > 0
