"""Tests of crossing_env.safety.episode (`EpisodeMetrics`) on hand-built snapshots."""

from __future__ import annotations

import math

import pytest

from crossing_env.safety import EpisodeMetrics
from crossing_env.types import CollisionEvent, PedState
from scenarios.config import ScenarioConfig
from tests.crossing_env.safety.snapshots import DT, Ped, Veh, _ego_through, make_gt, metrics

# ---------------------------------------------------------------------------------------------------------
# EpisodeMetrics
# ---------------------------------------------------------------------------------------------------------


def test_rejects_bad_dt_and_time_order() -> None:
    with pytest.raises(ValueError, match="dt"):
        EpisodeMetrics(ScenarioConfig(), 0.0)
    m = metrics()
    m.update(make_gt(1.0))
    with pytest.raises(ValueError, match="time went backwards"):
        m.update(make_gt(0.5))


def test_episode_ttc_separation_and_clearance() -> None:
    m = metrics()
    ped = Ped(1, (60.0, 1.75), radius=0.25)
    # step 1: ego at 30 -> front 32.25; gap 60 - 0.25 - 32.25 = 27.5 m at 10 m/s -> 2.75 s (< 3 s encounter)
    m.update(make_gt(0.1, ego_x=30.0, peds=[ped]))
    # step 2: ego at 45 -> gap 12.5 m -> 1.25 s (< 1.5 s serious), separation 12.5 m
    m.update(make_gt(0.2, ego_x=45.0, peds=[ped]))
    assert m.step_ttc == pytest.approx(1.25) and m.step_separation == pytest.approx(12.5)
    # step 3: ego stopped 0.5 m short: TTC not evaluated, separation 0.5 m (< 1 m clearance)
    m.update(make_gt(0.3, ego_x=57.0, ego_v=0.0, peds=[ped]))
    r = m.result()
    assert r.min_ttc == pytest.approx(1.25)
    assert r.encounter_time == pytest.approx(0.2) and r.serious_conflict_time == pytest.approx(0.1)
    assert r.min_separation == pytest.approx(0.5)
    assert r.clearance_violation_time == pytest.approx(0.1)


def test_episode_without_anyone_reports_never() -> None:
    m = metrics()
    m.update(make_gt(0.1))
    r = m.result()
    assert r.min_ttc == math.inf and r.min_separation == math.inf and r.min_ttc_vehicle == math.inf
    assert r.max_drac_crossing == 0.0 and r.yield_obligations == 0 and math.isnan(r.yield_compliance)


def test_episode_braking_counts() -> None:
    m = metrics()
    for k, a in enumerate([-1.0, -3.5, -4.2, -2.0, -3.0, -0.5, 1.0]):
        m.update(make_gt(0.1 * (k + 1), acc=a))
    r = m.result()
    assert r.hard_braking_steps == 3  # -3.5, -4.2, -3.0 (threshold inclusive)
    assert r.hard_braking_events == 2  # runs (-3.5, -4.2) and (-3.0)
    assert r.comfort_violation_steps == 1  # -4.2 <= -4.05
    assert r.max_deceleration == pytest.approx(4.2)


def test_episode_collisions() -> None:
    m = metrics()
    hit = [
        CollisionEvent(0.1, "pedestrian", 3, (50.0, 1.0), 5.0, True, car_speed=4.8),
        CollisionEvent(0.1, "pedestrian", 4, (50.0, 1.5), 7.5, False, car_speed=7.4),
        CollisionEvent(0.1, "vehicle", 9, (52.0, 1.5), 2.0, True, car_speed=9.0),
    ]
    m.update(make_gt(0.1, collisions=hit))
    r = m.result()
    assert r.collision and r.pedestrian_collisions == 2 and r.vehicle_collisions == 1
    assert r.compliant_pedestrian_collisions == 1 and r.noncompliant_pedestrian_collisions == 1
    assert r.max_impact_speed == pytest.approx(7.4)  # the car's speed at contact, pedestrian contacts only
    assert math.isnan(metrics().result().max_impact_speed)


