"""Pedestrian spawning: scripted and Poisson arrivals, bystanders, and each newcomer's drawn traits.

`PedestrianSpawning` is the spawning half of `crossing_env.pedestrians.population.PedestrianPopulation`
(which inherits it): it fills a free pool slot with a new pedestrian (speed, critical gap, rationality
phase, distraction, hesitation and turn-back draws, crossing point, waypoint and goal) and places the
bystanders at the scenario's waiting places. Draws come from the population's RNG in a fixed order, so
seeded episodes repeat exactly.
"""

from __future__ import annotations

import math

import numpy as np

from crossing_env.pedestrians.transitions import APPROACHING, INACTIVE, LEAVING
from crossing_env.road import RoadGeometry
from crossing_env.types import BehaviourEvent
from scenarios.config import PedestrianConfig, PedestrianSpawn, ScenarioConfig, WaitingPlace

__all__ = ["PedestrianSpawning"]


class PedestrianSpawning:
    """Spawning methods of the pedestrian pool; the pool's arrays and settings are set by the subclass.

    The subclass (`PedestrianPopulation`) owns the per-slot arrays written here (``state``, ``ids``,
    ``position``, ``velocity``, ``radius`` and the trait arrays), the RNG, the clock and the event list.
    """

    scenario: ScenarioConfig
    config: PedestrianConfig
    geometry: RoadGeometry
    rng: np.random.Generator
    dt: float
    time: float
    events: list[BehaviourEvent]

    def _log(self, i: int, kind: str) -> None:
        self.events.append(BehaviourEvent(time=self.time, pedestrian_id=int(self.ids[i]), kind=kind))

    def _draw_speed(self) -> float:
        c = self.config
        v = self.rng.normal(c.desired_speed_mean, c.desired_speed_std)
        return float(np.clip(v, c.desired_speed_min, c.desired_speed_max)) * self._speed_scale

    def _draw_critical_gap(self) -> float:
        b = self.config.behaviour
        mean, sd = b.critical_gap_mean, b.critical_gap_std
        sigma2 = math.log(1.0 + (sd / mean) ** 2)
        value = self.rng.lognormal(math.log(mean) - sigma2 / 2, math.sqrt(sigma2))
        return max(b.critical_gap_floor, float(value))

    def _draw_phase(self) -> float:
        b = self.config.behaviour
        if b.phase_distribution == "classical":
            return math.pi / 2
        if b.phase_distribution == "uniform":
            return float(self.rng.uniform(b.phase_mean - b.phase_std, b.phase_mean + b.phase_std))
        return float(self.rng.normal(b.phase_mean, b.phase_std))

    def spawn(self, spawn: PedestrianSpawn) -> int | None:
        """Place one pedestrian; returns its slot, or None if the pool is full."""
        free = np.flatnonzero(self.state == INACTIVE)
        if free.size == 0:
            return None
        i = int(free[0])
        b = self.config.behaviour
        geo = self.geometry
        side = 1.0 if spawn.side == "south" else -1.0
        start_y = self._walk_y[0] if side > 0 else self._walk_y[1]
        far_y = self._walk_y[1] if side > 0 else self._walk_y[0]
        self.ids[i] = self.next_id
        self.next_id += 1
        self.side[i] = side
        self.position[i] = (spawn.x, start_y)
        self.velocity[i] = 0.0
        self.radius[i] = spawn.radius if spawn.radius is not None else self.config.radius
        # Night slows everyone, explicitly placed pedestrians included (_draw_speed applies it itself).
        speed = (
            spawn.desired_speed * self._speed_scale if spawn.desired_speed is not None else self._draw_speed()
        )
        self.distracted[i] = (
            spawn.distracted if spawn.distracted is not None else self.rng.random() < b.distraction_rate
        )
        if self.distracted[i]:
            speed *= 0.8  # phone users walk about 20% slower
        self.base_speed[i] = speed
        self.desired_speed[i] = speed
        self.critical_gap[i] = (
            spawn.critical_gap if spawn.critical_gap is not None else self._draw_critical_gap()
        )
        if self.distracted[i]:
            self.critical_gap[i] *= 0.7  # a cursory glance: shorter gaps get accepted
        self.phase[i] = spawn.phase if spawn.phase is not None else self._draw_phase()
        self.runs[i] = spawn.runs if spawn.runs is not None else self.rng.random() < b.running_rate
        self.red_violator[i] = self.rng.random() < b.red_light_rate
        self.group[i] = spawn.group
        self.intends[i] = spawn.crosses
        self.intent_time[i] = round(self.time, 9)  # plans are fixed at spawn; turning back keeps them
        self.bystander[i] = not spawn.crosses  # walking past along the sidewalk
        self.dwell_left[i] = 0.0
        self.wait_time[i] = 0.0
        self.hesitate_left[i] = 0.0
        self.crossed_on_red[i] = False
        self.hesitate_at[i] = self.rng.uniform(0.2, 0.8) if self.rng.random() < b.hesitation_rate else np.inf
        self.turn_back_at[i] = self.rng.uniform(0.1, 0.4) if self.rng.random() < b.turn_back_rate else np.inf
        self.force_intensity[i] = self.config.social_force.ped_intensity
        self.turning_back[i] = False
        self.accepted_gap[i] = np.nan
        self.held[i] = False
        if not spawn.crosses:
            cx = spawn.x
            self.jaywalker[i] = False
        elif spawn.crossing_x is not None:
            cx = spawn.crossing_x
            self.jaywalker[i] = not (
                geo.has_crossing and geo.crossing_rect.x_min <= cx <= geo.crossing_rect.x_max
            )
        elif geo.has_crossing and spawn.crosses:
            half = max(0.0, self.scenario.crossing.width / 2 - 0.6)
            cx = self.scenario.crossing.position + self.rng.uniform(-half, half)
            self.jaywalker[i] = False
        else:
            cx = spawn.x
            self.jaywalker[i] = spawn.crosses
        self.crossing_x[i] = cx
        self.history[i] = self.position[i]
        if spawn.crosses:
            self.state[i] = APPROACHING
            self.waypoint[i] = (cx, self._kerb_y[0] if side > 0 else self._kerb_y[1])
            onward = np.sign(cx - spawn.x) or (1.0 if self.rng.random() < 0.5 else -1.0)
            self.goal[i] = (cx + onward * self.rng.uniform(8.0, 20.0), far_y)
            if self.jaywalker[i] and geo.has_crossing:  # on an unmarked road every crossing is "away"
                self._log(i, "jaywalk")
        else:
            self.state[i] = LEAVING
            direction = 1.0 if spawn.x < self.scenario.crossing.position else -1.0
            self.goal[i] = (spawn.x + direction * self.rng.uniform(40.0, 60.0), start_y)
            self.waypoint[i] = self.goal[i]
        if self.distracted[i]:
            self._log(i, "distracted")
        return i

    def _random_arrivals(self) -> None:
        """Poisson arrivals on both sidewalks near the crossing."""
        c = self.config
        if c.spawn_rate <= 0:
            return
        count = self.rng.poisson(c.spawn_rate / 60.0 * self.dt)
        for _ in range(count):
            side = "south" if self.rng.random() < 0.5 else "north"
            offset = self.rng.uniform(4.0, max(4.5, c.spawn_extent)) * (1 if self.rng.random() < 0.5 else -1)
            x = float(np.clip(self.scenario.crossing.position + offset, 1.0, self.scenario.road.length - 1.0))
            crosses = bool(self.rng.random() < c.cross_fraction)
            crossing_x = None
            if crosses and self.rng.random() < c.behaviour.jaywalk_rate:
                crossing_x = x  # crosses where it stands, away from the zebra
            group = -1
            companion = self.rng.random() < c.group_probability
            if companion:
                group = self.next_group
                self.next_group += 1
            spawn = PedestrianSpawn(x=x, side=side, crosses=crosses, crossing_x=crossing_x, group=group)
            first = self.spawn(spawn)
            if companion and first is not None:
                mate = PedestrianSpawn(
                    x=x - 0.8 * np.sign(offset),
                    side=side,
                    crosses=crosses,
                    crossing_x=self.crossing_x[first] + 0.6,
                    group=group,
                )
                self.spawn(mate)

    def spawn_bystander(self, place: WaitingPlace, group: int = -1) -> int | None:
        """One bystander standing at `place` (it walks on along the sidewalk after its dwell time)."""
        offset = self.rng.uniform(-place.spread / 2, place.spread / 2)
        x = float(np.clip(place.x + offset, 1.0, self._road_length - 1.0))
        i = self.spawn(PedestrianSpawn(x=x, side=place.side, crosses=False, group=group))
        if i is None:
            return None
        y = (
            self._kerb_lines[0] - place.kerb_distance
            if place.side == "south"
            else (self._kerb_lines[1] + place.kerb_distance)
        )
        self.position[i] = (x, y)
        self.history[i] = self.position[i]
        self.dwell_left[i] = self.rng.exponential(self.config.bystanders.dwell_mean)
        return i

    def _place_bystanders(self) -> None:
        """The people standing at the waiting places at the start (a corner's as one talking group)."""
        self._bystanders_placed = True
        for place in self.config.bystanders.places:
            group = -1
            if place.kind == "corner" and place.initial > 1:
                group = self.next_group
                self.next_group += 1
            for _ in range(place.initial):
                self.spawn_bystander(place, group)

    def _bystander_arrivals(self) -> None:
        """Poisson arrivals at the waiting places (off a bus, out of a shop)."""
        b = self.config.bystanders
        if b.arrival_rate <= 0:
            return
        for _ in range(self.rng.poisson(b.arrival_rate / 60.0 * self.dt)):
            place = b.places[int(self.rng.choice(len(b.places), p=self._place_weights))]
            self.spawn_bystander(place)
