"""The crossing world: road, vehicles, pedestrians and physics advanced together, one step at a time.

`World` is a plain class that takes a scenario and an explicit RNG, so it runs and is tested without
Gymnasium. The env turns its state into observations and rewards; metrics and recorders read
`World.ground_truth()`.
"""

from __future__ import annotations

import numpy as np

from crossing_env.config import EnvConfig, ScenarioConfig
from crossing_env.decisions import CrossingDecisionModel, GapAcceptance
from crossing_env.pedestrians import WAITING, CarSnapshot, PedestrianPopulation
from crossing_env.physics import PhysicsWorld
from crossing_env.road import RoadGeometry
from crossing_env.traffic import Traffic
from crossing_env.types import CollisionEvent, GroundTruth


def make_decision_model(scenario: ScenarioConfig) -> CrossingDecisionModel:
    """The decision model a scenario asks for."""
    if scenario.pedestrians.behaviour.decision_model == "qlb":
        from crossing_env.behaviour import QuantumGapAcceptance

        return QuantumGapAcceptance()
    return GapAcceptance()


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
        self.traffic = Traffic(scenario, self.geometry, rng)
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
        self._sized_radius = np.full(self.pedestrians.capacity, 0.3)
        self.collisions: list[CollisionEvent] = []
        """Ego collisions that began during the last step."""
        self.background_collisions: list[CollisionEvent] = []
        """Background car–pedestrian contacts that began during the last step (other_id: the pedestrian)."""
        self.background_contacts = 0
        self._ego_vehicle_contact = np.zeros(self.traffic.capacity, dtype=bool)
        self.conflict_area = self.geometry.conflict_area(scenario.ego.lane)
        self._refresh_masks()

    def _refresh_masks(self) -> None:
        """Per-pedestrian geometric masks, computed once per step for traffic, observation and truth."""
        peds = self.pedestrians
        self.ped_on_road = peds.on_road()
        """(n,) active and on the carriageway."""
        self.ped_on_crossing = peds.on_crossing()
        """(n,) active and inside the zebra area."""
        self.ped_legal = peds.legal(self.ped_on_road, self.ped_on_crossing)
        """(n,) not on the road, or crossing legally."""

    # ------------------------------------------------------------------ stepping
    def _car_snapshot(self) -> CarSnapshot:
        tr = self.traffic
        moving = tr.active & ~tr.parked
        return CarSnapshot(
            x=tr.x[moving],
            lane=tr.lane[moving],
            direction=tr.direction[moving],
            speed=tr.speed[moving],
            half_length=tr.length[moving] / 2,
            boxes=tr.boxes(),
        )

    def step(self, ego_acceleration: float) -> None:
        """Advance the world by `dt` with the given ego acceleration (m/s²)."""
        dt = self.dt
        self.time += dt
        green = self.geometry.pedestrian_green(self.time)
        peds, tr = self.pedestrians, self.traffic
        peds.step(self.time, self._car_snapshot(), green)
        # Background drivers: obstacles are pedestrians on the road, at the kerb, or on the zebra
        # (positions have not moved since the masks were refreshed at the end of the last step).
        act = peds.active
        near_zebra = np.abs(peds.crossing_x - self.scenario.crossing.position) < self.scenario.crossing.width
        waiting = (peds.state == WAITING) & near_zebra & act & ~peds.jaywalker
        acc = tr.background_accelerations(
            peds.position[self.ped_on_road & act],
            peds.position[waiting],
            peds.position[self.ped_on_crossing & act],
            green is True,
        )
        acc[0] = ego_acceleration
        start_positions = tr.positions()
        tr.advance(acc, dt, self.scenario.ego.max_speed)
        # Kinematic bodies move by velocity: use the mean velocity of the step so pymunk ends where we do.
        vel = (tr.positions() - start_positions) / dt
        self._resize_new_pedestrians()
        pos, pvel, contacts = self.physics.step(
            start_positions,
            vel,
            tr.active,
            peds.position,
            peds.velocity,
            act,
            dt,
            self.config.max_substep_displacement,
        )
        peds.position = np.where(act[:, None], pos, peds.position)
        peds.velocity = np.where(act[:, None], pvel, peds.velocity)
        self._refresh_masks()
        self._record_contacts(contacts)
        self._check_ego_vehicle_overlap()
        peds.record_history()
        tr.despawn_finished()
        tr._arrivals(dt)

    def _resize_new_pedestrians(self) -> None:
        peds = self.pedestrians
        changed = np.flatnonzero(peds.active & (np.abs(self._sized_radius - peds.radius) > 1e-9))
        for i in changed:
            self.physics.set_pedestrian_radius(int(i), float(peds.radius[i]))
            self._sized_radius[i] = peds.radius[i]

    def _record_contacts(self, contacts: list) -> None:
        self.collisions = []
        self.background_collisions = []
        legal = self.ped_legal
        for c in contacts:
            if c.vehicle_slot != 0:
                self.background_contacts += 1
                self.background_collisions.append(
                    CollisionEvent(
                        time=round(self.time, 9),
                        kind="background",
                        other_id=int(self.pedestrians.ids[c.pedestrian_slot]),
                        position=c.point,
                        relative_speed=c.relative_speed,
                        compliant=bool(legal[c.pedestrian_slot]),
                    )
                )
                continue
            self.collisions.append(
                CollisionEvent(
                    time=round(self.time, 9),
                    kind="pedestrian",
                    other_id=int(self.pedestrians.ids[c.pedestrian_slot]),
                    position=c.point,
                    relative_speed=c.relative_speed,
                    compliant=bool(legal[c.pedestrian_slot]),
                )
            )

    def _check_ego_vehicle_overlap(self) -> None:
        """Kinematic bodies never collide in pymunk, so ego–car contact is an overlap test along the lane.

        Vehicles keep their lanes and parked cars stand off the carriageway, so only cars in the ego's lane
        can touch it, and for those the boxes overlap exactly when their x-intervals do.
        """
        tr = self.traffic
        overlap = tr.active & (tr.lane == tr.lane[0]) & ~tr.parked
        overlap &= np.abs(tr.x - tr.x[0]) < (tr.length + tr.length[0]) / 2
        overlap[0] = False
        new = overlap & ~self._ego_vehicle_contact
        self._ego_vehicle_contact = overlap
        if not new.any():
            return
        for i in np.flatnonzero(new):
            rel = abs(tr.speed[0] - tr.speed[i] * tr.direction[i])
            self.collisions.append(
                CollisionEvent(
                    time=round(self.time, 9),
                    kind="vehicle",
                    other_id=int(tr.ids[i]),
                    position=(float((tr.x[0] + tr.x[i]) / 2), float(tr.y[0])),
                    relative_speed=float(rel),
                    compliant=True,
                )
            )

    # ------------------------------------------------------------------ views
    @property
    def ego_position(self) -> np.ndarray:
        """(2,) ego centre."""
        return np.array([self.traffic.x[0], self.traffic.y[0]])

    def ground_truth(self) -> GroundTruth:
        """A copy of the true state for metrics and recorders."""
        tr, peds = self.traffic, self.pedestrians
        bg = np.flatnonzero(tr.active)
        bg = bg[bg != 0]
        act = np.flatnonzero(peds.active)
        return GroundTruth(
            time=round(self.time, 9),
            ego_position=self.ego_position,
            ego_velocity=np.array([tr.speed[0] * tr.direction[0], 0.0]),
            ego_acceleration=float(tr.acceleration[0]),
            ego_size=(float(tr.length[0]), float(tr.width[0])),
            vehicle_ids=tr.ids[bg].copy(),
            vehicle_positions=tr.positions()[bg],
            vehicle_velocities=tr.velocities()[bg],
            vehicle_sizes=np.column_stack((tr.length[bg], tr.width[bg])),
            pedestrian_ids=peds.ids[act].copy(),
            pedestrian_positions=peds.position[act].copy(),
            pedestrian_velocities=peds.velocity[act].copy(),
            pedestrian_radii=peds.radius[act].copy(),
            pedestrian_states=peds.state[act].copy(),
            intends_to_cross=peds.intends[act].copy(),
            on_crossing=self.ped_on_crossing[act],
            on_road=self.ped_on_road[act],
            waiting=(peds.state[act] == WAITING),
            legal=self.ped_legal[act],
            conflict_area=self.conflict_area,
            signal_pedestrian_green=self.geometry.pedestrian_green(self.time),
            collisions=tuple(self.collisions),
            events=tuple(peds.events),
            extras={
                "phase": peds.phase[act].copy(),
                "distracted": peds.distracted[act].copy(),
                "jaywalker": peds.jaywalker[act].copy(),
                "desired_speed": peds.base_speed[act].copy(),
                "background_collisions": tuple(self.background_collisions),
            },
        )