def test_episode_following_vehicle() -> None:
    m = metrics()
    cars = [
        Veh(1, (50.0, 1.75), (5.0, 0.0)),  # same lane, 20 m ahead centre to centre
        Veh(2, (40.0, 5.25), (-10.0, 0.0)),  # oncoming lane: not scored for TTC
        Veh(3, (20.0, 1.75), (15.0, 0.0)),  # behind the ego: not scored
    ]
    m.update(make_gt(0.1, ego_x=30.0, vehicles=cars))
    r = m.result()
    # gap 20 - 4.5 = 15.5 m, closing 10 - 5 = 5 m/s -> TTC 3.1 s, DRAC 0.5·25/15.5 = 0.80645 m/s²
    assert r.min_ttc_vehicle == pytest.approx(3.1)
    assert r.max_drac_following == pytest.approx(0.5 * 25 / 15.5)
    # nearest footprint: car 2 at dx 10, dy 3.5 -> gaps 10 - 4.5 = 5.5 and 3.5 - 1.8 = 1.7 -> 5.757;
    # car 3: dx 10 -> 5.5 m bumper to bumper (smaller)
    assert r.min_vehicle_separation == pytest.approx(5.5)


def test_episode_crossing_drac() -> None:
    # A pedestrian standing in the conflict area never clears it: DRAC = stopping deceleration.
    # ego front at 98 (x = 95.75): d = 118 - 98 = 20 m at 10 m/s -> 100 / 40 = 2.5 m/s²
    m = metrics()
    m.update(make_gt(0.1, ego_x=95.75, peds=[Ped(1, (120.0, 1.0))]))
    assert m.result().max_drac_crossing == pytest.approx(2.5)
    # A pedestrian walking +y at 1.25 m/s from y = 1.0 leaves the grown area (y = 3.5 + 0.28) after
    # (3.78 - 1.0) / 1.25 = 2.224 s; the ego front is 20 m away at 10 m/s (arrives at 2 s, earlier):
    # vt = 22.24 <= 2d = 40 -> DRAC = 2 (10 - 20/2.224) / 2.224 = 0.90571 m/s²
    m = metrics()
    m.update(make_gt(0.1, ego_x=95.75, peds=[Ped(1, (120.0, 1.0), (0.0, 1.25))]))
    t_a = (3.78 - 1.0) / 1.25
    assert m.result().max_drac_crossing == pytest.approx(2 * (10 - 20 / t_a) / t_a)
    # ego 30 m away arrives at 3 s, after the pedestrian left (2.224 s): no deceleration needed
    m = metrics()
    m.update(make_gt(0.1, ego_x=85.75, peds=[Ped(1, (120.0, 1.0), (0.0, 1.25))]))
    assert m.result().max_drac_crossing == 0.0


def test_pet_pedestrian_first_then_ego_first() -> None:
    m = metrics()
    inside, outside = Ped(7, (120.0, 1.0)), Ped(7, (120.0, 5.0))
    # pedestrian 7 occupies the conflict area at t = 1.0, has left at t = 1.6
    _ego_through(m, 1.0, 60.0, [inside])
    _ego_through(m, 1.6, 80.0, [outside])
    # ego enters at t = 3.0 (front 116.0 + 2.25 = 118.25 > 118) -> PET = 3.0 - 1.6 = 1.4
    _ego_through(m, 3.0, 116.0, [outside])
    # ego has left at t = 4.0 (rear 124.5 - 2.25 = 122.25 > 122); pedestrian 8 enters at t = 5.0 -> PET 1.0
    _ego_through(m, 4.0, 124.5, [outside, Ped(8, (119.0, -1.0))])
    _ego_through(m, 5.0, 134.5, [outside, Ped(8, (119.0, 0.5))])
    r = m.result()
    assert r.pets_pedestrian_first == pytest.approx((1.4,))
    assert r.pets_ego_first == pytest.approx((1.0,))
    assert r.min_pet_pedestrian_first == pytest.approx(1.4) and r.min_pet_ego_first == pytest.approx(1.0)
    assert r.simultaneous_occupancies == 0


