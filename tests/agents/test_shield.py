"""The yielding shield: no action above the envelope gets through; through it, full throttle still yields."""

from __future__ import annotations

from dataclasses import replace

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

from agents import make_policy
from agents.config import YieldingConfig
from agents.policy import FunctionPolicy
from agents.registry import scenario_settings
from agents.shield import ShieldAction, ShieldedPolicy, YieldingShield
from agents.yielding import YieldingPolicy
from crossing_env import ENV_ID
from crossing_env.env import action_to_acceleration
from crossing_env.observation import PEDESTRIANS_KEY, EgoColumn, PedestrianColumn
from crossing_env.safety import EpisodeMetrics
from scenarios import load_scenario

SCENARIO = load_scenario("zebra_case1")
CONFIG = replace(YieldingConfig(), **scenario_settings(SCENARIO), dt=0.1)
BASE_OBS = gym.make(ENV_ID, scenario="zebra_case1").reset(seed=0)[0]

pedestrian = st.tuples(
    st.floats(-10.0, 60.0),  # dx
    st.floats(-6.0, 10.0),  # dy
    st.floats(-2.5, 2.5),  # vx
    st.floats(-2.5, 2.5),  # vy
    st.booleans(),  # on the crossing
    st.booleans(),  # waiting
)


@given(
    speed=st.floats(0.0, 20.0),
    to_stop=st.floats(-15.0, 80.0),
    zebra=st.booleans(),
    green=st.booleans(),
    peds=st.lists(pedestrian, max_size=4),
    requested=st.floats(-1.0, 1.0),
)
def test_no_action_above_the_envelope_gets_through(speed, to_stop, zebra, green, peds, requested):
    obs = {k: v.copy() for k, v in BASE_OBS.items()}
    ego = obs["ego"]
    ego[EgoColumn.SPEED] = speed
    ego[EgoColumn.DISTANCE_TO_STOP_LINE] = to_stop
    ego[EgoColumn.DISTANCE_PAST_CROSSING] = -(to_stop + 8.0)
    ego[EgoColumn.ZEBRA] = float(zebra)
    ego[EgoColumn.CAR_GREEN] = float(green)
    table = obs[PEDESTRIANS_KEY]
    table[:] = 0.0
    for k, (dx, dy, vx, vy, on_xing, waiting) in enumerate(peds):
        on_road = -1.75 < dy < 5.25
        table[k, [PedestrianColumn.PRESENCE, PedestrianColumn.DX, PedestrianColumn.DY]] = (1.0, dx, dy)
        table[k, [PedestrianColumn.VX, PedestrianColumn.VY]] = (vx, vy)
        table[k, PedestrianColumn.ON_CROSSING] = float(on_xing and on_road)
        table[k, PedestrianColumn.WAITING] = float(waiting and not on_road)
        table[k, PedestrianColumn.ON_ROAD] = float(on_road)
    bound = float(YieldingShield(CONFIG).limit(obs)[0])  # a fresh shield: the same state as the one below
    action, changed = YieldingShield(CONFIG).apply(np.array([requested], dtype=np.float32), obs)
    applied = float(action_to_acceleration(action, CONFIG.ego)[0])
    assert action.shape == (1,) and action.dtype == np.float32
    assert applied <= max(bound, -CONFIG.ego.max_deceleration) + 1e-4
    wanted = float(action_to_acceleration(float(np.float32(requested)), CONFIG.ego))  # as the float32 action
    assert changed == (wanted > bound)  # an action inside the envelope passes untouched
    if not changed:
        assert action[0] == np.float32(requested)


def _run(policy, scenario: str, seed: int) -> tuple[object, int]:
    env = gym.make(ENV_ID, scenario=scenario)
    obs, _ = env.reset(seed=seed)
    base = env.unwrapped
    metrics = EpisodeMetrics(base.scenario, base.config.dt)
    policy.reset(seed)
    done = False
    while not done:
        obs, _, terminated, truncated, info = env.step(policy(obs))
        metrics.update(info["ground_truth"])
        done = terminated or truncated
    return metrics.result(), policy.interventions


