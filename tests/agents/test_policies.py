"""Policies on hand-built observations, batched calls, the registry, and one closed-loop episode."""

from __future__ import annotations

import numpy as np
import pytest

from agents import (
    BUILTIN_POLICIES,
    POLICIES,
    AlwaysCautious,
    ConstantSpeed,
    HighwayEnvRule,
    TTCEmergencyBrake,
    YieldingConfig,
    YieldingPolicy,
    make_policy,
)
from crossing_env import EgoConfig, action_to_acceleration

EGO = EgoConfig()
LENGTH = 4.5
K, M = 16, 8


def make_obs(
    speed: float,
    to_stop: float,
    peds: list[dict] | None = None,
    vehicles: list[dict] | None = None,
    zebra: bool = True,
    car_green: bool = True,
    crossing_width: float = 4.0,
    offset: float = 3.0,
) -> dict[str, np.ndarray]:
    """Observation with the ego `to_stop` metres (front) before the stop line of a crossing."""
    past = -(to_stop + offset + crossing_width + LENGTH)  # ego rear − crossing far edge
    ego = np.array([speed, 0.0, to_stop, past, float(car_green), float(zebra)], dtype=np.float32)
    ped = np.zeros((K, 8), dtype=np.float32)
    for i, p in enumerate(peds or []):
        ped[i] = [
            1,
            p["dx"],
            p["dy"],
            p.get("vx", 0.0),
            p.get("vy", 0.0),
            p.get("oc", 0),
            p.get("w", 0),
            p.get("road", 0),
        ]
    veh = np.zeros((M, 7), dtype=np.float32)
    for i, v in enumerate(vehicles or []):
        veh[i] = [1, v["dx"], v["dy"], v.get("vx", 0.0), 0.0, 4.5, 1.8]
    hist = np.zeros((K, 8, 2), dtype=np.float32)
    return {"ego": ego, "pedestrians": ped, "pedestrian_history": hist, "vehicles": veh}


def crossing_centre(to_stop: float, offset: float = 3.0, width: float = 4.0) -> float:
    """x of the crossing's centre relative to the ego's centre."""
    return LENGTH / 2 + to_stop + offset + width / 2


def accel(action: np.ndarray) -> np.ndarray:
    return action_to_acceleration(np.asarray(action), EGO)


