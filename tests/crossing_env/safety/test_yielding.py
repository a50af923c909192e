"""Tests of crossing_env.safety.yielding: yield obligations, via `EpisodeMetrics` on hand-built snapshots."""

from __future__ import annotations

from crossing_env.safety import MetricsConfig
from crossing_env.safety.yielding import YieldTracker
from crossing_env.types import PedState
from tests.crossing_env.safety.snapshots import Ped, _ego_through, make_gt, metrics


def test_yield_compliant_after_pedestrian_clears() -> None:
    m = metrics()
    # ego at 50 (front 52.25), 10 m/s: 62.75 m to the stop line > 10²/(2·3) = 16.7 m -> obligation opens
    _ego_through(m, 0.1, 50.0, [Ped(1, (120.0, -0.5), state=PedState.WAITING)])
    # stepping off: state CROSSING while the centre is still over the sidewalk must not drop the obligation
    _ego_through(m, 1.0, 60.0, [Ped(1, (120.0, -0.2), (0, 1.3), state=PedState.CROSSING)])
    _ego_through(m, 2.0, 70.0, [Ped(1, (120.0, 1.0), (0, 1.3))])  # in the ego's half
    _ego_through(m, 4.0, 90.0, [Ped(1, (120.0, 4.0), (0, 1.3))])  # cleared it (y > 3.5)
    _ego_through(m, 5.0, 118.0, [Ped(1, (120.0, 5.5), (0, 1.3))])  # ego in the conflict area: fine
    r = m.result()
    assert (r.yield_obligations, r.yield_compliant, r.yield_violations) == (1, 1, 0)
    assert r.yield_compliance == 1.0


def test_yield_violation_when_entering_before_clearance() -> None:
    m = metrics()
    _ego_through(m, 0.1, 50.0, [Ped(1, (120.0, 1.0), (0, 1.3))])  # on the crossing in the ego's half
    _ego_through(m, 1.0, 118.0, [Ped(1, (120.0, 2.2), (0, 1.3))])  # ego enters, pedestrian still there
    _ego_through(m, 3.0, 130.0, [Ped(1, (120.0, 4.8), (0, 1.3))])
    r = m.result()
    assert (r.yield_obligations, r.yield_compliant, r.yield_violations) == (1, 0, 1)
    assert r.yield_compliance == 0.0


def test_no_obligation_when_too_close_to_stop() -> None:
    m = metrics()
    # front at 110.25: 4.75 m to the stop line < 16.7 m comfortable stopping distance -> no obligation
    _ego_through(m, 0.1, 108.0, [Ped(1, (120.0, 1.0), (0, 1.3))])
    _ego_through(m, 1.0, 118.0, [Ped(1, (120.0, 2.2), (0, 1.3))])
    assert m.result().yield_obligations == 0


def test_far_half_pedestrian_walking_towards_ego_half() -> None:
    walker = [Ped(1, (120.0, 5.0), (0, -1.3))]  # north half (y > 3.5) walking south, towards the ego's half
    m = metrics()
    _ego_through(m, 0.1, 50.0, walker)
    _ego_through(m, 1.0, 118.0, walker)
    assert m.result().yield_violations == 1
    m = metrics(MetricsConfig(far_half_counts=False))
    _ego_through(m, 0.1, 50.0, walker)
    _ego_through(m, 1.0, 118.0, walker)
    assert m.result().yield_obligations == 0
    # walking away (north) after having crossed the ego's half: no obligation either
    m = metrics()
    _ego_through(m, 0.1, 50.0, [Ped(1, (120.0, 5.0), (0, 1.3))])
    _ego_through(m, 1.0, 118.0, [Ped(1, (120.0, 6.0), (0, 1.3))])
    assert m.result().yield_obligations == 0


