"""Pedestrian population: trip state machine, crossing decisions and irrational acts.

State lives in fixed-size numpy arrays (a pool of `max_pedestrians` slots) so every per-step update is
vectorised; Python loops only run over the rare events (a spawn, a state change).

A pedestrian's trip: APPROACHING (walk along the sidewalk to the kerb point where it will cross) →
WAITING (gap acceptance through the decision model) → CROSSING → LEAVING (walk to the final goal) →
despawn. Pedestrians who do not intend to cross go straight to LEAVING along their sidewalk. Who appears,
where and with which traits is `crossing_env.pedestrians.spawning`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from crossing_common.cadence import HISTORY_INTERVAL
from crossing_env.pedestrians.crossing_decisions import CrossingDecisionModel, DecisionContext
from crossing_env.pedestrians.social_force import model_parameters, walk_step
from crossing_env.pedestrians.spawning import PedestrianSpawning
from crossing_env.pedestrians.transitions import (
    APPROACHING,
    CROSSING,
    GROUP_MAX_WAIT,
    HESITATES,
    INACTIVE,
    KERB_STANDOFF,
    TURNS_BACK,
    WAITING,
    begin_transitions,
    detour,
    finish_transitions,
    geometric_masks,
    waiting_context,
    walk_inputs,
)
from crossing_env.road import RoadGeometry
from crossing_env.types import BehaviourEvent, FloatArray, IntArray
from scenarios.config import PedestrianConfig, PedestrianSpawn, ScenarioConfig


@dataclass(frozen=True)
class CarSnapshot:
    """What pedestrians need to know about the vehicles for their gap decisions."""

    x: FloatArray
    """(C,) centre x of each moving vehicle."""
    direction: FloatArray
    """(C,) +1 / −1 travel direction."""
    speed: FloatArray
    """(C,) speed in m/s."""
    half_length: FloatArray
    """(C,) half vehicle length."""
    boxes: FloatArray
    """(C_all, 4) boxes of all vehicles (parked included) for the social force."""
    lane: IntArray
    """(C,) lane index of each moving vehicle (for lane-by-lane gap acceptance)."""


class PedestrianPopulation(PedestrianSpawning):
    """All pedestrians of an episode, as a pool of array slots (spawning: `PedestrianSpawning`)."""

    def __init__(
        self,
        scenario: ScenarioConfig,
        geometry: RoadGeometry,
        decision_model: CrossingDecisionModel,
        rng: np.random.Generator,
        dt: float,
        history_length: int = 8,
    ) -> None:
        self.scenario = scenario
        self.config: PedestrianConfig = scenario.pedestrians
        self.geometry = geometry
        self.decision_model = decision_model
        self.rng = rng
        self.dt = float(dt)
        steps = HISTORY_INTERVAL / dt
        if abs(steps - round(steps)) > 1e-9 or round(steps) < 1:
            raise ValueError(f"dt={dt} must divide the {HISTORY_INTERVAL} s history interval")
        self.history_every = round(steps)
        self.history_length = history_length
        n = self.config.max_pedestrians
        self.capacity = n
        self.state = np.zeros(n, dtype=np.int64)
        self.ids = np.full(n, -1, dtype=np.int64)
        self.position = np.zeros((n, 2))
        self.velocity = np.zeros((n, 2))
        self.radius = np.full(n, self.config.radius)
        self.desired_speed = np.ones(n)
        self.base_speed = np.ones(n)
        self.side = np.ones(n)  # +1 starts south (walks north), −1 starts north
        self.intends = np.zeros(n, dtype=bool)
        self.intent_time = np.full(n, np.nan)  # when the current intent was decided (s)
        self.bystander = np.zeros(n, dtype=bool)  # near the crossing, not meaning to cross
        self.dwell_left = np.zeros(n)  # seconds a bystander still stands at its waiting place
        self.crossing_x = np.zeros(n)
        self.waypoint = np.zeros((n, 2))
        self.goal = np.zeros((n, 2))
        self.critical_gap = np.full(n, 5.5)
        self.phase = np.full(n, math.pi / 2)
        self.distracted = np.zeros(n, dtype=bool)
        self.runs = np.zeros(n, dtype=bool)
        self.hesitate_at = np.full(n, np.inf)  # fraction of the crossing at which to pause
        self.hesitate_left = np.zeros(n)
        self.turn_back_at = np.full(n, np.inf)
        self.red_violator = np.zeros(n, dtype=bool)
        self.jaywalker = np.zeros(n, dtype=bool)
        self.crossed_on_red = np.zeros(n, dtype=bool)
        self.wait_time = np.zeros(n)
        self.group = np.full(n, -1, dtype=np.int64)
        self.force_intensity = np.full(n, self.config.social_force.ped_intensity)
        self.turning_back = np.zeros(n, dtype=bool)  # walking back to the start kerb after turning back
        self.accepted_gap = np.full(n, np.nan)  # gap (s) at the last start of a crossing (evaluation only)
        self.held = np.zeros(n, dtype=bool)  # a timed conflict's pedestrian standing until released
        self.history = np.zeros((n, history_length, 2))
        self.next_id = 0
        self.next_group = 1_000_000  # random groups get ids far from scenario-given ones
        self.step_count = 0
        self.time = 0.0
        self.events: list[BehaviourEvent] = []
        self._early_events: list[BehaviourEvent] = []  # logged before `step` (a release), kept for it
        self._pending = sorted(self.config.spawns, key=lambda s: s.time)
        self._kerb_y = (geometry.kerb_south - KERB_STANDOFF, geometry.kerb_north + KERB_STANDOFF)
        self._kerb_lines = (float(geometry.kerb_south), float(geometry.kerb_north))
        """(south, north) kerb y: the edges of the carriageway."""
        self._road_length = float(scenario.road.length)
        rect = geometry.crossing_rect
        self._zebra_box = (
            geometry.has_crossing,
            float(rect.x_min),
            float(rect.x_max),
            float(rect.y_min),
            float(rect.y_max),
        )
        """(has a crossing, x min, x max, y min, y max) of the zebra area, as `_geometric_masks` takes it."""
        self._zebra_span = (float(scenario.crossing.position), float(scenario.crossing.width))
        """(centre x, width) of the crossing, as `waiting_at_zebra` and the drivers' offers take it."""
        self._force_parameters = model_parameters(self.config.social_force)
        """The social-force config as the kernels take it (unpacked once, not every step)."""
        self._walk_y = (
            geometry.sidewalk_south.y_max - 0.55 * scenario.road.sidewalk_width,
            geometry.kerb_north + 0.55 * scenario.road.sidewalk_width,
        )
        """(south, north) walking lines: the middle of each sidewalk proper (beyond any parking strip)."""
        self._bystanders_placed = False
        places = self.config.bystanders.places
        weights = np.array([p.weight for p in places], dtype=np.float64)
        self._place_weights = weights / weights.sum() if weights.sum() > 0 else weights
        self._speed_scale = 0.9 if scenario.night else 1.0
        self._lanes = (float(scenario.road.lane_width), int(scenario.road.num_lanes))
        """(lane width, number of lanes), as the lane-by-lane gap check takes them."""

    # ------------------------------------------------------------------ spawning
    @property
    def active(self) -> np.ndarray:
        """(n,) mask of slots in use."""
        return self.state != INACTIVE

    # ------------------------------------------------------------------ per step
    def step(self, time: float, cars: CarSnapshot, pedestrian_green: bool | None) -> None:
        """Advance decisions and desired velocities by one step (physics integrates positions)."""
        self.time = time
        self.events, self._early_events = self._early_events, []
        while self._pending and self._pending[0].time <= time + 1e-9:
            self.spawn(self._pending.pop(0))
        if not self._bystanders_placed:
            self._place_bystanders()
        self._random_arrivals()
        self._bystander_arrivals()
        self._update_states(cars, pedestrian_green)
        detour(self.state, self.position, self.velocity, self.waypoint, self.radius, cars.boxes)
        if self.config.behaviour.update_force_intensity:
            self._update_force_intensity()
        self._update_velocities(cars)

    def _update_states(self, cars: CarSnapshot, pedestrian_green: bool | None) -> None:
        if not self.state.any():
            return  # nobody around: nothing to decide
        st = self.state
        # Each transition applies to the state held at the start of the step (one transition per step),
        # because `arrived` refers to the waypoint of that state. APPROACHING → WAITING at the kerb first.
        arrived, before, waiting, acts, any_acts = begin_transitions(
            self.position,
            self.velocity,
            self.waypoint,
            st,
            self.intends,
            self.group,
            self.side,
            *self._kerb_lines,
            self.wait_time,
            self.turning_back,
            self.dt,
            self.hesitate_at,
            self.turn_back_at,
        )
        # WAITING: decide (a timed conflict's held pedestrian waits for its release, not for a gap).
        if waiting.size and self.held.any():
            waiting = waiting[~self.held[waiting]]
        if waiting.size:
            red, gap, seen, critical_gap, phase, waited, red_violator, safe = waiting_context(
                waiting,
                pedestrian_green is False,
                self.jaywalker,
                self.distracted,
                self.critical_gap,
                self.phase,
                self.wait_time,
                self.red_violator,
                self.crossing_x,
                self.side,
                self.base_speed,
                self.radius,
                cars.x,
                cars.lane,
                cars.direction,
                cars.half_length,
                cars.speed,
                *self._lanes,
            )
            # A distracted pedestrian looks up late: `seen` is the gap it saw DISTRACTED_LOOK_DELAY ago.
            ctx = DecisionContext(
                gap=seen,
                critical_gap=critical_gap,
                phase=phase,
                waited=waited,
                red=red,
                red_violator=red_violator,
                dt=self.dt,
            )
            prob = self.decision_model.probability(ctx)
            # Nobody steps into a lane a car will occupy while they are in it (lane by lane, at their own
            # speed); the draw comes first so the random stream does not depend on the check.
            go = (self.rng.random(waiting.size) < prob) & safe
            # Groups move together: members wait at the kerb for companions still walking up (for at most
            # GROUP_MAX_WAIT), and if one member goes, waiting companions go too. A group decides on its
            # members' worst gap: if any waiting member's lanes are not safe, nobody in the group goes.
            groups = self.group[waiting]
            if go.any() and np.any(groups >= 0):
                walking_up = self.group[(self.state == APPROACHING) & self.intends & (self.group >= 0)]
                patient = waited < GROUP_MAX_WAIT
                held = (groups >= 0) & np.isin(groups, walking_up) & patient
                unsafe_groups = groups[~safe & (groups >= 0)]
                group_safe = ~((groups >= 0) & np.isin(groups, unsafe_groups))
                go &= ~held & group_safe
                moving_groups = groups[go & (groups >= 0)]
                go |= (groups >= 0) & np.isin(groups, moving_groups) & ~held & group_safe
            for k in np.flatnonzero(go):
                self.accepted_gap[waiting[k]] = gap[k]
                self._start_crossing(int(waiting[k]), bool(red[k]))
        # CROSSING: irrational acts (rare: Python handles them, drawing from the RNG in slot order).
        if any_acts:
            for i in np.flatnonzero(acts & HESITATES):
                self.hesitate_at[i] = np.inf
                self.hesitate_left[i] = self.rng.uniform(1.0, 2.5)
                self._log(i, "hesitate")
            for i in np.flatnonzero(acts & TURNS_BACK):
                self.turn_back_at[i] = np.inf
                # Head back to the kerb it came from (its side is unchanged), wait there and re-decide.
                self.state[i] = APPROACHING
                self.turning_back[i] = True
                start_kerb = self._kerb_y[0] if self.side[i] > 0 else self._kerb_y[1]
                self.waypoint[i] = (self.position[i, 0], start_kerb)
                self.desired_speed[i] = self.base_speed[i] * 1.2
                self._log(i, "turn_back")
        # CROSSING → LEAVING past the far kerb; LEAVING → despawn at the goal or off the map.
        finish_transitions(
            st,
            before,
            arrived,
            self.waypoint,
            self.goal,
            self.desired_speed,
            self.base_speed,
            self.hesitate_left,
            self.ids,
            self.velocity,
            self.position,
            self.dt,
            self._road_length,
        )

    def _start_crossing(self, i: int, red: bool) -> None:
        self.state[i] = CROSSING
        far = self._kerb_y[1] if self.side[i] > 0 else self._kerb_y[0]
        self.waypoint[i] = (self.crossing_x[i] + self.rng.normal(0.0, 0.2), far)
        self.crossed_on_red[i] = red
        self._log(i, "start_crossing")
        if red:
            self._log(i, "red_light")
        if self.runs[i]:
            self.desired_speed[i] = min(2.0 * self.base_speed[i], 3.5)
            self._log(i, "run")

    def spawn_held(self, spawn: PedestrianSpawn, start_y: float) -> int | None:
        """Place a timed conflict's pedestrian standing at (`spawn.x`, `start_y`) until `release_held`."""
        i = self.spawn(spawn)
        if i is None:
            return None
        self.position[i] = (spawn.x, start_y)
        self.history[i] = self.position[i]
        self.waypoint[i] = self.position[i]
        self.state[i] = WAITING
        self.held[i] = True
        self.hesitate_at[i] = np.inf  # it keeps its course: the timing is the scenario's
        self.turn_back_at[i] = np.inf
        return i

    def release_held(self, i: int, red: bool, time: float) -> None:
        """Step a held pedestrian off now (logged with the coming step's events)."""
        self.held[i] = False
        self.time = time
        events, self.events = self.events, []
        self._start_crossing(i, red)
        self._early_events, self.events = self.events, events

    def waiting_at_zebra(self) -> np.ndarray:
        """(n,) waiting to cross at the zebra (within its width of the centre line; jaywalkers aside)."""
        position, width = self._zebra_span
        return (self.state == WAITING) & (np.abs(self.crossing_x - position) < width) & ~self.jaywalker

    def irrational_now(self) -> np.ndarray:
        """(n,) visibly acting irrationally this step (what others can see and react to).

        Running, crossing on red or away from the zebra, hesitating mid-crossing, turning back, or being on
        the road with a phone.
        """
        crossing = self.state == CROSSING
        on_road = self.on_road()
        return self.active & (
            (crossing & (self.runs | self.crossed_on_red | (self.jaywalker & self.geometry.has_crossing)))
            | (self.hesitate_left > 0)
            | self.turning_back
            | (self.distracted & on_road)
        )

    def _update_force_intensity(self) -> None:
        """Seed Case 2: QLB-updated ped–ped intensity from the irrational fraction of neighbours in view."""
        from crossing_env.pedestrians.force_update import irrational_neighbour_fraction, updated_ped_intensity

        fraction = irrational_neighbour_fraction(self.position, self.active, self.irrational_now())
        self.force_intensity = updated_ped_intensity(self.config.social_force.ped_intensity, fraction)

    def _update_velocities(self, cars: CarSnapshot) -> None:
        rows, v0, stay = walk_inputs(
            self.state,
            self.hesitate_left,
            self.dwell_left,
            self.desired_speed,
            self.position,
            *self._kerb_lines,
            self.dt,
        )
        if rows.size == 0:
            return
        sf = self.config.social_force
        walk_step(
            rows,
            self.position,
            self.velocity,
            self.waypoint,
            v0,
            self.radius,
            stay,
            cars.boxes,
            *self._kerb_lines,
            self.force_intensity,
            self.dt,
            sf.max_speed_factor,
            self._force_parameters,
        )

    def record_history(self) -> None:
        """Append the current positions to the 0.4 s history (call once per step, after physics)."""
        self.step_count += 1
        if self.step_count % self.history_every == 0:
            self.history[:, :-1] = self.history[:, 1:]
            self.history[:, -1] = self.position

    def masks(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(on the carriageway, on the zebra, legal) per slot; the world refreshes them every step.

        Legal: on the zebra and not against red, or not on the road at all. Inactive slots are off the road.
        """
        return geometric_masks(
            self.state,
            self.position,
            *self._kerb_lines,
            *self._zebra_box,
            self.crossed_on_red,
            self.jaywalker,
        )

    def on_road(self) -> np.ndarray:
        """(n,) centre on the carriageway."""
        y = self.position[:, 1]
        return (y > self.geometry.kerb_south) & (y < self.geometry.kerb_north) & self.active