def test_kerb_pedestrian_does_not_occupy_conflict_area() -> None:
    m = metrics()
    # centre 0.2 m onto the sidewalk (y = -0.2): the 0.28 m body overhangs the kerb but is not on the road
    kerb = Ped(5, (120.0, -0.2), state=PedState.WAITING, waiting=False)
    _ego_through(m, 1.0, 80.0, [kerb])
    _ego_through(m, 2.0, 117.0, [kerb])
    assert m.result().simultaneous_occupancies == 0


def test_pet_simultaneous_occupancy_and_id_order() -> None:
    m = metrics()
    # two pedestrians, ids listed in different orders between steps: the state must follow the ids
    _ego_through(m, 1.0, 80.0, [Ped(20, (120.0, 1.0)), Ped(3, (150.0, -2.0))])
    # ego enters while pedestrian 20 is still inside: no PET, one simultaneous occupancy
    _ego_through(m, 2.0, 117.0, [Ped(3, (150.0, -2.0)), Ped(20, (120.0, 2.0))])
    r = m.result()
    assert r.simultaneous_occupancies == 1 and r.pets_pedestrian_first == () and r.pets_ego_first == ()


def test_delay_and_time_to_pass() -> None:
    m = metrics()
    # ego from x = 30 at a constant 10 m/s: x(t) = 30 + 10 t
    for k in range(120):
        t = DT * (k + 1)
        m.update(make_gt(t, ego_x=30.0 + 10.0 * t))
    r = m.result()
    # target 122 + 5 = 127 reached at t = 9.7; free flow 97 m / 13.9 m/s = 6.97842 s -> delay 2.72158 s
    assert r.passed_crossing and r.delay == pytest.approx(9.7 - 97.0 / 13.9)
    # trigger: front 30 m before 118 -> x = 88 - 2.25 = 85.75 at t = 5.575; rear clears 122 at
    # x = 124.25, t = 9.425 -> 3.85 s
    assert r.time_to_pass == pytest.approx(3.85)
    assert r.distance_travelled == pytest.approx(120.0)
    m = metrics()
    m.update(make_gt(0.1, ego_x=31.0))
    r = m.result()
    assert not r.passed_crossing and math.isnan(r.delay) and math.isnan(r.time_to_pass)


def test_pedestrian_waiting_times() -> None:
    m = metrics()
    a_wait = [PedState.APPROACHING] * 2 + [PedState.WAITING] * 8 + [PedState.CROSSING]
    for k, s in enumerate(a_wait):
        t = DT * (k + 1)
        peds = [
            Ped(1, (120.0, -0.5 if s != PedState.CROSSING else 0.3), state=s),
            # pedestrian 2 steps straight off at t = 0.5 without stopping -> 0 s
            Ped(
                2, (119.0, 7.5 if k < 4 else 6.8), state=PedState.APPROACHING if k < 4 else PedState.CROSSING
            ),
            # pedestrian 3 arrives at the kerb at t = 0.6 and is still waiting at the end
            Ped(3, (121.0, -0.6), state=PedState.APPROACHING if k < 5 else PedState.WAITING),
        ]
        m.update(make_gt(t, ego_x=30.0 + t, peds=peds))
    r = m.result()
    # pedestrian 1: WAITING first seen at t = 0.3, CROSSING at t = 1.1 -> 0.8 s
    assert sorted(r.pedestrian_wait_times) == pytest.approx([0.0, 0.8])
    assert r.censored_waits == 1


def test_reset_forgets_episode() -> None:
    m = metrics()
    m.update(make_gt(0.1, acc=-5.0, peds=[Ped(1, (40.0, 1.75))]))
    m.reset()
    m.update(make_gt(0.1))
    r = m.result()
    assert r.hard_braking_steps == 0 and r.min_separation == math.inf and r.steps == 1
