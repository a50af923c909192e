"""The compiled passes of the traffic: the IDM law, the background drivers' accelerations, motion, despawn.

They live together in one module because they call each other: numba's on-disk cache of a kernel is only
refreshed when the kernel's own file changes, so kernels never call kernels defined in another module.
`crossing_env.traffic.Traffic` calls them from Python.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from crossing_env.types import FloatArray
from scenarios.config import IDMConfig

PEDESTRIAN_LOOKAHEAD = 50.0
"""Drivers react to pedestrians on the carriageway within this distance ahead (m)."""
PATH_MARGIN = 1.5
"""Seconds: a driver brakes for a crossing pedestrian who will reach its lane before, or up to this long
after, the car has passed the pedestrian's line (design choice: a reaction time plus a little)."""
ASSUMED_WALK_SPEED = 1.4
"""Lateral speed (m/s) a driver assumes for a crossing pedestrian who is walking slower (hesitating)."""
YIELD_DECELERATION = 3.0
"""Deceleration (m/s²) a yielding driver accepts to stop for a zebra: "can stop comfortably" (rule 195 /
StVO §26); the same figure as `MetricsConfig.yield_deceleration`."""
CROSSING_STATE = 3
"""`PedState.CROSSING` as a plain int for the kernel."""

# ---------------------------------------------------------------------- car following
# Intelligent Driver Model (Treiber, Hennecke & Helbing 2000). highway-env's per-vehicle Python objects are
# what make its crossing-free intersections run at about 17 steps/s; here one compiled call advances every
# vehicle. The law lives in this module because the leader-search kernel below calls it: numba's on-disk
# cache of a kernel is only refreshed when the kernel's own file changes, so kernels never call kernels
# defined in another module.


def idm_parameters(params: IDMConfig) -> tuple[float, float, float, float, float, float]:
    """The config as the tuple the compiled functions take: (a, b, max deceleration, T, s0, δ)."""
    return (
        float(params.max_acceleration),
        float(params.comfortable_deceleration),
        float(params.max_deceleration),
        float(params.time_headway),
        float(params.min_gap),
        float(params.delta),
    )


@njit(cache=True, nogil=True)
def idm_scalar(
    speed: float,
    desired_speed: float,
    gap: float,
    leader_speed: float,
    params: tuple[float, float, float, float, float, float],
) -> float:
    """IDM acceleration of one vehicle (as `idm_acceleration`; `params` from `idm_parameters`)."""
    a, b, max_deceleration, time_headway, min_gap, delta = params
    free = 1.0 - (max(speed, 0.0) / max(desired_speed, 1e-3)) ** delta
    s_star = min_gap + max(
        0.0, speed * time_headway + speed * (speed - leader_speed) / (2.0 * math.sqrt(a * b))
    )
    interaction = (s_star / max(gap, 1e-2)) ** 2 if math.isfinite(gap) else 0.0
    return min(max(a * (free - interaction), -max_deceleration), a)


@njit(cache=True, nogil=True)
def _idm_all(
    speed: FloatArray,
    desired_speed: FloatArray,
    gap: FloatArray,
    leader_speed: FloatArray,
    params: tuple[float, float, float, float, float, float],
) -> FloatArray:
    out = np.empty(speed.shape[0])
    for i in range(speed.shape[0]):
        out[i] = idm_scalar(speed[i], desired_speed[i], gap[i], leader_speed[i], params)
    return out


def idm_acceleration(
    speed: FloatArray,
    desired_speed: FloatArray,
    gap: FloatArray,
    leader_speed: FloatArray,
    params: IDMConfig,
) -> FloatArray:
    """IDM acceleration for every vehicle.

    Args:
        speed: (N,) own speeds, m/s.
        desired_speed: (N,) desired speeds v0, m/s.
        gap: (N,) bumper-to-bumper distance to the leader (or obstacle), metres; `inf` for a free road.
        leader_speed: (N,) speed of the leader (0 for a stop line or pedestrian), m/s.
        params: IDM parameters.

    Returns:
        (N,) accelerations, clipped to [−max_deceleration, max_acceleration].
    """
    arrays = (np.ascontiguousarray(v, dtype=np.float64) for v in (speed, desired_speed, gap, leader_speed))
    return _idm_all(*arrays, idm_parameters(params))


