"""The prediction-aware yielding policy: releases on confident predictions, never against a visible duty."""

from __future__ import annotations

import numpy as np

from agents import PredictiveYielding, YieldingPolicy
from tests.agents.test_policies import K, accel, crossing_centre, make_obs


def _intent(value: float) -> np.ndarray:
    return np.r_[value, np.zeros(K - 1)].astype(np.float32)


def test_without_predictors_it_is_the_yielding_policy() -> None:
    rng = np.random.default_rng(3)
    for _ in range(50):
        peds = [
            {
                "dx": float(rng.uniform(5, 40)),
                "dy": float(rng.uniform(-4, 6)),
                "vx": float(rng.normal()),
                "vy": float(rng.normal()),
                "w": int(rng.random() < 0.3),
            }
            for _ in range(3)
        ]
        obs = make_obs(float(rng.uniform(0, 14)), float(rng.uniform(-5, 40)), peds)
        np.testing.assert_array_equal(PredictiveYielding()(obs), YieldingPolicy()(obs))


def test_releases_a_confident_non_crosser_at_the_kerb() -> None:
    waiting = {"dx": crossing_centre(25.0), "dy": -2.6, "w": 1}
    base = make_obs(12.0, 25.0, [waiting])
    obs = dict(base, crossing_intent=_intent(0.05), crossing_intention=_intent(0.05))
    assert accel(YieldingPolicy()(obs))[0] < -2.0  # the old policy stops whatever the estimate
    assert accel(PredictiveYielding()(obs))[0] >= 0.0  # predicted not to cross at all: drive on
    unsure = dict(obs, crossing_intent=_intent(0.5))
    assert accel(PredictiveYielding()(unsure))[0] < -2.0  # not confident: stop as before
    # A low near-term estimate alone (the QLB / classical wrappers) never releases: the car may be why
    # the pedestrian waits.
    near_term = dict(base, crossing_intention=_intent(0.0))
    assert accel(PredictiveYielding()(near_term))[0] < -2.0


def test_never_releases_against_a_visible_duty() -> None:
    low = _intent(0.0)
    stepping = {"dx": crossing_centre(25.0), "dy": -2.2, "vy": 0.8, "w": 1}  # stepping towards the road
    on_zebra = {"dx": crossing_centre(25.0), "dy": -1.0, "vy": 1.3, "oc": 1, "road": 1}
    for ped in (stepping, on_zebra):
        obs = dict(make_obs(12.0, 25.0, [ped]), crossing_intention=low, crossing_intent=low)
        assert accel(PredictiveYielding()(obs))[0] < -2.0, ped


def test_predicted_paths_replace_constant_velocity() -> None:
    # Pedestrian on the sidewalk 25 m ahead walking towards the road (constant velocity: in the ego's
    # corridor after 2.7 s, beyond the 2 s guard); the predictor says it stops before the kerb.
    ped = {"dx": 25.0, "dy": -4.5, "vy": 1.0}
    paths = np.zeros((K, 12, 2), dtype=np.float32)
    paths[0, :, 0], paths[0, :, 1] = 25.0, -4.5
    obs = dict(make_obs(12.0, 150.0, [ped]), predicted_paths=paths)
    assert accel(YieldingPolicy()(obs))[0] < -2.0  # the union with constant velocity brakes
    assert accel(PredictiveYielding()(obs))[0] >= 0.0  # the path says no conflict
    # The same predictor predicting a step into the lane: brake.
    paths[0, :, 1] = -4.5 + 1.0 * 0.4 * np.arange(1, 13)
    assert accel(PredictiveYielding()(dict(obs, predicted_paths=paths)))[0] < -2.0
    # Close to the lane and moving in (constant velocity: inside within the guard): brake whatever the path.
    close = dict(
        make_obs(12.0, 150.0, [{"dx": 25.0, "dy": -2.2, "vy": 1.0}]), predicted_paths=paths * 0 + paths[0, 0]
    )
    assert accel(PredictiveYielding()(close))[0] < -2.0


def test_closed_loop_with_the_oracle_intention_gives_way() -> None:
    import gymnasium as gym

    from agents import make_policy
    from crossing_env.safety import EpisodeMetrics
    from predictors.oracle import OracleIntention

    env = OracleIntention(gym.make("crossing_env/Crossing-v0", scenario="zebra_case1"))
    base = env.unwrapped
    obs, _ = env.reset(seed=0)
    policy = make_policy("predictive_yielding", scenario=base.scenario, dt=base.config.dt)
    metrics = EpisodeMetrics(base.scenario, base.config.dt)
    done = False
    while not done:
        obs, _, terminated, truncated, info = env.step(policy(obs))
        metrics.update(info["ground_truth"])
        done = terminated or truncated
    r = metrics.result()
    assert not r.collision and r.yield_obligations > 0 and r.yield_violations == 0


def test_at_a_zebra_a_pedestrian_walking_to_the_road_keeps_constant_velocity() -> None:
    """Found on four_lane_arterial: a path that rightly predicts a stop at the kerb let the car keep its
    speed, and by the time the pedestrian stood waiting (a legal duty) it could no longer stop comfortably."""
    x = crossing_centre(20.0)
    ped = {"dx": x, "dy": -4.5, "vy": 1.0}  # at the crossing, on the sidewalk, 2.7 s from the corridor
    paths = np.zeros((K, 12, 2), dtype=np.float32)
    paths[0, :, 0], paths[0, :, 1] = x, -3.5  # the predictor: stops at the kerb
    obs = dict(make_obs(12.0, 20.0, [ped]), predicted_paths=paths)
    assert accel(YieldingPolicy()(obs))[0] < 0.0
    assert accel(PredictiveYielding()(obs))[0] == accel(YieldingPolicy()(obs))[0]
    # The same pedestrian away from a zebra (an unmarked crossing): the path is trusted.
    unmarked = dict(make_obs(12.0, 20.0, [ped], zebra=False), predicted_paths=paths)
    assert accel(PredictiveYielding()(unmarked))[0] >= 0.0
