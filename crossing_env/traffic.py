"""Vehicles: the ego (slot 0, driven by the action) and background cars following their lanes with IDM.

Background drivers brake for anything in their lane ahead (cars, pedestrians on the carriageway), stop
at red, and, if they are "yielders", give way at the zebra to pedestrians on it or waiting at the kerb.
All of that is one vectorised pass per step.
"""

from __future__ import annotations

import numpy as np

from crossing_env.config import ScenarioConfig, VehicleSpawn
from crossing_env.idm import idm_acceleration
from crossing_env.road import RoadGeometry
from crossing_env.types import FloatArray

ENTRY_CLEARANCE = 20.0
"""A new car enters only if the nearest car in its lane is farther than this from the entry (m)."""
PEDESTRIAN_LOOKAHEAD = 40.0
"""Drivers react to pedestrians on the carriageway within this distance ahead (m)."""


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
        self.length = np.full(n, self.config.length)
        self.width = np.full(n, self.config.width)
        self.y = np.zeros(n)
        """(n,) centre y per slot (vehicles do not change lanes)."""
        self.direction = np.ones(n)
        """(n,) travel direction per slot (+1 towards +x)."""
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
        """Centre y and direction of slot i from its highway-env lane (parked: the strip by the south kerb).

        Done once per spawn: vehicles keep their lanes, so the hot path only reads the cached `y` and
        `direction` arrays instead of querying lane objects.
        """
        lane = self.geometry.lanes[self.lane[i]]
        self.direction[i] = float(np.sign(np.cos(lane.heading)))
        if self.parked[i]:
            self.y[i] = self.geometry.kerb_south - self.width[i] / 2 - 0.1
        else:
            # The lane's centre line (exact for our straight lanes; `lane.position` would add ~1e-14 m of
            # rounding from sin(π) on the lanes towards −x).
            self.y[i] = float(lane.start[1])

    def positions(self) -> FloatArray:
        """(n, 2) centres."""
        out = np.empty((self.capacity, 2))
        out[:, 0], out[:, 1] = self.x, self.y
        return out

    def velocities(self) -> FloatArray:
        """(n, 2) velocities."""
        out = np.zeros((self.capacity, 2))
        out[:, 0] = self.speed * self.direction
        return out

    def boxes(self, mask: np.ndarray | None = None) -> FloatArray:
        """(k, 4) axis-aligned boxes [x_min, y_min, x_max, y_max] of the selected (default: active) slots."""
        m = self.active if mask is None else mask
        x, y, hl, hw = self.x[m], self.y[m], self.length[m] / 2, self.width[m] / 2
        out = np.empty((x.size, 4))
        out[:, 0], out[:, 1], out[:, 2], out[:, 3] = x - hl, y - hw, x + hl, y + hw
        return out

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
        for lane in np.flatnonzero(arrivals):
            direction = self.geometry.lane_direction[lane]
            entry = 0.0 if direction > 0 else self.geometry.road.length
            in_lane = self.active & (self.lane == lane) & ~self.parked
            if np.any(np.abs(self.x[in_lane] - entry) < ENTRY_CLEARANCE):
                continue
            speed = self.scenario.road.speed_limit * 0.9
            self.spawn(VehicleSpawn(lane=int(lane), x=float(entry), speed=speed))

    # ------------------------------------------------------------------ dynamics
    def background_accelerations(
        self,
        ped_positions: FloatArray,
        ped_waiting_x: FloatArray,
        ped_on_crossing_x: FloatArray,
        cars_must_stop: bool,
    ) -> FloatArray:
        """IDM accelerations of all slots (the ego's entry is ignored by the caller).

        Args:
            ped_positions: (P, 2) pedestrians on the carriageway (obstacles in their lane).
            ped_waiting_x: (W, 2) positions of pedestrians waiting at the kerb of the crossing.
            ped_on_crossing_x: (Q, 2) positions of pedestrians on the crossing.
            cars_must_stop: the signal shows red to cars.
        """
        n = self.capacity
        act = self.active
        d = self.direction
        s = self.x * d  # position along each car's own travel direction
        half = self.length / 2
        gap = np.full(n, np.inf)
        lead_speed = np.zeros(n)
        # Leader in the same lane (ego included as a leader; parked cars are off the lane).
        moving = act & ~self.parked
        same = (self.lane[:, None] == self.lane[None, :]) & moving[:, None] & moving[None, :]
        ahead = (s[None, :] - s[:, None]) * same
        np.fill_diagonal(ahead, 0.0)
        bumper = ahead - half[:, None] - half[None, :]
        valid = same & (ahead > 0)
        bumper = np.where(valid, bumper, np.inf)
        lead = np.argmin(bumper, axis=1)
        gap = bumper[np.arange(n), lead]
        lead_speed = np.where(np.isfinite(gap), self.speed[lead], 0.0)
        # Pedestrians on the carriageway in the car's lane ahead.
        if ped_positions.shape[0]:
            lane_idx = np.minimum(
                np.maximum((ped_positions[:, 1] / self.geometry.road.lane_width).astype(np.int64), 0),
                self.geometry.road.num_lanes - 1,
            )
            ped_s = ped_positions[None, :, 0] * d[:, None]
            dist = ped_s - s[:, None] - half[:, None] - 0.5
            hit = (
                (lane_idx[None, :] == self.lane[:, None])
                & (dist > -half[:, None])
                & (dist < PEDESTRIAN_LOOKAHEAD)
            )
            ped_gap = np.where(hit, np.maximum(dist, 0.01), np.inf).min(axis=1)
            closer = ped_gap < gap
            gap = np.where(closer, ped_gap, gap)
            lead_speed = np.where(closer, 0.0, lead_speed)
        # Stop line: red signal for everyone, pedestrians at the zebra for yielders.
        yield_now = self.scenario.crossing.kind == "zebra" and (
            ped_waiting_x.shape[0] > 0 or ped_on_crossing_x.shape[0] > 0
        )
        if self.geometry.has_crossing and (cars_must_stop or yield_now):
            stop_s = np.where(d > 0, self.geometry.stop_line_x(1.0), -self.geometry.stop_line_x(-1.0))
            to_line = stop_s - (s + half)
            braking = self.scenario.traffic.idm.max_deceleration * 0.6
            can_stop = (to_line > self.speed**2 / (2 * braking)) | (to_line > -0.5) & (self.speed < 1.0)
            must = np.ones(n, dtype=bool) if cars_must_stop else self.yields
            stop = must & can_stop & (to_line > -1.0)
            line_gap = np.maximum(to_line, 0.01)
            closer = stop & (line_gap < gap)
            gap = np.where(closer, line_gap, gap)
            lead_speed = np.where(closer, 0.0, lead_speed)
        acc = idm_acceleration(self.speed, self.desired_speed, gap, lead_speed, self.config.idm)
        return np.where(act & ~self.parked, acc, 0.0)

    def advance(self, acceleration: FloatArray, dt: float, ego_max_speed: float) -> FloatArray:
        """Integrate speeds and positions (trapezoidal, no reversing); returns the per-slot displacement."""
        speed = np.maximum(0.0, self.speed + acceleration * dt)
        speed[0] = min(speed[0], ego_max_speed)
        speed[self.parked | ~self.active] = 0.0
        # The acceleration actually realised (clipped at standstill), for metrics.
        self.acceleration = (speed - self.speed) / dt
        dx = 0.5 * (self.speed + speed) * dt * self.direction
        self.x = self.x + dx
        self.speed = speed
        return dx

    def despawn_finished(self) -> None:
        """Remove background cars that have left the road."""
        length = self.geometry.road.length
        out = self.active & ((self.x < -10.0) | (self.x > length + 10.0))
        out[0] = False
        self.active[out] = False
        self.ids[out] = -1
