"""The sampling planner: proposals, the forecast hypotheses and their prior, the scorer, the policy."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from agents import make_policy
from agents.config import PlannerConfig
from agents.planner import SamplingPlanner
from agents.planner.forecasts import build_hypotheses, step_off_probability
from agents.planner.proposals import command, make_proposals
from agents.planner.scorer import choose, plan_index, score_proposals
from agents.view import parse_observation
from agents.yielding import YieldingPolicy
from crossing_env.observation import (
    CROSSING_INTENT_KEY,
    PEDESTRIAN_TRACKS_KEY,
    PREDICTED_SAMPLES_KEY,
    SAMPLE_WEIGHTS_KEY,
)
from tests.agents.test_policies import accel, crossing_centre, make_obs, stack

CFG = PlannerConfig()


def kerb_ped(dx: float, **extra: float) -> dict:
    """A pedestrian standing on the right-hand pavement at the kerb, `dx` ahead of the ego's centre."""
    return {"dx": dx, "dy": CFG.road_right - 0.3, "w": 1, **extra}


def far_kerb_ped(dx: float) -> dict:
    """A pedestrian at the far (left) kerb: a step-off reaches the ego's lane in about 2.7 s."""
    return {"dx": dx, "dy": CFG.road_left + 0.3, "w": 1}


def hypotheses(obs: dict, cfg: PlannerConfig = CFG):
    planner = SamplingPlanner(cfg)
    view = parse_observation(obs)
    return view, build_hypotheses(view, obs, cfg, planner._kerb_gap(view), planner._towards_road(view))


# -------------------------------------------------------------------------------------------- proposals


def test_proposals_span_stop_to_the_limit_with_an_emergency_stop() -> None:
    props = make_proposals(CFG)
    assert props.target[0] == 0.0 and props.target[-2] == pytest.approx(CFG.speed_limit)
    assert props.braking[-1] == CFG.ego.max_deceleration  # the emergency stop
    assert (props.braking[:-1] == CFG.comfortable_deceleration).all()
    a = command(np.full(len(props.target), 10.0), props, CFG)
    assert a[-1] == -CFG.ego.max_deceleration
    assert (a[:-1] >= -CFG.comfortable_deceleration).all() and (a[:-1] <= CFG.go_acceleration).all()
    assert a[0] < 0.0 < a[-2]  # the stop brakes, the limit accelerates
    with pytest.raises(ValueError, match="target_fractions"):
        make_proposals(dataclasses.replace(CFG, target_fractions=(0.5, 1.5)))


# ----------------------------------------------------------------------------------- forecast hypotheses


def test_prior_lets_anyone_at_the_kerb_step_off() -> None:
    walking_away = kerb_ped(30.0, vy=-1.0)
    far_from_kerb = {"dx": 30.0, "dy": CFG.road_right - 3.0, "w": 1}
    obs = make_obs(10.0, 20.0, [kerb_ped(30.0), walking_away, far_from_kerb])
    _, hyp = hypotheses(obs)
    np.testing.assert_allclose(hyp.weights[0, 0, :3, -1], [CFG.step_off_prior, 0.0, 0.0])
    np.testing.assert_allclose(hyp.weights[0, 0, :3].sum(-1), 1.0)
    # The step-off hypothesis walks straight across at the assumed pace; the path stays (constant velocity).
    walk = hyp.points[0, 0, 0, -1]
    assert walk[-1, 1] - walk[0, 1] == pytest.approx(CFG.assumed_walking_speed * 4.8)
    np.testing.assert_allclose(hyp.points[0, 0, 0, 0, :, 1], CFG.road_right - 0.3, atol=1e-6)
    # At a signalised crossing showing the car green, people wait for their own signal.
    _, hyp = hypotheses(make_obs(10.0, 20.0, [kerb_ped(30.0)], zebra=False, car_green=True))
    assert hyp.weights[0, 0, 0, -1] == pytest.approx(CFG.signal_step_off_prior)


def test_intent_updates_the_prior_and_a_crossing_forecast_carries_its_own_mass() -> None:
    obs = make_obs(10.0, 20.0, [kerb_ped(30.0), kerb_ped(35.0)])
    obs[CROSSING_INTENT_KEY] = np.array([0.0, 1.0] + [0.0] * 14, dtype=np.float32)
    planner = SamplingPlanner(CFG)
    view = parse_observation(obs)
    q = step_off_probability(view, obs, CFG, planner._kerb_gap(view), planner._towards_road(view))
    np.testing.assert_allclose(q[0, :2], [0.0, 2 * CFG.step_off_prior])
    # A forecast that has them crossing within the horizon needs no extra step-off hypothesis.
    samples = np.zeros((16, 2, 12, 2), dtype=np.float32)
    t = 0.4 * np.arange(1, 13)
    samples[0, :, :, 0] = 30.0
    samples[0, 0, :, 1] = CFG.road_right - 0.3 + 1.4 * t  # crosses
    samples[0, 1, :, 1] = CFG.road_right - 0.3  # stays
    weights = np.zeros((16, 2), dtype=np.float32)
    weights[0] = [0.5, 0.5]
    obs = make_obs(10.0, 20.0, [kerb_ped(30.0)])
    obs.update({PREDICTED_SAMPLES_KEY: samples, SAMPLE_WEIGHTS_KEY: weights})
    _, hyp = hypotheses(obs, dataclasses.replace(CFG, step_off_prior=0.8))
    np.testing.assert_allclose(hyp.weights[0, 0, 0], [0.5 * 0.7, 0.5 * 0.7, 0.3])


