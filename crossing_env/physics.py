"""pymunk world: real bodies, real contacts, and contact events between cars and pedestrians.

Cars are kinematic boxes (they push pedestrians and are never pushed: a car outweighs a person about
twenty to one and its motion comes from the driver model); pedestrians are dynamic circles of 70 kg.
All bodies live in fixed pools in a fixed order (vehicles first, then pedestrians), so state moves in and
out of pymunk in one batched array copy per step (`pymunk.batch`). Unused slots are parked far away with
a collision filter that matches nothing.

pymunk has no continuous collision detection, so each step is split into substeps such that no body
moves more than `max_substep_displacement` per substep (a 4.5 m car at 20 m/s still hits a pedestrian).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pymunk
import pymunk.batch
from numba import njit

from crossing_env.types import BoolArray, FloatArray

PEDESTRIAN = 1
CAR = 2
PEDESTRIAN_MASS = 70.0
_ALL = pymunk.ShapeFilter()
_NONE = pymunk.ShapeFilter(categories=0, mask=0)
_PARK_X = -10_000.0
# pymunk's batch buffers allocate C arrays that are never freed, so every world in the process shares
# one pair instead of leaking a pair per episode (steps never run concurrently within a process).
_SET_BUFFER = pymunk.batch.Buffer()  # pointed at each world's numpy state array before a set
_GET_BUFFER = pymunk.batch.Buffer()  # owned by pymunk, which grows it as needed


@dataclass(frozen=True)
class Contact:
    """A car–pedestrian contact that began during a step."""

    vehicle_slot: int
    pedestrian_slot: int
    point: tuple[float, float]
    relative_speed: float
    car_position: tuple[float, float]
    """The car's centre when the contact began (inside the step's substeps)."""
    car_speed: float
    """The car's speed then (m/s)."""
    pedestrian_position: tuple[float, float]
    """The pedestrian's centre then."""
    pedestrian_speed: float
    """The pedestrian's speed then (m/s)."""


def _on_car_pedestrian(arbiter: pymunk.Arbiter, space: pymunk.Space, data: list[Contact]) -> None:
    """Record the first contact of a car–pedestrian pair (module level so spaces stay picklable)."""
    car_shape, ped_shape = arbiter.shapes
    points = arbiter.contact_point_set.points
    point = points[0].point_a if points else car_shape.body.position
    car, ped = car_shape.body, ped_shape.body
    rel = car.velocity - ped.velocity
    data.append(
        Contact(
            car_shape.slot,
            ped_shape.slot,
            (float(point.x), float(point.y)),
            float(rel.length),
            (float(car.position.x), float(car.position.y)),
            float(car.velocity.length),
            (float(ped.position.x), float(ped.position.y)),
            float(ped.velocity.length),
        )
    )


