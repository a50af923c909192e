"""Vehicles: the ego (slot 0, driven by the action) and background cars following their lanes with IDM.

Background drivers brake for anything in their lane ahead (cars, pedestrians on the carriageway), stop
at red, and, if they are "yielders", give way at the zebra to pedestrians on it in their half or waiting at
the kerb, with offers that time out (`crossing_env.driver_offers`). The compiled passes are in
`crossing_env.traffic_kernels`.
"""

from __future__ import annotations

import numpy as np

from crossing_env.driver_offers import give_way_lines
from crossing_env.road import RoadGeometry
from crossing_env.traffic_kernels import (
    _advance,
    _background_accelerations,
    _boxes,
    _despawn,
    _moving,
    idm_parameters,
)
from crossing_env.types import FloatArray
from scenarios.config import ScenarioConfig, VehicleSpawn

ENTRY_CLEARANCE = 20.0
"""A new car enters only if the nearest car in its lane is farther than this from the entry (m)."""


class Traffic:
    """Pool of vehicles; slot 0 is the ego."""

    def __init__(self, scenario: ScenarioConfig, geometry: RoadGeometry, rng: np.random.Generator) -> None:
        self.scenario = scenario
        self.config = scenario.traffic
        self.geometry = geometry
        self.rng = rng
        n = self.config.max_vehicles + 1
        self.capacity = n
        self.active = np.zeros(n, dtype=bool)
        self.ids = np.full(n, -1, dtype=np.int64)
        self.lane = np.zeros(n, dtype=np.int64)
        self.x = np.zeros(n)
        self.speed = np.zeros(n)
        self.acceleration = np.zeros(n)
        self.desired_speed = np.full(n, scenario.road.speed_limit)
        self.yields = np.zeros(n, dtype=bool)
        self.parked = np.zeros(n, dtype=bool)
        self.offer_time = np.zeros(n)
        """(n,) seconds each yielding driver has stood at its line offering the way to waiting pedestrians."""
        self.declined_at = np.full(n, -np.inf)
        """(n,) when each driver's last offer was declined (s): it offers again only to later arrivals."""
        self.length = np.full(n, self.config.length)
        self.width = np.full(n, self.config.width)
        self.y = np.zeros(n)
        """(n,) centre y per slot (vehicles do not change lanes)."""
        self.direction = np.ones(n)
        """(n,) travel direction per slot (+1 towards +x)."""
        road, has_crossing = geometry.road, geometry.has_crossing
        self._road_constants = (
            float(road.lane_width),
            int(road.num_lanes),
            float(geometry.stop_line_x(1.0)) if has_crossing else 0.0,
            float(geometry.stop_line_x(-1.0)) if has_crossing else 0.0,
            idm_parameters(self.config.idm),
        )
        """What the leader-search kernel needs of the road, stop lines and IDM (fixed for an episode)."""
        self.next_id = 1
        ego = scenario.ego
        self.active[0] = True
        self.ids[0] = 0
        self.lane[0] = ego.lane
        self.x[0] = ego.x
        self.speed[0] = ego.speed
        self._place_laterally(0)
        for spawn in self.config.spawns:
            self.spawn(spawn)

    # ------------------------------------------------------------------ geometry helpers
    def _place_laterally(self, i: int) -> None:
        """Centre y and direction of slot i from its highway-env lane (parked: the parking strip's middle).

        Done once per spawn: vehicles keep their lanes, so the hot path only reads the cached `y` and
        `direction` arrays.
        """
        self.direction[i] = self.geometry.lane_direction[self.lane[i]]
        if self.parked[i]:
            strip = self.geometry.parking_strip
            self.y[i] = (strip.y_min + strip.y_max) / 2
        else:
            self.y[i] = self.geometry.lane_y[self.lane[i]]

    def boxes(self, mask: np.ndarray | None = None) -> FloatArray:
        """(k, 4) axis-aligned boxes [x_min, y_min, x_max, y_max] of the selected (default: active) slots."""
        return _boxes(self.x, self.y, self.length, self.width, self.active if mask is None else mask)

    def moving(self) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, np.ndarray]:
        """(x, direction, speed, half length, lane) of the active, not parked slots, in slot order."""
        return _moving(self.x, self.direction, self.speed, self.length, self.lane, self.active, self.parked)

    # ------------------------------------------------------------------ spawning
    def spawn(self, spawn: VehicleSpawn) -> int | None:
        """Place a background vehicle; returns its slot or None if the pool is full."""
        free = np.flatnonzero(~self.active[1:]) + 1
        if free.size == 0:
            return None
        i = int(free[0])
        self.active[i] = True
        self.ids[i] = self.next_id
        self.next_id += 1
        self.lane[i] = spawn.lane
        self.x[i] = spawn.x
        self.parked[i] = spawn.parked
        self._place_laterally(i)
        self.speed[i] = 0.0 if spawn.parked else spawn.speed
        self.acceleration[i] = 0.0
        self.offer_time[i] = 0.0
        self.declined_at[i] = -np.inf
        limit = self.scenario.road.speed_limit
        desired = spawn.desired_speed
        if desired is None:
            desired = max(0.5 * limit, limit + self.rng.normal(0.0, self.config.desired_speed_std))
        self.desired_speed[i] = desired
        self.yields[i] = (
            spawn.yields if spawn.yields is not None else self.rng.random() < self.config.yield_probability
        )
        return i

    def _arrivals(self, dt: float) -> None:
        rate = self.config.flow_per_lane / 3600.0 * dt
        if rate <= 0:
            return
        arrivals = self.rng.random(self.geometry.road.num_lanes) < rate
        for lane in arrivals.nonzero()[0]:
            direction = self.geometry.lane_direction[lane]
            entry = 0.0 if direction > 0 else self.geometry.road.length
            in_lane = self.active & (self.lane == lane) & ~self.parked
            if np.any(np.abs(self.x[in_lane] - entry) < ENTRY_CLEARANCE):
                continue
            speed = self.scenario.road.speed_limit * 0.9
            self.spawn(VehicleSpawn(lane=int(lane), x=float(entry), speed=speed))

    # ------------------------------------------------------------------ dynamics
    def give_way(
        self,
        time: float,
        dt: float,
        ped_positions: FloatArray,
        ped_velocities: FloatArray,
        ped_radius: FloatArray,
        on_crossing: np.ndarray,
        waiting_here: np.ndarray,
        wait_start: FloatArray,
    ) -> np.ndarray:
        """(n,) per slot: the (yielding) driver gives way at its stop line this step; offer timers advance.

        See `crossing_env.driver_offers`. All False where there is no zebra.
        """
        if self.scenario.crossing.kind != "zebra":
            return np.zeros(self.capacity, dtype=bool)
        road = self.geometry.road
        return give_way_lines(
            self.x,
            self.direction,
            self.speed,
            self.length,
            self.active,
            self.parked,
            self.yields,
            self.offer_time,
            self.declined_at,
            ped_positions,
            ped_velocities,
            ped_radius,
            on_crossing,
            waiting_here,
            wait_start,
            self._road_constants[2],
            self._road_constants[3],
            float(road.num_forward_lanes * road.lane_width),
            float(road.road_width),
            float(time),
            float(dt),
            float(self.config.offer_timeout),
        )

    def background_accelerations(
        self,
        ped_positions: FloatArray,
        ped_on_road: np.ndarray,
        pedestrians_at_zebra: bool | np.ndarray,
        cars_must_stop: bool,
        ped_velocities: FloatArray | None = None,
        ped_state: np.ndarray | None = None,
        ped_target_y: FloatArray | None = None,
        ped_radius: FloatArray | None = None,
    ) -> FloatArray:
        """IDM accelerations of all slots (the ego's entry is ignored by the caller).

        Args:
            ped_positions: (P, 2) pedestrian positions.
            ped_on_road: (P,) those on the carriageway (obstacles in their lane).
            pedestrians_at_zebra: per slot, the driver gives way at its line (`give_way`); a plain bool
                makes every yielding driver give way (someone waits at the kerb of the crossing or is on it).
            cars_must_stop: the signal shows red to cars.
            ped_velocities: (P, 2) velocities (default: standing).
            ped_state: (P,) `PedState` codes: crossing pedestrians still on the kerb count as in the road.
            ped_target_y: (P,) y each pedestrian walks towards (default: where it stands): a driver
                brakes for one whose path will cross its lane before it has passed.
            ped_radius: (P,) body radii (default 0.25 m).
        """
        p = ped_positions.shape[0]
        if ped_velocities is None:
            ped_velocities = np.zeros((p, 2))
        if ped_state is None:
            ped_state = np.zeros(p, dtype=np.int64)
        if ped_target_y is None:
            ped_target_y = np.ascontiguousarray(ped_positions[:, 1])
        if ped_radius is None:
            ped_radius = np.full(p, 0.25)
        # Stop line: red signal for everyone, pedestrians at the zebra for yielders.
        if isinstance(pedestrians_at_zebra, np.ndarray):
            line_for = pedestrians_at_zebra & self.yields
        else:
            line_for = self.yields & (self.scenario.crossing.kind == "zebra" and bool(pedestrians_at_zebra))
        if not self.geometry.has_crossing:
            line_for = np.zeros_like(line_for)
        return _background_accelerations(
            self.x,
            self.direction,
            self.lane,
            self.speed,
            self.length,
            self.desired_speed,
            self.active,
            self.parked,
            np.ascontiguousarray(line_for),
            ped_positions,
            ped_velocities,
            ped_on_road,
            ped_state,
            ped_target_y,
            ped_radius,
            bool(self.geometry.has_crossing and cars_must_stop),
            *self._road_constants,
        )

    def advance(
        self, acceleration: FloatArray, dt: float, ego_max_speed: float
    ) -> tuple[FloatArray, FloatArray]:
        """Integrate speeds and positions (trapezoidal, no reversing).

        Returns the (n, 2) positions at the start of the step and the (n, 2) mean velocities over it (what
        carries the kinematic bodies to the new positions in the physics step).
        """
        start, velocity, self.x, self.speed, self.acceleration = _advance(
            self.x,
            self.y,
            self.speed,
            self.direction,
            self.active,
            self.parked,
            acceleration,
            dt,
            ego_max_speed,
        )
        return start, velocity

    def despawn_finished(self) -> None:
        """Remove background cars that have left the road (10 m past either end)."""
        _despawn(self.x, self.active, self.ids, float(self.geometry.road.length))