# ------------------------------------------------------------------------------------------------ scorer


def test_faster_proposals_risk_someone_who_steps_off_and_the_choice_keeps_the_chance_constraint() -> None:
    obs = make_obs(13.9, 80.0, [far_kerb_ped(45.0)], zebra=False, car_green=True)
    cfg = dataclasses.replace(CFG, signal_step_off_prior=0.5)
    view, hyp = hypotheses(obs, cfg)
    props = make_proposals(cfg)
    scores = score_proposals(view.speed, np.full(1, np.inf), view.present, props, hyp, cfg)
    full, stop = len(props.target) - 2, 0
    assert scores.collision[0, full] == pytest.approx(0.5)  # cannot stop if they step off now
    assert scores.collision[0, stop] == 0.0
    assert (np.diff(scores.collision[0, :-1]) >= 0).all()  # the faster, the riskier
    assert scores.collision[0, -1] == 0.0  # the emergency stop is safe, and uncomfortable
    assert scores.score[0, -1] < scores.score[0, stop]
    chosen = choose(scores, np.full(1, -1), cfg)[0]
    assert scores.collision[0, chosen] <= cfg.collision_chance
    # Without the step-off hypothesis the full speed is free and best.
    scores = score_proposals(
        view.speed, np.full(1, np.inf), view.present, props, hypotheses(obs, CFG)[1], CFG
    )
    assert choose(scores, np.full(1, -1), CFG)[0] == full


def test_someone_who_may_step_off_does_not_walk_into_the_side_of_the_car_but_a_forecast_path_does() -> None:
    props = make_proposals(CFG)
    beside = make_obs(5.0, 60.0, [kerb_ped(0.0)], zebra=False)
    view, hyp = hypotheses(beside, dataclasses.replace(CFG, step_off_prior=1.0, signal_step_off_prior=1.0))
    scores = score_proposals(view.speed, np.full(1, np.inf), view.present, props, hyp, CFG)
    assert (scores.collision == 0.0).all()
    # Forecast to walk on into the car's path (constant velocity), the same person is a collision for the
    # proposals that are still there when they arrive, and the planner's choice is one that is not.
    walking = make_obs(5.0, 60.0, [{"dx": 0.0, "dy": -3.0, "vy": 1.4}], zebra=False)
    view, hyp = hypotheses(walking)
    scores = score_proposals(view.speed, np.full(1, np.inf), view.present, props, hyp, CFG)
    assert scores.collision[0, -1] >= 0.9  # the emergency stop waits for them right in their way
    assert scores.collision[0, choose(scores, np.full(1, -1), CFG)[0]] == 0.0
    # A step-off 12 m ahead of a car at 13.9 m/s cannot be avoided by holding the limit.
    ahead = make_obs(13.9, 60.0, [kerb_ped(12.0)], zebra=False)
    view, hyp = hypotheses(ahead, dataclasses.replace(CFG, step_off_prior=1.0, signal_step_off_prior=1.0))
    scores = score_proposals(view.speed, np.full(1, np.inf), view.present, props, hyp, CFG)
    assert scores.collision[0, -2] == 1.0


def test_the_legal_stop_binds_every_proposal() -> None:
    view, hyp = hypotheses(make_obs(10.0, 30.0))
    props = make_proposals(CFG)
    free = score_proposals(view.speed, np.full(1, np.inf), view.present, props, hyp, CFG)
    held = score_proposals(view.speed, np.full(1, 15.0), view.present, props, hyp, CFG)
    assert (held.score[0, 1:-1] < free.score[0, 1:-1]).all()  # less progress: each stops at the line
    assert held.first[0, -2] < 0.0  # brakes for the line now


# ------------------------------------------------------------------------------------------------ policy


def test_planner_gives_way_on_a_zebra_as_the_rules_do() -> None:
    ped = {"dx": crossing_centre(18.0), "dy": 0.0, "vy": 1.3, "oc": 1, "road": 1}
    obs = make_obs(10.0, 18.0, [ped])
    a = accel(SamplingPlanner()(obs))[0]
    assert a <= accel(YieldingPolicy()(obs))[0] + 1e-4
    assert a < -1.0


def test_planner_drives_on_with_nobody_about_and_is_batched() -> None:
    planner = make_policy("sampling_planner")
    assert isinstance(planner, SamplingPlanner) and planner.batched
    lone = make_obs(8.0, 40.0)
    busy = make_obs(12.0, 15.0, [kerb_ped(crossing_centre(15.0))])
    crossing = make_obs(10.0, 18.0, [{"dx": crossing_centre(18.0), "dy": 0.0, "vy": 1.3, "oc": 1, "road": 1}])
    singles = []
    for obs in (lone, busy, crossing):
        planner.reset(0)
        singles.append(planner(obs))
    assert accel(singles[0])[0] > 0.0
    planner.reset(0)
    batch = planner(stack([lone, busy, crossing]))
    np.testing.assert_array_equal(batch, np.concatenate(singles).reshape(3, 1))