class PhysicsWorld:
    """A pymunk space holding pooled vehicle and pedestrian bodies."""

    def __init__(
        self, vehicle_capacity: int, pedestrian_capacity: int, vehicle_size: tuple[float, float]
    ) -> None:
        self.space = pymunk.Space()
        self.space.iterations = 10
        self.num_vehicles = vehicle_capacity
        self.num_pedestrians = pedestrian_capacity
        self.contacts: list[Contact] = []
        self.vehicle_shapes: list[pymunk.Poly] = []
        self.pedestrian_shapes: list[pymunk.Circle] = []
        length, width = vehicle_size
        self._half_extent = np.tile([length / 2, width / 2], (vehicle_capacity, 1))
        """(V, 2) half length and half width of each vehicle box (for the substep test)."""
        self.radius = np.full(pedestrian_capacity, 0.3)
        """(P,) radius of each pedestrian circle (read-only outside; set with `set_pedestrian_radius`)."""
        for i in range(vehicle_capacity):
            body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
            body.position = (_PARK_X - 20.0 * i, -1000.0)
            shape = pymunk.Poly.create_box(body, (length, width))
            shape.collision_type = CAR
            shape.filter = _NONE
            shape.slot = i
            self.space.add(body, shape)
            self.vehicle_shapes.append(shape)
        for i in range(pedestrian_capacity):
            body = pymunk.Body(PEDESTRIAN_MASS, pymunk.moment_for_circle(PEDESTRIAN_MASS, 0, 0.3))
            body.position = (_PARK_X - 20.0 * i, 1000.0)
            shape = pymunk.Circle(body, 0.3)
            shape.collision_type = PEDESTRIAN
            shape.filter = _NONE
            shape.friction = 0.0
            shape.slot = i
            self.space.add(body, shape)
            self.pedestrian_shapes.append(shape)
        self.space.on_collision(CAR, PEDESTRIAN, begin=_on_car_pedestrian, data=self.contacts)
        self._set_buffer = _SET_BUFFER
        self._get_buffer = _GET_BUFFER
        self._fields = pymunk.batch.BodyFields.POSITION | pymunk.batch.BodyFields.VELOCITY
        self._state = np.zeros((vehicle_capacity + pedestrian_capacity, 4))
        self._vehicle_on = np.zeros(vehicle_capacity, dtype=bool)
        self._pedestrian_on = np.zeros(pedestrian_capacity, dtype=bool)
        self._parking = np.stack(
            [
                _PARK_X - 20.0 * np.arange(vehicle_capacity + pedestrian_capacity),
                np.r_[np.full(vehicle_capacity, -1000.0), np.full(pedestrian_capacity, 1000.0)],
            ],
            axis=1,
        )

    def set_vehicle_geometry(self, slot: int, length: float, width: float) -> None:
        """Resize a vehicle's box (pool bodies are created with the default size)."""
        shape = self.vehicle_shapes[slot]
        hl, hw = length / 2, width / 2
        shape.unsafe_set_vertices([(-hl, -hw), (hl, -hw), (hl, hw), (-hl, hw)])
        self._half_extent[slot] = (hl, hw)

    def set_pedestrian_radius(self, slot: int, radius: float) -> None:
        """Resize a pedestrian's circle."""
        self.pedestrian_shapes[slot].unsafe_set_radius(radius)
        self.radius[slot] = radius

    def _sync_filters(self, vehicles_on: BoolArray, pedestrians_on: BoolArray) -> None:
        """Switch collisions on for slots that became active and off for freed slots (rare)."""
        for shapes, old, new in (
            (self.vehicle_shapes, self._vehicle_on, vehicles_on),
            (self.pedestrian_shapes, self._pedestrian_on, pedestrians_on),
        ):
            for i in _sync_flags(old, new):
                shapes[i].filter = _ALL if new[i] else _NONE

    def step(
        self,
        vehicle_positions: FloatArray,
        vehicle_velocities: FloatArray,
        vehicles_on: BoolArray,
        pedestrian_positions: FloatArray,
        pedestrian_velocities: FloatArray,
        pedestrians_on: BoolArray,
        dt: float,
        max_displacement: float,
    ) -> tuple[FloatArray, FloatArray, list[Contact]]:
        """Move every body for `dt` seconds and return pedestrian positions, velocities and new contacts.

        Vehicle positions are the ones at the start of the step; their velocities carry them through it.
        Returned rows of pedestrians that are not on keep the values passed in.
        """
        self._sync_filters(vehicles_on, pedestrians_on)
        nv = self.num_vehicles
        state = self._state
        substeps = _pack_bodies(
            state,
            self._parking,
            np.ascontiguousarray(vehicle_positions, dtype=np.float64),
            np.ascontiguousarray(vehicle_velocities, dtype=np.float64),
            vehicles_on,
            pedestrian_positions,
            pedestrian_velocities,
            pedestrians_on,
            dt,
            self._half_extent,
            self.radius,
            max_displacement,
        )
        self._set_buffer.set_float_buf(state.reshape(-1))
        pymunk.batch.set_space_bodies(self.space, self._fields, self._set_buffer)
        self.contacts.clear()
        h = dt / substeps
        for _ in range(substeps):
            self.space.step(h)
        buf = self._get_buffer
        buf.clear()
        pymunk.batch.get_space_bodies(self.space, self._fields, buf)
        out = np.frombuffer(buf.float_buf(), dtype=np.float64).reshape(-1, 4)
        pos, vel = _unpack_pedestrians(out, nv, pedestrians_on, pedestrian_positions, pedestrian_velocities)
        return pos, vel, list(self.contacts)


