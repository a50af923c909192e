"""The yielding shield: no action above the envelope gets through; through it, full throttle still yields."""

from __future__ import annotations

from dataclasses import replace

import gymnasium as gym
import numpy as np
from hypothesis import given
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
