"""Pedestrian population: spawning, trip state machine, crossing decisions and irrational acts.

State lives in fixed-size numpy arrays (a pool of `max_pedestrians` slots) so every per-step update is
vectorised; Python loops only run over the rare events (a spawn, a state change).

A pedestrian's trip: APPROACHING (walk along the sidewalk to the kerb point where it will cross) →
WAITING (gap acceptance through the decision model) → CROSSING → LEAVING (walk to the final goal) →
despawn. Pedestrians who do not intend to cross go straight to LEAVING along their sidewalk.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from crossing_env.config import PedestrianConfig, PedestrianSpawn, ScenarioConfig
from crossing_env.decisions import CrossingDecisionModel, DecisionContext
from crossing_env.road import RoadGeometry
from crossing_env.social_force import model_parameters, walk_step
from crossing_env.types import BehaviourEvent, FloatArray, PedState

# Plain ints for the hot path (IntEnum comparisons go through Python-level enum machinery).
INACTIVE, APPROACHING, WAITING, CROSSING, LEAVING = (int(state) for state in PedState)
HESITATES, TURNS_BACK = 1, 2
"""Flags of the irrational acts a crossing pedestrian can start in a step."""

HISTORY_INTERVAL = 0.4
"""Seconds between history samples: the ETH/UCY cadence trajectory predictors are trained on."""
KERB_STANDOFF = 0.45
"""Distance in metres from the kerb line at which a waiting pedestrian stands."""
ARRIVAL_TOLERANCE = 0.35
"""Distance in metres at which a waypoint counts as reached."""
CROWD_ARRIVAL = 3.0
"""A pedestrian stopped this close to its kerb point (blocked by a waiting crowd) counts as waiting."""
CROWD_STOPPED_SPEED = 0.15
"""Speed (m/s) below which a pedestrian near its kerb point counts as held up by the crowd."""
KERB_ARRIVAL = (2.0, 0.6)
"""(along x, across y) metres within which a pedestrian heading for a kerb point counts as arrived at it."""
DISTRACTED_LOOK_DELAY = 1.0
"""Seconds by which a distracted pedestrian's view of the traffic lags (late reaction to approaching cars)."""
GROUP_JOIN_DISTANCE = 1.5
"""Metres from a waiting companion at which a group member walking up counts as arrived at the kerb."""
GROUP_MAX_WAIT = 15.0
"""Seconds a group member at the kerb waits for companions still walking up before deciding alone."""


@dataclass(frozen=True)
class CarSnapshot:
    """What pedestrians need to know about the vehicles for their gap decisions."""

    x: FloatArray
    """(C,) front-centre... centre x of each moving vehicle."""
    direction: FloatArray
    """(C,) +1 / −1 travel direction."""
    speed: FloatArray
    """(C,) speed in m/s."""
    half_length: FloatArray
    """(C,) half vehicle length."""
    boxes: FloatArray
    """(C_all, 4) boxes of all vehicles (parked included) for the social force."""


