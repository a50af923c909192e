"""Tests of crossing_env.safety.stops: unneeded stops are counted in hindsight."""

from __future__ import annotations

from crossing_env.types import PedState
from tests.crossing_env.safety.snapshots import Ped, make_gt, metrics


def _waiter(intends: bool) -> Ped:
    return Ped(1, (120.0, -0.5), state=PedState.WAITING, intends=intends)


def _stop_then_go(m, ped_during_stop: Ped, ped_after: Ped) -> None:  # type: ignore[no-untyped-def]
    """Ego brakes from 10 m/s to a stop 1 m before the stop line, waits 2 s, then drives through."""
    t = 0.0
    for x, v in [(80.0, 10.0), (100.0, 6.0), (110.0, 2.0), (111.75, 0.0)]:
        t += 0.5
        m.update(make_gt(t, ego_x=x, ego_v=v, peds=[ped_during_stop]))
    for _ in range(20):
        t += 0.1
        m.update(make_gt(t, ego_x=111.75, ego_v=0.0, peds=[ped_during_stop]))
    for x, v in [(113.0, 2.0), (118.0, 4.0), (126.0, 6.0), (140.0, 8.0)]:
        t += 0.5
        m.update(make_gt(t, ego_x=x, ego_v=v, peds=[ped_after]))


def test_stop_for_a_pedestrian_who_does_not_cross_is_unneeded() -> None:
    m = metrics()
    _stop_then_go(m, _waiter(False), _waiter(False))
    r = m.result()
    assert (r.stops, r.unneeded_stops) == (1, 1)


def test_stop_for_a_pedestrian_who_crosses_is_needed() -> None:
    m = metrics()
    crossing = Ped(1, (120.0, 1.0), (0.0, 1.3), state=PedState.CROSSING)
    # the pedestrian steps onto the road while the ego waits, then the ego goes
    t = 0.0
    for x, v in [(80.0, 10.0), (100.0, 6.0), (110.0, 2.0), (111.75, 0.0)]:
        t += 0.5
        m.update(make_gt(t, ego_x=x, ego_v=v, peds=[_waiter(True)]))
    t += 0.5
    m.update(make_gt(t, ego_x=111.75, ego_v=0.0, peds=[crossing]))
    t += 3.0
    m.update(make_gt(t, ego_x=126.0, ego_v=6.0, peds=[Ped(1, (120.0, 8.0), (0.0, 1.3))]))
    r = m.result()
    assert (r.stops, r.unneeded_stops) == (1, 0)


def test_stop_with_nobody_at_the_kerb_is_not_counted() -> None:
    m = metrics()
    far = Ped(1, (60.0, -1.5), (1.3, 0.0), state=PedState.LEAVING, intends=False)  # 60 m from the zebra
    _stop_then_go(m, far, far)
    r = m.result()
    assert (r.stops, r.unneeded_stops) == (0, 0)