def test_full_throttle_through_the_shield_yields_at_a_zebra():
    """A learned part that always asks for full throttle still gives way: the shield does the yielding."""
    full = FunctionPolicy(lambda obs: np.ones(1, dtype=np.float32))
    for seed in (0, 1):
        policy = ShieldedPolicy(full, YieldingShield(CONFIG))
        result, interventions = _run(policy, "zebra_case1", seed)
        assert result.yield_obligations > 0 and result.yield_violations == 0
        assert not result.collision and interventions > 0
        assert result.max_speed_over_limit == 0.0


def test_shield_action_wrapper_reports_interventions():
    env = ShieldAction(
        gym.make(ENV_ID, scenario="zebra_case1"),
        lambda scenario, dt: make_policy("yielding", scenario=scenario, dt=dt).config,
    )
    env.reset(seed=0)
    flags = []
    for _ in range(150):
        _, _, terminated, truncated, info = env.step(np.ones(1, dtype=np.float32))
        flags.append(info["shield"])
        if terminated or truncated:
            break
    assert set(flags) == {0.0, 1.0}  # free on the open road, replaced before the crossing


def test_a_zero_residual_drives_exactly_as_the_rule():
    """Residual mode: action 0 asks for the rule's own acceleration, which its envelope always lets through
    (up to the 0.01 m/s margin under the speed limit)."""
    env = gym.make(ENV_ID, scenario="busy_zebra")
    obs, _ = env.reset(seed=2)
    rule = YieldingPolicy(CONFIG)
    shield = YieldingShield(CONFIG)
    replaced = 0
    for _ in range(200):
        expected = rule(obs)
        action, changed = shield.apply(np.zeros(1, dtype=np.float32), obs, residual_scale=2.0)
        replaced += changed
        if not changed:
            np.testing.assert_allclose(action, expected, atol=1e-6)
        obs, _, terminated, truncated, _ = env.step(expected)
        if terminated or truncated:
            break
    assert replaced <= 5  # only where the rule's cruise control touches the speed limit


def test_a_positive_residual_is_capped_by_the_envelope_at_a_waiting_pedestrian():
    """Full positive residual through the shield at a zebra still yields (no violation, no collision)."""
    full = FunctionPolicy(lambda obs: np.ones(1, dtype=np.float32))
    policy = ShieldedPolicy(full, YieldingShield(CONFIG), residual_scale=2.0)
    result, interventions = _run(policy, "zebra_case1", 0)
    assert result.yield_obligations > 0 and result.yield_violations == 0 and not result.collision
    assert interventions > 0


def _kerb_obs(speed: float, to_stop: float) -> dict[str, np.ndarray]:
    """A zebra 4 m wide ahead with one pedestrian standing at the kerb of the ego's half, at its centre."""
    obs = {k: np.zeros_like(v) for k, v in BASE_OBS.items()}
    front = CONFIG.ego_length / 2
    near = to_stop + CONFIG.stop_line_offset  # ego front → crossing's near edge
    obs["ego"][[EgoColumn.SPEED, EgoColumn.DISTANCE_TO_STOP_LINE]] = (speed, to_stop)
    obs["ego"][EgoColumn.DISTANCE_PAST_CROSSING] = -(near + 4.0 + 2 * front)
    obs["ego"][[EgoColumn.CAR_GREEN, EgoColumn.ZEBRA]] = (1.0, 1.0)
    ped = obs[PEDESTRIANS_KEY][0]
    ped[[PedestrianColumn.PRESENCE, PedestrianColumn.WAITING]] = (1.0, 1.0)
    ped[[PedestrianColumn.DX, PedestrianColumn.DY]] = (front + near + 2.0, CONFIG.road_right - 0.5)
    obs["pedestrian_tracks"][0] = 1.0
    return obs