class PedestrianPopulation:
    """All pedestrians of an episode, as a pool of array slots."""

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
        self.history = np.zeros((n, history_length, 2))
        self.next_id = 0
        self.next_group = 1_000_000  # random groups get ids far from scenario-given ones
        self.step_count = 0
        self.time = 0.0
        self.events: list[BehaviourEvent] = []
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
        """(centre x, width) of the crossing, as `_anyone_at_zebra` takes it."""
        self._force_parameters = model_parameters(self.config.social_force)
        """The social-force config as the kernels take it (unpacked once, not every step)."""
        self._walk_y = (
            geometry.kerb_south - 0.55 * scenario.road.sidewalk_width,
            geometry.kerb_north + 0.55 * scenario.road.sidewalk_width,
        )
        self._speed_scale = 0.9 if scenario.night else 1.0

    # ------------------------------------------------------------------ spawning
    @property
    def active(self) -> np.ndarray:
        """(n,) mask of slots in use."""
        return self.state != INACTIVE

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
        self.wait_time[i] = 0.0
        self.hesitate_left[i] = 0.0
        self.crossed_on_red[i] = False
        self.hesitate_at[i] = self.rng.uniform(0.2, 0.8) if self.rng.random() < b.hesitation_rate else np.inf
        self.turn_back_at[i] = self.rng.uniform(0.1, 0.4) if self.rng.random() < b.turn_back_rate else np.inf
        self.force_intensity[i] = self.config.social_force.ped_intensity
        self.turning_back[i] = False
        self.accepted_gap[i] = np.nan
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

    # ------------------------------------------------------------------ per step
    def _log(self, i: int, kind: str) -> None:
        self.events.append(BehaviourEvent(time=self.time, pedestrian_id=int(self.ids[i]), kind=kind))

    def step(self, time: float, cars: CarSnapshot, pedestrian_green: bool | None) -> None:
        """Advance decisions and desired velocities by one step (physics integrates positions)."""
        self.time = time
        self.events = []
        while self._pending and self._pending[0].time <= time + 1e-9:
            self.spawn(self._pending.pop(0))
        self._random_arrivals()
        self._update_states(cars, pedestrian_green)
        if self.config.behaviour.update_force_intensity:
            self._update_force_intensity()
        self._update_velocities(cars)

    def _update_states(self, cars: CarSnapshot, pedestrian_green: bool | None) -> None:
        if not self.state.any():
            return  # nobody around: nothing to decide
        st = self.state
        # Each transition applies to the state held at the start of the step (one transition per step),
        # because `arrived` refers to the waypoint of that state. APPROACHING → WAITING at the kerb first.
        arrived, before, waiting, acts, any_acts = _begin_transitions(
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
        # WAITING: decide.
        if waiting.size:
            red, gap, seen, critical_gap, phase, waited, red_violator = _waiting_context(
                waiting,
                pedestrian_green is False,
                self.jaywalker,
                self.distracted,
                self.critical_gap,
                self.phase,
                self.wait_time,
                self.red_violator,
                self.crossing_x,
                cars.x,
                cars.direction,
                cars.half_length,
                cars.speed,
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
            go = self.rng.random(waiting.size) < prob
            # Groups move together: members wait at the kerb for companions still walking up (for at most
            # GROUP_MAX_WAIT), and if one member goes, waiting companions go too.
            groups = self.group[waiting]
            if go.any() and np.any(groups >= 0):
                walking_up = self.group[(self.state == APPROACHING) & self.intends & (self.group >= 0)]
                patient = waited < GROUP_MAX_WAIT
                held = (groups >= 0) & np.isin(groups, walking_up) & patient
                go &= ~held
                moving_groups = groups[go & (groups >= 0)]
                go |= (groups >= 0) & np.isin(groups, moving_groups) & ~held
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
        _finish_transitions(
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

    def anyone_at_zebra(self, on_crossing: np.ndarray) -> bool:
        """Whether anyone waits by the crossing (jaywalkers aside) or is on it (`on_crossing`)."""
        return _anyone_at_zebra(self.state, self.crossing_x, self.jaywalker, on_crossing, *self._zebra_span)

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
        from crossing_env.behaviour import irrational_neighbour_fraction, updated_ped_intensity

        fraction = irrational_neighbour_fraction(self.position, self.active, self.irrational_now())
        self.force_intensity = updated_ped_intensity(self.config.social_force.ped_intensity, fraction)

    def _update_velocities(self, cars: CarSnapshot) -> None:
        rows, v0, stay = _walk_inputs(
            self.state, self.hesitate_left, self.desired_speed, self.position, *self._kerb_lines
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
        return _geometric_masks(
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


@njit(cache=True, nogil=True)
def _arrived(
    position: FloatArray,
    velocity: FloatArray,
    waypoint: FloatArray,
    state: np.ndarray,
    intends: np.ndarray,
    group: np.ndarray,
    side: np.ndarray,
    kerb_south: float,
    kerb_north: float,
) -> np.ndarray:
    """(n,) whether each slot has reached the waypoint of its current state (compiled: per-step hot path).

    Besides being within `ARRIVAL_TOLERANCE` of it: in a crowd the exact kerb point may be taken by
    someone else, so being close to it along the kerb counts, and so does standing still within
    `CROWD_ARRIVAL` of it, held up behind a crowd already waiting; a group member walking up joins a
    companion waiting at the kerb (its own kerb point may be behind that companion); and a crossing ends
    within half a metre of the far kerb, where a crowd waiting to cross the other way can block the last
    step (otherwise crowds at the zebra deadlock).
    """
    n = position.shape[0]
    arrived = np.zeros(n, dtype=np.bool_)
    for i in range(n):
        if state[i] == INACTIVE:
            continue
        x, y = position[i, 0], position[i, 1]
        dx, dy = waypoint[i, 0] - x, waypoint[i, 1] - y
        dist = math.sqrt(dx * dx + dy * dy)
        arrived[i] = dist < ARRIVAL_TOLERANCE
        on_road = kerb_south < y < kerb_north
        if state[i] == APPROACHING and intends[i] and not on_road:
            near_kerb = abs(dy) < KERB_ARRIVAL[1] and abs(dx) < KERB_ARRIVAL[0]
            speed2 = velocity[i, 0] * velocity[i, 0] + velocity[i, 1] * velocity[i, 1]
            held_up = dist < CROWD_ARRIVAL and speed2 < CROWD_STOPPED_SPEED**2
            arrived[i] |= near_kerb or held_up
            if group[i] >= 0 and not arrived[i]:
                for j in range(n):
                    if state[j] == WAITING and group[j] == group[i]:
                        gx, gy = x - position[j, 0], y - position[j, 1]
                        if gx * gx + gy * gy < GROUP_JOIN_DISTANCE**2:
                            arrived[i] = True
                            break
        elif state[i] == CROSSING:
            arrived[i] |= y > kerb_north - 0.5 if side[i] > 0 else y < kerb_south + 0.5
    return arrived


@njit(cache=True, nogil=True)
def _gaps(
    crossing_x: FloatArray,
    rows: np.ndarray,
    car_x: FloatArray,
    direction: FloatArray,
    half_length: FloatArray,
    speed: FloatArray,
) -> FloatArray:
    """Time gap (s) until the first approaching car reaches the crossing line of each pedestrian at `rows`.

    Cars already past the line and stopped cars are ignored (every line spans the whole carriageway); a
    car whose body already covers the line gives a gap of 0.
    """
    out = np.full(rows.shape[0], np.inf)
    for k in range(rows.shape[0]):
        cx = crossing_x[rows[k]]
        for c in range(car_x.shape[0]):
            # Distance from the car's front to the pedestrian's line, along the car's travel direction.
            ahead = (cx - car_x[c]) * direction[c] - half_length[c]
            if ahead < 0:
                if ahead > -2 * half_length[c] - 0.5:
                    out[k] = 0.0  # the car's body covers the line
            elif speed[c] > 0.3:
                out[k] = min(out[k], ahead / max(speed[c], 1e-3))
    return out


@njit(cache=True, nogil=True)
def _start_waiting(
    state: np.ndarray, arrived: np.ndarray, wait_time: FloatArray, turning_back: np.ndarray, dt: float
) -> tuple[np.ndarray, np.ndarray]:
    """APPROACHING → WAITING for arrivals; returns the states before and the slots still waiting.

    Those waiting since an earlier step have their waiting time advanced by `dt`.
    """
    before = state.copy()
    still = 0
    for i in range(state.shape[0]):
        if before[i] == APPROACHING and arrived[i]:
            state[i] = WAITING
            wait_time[i] = 0.0
            turning_back[i] = False
        elif before[i] == WAITING:
            still += 1
    waiting = np.empty(still, dtype=np.int64)
    k = 0
    for i in range(state.shape[0]):
        if before[i] == WAITING:
            wait_time[i] += dt
            waiting[k] = i
            k += 1
    return before, waiting


@njit(cache=True, nogil=True)
def _crossing_acts(
    before: np.ndarray,
    position: FloatArray,
    side: np.ndarray,
    hesitate_at: FloatArray,
    turn_back_at: FloatArray,
    kerb_south: float,
    kerb_north: float,
) -> np.ndarray:
    """(n,) flags: `HESITATES` / `TURNS_BACK` where a crossing pedestrian reaches that act's road fraction.

    Only slots crossing since before this step count.
    """
    acts = np.zeros(before.shape[0], dtype=np.int8)
    road_width = kerb_north - kerb_south
    for i in range(before.shape[0]):
        if before[i] != CROSSING:
            continue
        walked = position[i, 1] - kerb_south if side[i] > 0 else kerb_north - position[i, 1]
        progress = walked / road_width
        if progress >= hesitate_at[i]:
            acts[i] |= HESITATES
        if progress >= turn_back_at[i]:
            acts[i] |= TURNS_BACK
    return acts


@njit(cache=True, nogil=True)
def _finish_transitions(
    state: np.ndarray,
    before: np.ndarray,
    arrived: np.ndarray,
    waypoint: FloatArray,
    goal: FloatArray,
    desired_speed: FloatArray,
    base_speed: FloatArray,
    hesitate_left: FloatArray,
    ids: np.ndarray,
    velocity: FloatArray,
    position: FloatArray,
    dt: float,
    road_length: float,
) -> None:
    """The step's last transitions, and hesitation timers run down.

    CROSSING → LEAVING past the far kerb (unless it just turned back); LEAVING → INACTIVE at the goal;
    anyone off the map → INACTIVE.
    """
    for i in range(state.shape[0]):
        if before[i] == CROSSING and arrived[i] and state[i] == CROSSING:
            state[i] = LEAVING
            waypoint[i, 0], waypoint[i, 1] = goal[i, 0], goal[i, 1]
            desired_speed[i] = base_speed[i]
        hesitate_left[i] = max(0.0, hesitate_left[i] - dt)
        off_map = position[i, 0] < -5.0 or position[i, 0] > road_length + 5.0
        if (before[i] == LEAVING and arrived[i]) or (off_map and state[i] != INACTIVE):
            state[i] = INACTIVE
            ids[i] = -1
            velocity[i, 0] = velocity[i, 1] = 0.0


@njit(cache=True, nogil=True)
def _walk_inputs(
    state: np.ndarray,
    hesitate_left: FloatArray,
    desired_speed: FloatArray,
    position: FloatArray,
    kerb_south: float,
    kerb_north: float,
) -> tuple[np.ndarray, FloatArray, np.ndarray]:
    """Active slots, desired speeds and sidewalk constraint for the social-force step.

    Hesitating pedestrians want to stand (v0 = 0); waiting ones keep walking towards their kerb point
    (the arrival slow-down makes them stand there; with no attraction, the kerb repulsion would push them
    back). Only crossing pedestrians may be on the carriageway: everyone else is held on the sidewalk.
    (The step itself is `social_force.walk_step`, called from Python: kernels never call kernels of
    another module, whose changes numba's on-disk cache would not notice.)
    """
    rows = np.flatnonzero(state != INACTIVE)
    v0 = np.where(hesitate_left > 0, 0.0, desired_speed)
    stay = np.empty(state.shape[0], dtype=np.bool_)
    for i in range(state.shape[0]):
        on_road = kerb_south < position[i, 1] < kerb_north
        stay[i] = state[i] != CROSSING and not (state[i] == APPROACHING and on_road)
    return rows, v0, stay


@njit(cache=True, nogil=True)
def _anyone_at_zebra(
    state: np.ndarray,
    crossing_x: FloatArray,
    jaywalker: np.ndarray,
    on_crossing: np.ndarray,
    crossing_position: float,
    crossing_width: float,
) -> bool:
    """`PedestrianPopulation.anyone_at_zebra` in one pass."""
    for i in range(state.shape[0]):
        if on_crossing[i] and state[i] != INACTIVE:
            return True
        waiting_here = state[i] == WAITING and abs(crossing_x[i] - crossing_position) < crossing_width
        if waiting_here and not jaywalker[i]:
            return True
    return False


@njit(cache=True, nogil=True)
def _geometric_masks(
    state: np.ndarray,
    position: FloatArray,
    kerb_south: float,
    kerb_north: float,
    has_crossing: bool,
    x_min: float,
    x_max: float,
    y_min: float,
    y_max: float,
    crossed_on_red: np.ndarray,
    jaywalker: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`PedestrianPopulation.masks`: on the carriageway, on the zebra, crossing legally (or off the road)."""
    n = state.shape[0]
    on_road, on_crossing, legal = np.zeros(n, np.bool_), np.zeros(n, np.bool_), np.ones(n, np.bool_)
    for i in range(n):
        if state[i] == INACTIVE:
            continue
        x, y = position[i, 0], position[i, 1]
        on_road[i] = kerb_south < y < kerb_north
        on_crossing[i] = has_crossing and x_min <= x <= x_max and y_min <= y <= y_max
        if on_road[i]:
            legal[i] = on_crossing[i] and not crossed_on_red[i] and not jaywalker[i]  # no zebra: never
    return on_road, on_crossing, legal


@njit(cache=True, nogil=True)
def _waiting_context(
    waiting: np.ndarray,
    signal_red: bool,
    jaywalker: np.ndarray,
    distracted: np.ndarray,
    critical_gap: FloatArray,
    phase: FloatArray,
    wait_time: FloatArray,
    red_violator: np.ndarray,
    crossing_x: FloatArray,
    car_x: FloatArray,
    direction: FloatArray,
    half_length: FloatArray,
    speed: FloatArray,
) -> tuple[np.ndarray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, np.ndarray]:
    """Per waiting slot: (red, gap, gap seen, critical gap, phase, waited, red violator).

    Red applies to the zebra's signal, so not to jaywalkers; the gap seen by a distracted pedestrian is
    the one of `DISTRACTED_LOOK_DELAY` seconds ago.
    """
    red = np.empty(waiting.shape[0], np.bool_)
    for k in range(waiting.shape[0]):
        red[k] = signal_red and not jaywalker[waiting[k]]
    gap = _gaps(crossing_x, waiting, car_x, direction, half_length, speed)
    seen = gap + DISTRACTED_LOOK_DELAY * distracted[waiting]
    return red, gap, seen, critical_gap[waiting], phase[waiting], wait_time[waiting], red_violator[waiting]


@njit(cache=True, nogil=True)
def _begin_transitions(
    position: FloatArray,
    velocity: FloatArray,
    waypoint: FloatArray,
    state: np.ndarray,
    intends: np.ndarray,
    group: np.ndarray,
    side: np.ndarray,
    kerb_south: float,
    kerb_north: float,
    wait_time: FloatArray,
    turning_back: np.ndarray,
    dt: float,
    hesitate_at: FloatArray,
    turn_back_at: FloatArray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, bool]:
    """The step's transitions up to the decisions, in one call.

    Returns (arrived, states before, still waiting, crossing acts, whether any act starts). Acts only
    concern those crossing since before the step, whom the decisions cannot change.
    """
    arrived = _arrived(position, velocity, waypoint, state, intends, group, side, kerb_south, kerb_north)
    before, waiting = _start_waiting(state, arrived, wait_time, turning_back, dt)
    acts = _crossing_acts(before, position, side, hesitate_at, turn_back_at, kerb_south, kerb_north)
    return arrived, before, waiting, acts, acts.any()
