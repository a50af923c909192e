"""The crossing world: road, vehicles, pedestrians and physics advanced together, one step at a time.

`World` is a plain class that takes a scenario and an explicit RNG, so it runs and is tested without
Gymnasium. The env turns its state into observations and rewards; metrics and recorders read
`World.ground_truth()`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from crossing_env.collision_fault import (
    AT_FAULT_TYPES,
    contact_type,
    front_touches_box,
    front_touches_disc,
    is_behind,
)
from crossing_env.conflict import ConflictScript, draw_plan, occluder_slot
from crossing_env.pedestrians.crossing_decisions import CrossingDecisionModel, make_decision_model
from crossing_env.pedestrians.population import CarSnapshot, PedestrianPopulation
from crossing_env.pedestrians.transitions import WAITING
from crossing_env.physics import PhysicsWorld
from crossing_env.road import RoadGeometry
from crossing_env.traffic import Traffic
from crossing_env.types import CollisionEvent, ConflictTruth, FloatArray, GroundTruth
from scenarios.config import EnvConfig, ScenarioConfig


class World:
    """Road, traffic, pedestrians and the pymunk space of one episode."""

    def __init__(
        self,
        scenario: ScenarioConfig,
        rng: np.random.Generator,
        config: EnvConfig | None = None,
        decision_model: CrossingDecisionModel | None = None,
    ) -> None:
        self.scenario = scenario
        self.config = config or EnvConfig()
        self.rng = rng
        self.dt = float(self.config.dt)
        self.time = 0.0
        self.geometry = RoadGeometry(scenario.road, scenario.crossing)
        # A timed conflict is drawn first (its draws do not depend on anything else in the episode).
        self.conflict: ConflictScript | None = None
        """The scenario's timed conflict (`plan`: what was drawn; `stepped_off_at`), or None."""
        if scenario.conflict is not None:
            self.conflict = ConflictScript(draw_plan(scenario, self.geometry, rng), scenario)
        self.traffic = Traffic(scenario, self.geometry, rng)
        if self.conflict is not None:
            plan = self.conflict.plan
            self.traffic.speed[0] = min(plan.ego_speed, scenario.ego.max_speed)
            slot = occluder_slot(scenario)
            if plan.occluder_x is not None and slot is not None:
                self.traffic.x[slot] = plan.occluder_x
        self.pedestrians = PedestrianPopulation(
            scenario,
            self.geometry,
            decision_model or make_decision_model(scenario),
            rng,
            self.dt,
            history_length=self.config.observation.history_length,
        )
        t = scenario.traffic
        self.physics = PhysicsWorld(self.traffic.capacity, self.pedestrians.capacity, (t.length, t.width))
        self.collisions: list[CollisionEvent] = []
        """Ego collisions that began during the last step."""
        self.background_collisions: list[CollisionEvent] = []
        """Background car–pedestrian contacts that began during the last step (other_id: the pedestrian)."""
        self.background_contacts = 0
        self._ego_vehicle_contact = np.zeros(self.traffic.capacity, dtype=bool)
        self.conflict_area = self.geometry.conflict_area(scenario.ego.lane)
        if self.conflict is not None:
            self.conflict.spawn(self.pedestrians)
        self._refresh_masks()

    def _refresh_masks(self) -> None:
        """Per-pedestrian geometric masks, computed once per step for traffic, observation and truth."""
        self.ped_on_road, self.ped_on_crossing, self.ped_legal = self.pedestrians.masks()
        """(n,) each: active and on the carriageway; active and inside the zebra area; not on the road,
        or crossing legally."""

    # ------------------------------------------------------------------ stepping
    def _car_snapshot(self) -> CarSnapshot:
        x, direction, speed, half_length, lane = self.traffic.moving()
        return CarSnapshot(
            x=x,
            direction=direction,
            speed=speed,
            half_length=half_length,
            boxes=self.traffic.boxes(),
            lane=lane,
        )

    def step(self, ego_acceleration: float) -> None:
        """Advance the world by `dt` with the given ego acceleration (m/s²)."""
        dt = self.dt
        self.time += dt
        green = self.geometry.pedestrian_green(self.time)
        peds, tr = self.pedestrians, self.traffic
        if self.conflict is not None:
            ego = (float(tr.x[0]), float(tr.speed[0]), float(tr.length[0]))
            self.conflict.step(self.time, ego, green is False, peds)
        peds.step(self.time, self._car_snapshot(), green)
        if self.conflict is not None:
            self.conflict.hold_course(peds)
        # Background drivers: obstacles are pedestrians on the road, at the kerb, or on the zebra
        # (positions have not moved since the masks were refreshed at the end of the last step).
        if self.scenario.crossing.kind == "zebra":
            at_zebra = tr.give_way(
                self.time,
                dt,
                peds.position,
                peds.velocity,
                peds.radius,
                self.ped_on_crossing & peds.active,
                peds.waiting_at_zebra(),
                self.time - peds.wait_time,
            )
        else:  # nobody gives way at a signal or an unmarked crossing: no per-step masks to build
            at_zebra = np.zeros(tr.capacity, dtype=bool)
        acc = tr.background_accelerations(
            peds.position,
            self.ped_on_road,
            at_zebra,
            green is True,
            peds.velocity,
            peds.state,
            np.ascontiguousarray(peds.waypoint[:, 1]),
            peds.radius,
        )
        acc[0] = ego_acceleration
        # Kinematic bodies move by velocity: use the mean velocity of the step so pymunk ends where we do.
        start_positions, vel = tr.advance(acc, dt, self.scenario.ego.max_speed)
        act = peds.active
        self._resize_new_pedestrians()
        peds.position, peds.velocity, contacts = self.physics.step(
            start_positions,
            vel,
            tr.active,
            peds.position,
            peds.velocity,
            act,
            dt,
            self.config.max_substep_displacement,
        )
        _keep_on_walkways(
            peds.position, peds.velocity, peds.radius, peds.state, *self.geometry.walkway_bounds
        )
        self._refresh_masks()
        self._record_contacts(contacts)
        self._check_ego_vehicle_overlap()
        peds.record_history()
        tr.despawn_finished()
        tr._arrivals(dt)

    @property
    def intent_decided_at(self) -> np.ndarray:
        """Per pool slot: when its pedestrian's current intent was decided (s); NaN while undecided."""
        return self.pedestrians.intent_time

    def _resize_new_pedestrians(self) -> None:
        peds = self.pedestrians
        for i in _resized(peds.state, self.physics.radius, peds.radius):
            self.physics.set_pedestrian_radius(int(i), float(peds.radius[i]))

    def _record_contacts(self, contacts: list) -> None:
        self.collisions = []
        self.background_collisions = []
        tr = self.traffic
        for c in contacts:
            ego = c.vehicle_slot == 0
            kind, fault = "background", ""
            if ego:
                kind = "pedestrian"
                (ex, ey), (px, py) = c.car_position, c.pedestrian_position
                length, width, heading = float(tr.length[0]), float(tr.width[0]), self._ego_heading()
                radius = float(self.pedestrians.radius[c.pedestrian_slot])
                fault = contact_type(
                    c.car_speed,
                    c.pedestrian_speed,
                    other_static=False,
                    other_behind=is_behind(ex, ey, heading, length, px, py),
                    front_touch=front_touches_disc(ex, ey, heading, length, width, px, py, radius),
                )
            event = CollisionEvent(
                time=round(self.time, 9),
                kind=kind,
                other_id=int(self.pedestrians.ids[c.pedestrian_slot]),
                position=c.point,
                relative_speed=c.relative_speed,
                compliant=bool(self.ped_legal[c.pedestrian_slot]),
                contact_type=fault,
                car_speed=c.car_speed,
                at_fault=fault in AT_FAULT_TYPES,
            )
            (self.collisions if ego else self.background_collisions).append(event)
        self.background_contacts += len(self.background_collisions)

    def _check_ego_vehicle_overlap(self) -> None:
        """Kinematic bodies never collide in pymunk: ego–car contact is `_new_ego_overlaps`.

        Parked vehicles stand off the carriageway, so the ego only ever touches moving road users' vehicles
        (kind 'vehicle'; none is static).
        """
        tr = self.traffic
        new = _new_ego_overlaps(tr.active, tr.lane, tr.parked, tr.x, tr.length, self._ego_vehicle_contact)
        if not new.shape[0]:
            return
        sign, heading, length = float(tr.direction[0]), self._ego_heading(), float(tr.length[0])
        for i in new:
            rel = abs(tr.speed[0] * tr.direction[0] - tr.speed[i] * tr.direction[i])
            fault = contact_type(
                float(abs(tr.speed[0])),
                float(abs(tr.speed[i])),
                other_static=False,
                other_behind=is_behind(
                    float(tr.x[0]), float(tr.y[0]), heading, length, float(tr.x[i]), float(tr.y[i])
                ),
                front_touch=front_touches_box(
                    float(tr.x[0]), length, sign, float(tr.x[i]), float(tr.length[i])
                ),
            )
            self.collisions.append(
                CollisionEvent(
                    time=round(self.time, 9),
                    kind="vehicle",
                    other_id=int(tr.ids[i]),
                    position=(float((tr.x[0] + tr.x[i]) / 2), float(tr.y[0])),
                    relative_speed=float(rel),
                    compliant=True,
                    contact_type=fault,
                    car_speed=float(abs(tr.speed[0])),
                    at_fault=fault in AT_FAULT_TYPES,
                )
            )

    def _ego_heading(self) -> float:
        """The ego's heading (rad): along +x or −x, as its lane runs."""
        return 0.0 if self.traffic.direction[0] > 0 else math.pi

    # ------------------------------------------------------------------ views
    @property
    def ego_position(self) -> np.ndarray:
        """(2,) ego centre."""
        return np.array([self.traffic.x[0], self.traffic.y[0]])

    def ground_truth(self) -> GroundTruth:
        """A copy of the true state for metrics and recorders."""
        tr, peds = self.traffic, self.pedestrians
        bg = tr.active[1:].nonzero()[0] + 1  # background vehicles: every active slot but the ego's
        act = peds.active.nonzero()[0]
        # Fancy indexing copies, so every array below is the snapshot's own.
        bg_positions, bg_velocities, bg_sizes = _vehicle_rows(
            bg, tr.x, tr.y, tr.speed, tr.direction, tr.length, tr.width
        )
        states = peds.state[act]
        extras = {
            "phase": peds.phase[act],
            "distracted": peds.distracted[act],
            "jaywalker": peds.jaywalker[act],
            "desired_speed": peds.base_speed[act],
            "background_collisions": tuple(self.background_collisions),
        }
        conflict = self.conflict
        if conflict is not None and conflict.slot is not None:
            plan = conflict.plan
            extras["conflict"] = ConflictTruth(
                pedestrian_id=int(peds.ids[conflict.slot]),
                dummy=bool(conflict.config.dummy),
                released_at=math.nan if conflict.stepped_off_at is None else conflict.stepped_off_at,
                x=plan.x,
                start_y=plan.start_y,
                speed=plan.pedestrian_speed,
                radius=plan.radius,
                along_speed=abs(plan.along_speed),
            )
        return GroundTruth(
            time=round(self.time, 9),
            ego_position=self.ego_position,
            ego_velocity=np.array([tr.speed[0] * tr.direction[0], 0.0]),
            ego_acceleration=float(tr.acceleration[0]),
            ego_size=(float(tr.length[0]), float(tr.width[0])),
            vehicle_ids=tr.ids[bg],
            vehicle_positions=bg_positions,
            vehicle_velocities=bg_velocities,
            vehicle_sizes=bg_sizes,
            pedestrian_ids=peds.ids[act],
            pedestrian_positions=peds.position[act],
            pedestrian_velocities=peds.velocity[act],
            pedestrian_radii=peds.radius[act],
            pedestrian_states=states,
            intends_to_cross=peds.intends[act],
            intent_decided_at=peds.intent_time[act],
            is_bystander=peds.bystander[act],
            on_crossing=self.ped_on_crossing[act],
            on_road=self.ped_on_road[act],
            waiting=(states == WAITING),
            legal=self.ped_legal[act],
            conflict_area=self.conflict_area,
            signal_pedestrian_green=self.geometry.pedestrian_green(self.time),
            collisions=tuple(self.collisions),
            events=tuple(peds.events),
            extras=extras,
        )