@settings(max_examples=30, deadline=None)
# The residual learner's way over the line before the duty limit (found by this test).
@example(speed=5.0, to_stop=30.95, residual_scale=2.0, requests=[0.25, 0.28, 0.4, 0.91, 0.47, 0.5, 0.94, 0.2])
@given(
    speed=st.floats(0.0, 13.9),
    to_stop=st.floats(0.6, 40.0),
    residual_scale=st.sampled_from([0.0, 2.0]),
    requests=st.lists(st.floats(0.1, 1.0), min_size=8, max_size=8),
)
def test_a_pedestrian_at_the_kerb_is_always_given_a_comfortable_stop_before_the_line(
    speed, to_stop, residual_scale, requests
):
    """Whatever the learned part asks for, a car that could stop comfortably for someone waiting at the kerb
    stops before the stop line, and the shield never makes it brake harder than the rule would there or than
    the rule's legal-stop limit (`yield_max_deceleration`).

    A learner that keeps speed to the last comfortable point can reach the rule's stop point a little fast;
    there the rule gives its stop up (within 5 cm of it above 0.5 m/s), and the envelope used to let the car
    roll over the line into the crossing while people waited (busy_zebra, children_running episodes).
    """
    assume(speed * speed <= 2.0 * CONFIG.comfortable_deceleration * (to_stop - CONFIG.stop_buffer))
    shield = YieldingShield(CONFIG)
    rule = YieldingPolicy(CONFIG)  # sees what the shield's rule sees: the rule's own acceleration
    stood = 0
    for step in range(300):
        obs = _kerb_obs(speed, to_stop)
        requested = np.array([requests[step % len(requests)]], dtype=np.float32)
        action, changed = shield.apply(requested, obs, residual_scale)
        own = float(rule.acceleration(obs)[0])
        accel = float(action_to_acceleration(action, CONFIG.ego)[0])
        if changed:  # the action is the envelope's limit: no harder than the rule or a legal stop brakes
            assert accel >= min(own, -CONFIG.yield_max_deceleration) - 1e-4, (step, speed, to_stop)
        new_speed = max(speed + accel * CONFIG.dt, 0.0)
        to_stop -= 0.5 * (speed + new_speed) * CONFIG.dt
        speed = new_speed
        assert to_stop > 0.0, f"passed the stop line at step {step} ({speed:.2f} m/s)"
        stood = stood + 1 if speed < 0.05 and to_stop < 3.0 else 0
        if stood >= 10:  # stands at the line (the offer times out only after `offer_timeout`)
            return
    raise AssertionError(f"never stopped at the line ({to_stop:.2f} m left at {speed:.2f} m/s)")


