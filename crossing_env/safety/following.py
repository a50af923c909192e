"""Ego–vehicle measures of one snapshot: box–box separation, car-following TTC and DRAC.

Used by `EpisodeMetrics`. Vehicles are axis-aligned boxes (heading ±x). The following measures are SUMO's
(SSM device): TTC = gap / closing speed and DRAC = 0.5 · closing speed² / gap, scored only against
vehicles ahead of the ego whose footprint overlaps its own laterally (its lane), and only while the ego
closes in on them; vehicles behind and oncoming traffic are not scored.
"""

from __future__ import annotations

import numpy as np

from crossing_env.types import GroundTruth

__all__ = ["vehicle_measures"]


def vehicle_measures(
    gt: GroundTruth, ego_vx: float, half: np.ndarray
) -> tuple[float, tuple[float, float] | None]:
    """(minimum ego–vehicle separation, (minimum following TTC, maximum following DRAC) or None).

    Args:
        gt: A snapshot with at least one background vehicle.
        ego_vx: The ego's velocity along x, m/s.
        half: (2,) the ego's half length and half width, metres.

    Returns:
        The minimum edge-to-edge distance to any vehicle (m, negative when overlapping), and the following
        TTC (s) and DRAC (m/s²) against the vehicles ahead in the ego's lane that it closes in on (None
        when there are none).
    """
    q = gt.vehicle_positions - gt.ego_position
    reach = half + 0.5 * gt.vehicle_sizes  # half extents of the Minkowski sum of both boxes
    d = np.abs(q) - reach
    dx, dy = d[:, 0], d[:, 1]
    sep = np.hypot(np.maximum(dx, 0.0), np.maximum(dy, 0.0)) + np.minimum(np.maximum(dx, dy), 0.0)
    min_sep = float(sep.min())
    ahead = (q[:, 0] > 0.0) & (dy < 0.0)  # in front and overlapping laterally: same lane
    if not np.count_nonzero(ahead):
        return min_sep, None
    gap = dx[ahead]  # bumper-to-bumper distance (q_x > 0)
    closing = ego_vx - gt.vehicle_velocities[ahead, 0]
    fast = closing > 0.0
    if not np.count_nonzero(fast):
        return min_sep, None
    gap, closing = gap[fast], closing[fast]
    with np.errstate(divide="ignore"):
        ttc = float((np.maximum(gap, 0.0) / closing).min())
        drac = float((0.5 * closing * closing / np.maximum(gap, 0.0)).max())
    return min_sep, (ttc, drac)
