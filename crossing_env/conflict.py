"""The scenario's timed conflict (`[conflict]`): per-episode draws, the key pedestrian's placement, trigger.

As in Euro NCAP's AEB pedestrian tests, the pedestrian is synchronised to the ego: it stands on the sidewalk
and steps off when the ego's time to arrive at the conflict point, at its current speed, falls to the drawn
time; its start is set back so that, walking at its speed, it would meet the ego's front at the drawn
fraction of the car's width if the car held its speed. Every value is drawn once, in a fixed order, from the
world's seeded generator (`draw_plan`), so a seed gives one episode.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from crossing_env.pedestrians.transitions import CROSSING, KERB_STANDOFF
from crossing_env.road import RoadGeometry
from scenarios.config import ConflictConfig, PedestrianSpawn, ScenarioConfig

if TYPE_CHECKING:
    from crossing_env.pedestrians.population import PedestrianPopulation

RELEASE_DISTANCE = 60.0
"""A car standing (below `STOPPED_SPEED`) within this distance (m) of the conflict point, front to point,
for `RELEASE_STANDSTILL` seconds releases the pedestrian: someone given the way takes it."""
RELEASE_STANDSTILL = 1.0
"""Seconds of standstill before the pedestrian takes a car's offer (see `RELEASE_DISTANCE`)."""
STOPPED_SPEED = 0.5
"""Ego speed (m/s) below which the ego counts as standing for the release."""
WALL_CLEARANCE = 0.1
"""Metres kept between the pedestrian's body and the building line when it is set back."""


@dataclass(frozen=True)
class ConflictPlan:
    """What was drawn for one episode, and where the key pedestrian starts (for tests, logs and replay)."""

    x: float
    """Conflict point along the road (m): the pedestrian's crossing line."""
    side: str
    """'near' (south kerb) or 'far' (north kerb)."""
    ego_speed: float
    """The ego's initial speed (m/s)."""
    pedestrian_speed: float
    """The pedestrian's walking speed (m/s), night and phone slow-downs included."""
    impact_offset: float
    """Impact point as a fraction of the ego's width from its right edge."""
    impact_y: float
    """Impact point's y (m)."""
    start_y: float
    """Where the pedestrian stands until it steps off (y, m)."""
    time_to_arrival: float
    """The ego's time to arrive at the conflict point at which the pedestrian steps off (s)."""
    occluder_x: float | None
    """Centre x of the occluding parked vehicle, when it was moved (m)."""
    radius: float
    """The pedestrian's body radius (m)."""
    along_speed: float = 0.0
    """Its velocity along the road once released (m/s, signed in x): 0 for a pedestrian who crosses, the
    walking speed the ego's way for one walking ahead in its lane ('ahead', Euro NCAP CPLA)."""


def _uniform(rng: np.random.Generator, bounds: tuple[float, ...], default: float) -> float:
    if not bounds:
        return default
    return float(rng.uniform(bounds[0], bounds[1]))


def draw_plan(scenario: ScenarioConfig, geometry: RoadGeometry, rng: np.random.Generator) -> ConflictPlan:
    """Draw the episode's conflict (in a fixed order: side, point, speeds, offset, time, occluder gap)."""
    c: ConflictConfig = scenario.conflict  # type: ignore[assignment]
    side = c.side if c.side != "either" else ("far" if rng.random() < 0.5 else "near")
    x = scenario.crossing.position + _uniform(rng, c.x_offset, 0.0)
    if c.ego_speed_grid:  # one draw either way, so the draws after it keep their order
        ego_speed = float(c.ego_speed_grid[int(rng.integers(len(c.ego_speed_grid)))])
    else:
        ego_speed = _uniform(rng, c.ego_speed, scenario.ego.speed)
    walk = _uniform(rng, c.pedestrian_speed, 1.4)
    walk *= (0.9 if scenario.night else 1.0) * (0.8 if c.distracted else 1.0)
    offset = _uniform(rng, c.impact_offset, 0.5)
    wanted = _uniform(rng, c.time_to_arrival, 3.0)
    gap = _uniform(rng, c.occluder_gap, 0.0) if c.occluder_gap else None
    radius = c.radius if c.radius is not None else scenario.pedestrians.radius
    width = scenario.traffic.width
    impact_y = float(geometry.lane_y[scenario.ego.lane]) - width / 2 + offset * width
    # Walking from a standstill, the social force lags the pedestrian by about one relaxation time; a
    # dummy moves at its speed from the first step.
    lag = 0.0 if c.dummy else scenario.pedestrians.social_force.relaxation_time
    south, north = geometry.walkway_bounds
    along = 0.0
    if side == "ahead":  # stands in the ego's lane, on the car's line of impact, and walks the car's way
        start_y = impact_y
        along = walk * float(geometry.lane_direction[scenario.ego.lane])
    elif side == "near":  # walks north, from the south sidewalk (or the parking strip in front of it)
        lo, hi = south + radius + WALL_CLEARANCE, geometry.kerb_south - KERB_STANDOFF
        start_y = float(np.clip(impact_y - walk * max(wanted - lag, 0.0), lo, hi))
    else:
        lo, hi = geometry.kerb_north + KERB_STANDOFF, north - radius - WALL_CLEARANCE
        start_y = float(np.clip(impact_y + walk * max(wanted - lag, 0.0), lo, hi))
    tta = wanted if side == "ahead" else lag + abs(impact_y - start_y) / walk
    occluder_x = None
    if gap is not None:
        occluder_x = x - radius - gap - scenario.traffic.length / 2
    return ConflictPlan(
        x=float(x),
        side=side,
        ego_speed=float(ego_speed),
        pedestrian_speed=float(walk),
        impact_offset=float(offset),
        impact_y=float(impact_y),
        start_y=start_y,
        time_to_arrival=float(tta),
        occluder_x=occluder_x,
        radius=float(radius),
        along_speed=along,
    )