def test_yield_declined_offer_and_dropped_waiter() -> None:
    m = metrics()
    waiter = Ped(1, (120.0, -0.5), state=PedState.WAITING)
    # ego stopped with its front 1 m before the stop line (x = 111.75) while the pedestrian waits 3 s
    for k in range(31):
        m.update(make_gt(0.1 * (k + 1), ego_x=111.75, ego_v=0.0, peds=[waiter]))
    m.update(make_gt(3.5, ego_x=118.0, ego_v=3.0, peds=[waiter]))  # then drives through
    r = m.result()
    assert (r.yield_obligations, r.yield_compliant, r.yield_violations, r.yield_offers_declined) == (
        1,
        1,
        0,
        1,
    )
    # a car that crept over the line and stands before the crossing (front at 117 m, crossing from 118 m)
    # is still offering: the offer is declined after 3 s, not violated
    m = metrics()
    m.update(make_gt(0.1, ego_x=50.0, ego_v=10.0, peds=[waiter]))  # the obligation opens
    for k in range(31):
        m.update(make_gt(0.2 + 0.1 * k, ego_x=114.75, ego_v=0.0, peds=[waiter]))
    m.update(make_gt(3.5, ego_x=118.0, ego_v=3.0, peds=[waiter]))
    r = m.result()
    assert (r.yield_obligations, r.yield_violations, r.yield_offers_declined) == (1, 0, 1)
    # a pedestrian who stops waiting and walks off along the sidewalk is not an obligation
    m = metrics()
    _ego_through(m, 0.1, 50.0, [waiter])
    _ego_through(m, 1.0, 60.0, [Ped(1, (125.0, -0.5), (1.3, 0), state=PedState.LEAVING)])
    _ego_through(m, 2.0, 118.0, [Ped(1, (126.0, -0.5), (1.3, 0), state=PedState.LEAVING)])
    assert m.result().yield_obligations == 0


def test_waiting_far_from_crossing_and_crossing_kinds() -> None:
    m = metrics()
    _ego_through(m, 0.1, 50.0, [Ped(1, (100.0, -0.5), state=PedState.WAITING)])  # 20 m from the zebra
    _ego_through(m, 1.0, 118.0, [Ped(1, (100.0, -0.5), state=PedState.WAITING)])
    assert m.result().yield_obligations == 0
    on_half = [Ped(1, (120.0, 1.0), (0, 1.3))]
    for kind, green, expected in [("none", None, 0), ("signalised", False, 0), ("signalised", True, 1)]:
        m = metrics(kind=kind)
        m.update(make_gt(0.1, ego_x=50.0, peds=on_half, green=green))
        m.update(make_gt(1.0, ego_x=118.0, peds=on_half, green=green))
        assert m.result().yield_violations == expected, kind


def _waiter(intends: bool) -> Ped:
    return Ped(1, (120.0, -0.5), state=PedState.WAITING, intends=intends)


def _drive_through(m, peds_before, peds_after) -> None:  # type: ignore[no-untyped-def]
    m.update(make_gt(0.1, ego_x=50.0, peds=peds_before))
    m.update(make_gt(1.0, ego_x=118.0, peds=peds_after))


def test_compliance_counts_only_pedestrians_who_intend_to_cross() -> None:
    # The same standing pedestrian at the kerb by the zebra, the ego drives through without stopping.
    m = metrics()
    _drive_through(m, [_waiter(True)], [_waiter(True)])
    r = m.result()
    assert (r.yield_obligations, r.yield_violations) == (1, 1)
    m = metrics()
    _drive_through(m, [_waiter(False)], [_waiter(False)])  # a bystander: no duty, no violation
    r = m.result()
    assert (r.yield_obligations, r.yield_violations) == (0, 0)


def _declined_offer(m, waiter: Ped, ego_x: float = 111.75) -> float:
    """The ego stands (front 1 m before the stop line) for 3.1 s while `waiter` waits: declined. Returns t."""
    m.update(make_gt(0.1, ego_x=50.0, ego_v=10.0, peds=[waiter]))  # the obligation opens on the approach
    t = 0.1
    for _ in range(31):
        t = round(t + 0.1, 9)
        m.update(make_gt(t, ego_x=ego_x, ego_v=0.0, peds=[waiter]))
    assert m.result().yield_offers_declined == 1
    return t


