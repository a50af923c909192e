"""Background drivers giving way at a zebra: who they give way to, and offers that time out.

A yielding driver stops at its stop line for a pedestrian on the crossing in its half of the road (or walking
towards it), and offers the way to pedestrians waiting at the zebra. Like the ego's `yielding` policy (and
`MetricsConfig.offer_timeout`), an offer is per pedestrian and times out: a driver who has stood at the line
for `TrafficConfig.offer_timeout` while the only reason was people who keep waiting takes the offer as
declined and drives on; someone who starts waiting after that gets a new offer. So no background driver
waits for ever for someone who does not cross.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from crossing_env.types import FloatArray

OFFER_STOP_SPEED = 0.1
"""Speed (m/s) below which a driver at its line counts as standing, offering the way."""
OFFER_LINE_DISTANCE = 4.0
"""A driver whose front is within this distance (m) of its stop line (IDM stops it about s0 = 2 m short)
counts as standing at the line."""
TOWARDS_SPEED = 0.05
"""Lateral speed (m/s) towards a driver's half above which a pedestrian on the crossing counts as coming."""


@njit(cache=True, nogil=True)
def give_way_lines(
    x: FloatArray,
    direction: FloatArray,
    speed: FloatArray,
    length: FloatArray,
    active: np.ndarray,
    parked: np.ndarray,
    yields: np.ndarray,
    offer_time: FloatArray,
    declined_at: FloatArray,
    ped_position: FloatArray,
    ped_velocity: FloatArray,
    ped_radius: FloatArray,
    on_crossing: np.ndarray,
    waiting_here: np.ndarray,
    wait_start: FloatArray,
    stop_x_forward: float,
    stop_x_backward: float,
    half_boundary: float,
    road_width: float,
    time: float,
    dt: float,
    timeout: float,
) -> np.ndarray:
    """(n,) per vehicle slot: this yielding driver gives way at its stop line now (timers updated in place).

    `waiting_here`: pedestrians waiting to cross at the zebra; `wait_start`: when each began waiting (s);
    `half_boundary`: y between the forward half (below) and the backward half of the road.
    """
    n = x.shape[0]
    out = np.zeros(n, np.bool_)
    for i in range(1, n):
        if not active[i] or parked[i] or not yields[i]:
            offer_time[i] = 0.0
            continue
        d = direction[i]
        lo, hi = (0.0, half_boundary) if d > 0 else (half_boundary, road_width)
        centre = 0.5 * (lo + hi)
        crossing_for = False
        counted = False
        for k in range(ped_position.shape[0]):
            if on_crossing[k]:
                y, r = ped_position[k, 1], ped_radius[k]
                coming = (centre - y) * ped_velocity[k, 1] > TOWARDS_SPEED * abs(centre - y)
                if (y + r > lo and y - r < hi) or coming:
                    crossing_for = True
            elif waiting_here[k] and wait_start[k] > declined_at[i] + 1e-9:
                counted = True
        stop_s = stop_x_forward if d > 0 else -stop_x_backward
        to_line = stop_s - (x[i] * d + length[i] / 2)
        standing = speed[i] < OFFER_STOP_SPEED and -0.5 < to_line < OFFER_LINE_DISTANCE
        if standing and counted and not crossing_for:
            offer_time[i] += dt
            if offer_time[i] >= timeout - 1e-9:  # declined: drive on, new offers only to newcomers
                declined_at[i] = time
                offer_time[i] = 0.0
                counted = False
        elif not standing:
            offer_time[i] = 0.0
        out[i] = crossing_for or counted
    return out