def occluder_slot(scenario: ScenarioConfig) -> int | None:
    """Traffic pool slot of the first parked spawn (spawns fill slots 1, 2, ... in order at reset)."""
    for j, spawn in enumerate(scenario.traffic.spawns):
        if spawn.parked:
            return j + 1
    return None


class ConflictScript:
    """Places the key pedestrian at reset and steps it off when the ego's arrival is due."""

    def __init__(self, plan: ConflictPlan, scenario: ScenarioConfig) -> None:
        self.plan = plan
        self.config: ConflictConfig = scenario.conflict  # type: ignore[assignment]
        self.slot: int | None = None
        """Pedestrian pool slot of the key pedestrian (None until placed)."""
        self.stepped_off_at: float | None = None
        """World time at which it stepped off (None while it stands)."""
        self._standing = 0.0

    def spawn(self, pedestrians: PedestrianPopulation) -> None:
        """Place the standing pedestrian (before the first step)."""
        p = self.plan
        spawn = PedestrianSpawn(
            x=p.x,
            side="north" if p.side == "far" else "south",
            crossing_x=p.x,
            # The plan's speed already has the night and phone slow-downs; spawning applies them again.
            desired_speed=p.pedestrian_speed
            / ((0.9 if pedestrians.scenario.night else 1.0) * (0.8 if self.config.distracted else 1.0)),
            critical_gap=0.0,
            distracted=self.config.distracted,
            runs=False,
            radius=p.radius,
        )
        self.slot = pedestrians.spawn_held(spawn, p.start_y)

    def step(
        self, time: float, ego: tuple[float, float, float], red: bool, pedestrians: PedestrianPopulation
    ) -> None:
        """Release the pedestrian when the ego's time to arrival reaches the plan's (or it stands, offering).

        `ego` is (centre x, speed, length); `red`: the pedestrian signal shows red (it crosses against it).
        """
        if self.slot is None or self.stepped_off_at is not None:
            return
        p = self.plan
        ego_x, ego_speed, ego_length = ego
        to_point = p.x - p.radius - (ego_x + ego_length / 2)
        if to_point <= 0.0:  # the car is past: the conflict did not happen; release it to walk on
            release = True
        else:
            arrival = to_point / max(ego_speed, 1e-3)
            standing = ego_speed < STOPPED_SPEED and to_point < RELEASE_DISTANCE
            self._standing = self._standing + pedestrians.dt if standing else 0.0
            release = arrival <= p.time_to_arrival + 1e-9 or self._standing >= RELEASE_STANDSTILL - 1e-9
        if release:
            self.stepped_off_at = round(time, 9)
            pedestrians.release_held(self.slot, red, time)

    def hold_course(self, pedestrians: PedestrianPopulation) -> None:
        """A dummy's velocity: still until released, then straight along its line at its speed.

        Its line crosses the road, or runs along the ego's lane for one walking ahead.

        Called after `PedestrianPopulation.step` (which set everyone's velocity from the social force) and
        before the physics moves the bodies: the dummy reacts to nothing until a contact pushes it.
        """
        i = self.slot
        if not self.config.dummy or i is None:
            return
        if self.stepped_off_at is None:
            pedestrians.velocity[i] = 0.0
        elif self.plan.along_speed:
            pedestrians.velocity[i, 0] = self.plan.along_speed
            pedestrians.velocity[i, 1] = 0.0
        elif pedestrians.state[i] == CROSSING:
            towards = 1.0 if self.plan.side == "near" else -1.0  # near: walks north (+y), far: south
            pedestrians.velocity[i, 0] = 0.0
            pedestrians.velocity[i, 1] = towards * self.plan.pedestrian_speed
