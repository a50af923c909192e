"""Tests of crossing_env.safety.following (ego–vehicle separation, following TTC and DRAC)."""

from __future__ import annotations

import numpy as np
import pytest

from crossing_env.safety.following import vehicle_measures
from tests.crossing_env.safety.snapshots import Veh, make_gt

HALF = np.array([2.25, 0.9])


def test_leader_ahead_in_lane() -> None:
    # ego at x = 30 (front 32.25) at 10 m/s; leader at 50 (rear 47.75) at 4 m/s: gap 15.5 m, closing 6 m/s
    gt = make_gt(0.1, ego_x=30.0, vehicles=[Veh(1, (50.0, 1.75), (4.0, 0.0))])
    sep, following = vehicle_measures(gt, 10.0, HALF)
    assert sep == pytest.approx(15.5)
    assert following == pytest.approx((15.5 / 6.0, 0.5 * 36.0 / 15.5))


def test_vehicles_behind_oncoming_or_slower_are_not_scored() -> None:
    behind = Veh(1, (10.0, 1.75), (20.0, 0.0))
    oncoming = Veh(2, (60.0, 5.25), (-10.0, 0.0))  # other lane: no lateral overlap
    faster = Veh(3, (80.0, 1.75), (15.0, 0.0))  # ahead but pulling away
    gt = make_gt(0.1, ego_x=30.0, vehicles=[behind, oncoming, faster])
    sep, following = vehicle_measures(gt, 10.0, HALF)
    assert following is None
    assert sep == pytest.approx(30.0 - 2.25 - 10.0 - 2.25)  # the one behind is nearest
