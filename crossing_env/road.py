"""Road geometry: highway-env lanes plus our own sidewalks, zebra crossing and pedestrian signal.

highway-env provides the lanes (`StraightLane` in a `RoadNetwork`) so that its tools (lane coordinates,
rendering conventions) apply; it has no pedestrian infrastructure, so sidewalks, the crossing and the
signal are plain geometry here. All numbers that the hot path needs are precomputed as floats/arrays.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np
from gymnasium.envs.registration import EnvSpec, registry

from crossing_env.types import ConflictArea
from scenarios.config import CrosswalkConfig, RoadConfig, SignalConfig

HIGHWAY_ENV_MARKER = "highway-v0"
"""The id whose presence makes highway-env's package import skip registering its own envs."""


def _import_lanes() -> None:
    """Import highway-env's lane modules without its env registry.

    Registering highway-env's envs imports their modules, which load matplotlib's pyplot and pandas: about
    1 s of every process that only needs lanes. highway-env skips the registration when
    `HIGHWAY_ENV_MARKER` is already registered, so a placeholder stands there during the import. Call
    `register_highway_envs` to get highway-env's envs in the same process later.
    """
    if "highway_env" in sys.modules or HIGHWAY_ENV_MARKER in registry:
        return
    placeholder = EnvSpec(HIGHWAY_ENV_MARKER, entry_point="highway_env.envs.highway_env:HighwayEnv")
    registry[HIGHWAY_ENV_MARKER] = placeholder
    try:
        import highway_env  # noqa: F401
    finally:
        if registry.get(HIGHWAY_ENV_MARKER) is placeholder:
            del registry[HIGHWAY_ENV_MARKER]


def register_highway_envs() -> None:
    """Register highway-env's own envs (``intersection-v0``...), which `crossing_env` does not load."""
    import highway_env

    highway_env._register_highway_envs()  # idempotent


_import_lanes()

from highway_env.road.lane import LineType, StraightLane  # noqa: E402
from highway_env.road.road import RoadNetwork  # noqa: E402


@dataclass(frozen=True)
class Rect:
    """Axis-aligned rectangle [x_min, x_max] × [y_min, y_max] in metres."""

    x_min: float
    x_max: float
    y_min: float
    y_max: float


class PedestrianSignal:
    """Fixed-time pedestrian signal: green for pedestrians means red for cars."""

    def __init__(self, config: SignalConfig) -> None:
        self.config = config
        self.cycle = config.pedestrian_green + config.pedestrian_red

    def pedestrian_green(self, time: float) -> bool:
        """Whether pedestrians have the walk signal at `time` (seconds)."""
        return ((time + self.config.offset) % self.cycle) < self.config.pedestrian_green

    def time_to_change(self, time: float) -> float:
        """Seconds until the current phase ends."""
        t = (time + self.config.offset) % self.cycle
        green = self.config.pedestrian_green
        return green - t if t < green else self.cycle - t


class RoadGeometry:
    """Lanes, kerbs, sidewalks, the crossing and the optional signal of one straight road."""

    def __init__(self, road: RoadConfig, crossing: CrosswalkConfig) -> None:
        self.road = road
        self.crossing = crossing
        width = road.lane_width
        self.network = RoadNetwork()
        self.lanes: list[StraightLane] = []
        n_fwd = road.num_forward_lanes
        for i in range(road.num_lanes):
            y = (i + 0.5) * width
            forward = i < n_fwd
            start, end = ((0.0, y), (road.length, y)) if forward else ((road.length, y), (0.0, y))
            lower = LineType.CONTINUOUS_LINE if i in (0, n_fwd) else LineType.STRIPED
            upper = LineType.CONTINUOUS_LINE if i in (road.num_lanes - 1, n_fwd - 1) else LineType.NONE
            lane = StraightLane(
                start, end, width=width, line_types=(lower, upper), speed_limit=road.speed_limit
            )
            self.lanes.append(lane)
            self.network.add_lane("west" if forward else "east", "east" if forward else "west", lane)
        #: (L,) lane centre y coordinates and (L,) travel direction (+1 towards +x, −1 towards −x).
        self.lane_y = np.array([lane.start[1] for lane in self.lanes], dtype=np.float64)
        self.lane_direction = np.array([1.0 if i < n_fwd else -1.0 for i in range(road.num_lanes)])
        self.kerb_south = 0.0
        self.kerb_north = float(road.road_width)
        strip = road.parking_strip
        self.parking_strip = Rect(0.0, road.length, -strip, 0.0)
        """The parking strip along the south kerb (empty when the road has none)."""
        self.sidewalk_south = Rect(0.0, road.length, -strip - road.sidewalk_width, -strip)
        self.sidewalk_north = Rect(0.0, road.length, road.road_width, road.road_width + road.sidewalk_width)
        self.walkway_bounds = (self.sidewalk_south.y_min, self.sidewalk_north.y_max)
        """(south, north) outer edges of the walkways (building lines): nobody walks beyond them."""
        half = crossing.width / 2
        self.has_crossing = crossing.kind != "none"
        self.crossing_rect = Rect(crossing.position - half, crossing.position + half, 0.0, road.road_width)
        self.signal = PedestrianSignal(crossing.signal) if crossing.kind == "signalised" else None

    def stop_line_x(self, direction: float) -> float:
        """X of the stop line for traffic moving in `direction` (+1 or −1)."""
        c = self.crossing
        if direction > 0:
            return c.position - c.width / 2 - c.stop_line_offset
        return c.position + c.width / 2 + c.stop_line_offset

    def lane_bounds(self, lane: int) -> tuple[float, float]:
        """(y_min, y_max) of a lane."""
        w = self.road.lane_width
        return lane * w, (lane + 1) * w

    def conflict_area(self, ego_lane: int) -> ConflictArea:
        """The ego lane × crossing rectangle, plus the ego's half of the road."""
        y_min, y_max = self.lane_bounds(ego_lane)
        n_fwd = self.road.num_forward_lanes
        return ConflictArea(
            x_min=self.crossing_rect.x_min,
            x_max=self.crossing_rect.x_max,
            y_min=y_min,
            y_max=y_max,
            stop_line_x=self.stop_line_x(1.0),
            half_y_min=0.0,
            half_y_max=n_fwd * self.road.lane_width,
        )

    def pedestrian_green(self, time: float) -> bool | None:
        """Pedestrian signal state, None without a signal."""
        return None if self.signal is None else self.signal.pedestrian_green(time)
