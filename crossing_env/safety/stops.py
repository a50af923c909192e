"""Unneeded stops: the ego slowed (almost) to a stop near a crossing for pedestrians who then did not cross.

A stop begins when the ego's speed falls below `MetricsConfig.unneeded_stop_speed` while its front is
before the crossing's far edge and at most `offer_distance` before the stop line. The pedestrians who could
have been its reason are those off the road, on a sidewalk within `stop_attribution_lateral` of a kerb and
within `stop_attribution_distance` of the crossing along the road. The stop is *unneeded* when there was at
least one such pedestrian, nobody was on the carriageway ahead of the ego's rear when it began (then
stopping is needed whatever the kerb does), and none of those pedestrians stepped onto the carriageway
before the ego's rear cleared the crossing (or the episode ended). Hindsight, by design: it measures what a
perfect prediction could have saved, so it also counts stops for pedestrians who intend to cross but let
the car go first. Stops with nobody at the kerb (queues, red lights) are never counted.
"""

from __future__ import annotations

import numpy as np

from crossing_env.safety.results import MetricsConfig
from crossing_env.types import GroundTruth

__all__ = ["UnneededStops"]


class UnneededStops:
    """Per-episode counter of stops and unneeded stops, fed with `GroundTruth` snapshots."""

    def __init__(self, config: MetricsConfig, road_width: float) -> None:
        self.config = config
        self.road_width = float(road_width)
        """Kerb-to-kerb width (m): the south kerb is at y = 0, the north one at y = road_width."""
        self.stops = 0
        """Stops near the crossing with at least one pedestrian at the kerb as a possible reason."""
        self.unneeded = 0
        """Of those, stops after which none of those pedestrians stepped onto the road in front of the ego."""
        self._moving = True
        self._pending: list[set[int]] = []  # candidate ids of each unresolved stop
        self._crossed_ids: set[int] = set()

    def update(self, gt: GroundTruth, speed: float, front: float, rear: float) -> None:
        """Add one snapshot (after the ego state of this step is known)."""
        cfg = self.config
        ca = gt.conflict_area
        if gt.pedestrian_ids.shape[0]:
            on_road = gt.on_road & (gt.pedestrian_positions[:, 0] > rear)
            if self._pending and on_road.any():
                self._crossed_ids.update(int(i) for i in gt.pedestrian_ids[on_road])
        else:
            on_road = np.zeros(0, dtype=bool)
        if self._pending:
            still = []
            for ids in self._pending:
                if ids & self._crossed_ids:
                    continue  # someone it stopped for stepped out: a needed stop
                if rear >= ca.x_max:
                    self.unneeded += 1  # the ego cleared the crossing and nobody it stopped for crossed
                    continue
                still.append(ids)
            self._pending = still
        moving = speed >= cfg.unneeded_stop_speed
        begins = self._moving and not moving
        self._moving = moving
        if not begins or front >= ca.x_max or ca.stop_line_x - front > cfg.offer_distance:
            return
        if on_road.any():
            return  # someone is already on the road ahead: stopping is needed
        pos = gt.pedestrian_positions
        cx = 0.5 * (ca.x_min + ca.x_max)
        near_x = np.abs(pos[:, 0] - cx) <= 0.5 * (ca.x_max - ca.x_min) + cfg.stop_attribution_distance
        kerb = self._kerb_distance(gt)
        candidates = near_x & ~gt.on_road & (kerb <= cfg.stop_attribution_lateral)
        if candidates.any():
            self.stops += 1
            self._pending.append({int(i) for i in gt.pedestrian_ids[candidates]})

    def _kerb_distance(self, gt: GroundTruth) -> np.ndarray:
        """Distance (m) of each pedestrian from the nearer kerb (the carriageway spans y in [0, width])."""
        y = gt.pedestrian_positions[:, 1]
        return np.minimum(np.abs(y), np.abs(y - self.road_width))

    def unneeded_so_far(self) -> int:
        """Unneeded stops, counting unresolved stops as unneeded (at the episode's end nobody crossed)."""
        return self.unneeded + sum(1 for ids in self._pending if not ids & self._crossed_ids)