def test_intent_that_rules_a_pedestrian_out_lets_the_planner_drive_faster() -> None:
    obs = make_obs(13.9, 80.0, [far_kerb_ped(45.0)], zebra=False, car_green=False)
    cfg = dataclasses.replace(CFG, step_off_prior=0.5)
    prior = accel(SamplingPlanner(cfg)(obs))[0]
    ruled_out = dict(obs)
    ruled_out[CROSSING_INTENT_KEY] = np.zeros(16, dtype=np.float32)
    told = accel(SamplingPlanner(cfg)(ruled_out))[0]
    assert prior < -1.0 and told == pytest.approx(0.0, abs=1e-3)  # slows for the prior; holds the limit


def test_behind_someone_walking_away_along_the_lane_the_planner_follows_rather_than_stops() -> None:
    walker = {"dx": 8.0, "dy": 0.0, "vx": 1.4, "road": 1}
    view, hyp = hypotheses(make_obs(3.0, 80.0, [walker], zebra=False))
    props = make_proposals(CFG)
    scores = score_proposals(view.speed, np.full(1, np.inf), view.present, props, hyp, CFG)
    assert (scores.collision == 0.0).all()
    best = choose(scores, np.full(1, -1), CFG)[0]
    assert props.target[best] > 0.0  # it follows at their pace; the closing speed, not its own, sets TTC
    assert scores.first[0, best] >= -CFG.comfortable_deceleration


def test_with_plan_conditioned_forecasts_each_plan_keeps_its_own_step_off_mass() -> None:
    """Under a plan that keeps someone on the kerb (waiting for the car), they may still step off."""
    obs = make_obs(10.0, 80.0, [kerb_ped(30.0)])
    plans = np.zeros((2, 16, 12, 2), dtype=np.float32)
    plans[:, 0, :, 0] = 30.0
    plans[0, 0, :, 1] = CFG.road_right - 0.3 + 1.4 * 0.4 * np.arange(1, 13)  # go: they cross
    plans[1, 0, :, 1] = CFG.road_right - 0.3  # slow: they wait
    obs.update({"plan_paths": plans, "plan_accelerations": np.array([1.5, -2.5], dtype=np.float32)})
    _, hyp = hypotheses(obs)
    assert hyp.points.shape[1] == 2
    np.testing.assert_allclose(hyp.weights[0, :, 0, -1], [0.0, CFG.step_off_prior])
    assert list(hyp.reactive) == [False, True]


def test_a_proposal_that_only_defers_a_crossing_is_charged_the_wait_still_ahead() -> None:
    obs = make_obs(10.0, 80.0, [kerb_ped(30.0)], zebra=False)
    plans = np.zeros((2, 16, 12, 2), dtype=np.float32)
    plans[:, 0, :, 0] = 30.0
    plans[0, 0, :, 1] = CFG.road_right - 0.3 + 1.4 * 0.4 * np.arange(1, 13)  # go: they cross
    plans[1, 0, :, 1] = CFG.road_right - 0.3  # slow: they wait for the car
    obs.update({"plan_paths": plans, "plan_accelerations": np.array([1.5, -2.5], dtype=np.float32)})
    view, hyp = hypotheses(obs)
    props = make_proposals(CFG)
    charged = score_proposals(view.speed, np.full(1, np.inf), view.present, props, hyp, CFG)
    free = score_proposals(
        view.speed, np.full(1, np.inf), view.present, props, hyp._replace(crossing=hyp.crossing * 0), CFG
    )
    slow = plan_index(view.speed, props, hyp, CFG)[0] == 1
    assert slow.any() and (~slow).any()
    assert (charged.score[0, slow] < free.score[0, slow]).all()  # the crossing is still ahead of them
    np.testing.assert_array_equal(charged.score[0, ~slow], free.score[0, ~slow])


def test_a_restarted_episode_in_a_batch_slot_forgets_the_proposal_held() -> None:
    """A vector env restarts an element without `reset`: the held proposal must go with its episode."""
    cfg = dataclasses.replace(CFG, switch_margin=1.0)  # hysteresis that keeps any feasible proposal
    red = make_obs(0.0, 1.0, zebra=False, car_green=False)  # standing at a red light: the stop is held
    free = make_obs(8.0, 60.0)  # the next episode in the same slot, nobody about
    for obs in (red, free):
        obs[PEDESTRIAN_TRACKS_KEY] = np.zeros(16, dtype=np.float32)  # with tracks the rules keep memory
    planner = SamplingPlanner(cfg)
    planner(red)
    assert planner.proposal_history[-1][0] == 0
    restarted = planner(free)
    fresh = SamplingPlanner(cfg)
    np.testing.assert_array_equal(restarted, fresh(free))
    assert planner.proposal_history[-1][0] == fresh.proposal_history[-1][0] != 0