@settings(max_examples=60, deadline=None)
@given(
    profile_share=st.floats(0.8, 1.3),  # speed / the comfortable profile's speed
    to_stop=st.floats(15.0, 40.0),
    along=st.floats(-1.0, 1.0),
    kerb_gap=st.floats(2.1, 3.0),
    far_side=st.booleans(),
    velocity=st.tuples(st.floats(-1.5, 1.5), st.floats(-1.5, 1.5)),
    requested=st.floats(-1.0, 1.0),
)
# Found by random search (not by the derandomised CI examples): on the profile, the rule's stop braking for
# the readiness target asked for more than the profile allows.
@example(
    profile_share=1.0,
    to_stop=38.0,
    along=0.0,
    kerb_gap=3.0,
    far_side=False,
    velocity=(0.0, 0.0),
    requested=1.0,
)
def test_faster_than_the_rule_only_where_a_stop_stays_comfortable(
    profile_share, to_stop, along, kerb_gap, far_side, velocity, requested
):
    """Someone a step from the kerb at a zebra owes the car nothing yet, but may wait there before the car
    arrives: through the shield the car accelerates beyond the rule only while it stays on the comfortable
    braking profile of the stop point (the next test: without the readiness limit it need not)."""
    dt, s = CONFIG.dt, to_stop - CONFIG.stop_buffer
    speed = min(profile_share * np.sqrt(2.0 * CONFIG.comfortable_deceleration * s), CONFIG.speed_limit - 0.5)
    obs = _kerb_obs(speed, to_stop)
    ped = obs[PEDESTRIANS_KEY][0]
    ped[PedestrianColumn.WAITING] = 0.0
    ped[PedestrianColumn.DX] += 2.0 * along  # along the 4 m crossing
    ped[PedestrianColumn.DY] = CONFIG.road_left + kerb_gap if far_side else CONFIG.road_right - kerb_gap
    ped[[PedestrianColumn.VX, PedestrianColumn.VY]] = velocity
    rule = float(YieldingPolicy(CONFIG).acceleration(obs)[0])  # a fresh rule: the shield's state below
    action, _ = YieldingShield(CONFIG).apply(np.array([requested], dtype=np.float32), obs)
    accel = float(action_to_acceleration(action, CONFIG.ego)[0])
    v_next, s_next = speed + accel * dt, s - speed * dt - 0.5 * accel * dt * dt
    comfortable = v_next * v_next <= 2.0 * CONFIG.comfortable_deceleration * s_next + 1e-3
    assert accel <= rule + 1e-4 or comfortable


def test_without_the_readiness_limit_the_learner_may_outpace_the_rule_near_someone_at_the_kerb():
    """The case the readiness limit exists for: 10 m/s, 18 m before the line (a comfortable stop needs
    9.4 m/s or less), someone 2.5 m from the kerb; full throttle is held to the rule's own acceleration."""
    obs = _kerb_obs(10.0, 18.0)
    ped = obs[PEDESTRIANS_KEY][0]
    ped[PedestrianColumn.WAITING] = 0.0
    ped[PedestrianColumn.DY] = CONFIG.road_right - 2.5
    rule = float(YieldingPolicy(CONFIG).acceleration(obs)[0])

    def full_throttle(shield: YieldingShield) -> float:
        action, _ = shield.apply(np.ones(1, dtype=np.float32), obs)
        return float(action_to_acceleration(action, CONFIG.ego)[0])

    ready, free = full_throttle(YieldingShield(CONFIG)), full_throttle(YieldingShield(CONFIG, ready=False))
    assert rule > 0.0  # the rule itself still speeds up (nobody owed a stop yet)
    assert ready == pytest.approx(rule, abs=1e-4)
    assert free == pytest.approx(CONFIG.ego.max_acceleration, abs=1e-4)


def test_offset_one_at_action_zero_is_the_full_residual_and_minus_one_is_the_rule():
    """``residual_offset`` shifts the residual: offset 1 with action 0 asks for the full +1 (the
    envelope-max start of the shielded learner, `shield_max_policy`), with action −1 for the rule itself."""
    from agents.registry import shield_max_policy

    env = gym.make(ENV_ID, scenario="busy_zebra")
    obs, _ = env.reset(seed=2)
    a, b, c, d = (YieldingShield(CONFIG) for _ in range(4))
    reference = shield_max_policy(SCENARIO, dt=CONFIG.dt)  # builds CONFIG's shield itself
    for _ in range(200):
        full, _ = a.apply(np.ones(1, dtype=np.float32), obs, residual_scale=2.0)
        start, _ = b.apply(np.zeros(1, dtype=np.float32), obs, residual_scale=2.0, residual_offset=1.0)
        back, _ = c.apply(-np.ones(1, dtype=np.float32), obs, residual_scale=2.0, residual_offset=1.0)
        rule, _ = d.apply(np.zeros(1, dtype=np.float32), obs, residual_scale=2.0)
        np.testing.assert_array_equal(start, full)
        np.testing.assert_array_equal(reference(obs), full)
        np.testing.assert_array_equal(back, rule)
        obs, _, terminated, truncated, _ = env.step(start)
        if terminated or truncated:
            break
