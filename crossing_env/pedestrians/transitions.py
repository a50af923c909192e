"""The pedestrian trip state machine's compiled kernels: arrivals, gaps, transitions, masks, walking inputs.

Deterministic per-step work over the whole pool, compiled with numba; the random draws and the pluggable
decision model stay in `crossing_env.pedestrians.population`, which calls these kernels. No kernel here calls
a kernel of another module (numba's disk cache would keep the callee's old code after an edit).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from crossing_env.types import FloatArray, PedState

# Plain ints for the hot path (IntEnum comparisons go through Python-level enum machinery).
INACTIVE, APPROACHING, WAITING, CROSSING, LEAVING = (int(state) for state in PedState)
HESITATES, TURNS_BACK = 1, 2
"""Flags of the irrational acts a crossing pedestrian can start in a step."""

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
LANE_GAP_MARGIN = 1.0
"""Seconds of margin a pedestrian keeps, lane by lane, between its own time in a lane and a car's (design
choice: about one human reaction time, so a driver who reacts late can still brake)."""
START_UP_TIME = 0.5
"""Seconds a pedestrian at the kerb loses getting up to walking speed (the social force's relaxation time)."""


@njit(cache=True, nogil=True)
def arrivals(
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
def gaps(
    crossing_x: FloatArray,
    rows: np.ndarray,
    car_x: FloatArray,
    direction: FloatArray,
    half_length: FloatArray,
    speed: FloatArray,
) -> FloatArray:
    """Time gap (s) until the first approaching car reaches the crossing line of each pedestrian at `rows`.

    Cars already past the line and stopped cars are ignored (every line spans the whole carriageway); a
    moving car whose body already covers the line gives a gap of 0.
    """
    out = np.full(rows.shape[0], np.inf)
    for k in range(rows.shape[0]):
        cx = crossing_x[rows[k]]
        for c in range(car_x.shape[0]):
            # Distance from the car's front to the pedestrian's line, along the car's travel direction.
            ahead = (cx - car_x[c]) * direction[c] - half_length[c]
            if ahead < 0:
                if ahead > -2 * half_length[c] - 0.5 and speed[c] > 0.3:
                    out[k] = 0.0  # a moving car's body covers the line (a stopped one is walked round)
            elif speed[c] > 0.3:
                out[k] = min(out[k], ahead / max(speed[c], 1e-3))
    return out


@njit(cache=True, nogil=True)
def lane_safe(
    rows: np.ndarray,
    crossing_x: FloatArray,
    side: FloatArray,
    walk_speed: FloatArray,
    radius: FloatArray,
    look_delay: FloatArray,
    car_x: FloatArray,
    car_lane: np.ndarray,
    direction: FloatArray,
    half_length: FloatArray,
    speed: FloatArray,
    lane_width: float,
    num_lanes: int,
) -> np.ndarray:
    """Per pedestrian at `rows`: whether every lane it must cross is free while it is in that lane.

    Lane by lane, the pedestrian's time in the lane (entering with its body edge, leaving with its far
    edge, at its own walking speed from a standstill at the kerb) is compared with the time each moving
    car occupies the pedestrian's line (front reaching it to rear leaving it, at constant speed, seen
    `look_delay` late): the two must be `LANE_GAP_MARGIN` apart. A car far enough away, or one that
    passes before the pedestrian reaches its lane, is no conflict; stopped cars are none either.
    """
    out = np.ones(rows.shape[0], np.bool_)
    for k in range(rows.shape[0]):
        i = rows[k]
        v = max(walk_speed[i], 0.3)
        r = radius[i]
        for c in range(car_x.shape[0]):
            if speed[c] <= 0.3:
                continue
            lane = min(max(car_lane[c], 0), num_lanes - 1)
            # Distance walked from the kerb standoff to enter / leave the lane (south side walks north).
            near = lane * lane_width if side[i] > 0 else (num_lanes - lane - 1) * lane_width
            t_in = START_UP_TIME + max(near + KERB_STANDOFF - r, 0.0) / v
            t_out = START_UP_TIME + (near + lane_width + KERB_STANDOFF + r) / v
            ahead = (crossing_x[i] - car_x[c]) * direction[c] - half_length[c]
            t_front = (ahead - r) / speed[c] + look_delay[k]
            t_rear = (ahead + 2.0 * half_length[c] + r) / speed[c] + look_delay[k]
            if t_rear > t_in - LANE_GAP_MARGIN and t_front < t_out + LANE_GAP_MARGIN:
                out[k] = False
                break
    return out


@njit(cache=True, nogil=True)
def start_waiting(
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
def crossing_acts(
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
def finish_transitions(
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
def walk_inputs(
    state: np.ndarray,
    hesitate_left: FloatArray,
    dwell_left: FloatArray,
    desired_speed: FloatArray,
    position: FloatArray,
    kerb_south: float,
    kerb_north: float,
    dt: float,
) -> tuple[np.ndarray, FloatArray, np.ndarray]:
    """Active slots, desired speeds and sidewalk constraint for the social-force step.

    Hesitating pedestrians and bystanders standing at their place want to stand (v0 = 0); the bystanders'
    dwell timers run down here. Waiting ones keep walking towards their kerb point
    (the arrival slow-down makes them stand there; with no attraction, the kerb repulsion would push them
    back). Only crossing pedestrians may be on the carriageway: everyone else is held on the sidewalk.
    (The step itself is `social_force.walk_step`, called from Python: kernels never call kernels of
    another module, whose changes numba's on-disk cache would not notice.)
    """
    rows = np.flatnonzero(state != INACTIVE)
    v0 = np.where((hesitate_left > 0) | (dwell_left > 0), 0.0, desired_speed)
    stay = np.empty(state.shape[0], dtype=np.bool_)
    for i in range(state.shape[0]):
        dwell_left[i] = max(0.0, dwell_left[i] - dt)
        on_road = kerb_south < position[i, 1] < kerb_north
        stay[i] = state[i] != CROSSING and not (state[i] == APPROACHING and on_road)
    return rows, v0, stay


@njit(cache=True, nogil=True)
def detour(
    state: np.ndarray,
    position: FloatArray,
    velocity: FloatArray,
    waypoint: FloatArray,
    radius: FloatArray,
    boxes: FloatArray,
) -> None:
    """Crossing pedestrians held up by a vehicle standing on their line walk round it (waypoints in place).

    A crossing pedestrian slower than 0.3 m/s whose straight line to its far-kerb waypoint runs into a
    vehicle box within 1.5 m moves its waypoint's x past the nearer end of the box (plus its radius and
    0.3 m), instead of waiting behind the vehicle for as long as it stands there.
    """
    for i in range(state.shape[0]):
        if state[i] != CROSSING:
            continue
        vx, vy = velocity[i, 0], velocity[i, 1]
        if vx * vx + vy * vy > 0.09:
            continue
        x, y, r = position[i, 0], position[i, 1], radius[i]
        ty = waypoint[i, 1]
        for c in range(boxes.shape[0]):
            x0, y0, x1, y1 = boxes[c, 0], boxes[c, 1], boxes[c, 2], boxes[c, 3]
            if not (x0 - r < x < x1 + r):
                continue
            ahead = y0 - (y + r) if ty > y else (y - r) - y1
            if -r < ahead < 1.5:
                left, right = x0 - r - 0.3, x1 + r + 0.3
                waypoint[i, 0] = left if x - left < right - x else right
                break


@njit(cache=True, nogil=True)
def geometric_masks(
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
def waiting_context(
    waiting: np.ndarray,
    signal_red: bool,
    jaywalker: np.ndarray,
    distracted: np.ndarray,
    critical_gap: FloatArray,
    phase: FloatArray,
    wait_time: FloatArray,
    red_violator: np.ndarray,
    crossing_x: FloatArray,
    side: FloatArray,
    walk_speed: FloatArray,
    radius: FloatArray,
    car_x: FloatArray,
    car_lane: np.ndarray,
    direction: FloatArray,
    half_length: FloatArray,
    speed: FloatArray,
    lane_width: float,
    num_lanes: int,
) -> tuple[np.ndarray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, np.ndarray, np.ndarray]:
    """Per waiting slot: (red, gap, gap seen, critical gap, phase, waited, red violator, lanes safe).

    Red applies to the zebra's signal, so not to jaywalkers; the gap seen by a distracted pedestrian is
    the one of `DISTRACTED_LOOK_DELAY` seconds ago. "Lanes safe" is `lane_safe` with that late look; a
    pedestrian who does not look (critical gap 0, children running out) skips the check.
    """
    red = np.empty(waiting.shape[0], np.bool_)
    for k in range(waiting.shape[0]):
        red[k] = signal_red and not jaywalker[waiting[k]]
    gap = gaps(crossing_x, waiting, car_x, direction, half_length, speed)
    delay = DISTRACTED_LOOK_DELAY * distracted[waiting]
    seen = gap + delay
    safe = lane_safe(
        waiting,
        crossing_x,
        side,
        walk_speed,
        radius,
        delay,
        car_x,
        car_lane,
        direction,
        half_length,
        speed,
        lane_width,
        num_lanes,
    )
    crit = critical_gap[waiting]
    safe |= crit <= 0.0
    return red, gap, seen, crit, phase[waiting], wait_time[waiting], red_violator[waiting], safe


@njit(cache=True, nogil=True)
def begin_transitions(
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
    arrived = arrivals(position, velocity, waypoint, state, intends, group, side, kerb_south, kerb_north)
    before, waiting = start_waiting(state, arrived, wait_time, turning_back, dt)
    acts = crossing_acts(before, position, side, hesitate_at, turn_back_at, kerb_south, kerb_north)
    return arrived, before, waiting, acts, acts.any()