@njit(cache=True, nogil=True)
def _vehicle_rows(
    slots: np.ndarray,
    x: FloatArray,
    y: FloatArray,
    speed: FloatArray,
    direction: FloatArray,
    length: FloatArray,
    width: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(k, 2) positions, velocities (speed · direction along x) and sizes of the vehicles in `slots`."""
    k = slots.shape[0]
    positions = np.empty((k, 2))
    velocities = np.zeros((k, 2))
    sizes = np.empty((k, 2))
    for j in range(k):
        i = slots[j]
        positions[j, 0], positions[j, 1] = x[i], y[i]
        velocities[j, 0] = speed[i] * direction[i]
        sizes[j, 0], sizes[j, 1] = length[i], width[i]
    return positions, velocities, sizes


@njit(cache=True, nogil=True)
def _resized(state: np.ndarray, body_radius: FloatArray, radius: FloatArray) -> np.ndarray:
    """Active pool slots whose body radius differs from the one their physics circle was given."""
    return np.flatnonzero((state != 0) & (np.abs(body_radius - radius) > 1e-9))


@njit(cache=True, nogil=True)
def _keep_on_walkways(
    position: FloatArray,
    velocity: FloatArray,
    radius: FloatArray,
    state: np.ndarray,
    south: float,
    north: float,
) -> None:
    """The building lines: bodies pushed past a walkway's outer edge are put back against it (in place).

    A crowd or a car can push a pedestrian outwards; its outward velocity is removed as well. A static
    pymunk wall would do the same, but with one, runs with the same seed differed in the last bits.
    """
    for i in range(state.shape[0]):
        if state[i] == 0:
            continue
        lo, hi = south + radius[i], north - radius[i]
        if position[i, 1] < lo:
            position[i, 1] = lo
            velocity[i, 1] = max(velocity[i, 1], 0.0)
        elif position[i, 1] > hi:
            position[i, 1] = hi
            velocity[i, 1] = min(velocity[i, 1], 0.0)


@njit(cache=True, nogil=True)
def _new_ego_overlaps(
    active: np.ndarray,
    lane: np.ndarray,
    parked: np.ndarray,
    x: FloatArray,
    length: FloatArray,
    in_contact: np.ndarray,
) -> np.ndarray:
    """Slots whose box started overlapping the ego's (slot 0) this step; `in_contact` is updated in place.

    Vehicles keep their lanes and parked ones stand off the carriageway, so a car can only touch the ego in
    its lane, and there the boxes overlap exactly when the x-intervals do.
    """
    new = np.zeros(x.shape[0], np.bool_)
    for i in range(1, x.shape[0]):
        overlap = (
            active[i]
            and lane[i] == lane[0]
            and not parked[i]
            and abs(x[i] - x[0]) < (length[i] + length[0]) / 2
        )
        new[i] = overlap and not in_contact[i]
        in_contact[i] = overlap
    return np.flatnonzero(new)