def test_a_declined_obligation_reopens_when_the_pedestrian_steps_on_after_all() -> None:
    """Stop briefly, then go: the pedestrian who declined steps onto the zebra as the car pulls away."""
    m = metrics()
    tracker_violations = []
    t = _declined_offer(m, Ped(1, (120.0, -0.5), state=PedState.WAITING))
    # The car starts (front 114.25, 1 m/s: it can stop within 0.17 m, 3.75 m before the crossing) as she
    # steps onto the zebra in its half: she is owed the way again.
    m.update(make_gt(t + 0.1, ego_x=112.0, ego_v=1.0, peds=[Ped(1, (120.0, 0.4), (0, 1.3))]))
    assert m.result().yield_unresolved == 1
    # It drives on into the conflict area while she is in its half: a violation.
    m.update(make_gt(t + 0.2, ego_x=116.5, ego_v=3.0, peds=[Ped(1, (120.0, 0.6), (0, 1.3))]))
    tracker_violations.append(m.result().yield_violations)
    r = m.result()
    assert (r.yield_obligations, r.yield_compliant, r.yield_violations, r.yield_offers_declined) == (
        2,
        1,
        1,
        1,
    )
    assert r.yield_unresolved == 0 and r.yield_compliance == 0.5


def test_a_reopened_obligation_met_counts_as_met() -> None:
    m = metrics()
    t = _declined_offer(m, Ped(1, (120.0, -0.5), state=PedState.WAITING))
    # She steps on; the car waits for her to clear its half, then goes.
    m.update(make_gt(t + 0.1, ego_x=111.75, ego_v=0.0, peds=[Ped(1, (120.0, 0.4), (0, 1.3))]))
    m.update(make_gt(t + 3.0, ego_x=111.75, ego_v=0.0, peds=[Ped(1, (120.0, 4.2), (0, 1.3))]))
    m.update(make_gt(t + 4.0, ego_x=118.0, ego_v=5.0, peds=[Ped(1, (120.0, 5.5), (0, 1.3))]))
    r = m.result()
    assert (r.yield_obligations, r.yield_compliant, r.yield_violations, r.yield_offers_declined) == (
        2,
        2,
        0,
        1,
    )


def test_a_waived_obligation_reopens_and_counts_once() -> None:
    """She walked off along the sidewalk (waived, not counted), came back and stepped onto the zebra."""
    m = metrics()
    _ego_through(m, 0.1, 50.0, [Ped(1, (120.0, -0.5), state=PedState.WAITING)])  # opens
    _ego_through(m, 0.5, 54.0, [Ped(1, (123.0, -1.0), (1.3, 0), state=PedState.LEAVING)])  # waived
    assert m.result().yield_obligations == 0
    _ego_through(m, 1.0, 60.0, [Ped(1, (120.0, 0.5), (0, 1.3))])  # back, and onto the zebra
    _ego_through(m, 1.5, 118.0, [Ped(1, (120.0, 1.2), (0, 1.3))])  # the car drives into her path
    r = m.result()
    assert (r.yield_obligations, r.yield_compliant, r.yield_violations) == (1, 0, 1)


def test_no_reopening_when_the_car_can_no_longer_stop_before_the_crossing() -> None:
    m = metrics()
    t = _declined_offer(m, Ped(1, (120.0, -0.5), state=PedState.WAITING))
    # Front at 117.25 at 6 m/s: 0.75 m to the crossing, 6 m needed to stop: too late to be owed anything.
    m.update(make_gt(t + 1.0, ego_x=115.0, ego_v=6.0, peds=[Ped(1, (120.0, 0.4), (0, 1.3))]))
    r = m.result()
    assert (r.yield_obligations, r.yield_violations, r.yield_unresolved) == (1, 0, 0)


def test_the_reward_counts_the_reopened_violation_as_the_metric_does() -> None:
    """`YieldTracker.update` is the reward's failing_to_yield and the metric's count: one piece of code."""
    tracker = YieldTracker("zebra", 0.1)
    per_step = []
    waiter = Ped(1, (120.0, -0.5), state=PedState.WAITING)
    per_step.append(tracker.update(make_gt(0.1, ego_x=50.0, ego_v=10.0, peds=[waiter])))
    for k in range(31):
        per_step.append(tracker.update(make_gt(0.2 + 0.1 * k, ego_x=111.75, ego_v=0.0, peds=[waiter])))
    per_step.append(
        tracker.update(make_gt(3.4, ego_x=112.0, ego_v=1.0, peds=[Ped(1, (120.0, 0.4), (0, 1.3))]))
    )
    per_step.append(
        tracker.update(make_gt(3.5, ego_x=116.5, ego_v=3.0, peds=[Ped(1, (120.0, 0.6), (0, 1.3))]))
    )
    assert per_step[-1] == 1 and sum(per_step) == 1
    assert tracker.counts() == (1, 1, 1, 0)