@njit(cache=True, nogil=True)
def _background_accelerations(
    x: FloatArray,
    direction: FloatArray,
    lane: np.ndarray,
    speed: FloatArray,
    length: FloatArray,
    desired_speed: FloatArray,
    active: np.ndarray,
    parked: np.ndarray,
    gives_way: np.ndarray,
    ped_positions: FloatArray,
    ped_velocities: FloatArray,
    ped_on_road: np.ndarray,
    ped_state: np.ndarray,
    ped_target_y: FloatArray,
    ped_radius: FloatArray,
    everyone_stops: bool,
    lane_width: float,
    num_lanes: int,
    stop_x_forward: float,
    stop_x_backward: float,
    idm: tuple[float, float, float, float, float, float],
) -> FloatArray:
    """Per slot: the nearest obstacle ahead (leader in lane, pedestrian in its path, stop line), then IDM.

    Positions are measured along each car's own travel direction (`s = x · direction`); parked and free
    slots get 0. Ties between equally close leaders go to the lower slot.

    A pedestrian is in a car's path when it is on the carriageway (or has just started crossing) and its
    body covers the car's lane, or its walk towards its target will bring it into the lane before the car
    has passed its line (plus `PATH_MARGIN`). Every driver, yielder or not, treats such a pedestrian as a
    standing obstacle; IDM then brakes up to the maximum deceleration.
    """
    n = x.shape[0]
    acc = np.zeros(n)
    for i in range(n):
        if not active[i] or parked[i]:
            continue
        d = direction[i]
        s = x[i] * d
        half = length[i] / 2
        gap, lead_speed = np.inf, 0.0
        # Leader in the same lane (the ego included; parked cars stand off the lane).
        for j in range(n):
            if j == i or not active[j] or parked[j] or lane[j] != lane[i]:
                continue
            ahead = x[j] * d - s
            if ahead > 0:
                bumper = ahead - half - length[j] / 2
                if bumper < gap:
                    gap, lead_speed = bumper, speed[j]
        # Pedestrians in the car's path ahead.
        lane_lo, lane_hi = lane[i] * lane_width, (lane[i] + 1) * lane_width
        for k in range(ped_positions.shape[0]):
            if not (ped_on_road[k] or ped_state[k] == CROSSING_STATE):
                continue
            r = ped_radius[k]
            dist = ped_positions[k, 0] * d - s - half - r
            if not (-half - 2 * r < dist < PEDESTRIAN_LOOKAHEAD):
                continue
            y, ty = ped_positions[k, 1], ped_target_y[k]
            if y + r > lane_lo and y - r < lane_hi:
                in_path = True  # in the lane now
            elif min(y, ty) - r < lane_hi and max(y, ty) + r > lane_lo:
                # Will walk into the lane: when, at its lateral speed (or a brisk walk if it is slower)?
                lateral = lane_lo - (y + r) if ty > y else (y - r) - lane_hi
                towards = ped_velocities[k, 1] if ty > y else -ped_velocities[k, 1]
                t_ped = max(lateral, 0.0) / max(towards, ASSUMED_WALK_SPEED)
                t_pass = (dist + length[i] + 2 * r) / max(speed[i], 0.1)
                in_path = t_ped < t_pass + PATH_MARGIN
            else:
                in_path = False
            if in_path:
                ped_gap = max(dist, 0.01)
                if ped_gap < gap:
                    gap, lead_speed = ped_gap, 0.0
        if everyone_stops or gives_way[i]:
            stop_s = stop_x_forward if d > 0 else -stop_x_backward
            to_line = stop_s - (s + half)
            braking = YIELD_DECELERATION if not everyone_stops else idm[2] * 0.6
            can_stop = to_line > speed[i] ** 2 / (2 * braking) or (to_line > -0.5 and speed[i] < 1.0)
            line_gap = max(to_line, 0.01)
            if can_stop and to_line > -1.0 and line_gap < gap:
                gap, lead_speed = line_gap, 0.0
        acc[i] = idm_scalar(speed[i], desired_speed[i], gap, lead_speed, idm)
    return acc


@njit(cache=True, nogil=True)
def _boxes(
    x: FloatArray, y: FloatArray, length: FloatArray, width: FloatArray, mask: np.ndarray
) -> FloatArray:
    """(k, 4) boxes [x_min, y_min, x_max, y_max] of the masked slots."""
    rows = np.flatnonzero(mask)
    out = np.empty((rows.shape[0], 4))
    for k in range(rows.shape[0]):
        i = rows[k]
        hl, hw = length[i] / 2, width[i] / 2
        out[k, 0], out[k, 1], out[k, 2], out[k, 3] = x[i] - hl, y[i] - hw, x[i] + hl, y[i] + hw
    return out


@njit(cache=True, nogil=True)
def _moving(
    x: FloatArray,
    direction: FloatArray,
    speed: FloatArray,
    length: FloatArray,
    lane: np.ndarray,
    active: np.ndarray,
    parked: np.ndarray,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, np.ndarray]:
    """`Traffic.moving` without a numpy call per field."""
    rows = np.flatnonzero(active & ~parked)
    return x[rows], direction[rows], speed[rows], length[rows] / 2, lane[rows]


@njit(cache=True, nogil=True)
def _advance(
    x: FloatArray,
    y: FloatArray,
    speed: FloatArray,
    direction: FloatArray,
    active: np.ndarray,
    parked: np.ndarray,
    acceleration: FloatArray,
    dt: float,
    ego_max_speed: float,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """`Traffic.advance`: (start positions, mean velocities, new x, new speed, realised acceleration).

    Parked and free slots stand still; the ego (slot 0) is capped at its maximum speed. The realised
    acceleration is clipped at standstill (no reversing), for metrics.
    """
    n = x.shape[0]
    start, velocity = np.empty((n, 2)), np.zeros((n, 2))
    new_x, new_speed, realised = np.empty(n), np.empty(n), np.empty(n)
    for i in range(n):
        v = max(0.0, speed[i] + acceleration[i] * dt)
        if i == 0:
            v = min(v, ego_max_speed)
        if parked[i] or not active[i]:
            v = 0.0
        realised[i] = (v - speed[i]) / dt
        new_x[i] = x[i] + 0.5 * (speed[i] + v) * dt * direction[i]
        new_speed[i] = v
        start[i, 0], start[i, 1] = x[i], y[i]
        velocity[i, 0] = (new_x[i] - x[i]) / dt
    return start, velocity, new_x, new_speed, realised


@njit(cache=True, nogil=True)
def _despawn(x: FloatArray, active: np.ndarray, ids: np.ndarray, road_length: float) -> None:
    """`Traffic.despawn_finished` in place; the ego (slot 0) always stays."""
    for i in range(1, x.shape[0]):
        if active[i] and (x[i] < -10.0 or x[i] > road_length + 10.0):
            active[i] = False
            ids[i] = -1