@njit(cache=True, nogil=True)
def _pack_bodies(
    state: FloatArray,
    parking: FloatArray,
    vehicle_positions: FloatArray,
    vehicle_velocities: FloatArray,
    vehicles_on: BoolArray,
    pedestrian_positions: FloatArray,
    pedestrian_velocities: FloatArray,
    pedestrians_on: BoolArray,
    dt: float,
    half_extent: FloatArray,
    radius: FloatArray,
    max_displacement: float,
) -> int:
    """Fill the body state rows (x, y, vx, vy; vehicles first, free slots parked) and count substeps.

    One substep is exact enough unless some car could touch some pedestrian within the step: per axis,
    the centres closer than the car's half extent, the pedestrian's radius, what both bodies travel in
    `dt`, and a 1 m margin. Then the step is split so that the fastest body
    moves at most `max_displacement` per substep (no tunnelling).
    """
    nv = vehicles_on.shape[0]
    fastest = 0.0
    for i in range(state.shape[0]):
        on = vehicles_on[i] if i < nv else pedestrians_on[i - nv]
        if not on:
            state[i, 0], state[i, 1] = parking[i, 0], parking[i, 1]
            state[i, 2] = state[i, 3] = 0.0
            continue
        pos, vel, k = (vehicle_positions, vehicle_velocities, i) if i < nv else (
            pedestrian_positions, pedestrian_velocities, i - nv
        )  # fmt: skip
        state[i, 0], state[i, 1], state[i, 2], state[i, 3] = pos[k, 0], pos[k, 1], vel[k, 0], vel[k, 1]
        fastest = max(fastest, abs(vel[k, 0]), abs(vel[k, 1]))
    for c in range(nv):
        if not vehicles_on[c]:
            continue
        reach_x = half_extent[c, 0] + abs(state[c, 2]) * dt + 1.0
        reach_y = half_extent[c, 1] + abs(state[c, 3]) * dt + 1.0
        for p in range(nv, state.shape[0]):
            k = p - nv
            if (
                pedestrians_on[k]
                and abs(state[c, 0] - state[p, 0]) < reach_x + radius[k] + abs(state[p, 2]) * dt
                and abs(state[c, 1] - state[p, 1]) < reach_y + radius[k] + abs(state[p, 3]) * dt
            ):
                return max(1, math.ceil(fastest * math.sqrt(2.0) * dt / max_displacement))
    return 1


@njit(cache=True, nogil=True)
def _sync_flags(old: BoolArray, new: BoolArray) -> np.ndarray:
    """Slots where `new` differs from `old`; then `old` takes `new`'s values."""
    # Plain loops: `np.flatnonzero(old != new)` and `old[:] = new` compile numba's broadcasting (with its
    # error-message strings), several seconds on a fresh install, for two arrays of the same length.
    changed = np.empty(old.shape[0], np.int64)
    n = 0
    for i in range(old.shape[0]):
        if old[i] != new[i]:
            changed[n] = i
            n += 1
            old[i] = new[i]
    return changed[:n]


@njit(cache=True, nogil=True)
def _unpack_pedestrians(
    out: FloatArray, nv: int, pedestrians_on: BoolArray, positions: FloatArray, velocities: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """New (P, 2) position and velocity arrays: pymunk's rows for pedestrians that are on, else the old."""
    pos, vel = positions.copy(), velocities.copy()
    for k in range(pedestrians_on.shape[0]):
        if pedestrians_on[k]:
            pos[k, 0], pos[k, 1] = out[nv + k, 0], out[nv + k, 1]
            vel[k, 0], vel[k, 1] = out[nv + k, 2], out[nv + k, 3]
    return pos, vel