def stack(obs_list: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    return {k: np.stack([o[k] for o in obs_list]) for k in obs_list[0]}


# --------------------------------------------------------------------------------------------- yielding


def test_yielding_brakes_comfortably_for_pedestrian_on_crossing() -> None:
    pol = YieldingPolicy()
    ped = {"dx": crossing_centre(18.0), "dy": 0.0, "vy": 1.3, "oc": 1, "road": 1}
    a = accel(pol(make_obs(10.0, 18.0, [ped])))
    assert a.shape == (1,)
    assert -4.0 <= a[0] <= -2.0  # comfortable-to-firm braking, not an emergency stop


def test_yielding_stops_before_the_line_with_comfortable_braking() -> None:
    """Closed loop on a point mass: a pedestrian stays on the crossing; the car must stop before the line."""
    pol = YieldingPolicy()
    v, to_stop, dt = 13.9, 70.0, 0.1
    decels = []
    for _ in range(400):
        ped = {"dx": crossing_centre(to_stop), "dy": 0.5, "vy": 0.0, "oc": 1, "road": 1}
        a = float(accel(pol(make_obs(v, to_stop, [ped])))[0])
        decels.append(-a)
        v_new = max(0.0, v + a * dt)
        to_stop -= 0.5 * (v + v_new) * dt
        v = v_new
    assert v < 0.05
    assert 0.0 <= to_stop <= 2.0  # stopped before the line, close to it
    assert max(decels) <= 3.0 + 1e-6  # never harder than comfortable (ITE hard-braking threshold)
    assert max(decels) >= 2.0  # and it did brake late, not creep in from far away


def test_yielding_proceeds_when_clear_and_cruises() -> None:
    pol = YieldingPolicy()
    assert accel(pol(make_obs(8.0, 20.0)))[0] > 0.5  # nobody there: speed up towards the limit
    # Pedestrian on the crossing in the far half, walking away from the ego's lane: no reason to stop.
    away = {"dx": crossing_centre(10.0), "dy": 4.5, "vy": 1.3, "oc": 1, "road": 1}
    assert accel(pol(make_obs(10.0, 10.0, [away])))[0] >= 0.0
    # Pedestrian that has crossed (behind the kerb on the far side), stopped car at the line: go.
    done = {"dx": crossing_centre(0.5), "dy": 6.5, "vy": 1.3}
    assert accel(pol(make_obs(0.0, 0.5, [done])))[0] > 0.5


def test_yielding_gives_way_to_waiting_pedestrian_at_zebra_only() -> None:
    pol = YieldingPolicy()
    waiting = {"dx": crossing_centre(25.0), "dy": -2.6, "w": 1}
    a = accel(pol(make_obs(12.0, 25.0, [waiting])))[0]
    assert a < -2.0
    # Same pedestrian at a signalised crossing with green for cars: no yielding.
    a_sig = accel(pol(make_obs(12.0, 25.0, [waiting], zebra=False, car_green=True)))[0]
    assert a_sig >= 0.0
    # Red for cars: stop at the line.
    assert accel(pol(make_obs(12.0, 25.0, [], zebra=False, car_green=False)))[0] < -2.0


def test_yielding_does_not_slam_brakes_for_kerb_pedestrian_when_too_close() -> None:
    pol = YieldingPolicy()
    waiting = {"dx": crossing_centre(4.0), "dy": -2.6, "w": 1}
    # 4 m from the line at 12 m/s (needs 18 m/s²): cannot stop; the pedestrian is still on the kerb.
    assert accel(pol(make_obs(12.0, 4.0, [waiting])))[0] > -1.0


def test_yielding_emergency_brakes_for_pedestrian_entering_lane() -> None:
    pol = YieldingPolicy()
    # Mid-block jaywalker 15 m ahead stepping into the lane from the right kerb.
    jay = {"dx": 15.0, "dy": -1.8, "vy": 1.4, "road": 1}
    a = accel(pol(make_obs(12.0, 150.0, [jay])))[0]
    assert a <= -4.0
    # The same pedestrian walking away from the lane: no braking.
    away = {"dx": 15.0, "dy": -2.6, "vy": -1.4}
    assert accel(pol(make_obs(12.0, 150.0, [away])))[0] >= 0.0


def test_yielding_uses_predictions_and_intention() -> None:
    pol = YieldingPolicy()
    ped = {"dx": 20.0, "dy": -3.0}  # standing on the sidewalk mid-block: constant velocity says "no conflict"
    obs = make_obs(10.0, 150.0, [ped])
    assert accel(pol(obs))[0] >= 0.0
    paths = np.zeros((K, 12, 2), dtype=np.float32)
    t = 0.4 * np.arange(1, 13)
    paths[0, :, 0] = 20.0
    paths[0, :, 1] = -3.0 + 1.5 * t  # predicted to step into the lane within ~1.2 s
    obs_pred = dict(obs, predicted_paths=paths)
    assert accel(pol(obs_pred))[0] < -1.0
    assert accel(YieldingPolicy(YieldingConfig(use_predictions=False))(obs_pred))[0] >= 0.0

    # Walking along the kerb at the zebra: with no prediction the car cannot tell a passer-by from someone
    # about to cross, so it is ready to give way; walking away from the road, it is not.
    by_kerb = {"dx": crossing_centre(25.0) - 1.0, "dy": -3.0, "vx": 1.3}
    assert accel(pol(make_obs(12.0, 25.0, [by_kerb])))[0] < -2.0
    leaving = dict(by_kerb, vx=0.0, vy=-1.3)
    assert accel(pol(make_obs(12.0, 25.0, [leaving])))[0] >= 0.0
    # Walking along the sidewalk further from the kerb (not waiting): yield only if predicted to cross.
    walker = {"dx": crossing_centre(25.0) - 1.0, "dy": -4.0, "vx": 1.3}
    base = make_obs(12.0, 25.0, [walker])
    low = dict(base, crossing_intention=np.r_[0.1, np.zeros(K - 1)].astype(np.float32))
    high = dict(base, crossing_intention=np.r_[0.9, np.zeros(K - 1)].astype(np.float32))
    assert accel(pol(base))[0] >= 0.0
    assert accel(pol(low))[0] >= 0.0
    assert accel(pol(high))[0] < -2.0
    # A waiting pedestrian is yielded to whatever the estimate says (the legal duty).
    waiting = {"dx": crossing_centre(25.0), "dy": -2.6, "w": 1}
    low_wait = dict(make_obs(12.0, 25.0, [waiting]), crossing_intention=low["crossing_intention"])
    assert accel(pol(low_wait))[0] < -2.0
    # Mid-block, standing at the kerb 18 m ahead: brake only when predicted to step out.
    kerb = make_obs(10.0, 150.0, [{"dx": 18.0, "dy": -2.2}])
    assert accel(pol(kerb))[0] >= 0.0
    kerb_high = dict(kerb, crossing_intention=high["crossing_intention"])
    assert accel(pol(kerb_high))[0] < -2.0


def test_yielding_follows_vehicle_ahead_and_slows_beside_stopped_vehicle() -> None:
    pol = YieldingPolicy()
    lead = {"dx": 12.0, "dy": 0.0, "vx": 0.0}
    assert accel(pol(make_obs(10.0, 60.0, vehicles=[lead])))[0] < -3.0
    # A car stopped in the neighbouring lane just before the zebra may hide a pedestrian: slow down.
    beside = {"dx": 25.0, "dy": -3.5, "vx": 0.0}
    assert accel(pol(make_obs(13.0, 25.0, vehicles=[beside])))[0] < -2.0
    assert accel(pol(make_obs(13.0, 25.0)))[0] >= 0.0


def test_yielding_does_not_overtake_the_vehicle_nearest_a_zebra() -> None:
    """UK rule 191: a car slowing in the next lane of the ego's direction before a zebra is not overtaken."""
    pol = YieldingPolicy(YieldingConfig(half_right=-5.25, road_right=-5.25))  # two lanes each way
    slowing = {"dx": 15.0, "dy": -3.5, "vx": 6.0}
    assert accel(pol(make_obs(13.0, 25.0, vehicles=[slowing])))[0] < -1.0
    # Far from any crossing it may be overtaken; a parked car (outside the carriageway) never counts.
    assert accel(pol(make_obs(13.0, 150.0, vehicles=[slowing])))[0] >= 0.0
    parked = {"dx": 15.0, "dy": -6.5, "vx": 0.0}
    assert accel(pol(make_obs(13.0, 60.0, vehicles=[parked])))[0] >= 0.0


def test_yielding_offer_declined_after_timeout() -> None:
    """Stopped at the line for a pedestrian who keeps waiting: after the timeout the car goes."""
    cfg = YieldingConfig(offer_timeout=1.0, dt=0.1)
    pol = YieldingPolicy(cfg)
    waiting = {"dx": crossing_centre(0.5), "dy": -2.6, "w": 1}
    obs = make_obs(0.0, 0.5, [waiting])
    actions = [float(accel(pol(obs))[0]) for _ in range(15)]
    assert actions[0] < 0.0
    assert actions[-1] > 0.0
    # Someone who arrives at the kerb after the offer timed out gets an offer of their own.
    newcomer = {"dx": crossing_centre(0.5) + 1.0, "dy": 6.0, "w": 1}  # at the far kerb
    assert accel(pol(make_obs(0.0, 0.5, [waiting, newcomer])))[0] <= 0.0
    # ...and declines it in turn: then the car goes again.
    after = [float(accel(pol(make_obs(0.0, 0.5, [waiting, newcomer])))[0]) for _ in range(15)]
    assert after[-1] > 0.0
    # A pedestrian on the crossing is never "declined".
    pol.reset()
    on = {"dx": crossing_centre(0.5), "dy": 0.0, "vy": 1.2, "oc": 1, "road": 1}
    obs_on = make_obs(0.0, 0.5, [on])
    assert all(float(accel(pol(obs_on))[0]) <= 0.0 for _ in range(30))


# --------------------------------------------------------------------------------------------- baselines


def test_constant_speed_holds_speed() -> None:
    ped = {"dx": 5.0, "dy": 0.0, "oc": 1, "road": 1}
    out = ConstantSpeed()(make_obs(10.0, 3.0, [ped]))
    assert out.dtype == np.float32
    np.testing.assert_array_equal(out, np.zeros(1, np.float32))


def test_ttc_brake_threshold() -> None:
    pol = TTCEmergencyBrake()
    near = make_obs(10.0, 100.0, [{"dx": 10.0, "dy": 0.0, "road": 1}])  # TTC = (10 − 2.25 − 0.3)/10 ≈ 0.75 s
    far = make_obs(10.0, 100.0, [{"dx": 40.0, "dy": 0.0, "road": 1}])  # ≈ 3.7 s
    assert pol.ttc(near)[0] == pytest.approx(0.745, abs=1e-3)
    assert pol(near)[0] == pytest.approx(-1.0)
    assert pol(far)[0] > -0.5


def test_highway_rule_brakes_for_predicted_collision_within_two_seconds() -> None:
    pol = HighwayEnvRule()
    crossing_ped = {
        "dx": 15.0,
        "dy": -2.5,
        "vy": 1.4,
    }  # reaches the lane centre in ~1.8 s, ego there in ~1.3 s
    assert accel(pol(make_obs(10.0, 100.0, [crossing_ped])))[0] < -3.0
    late = {"dx": 40.0, "dy": -2.5, "vy": 1.4}  # ego needs 3.8 s: beyond the 2 s horizon
    assert accel(pol(make_obs(10.0, 100.0, [late])))[0] >= 0.0


def test_always_cautious_crawls_at_every_crossing() -> None:
    pol = AlwaysCautious()
    assert accel(pol(make_obs(10.0, 10.0)))[0] < -1.0  # nobody there, still slows down
    assert accel(pol(make_obs(10.0, 200.0)))[0] > 0.0  # far from any crossing: cruise
    assert accel(pol(make_obs(2.0, 0.0)))[0] == pytest.approx(0.0, abs=0.3)  # crawl through


# ------------------------------------------------------------------------------------ batching / registry


@pytest.mark.parametrize("name", BUILTIN_POLICIES)
def test_policies_work_batched(name: str) -> None:
    obs_list = [
        make_obs(10.0, 18.0, [{"dx": crossing_centre(18.0), "dy": 0.0, "vy": 1.3, "oc": 1, "road": 1}]),
        make_obs(8.0, 40.0),
        make_obs(12.0, 25.0, [{"dx": crossing_centre(25.0), "dy": -2.6, "w": 1}]),
        make_obs(10.0, 100.0, [{"dx": 10.0, "dy": 0.0, "road": 1}]),
    ]
    single = np.stack([make_policy(name)(o) for o in obs_list])
    batched = make_policy(name)(stack(obs_list))
    assert batched.shape == (4, 1)
    assert batched.dtype == np.float32
    np.testing.assert_allclose(batched, single, atol=1e-6)
    assert np.all(np.abs(batched) <= 1.0)
    # Extra leading axes (e.g. (envs, time)) keep their shape.
    two = make_policy(name)({k: v.reshape(2, 2, *v.shape[1:]) for k, v in stack(obs_list).items()})
    np.testing.assert_allclose(two.reshape(4, 1), single, atol=1e-6)


def test_registry() -> None:
    builtin = {
        "yielding",
        "predictive_yielding",
        "constant_speed",
        "ttc_brake",
        "always_cautious",
        "highway_rule",
    }
    assert set(BUILTIN_POLICIES) == builtin
    assert POLICIES == (*BUILTIN_POLICIES, "ppo_shielded")
    with pytest.raises(ValueError, match="unknown policy 'nope'"):
        make_policy("nope")
    with pytest.raises(ValueError, match="bogus"):
        make_policy("yielding", bogus=1.0)
    pol = make_policy("yielding", comfortable_deceleration=2.0)
    assert pol.config.comfortable_deceleration == 2.0


def test_make_policy_reads_scenario() -> None:
    from scenarios import load_scenario

    sc = load_scenario("four_lane_arterial")
    pol = make_policy("yielding", scenario=sc, dt=0.1)
    assert pol.config.speed_limit == sc.road.speed_limit
    assert pol.config.ego == sc.ego
    # Ego in lane 1 of a 4-lane two-way road: its half spans lanes 0-1, i.e. y in [0, 7] → [-5.25, 1.75].
    assert pol.config.half_right == pytest.approx(-(sc.ego.lane + 0.5) * sc.road.lane_width)
    assert pol.config.half_left == pytest.approx(
        2 * sc.road.lane_width - (sc.ego.lane + 0.5) * sc.road.lane_width
    )


def test_bad_observation_is_rejected() -> None:
    with pytest.raises(KeyError, match="pedestrians"):
        YieldingPolicy()({"ego": np.zeros(6, np.float32)})
    with pytest.raises(ValueError, match="ego"):
        YieldingPolicy()({"ego": np.zeros(5, np.float32), "pedestrians": np.zeros((K, 8), np.float32)})


# --------------------------------------------------------------------------------------------- closed loop


def test_yielding_in_env_gives_way_without_collision() -> None:
    import gymnasium as gym

    import crossing_env
    from crossing_env.safety import EpisodeMetrics
    from scenarios import load_scenario

    sc = load_scenario("zebra_case1")
    env = gym.make(crossing_env.ENV_ID, scenario=sc)
    pol = make_policy("yielding", scenario=sc, dt=0.1)
    obs, _ = env.reset(seed=3)
    metrics = EpisodeMetrics(sc, 0.1)
    done = False
    while not done:
        obs, _, term, trunc, info = env.step(pol(obs))
        metrics.update(info["ground_truth"])
        done = term or trunc
    res = metrics.result()
    assert not res.collision
    assert res.yield_violations == 0
    assert res.yield_obligations >= 1
    assert res.max_deceleration <= 4.05  # within nuPlan's comfort bound


def test_policy_drives_a_vector_env() -> None:
    import gymnasium as gym

    import crossing_env

    envs = gym.make_vec(crossing_env.ENV_ID, num_envs=2, vectorization_mode="sync", scenario="zebra_case1")
    pol = make_policy("yielding", dt=0.1)
    obs, _ = envs.reset(seed=[1, 2])
    speeds = []
    for _ in range(40):
        action = pol(obs)
        assert action.shape == (2, 1)
        assert envs.action_space.contains(action)
        obs, *_ = envs.step(action)
        speeds.append(obs["ego"][:, 0].copy())
    envs.close()
    assert np.all(np.isfinite(speeds))
    assert np.all(np.asarray(speeds) > 5.0)  # comfortable, late braking: still above 5 m/s after 4 s
