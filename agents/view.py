"""What the policies read: the observation parsed into batched arrays, and shared kinematics.

Geometry recovered from the observation (ego frame: heading +x, origin at the ego's centre):

- the stop line lies ``length / 2 + distance_to_stop_line`` ahead of the ego's centre;
- the crossing's far edge lies ``-distance_past_crossing - length / 2`` ahead;
- pedestrian slots give relative position and velocity; the ego's lane centre is at dy = 0.

Policies accept one observation (``obs[EGO_KEY]`` of shape (6,), action (1,)) or a batch with any leading
axes (``obs[EGO_KEY]`` (..., 6), action (..., 1)), so they drive Gymnasium vector envs directly. Keys and
columns are read by their names in `crossing_env.observation`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

from agents.config import DrivingConfig
from crossing_env.env import acceleration_to_action
from crossing_env.observation import (
    CROSSING_INTENT_KEY,
    CROSSING_INTENTION_KEY,
    EGO_KEY,
    HISTORY_INTERVAL,
    PEDESTRIAN_TRACKS_KEY,
    PEDESTRIANS_KEY,
    PREDICTED_PATHS_KEY,
    VEHICLES_KEY,
    EgoColumn,
    PedestrianColumn,
    PointColumn,
    VehicleColumn,
)

ObsLike = Mapping[str, Any]

EPS = 1e-6
_EGO, _PED, _VEH = len(EgoColumn), len(PedestrianColumn), len(VehicleColumn)


@dataclass
class View:
    """Flattened batch view of an observation: leading axes folded into B."""

    lead: tuple[int, ...]
    speed: np.ndarray  # (B,)
    to_stop: np.ndarray  # (B,) ego front → stop line
    past: np.ndarray  # (B,) ego rear − crossing far edge
    car_green: np.ndarray  # (B,)
    zebra: np.ndarray  # (B,)
    present: np.ndarray  # (B, K) bool
    px: np.ndarray  # (B, K)
    py: np.ndarray
    vx: np.ndarray
    vy: np.ndarray
    on_crossing: np.ndarray  # (B, K) bool
    waiting: np.ndarray
    on_road: np.ndarray
    vehicles: np.ndarray  # (B, M, 7) columns `VehicleColumn`
    intention: np.ndarray | None  # (B, K)
    paths: np.ndarray | None  # (B, K, T, 2)
    intent: np.ndarray | None = None  # (B, K) P(means to cross at all), from ``crossing_intent`` if given
    tracks: np.ndarray | None = None  # (B, K) int64 track ids (0: empty slot), from ``pedestrian_tracks``


def parse_observation(obs: ObsLike) -> View:
    """Parse a single or batched observation into (B, ...) float64 arrays; raise on a bad layout."""
    for key in (EGO_KEY, PEDESTRIANS_KEY):
        if key not in obs:
            raise KeyError(f"policy observation lacks {key!r}; got keys {sorted(obs)}")
    ego = np.asarray(obs[EGO_KEY], dtype=np.float64)
    if ego.ndim < 1 or ego.shape[-1] != _EGO:
        raise ValueError(f"obs[{EGO_KEY!r}] must have shape (..., {_EGO}), got {ego.shape}")
    lead = ego.shape[:-1]
    ego = ego.reshape(-1, _EGO)
    b = ego.shape[0]
    ped = np.asarray(obs[PEDESTRIANS_KEY], dtype=np.float64)
    if ped.shape[: len(lead)] != lead or ped.ndim != len(lead) + 2 or ped.shape[-1] != _PED:
        raise ValueError(f"obs[{PEDESTRIANS_KEY!r}] must have shape {(*lead, 'K', _PED)}, got {ped.shape}")
    ped = ped.reshape(b, -1, _PED)
    k = ped.shape[1]
    if VEHICLES_KEY in obs:
        veh = np.asarray(obs[VEHICLES_KEY], dtype=np.float64).reshape(b, -1, _VEH)
    else:
        veh = np.zeros((b, 0, _VEH))
    intention = obs.get(CROSSING_INTENTION_KEY)
    if intention is not None:
        intention = np.asarray(intention, dtype=np.float64).reshape(b, k)
    paths = obs.get(PREDICTED_PATHS_KEY)
    if paths is not None:
        paths = np.asarray(paths, dtype=np.float64)
        paths = paths.reshape(b, k, paths.shape[-2], len(PointColumn))
    intent = obs.get(CROSSING_INTENT_KEY)
    if intent is not None:
        intent = np.asarray(intent, dtype=np.float64).reshape(b, k)
    present = ped[..., PedestrianColumn.PRESENCE] > 0.5
    tracks = obs.get(PEDESTRIAN_TRACKS_KEY)
    if tracks is not None:
        ids = np.rint(np.asarray(tracks, dtype=np.float64).reshape(b, k))
        tracks = np.where(present, ids, 0).astype(np.int64)
    return View(
        lead=lead,
        speed=ego[:, EgoColumn.SPEED],
        to_stop=ego[:, EgoColumn.DISTANCE_TO_STOP_LINE],
        past=ego[:, EgoColumn.DISTANCE_PAST_CROSSING],
        car_green=ego[:, EgoColumn.CAR_GREEN],
        zebra=ego[:, EgoColumn.ZEBRA],
        present=present,
        px=ped[..., PedestrianColumn.DX],
        py=ped[..., PedestrianColumn.DY],
        vx=ped[..., PedestrianColumn.VX],
        vy=ped[..., PedestrianColumn.VY],
        on_crossing=present & (ped[..., PedestrianColumn.ON_CROSSING] > 0.5),
        waiting=present & (ped[..., PedestrianColumn.WAITING] > 0.5),
        on_road=present & (ped[..., PedestrianColumn.ON_ROAD] > 0.5),
        vehicles=veh,
        intention=intention,
        paths=paths,
        intent=intent,
        tracks=tracks,
    )


def finish(accel: np.ndarray, view: View, cfg: DrivingConfig) -> np.ndarray:
    """Acceleration (B,) → normalised float32 action of shape (*lead, 1)."""
    return acceleration_to_action(accel, cfg.ego).reshape(*view.lead, 1)


def cruise(view: View, cfg: DrivingConfig, target: np.ndarray | float | None = None) -> np.ndarray:
    """Proportional speed control towards `target` (default: the speed limit), bounded comfortably."""
    goal = cfg.speed_limit if target is None else target
    return np.clip(
        cfg.cruise_gain * (goal - view.speed), -cfg.idm_comfortable_deceleration, cfg.cruise_acceleration
    )


def follow(view: View, cfg: DrivingConfig) -> np.ndarray:
    """IDM acceleration (B,) behind the nearest vehicle ahead in the ego's lane (+inf when none)."""
    veh = view.vehicles
    if veh.shape[1] == 0:
        return np.full(view.speed.shape, np.inf)
    dx = veh[..., VehicleColumn.DX]
    ahead = (
        (veh[..., VehicleColumn.PRESENCE] > 0.5)
        & (np.abs(veh[..., VehicleColumn.DY]) < cfg.lane_width / 2)
        & (dx > 0.0)
    )
    if not ahead.any():  # nobody to follow (most steps): the same +inf, without the IDM arithmetic
        return np.full(view.speed.shape, np.inf)
    gap = dx - cfg.ego_length / 2 - veh[..., VehicleColumn.LENGTH] / 2
    gap = np.where(ahead, gap, np.inf)
    j = np.argmin(gap, axis=1)
    rows = np.arange(gap.shape[0])
    s = np.maximum(gap[rows, j], 0.1)
    lead_v = veh[rows, j, VehicleColumn.VX]
    v = view.speed
    a_max, b = cfg.cruise_acceleration, cfg.idm_comfortable_deceleration
    s_star = cfg.idm_min_gap + np.maximum(
        0.0, v * cfg.idm_time_headway + v * (v - lead_v) / (2 * np.sqrt(a_max * b))
    )
    v0 = max(cfg.speed_limit, EPS)
    acc = a_max * (1.0 - (v / v0) ** 4 - (s_star / s) ** 2)
    acc = np.maximum(acc, -cfg.ego.max_deceleration)
    return np.where(np.isfinite(gap[rows, j]), acc, np.inf)


def travel_time(dist: np.ndarray, v: np.ndarray, accel: float, v_max: float) -> np.ndarray:
    """Time to cover `dist` (≥ 0; ≤ 0 gives 0) from speed v accelerating at `accel` up to `v_max`.

    Computed in float64 (the views `parse_observation` builds are float64).
    """
    d = np.maximum(dist, 0.0)
    v = np.broadcast_to(v, d.shape)
    if accel <= 0.0:
        with np.errstate(divide="ignore"):
            return np.where(d <= 0.0, 0.0, np.where(v > EPS, d / np.maximum(v, EPS), np.inf))
    out = np.empty(d.shape)
    _travel_time_kernel(*_flat(d, v), float(accel), float(v_max), out.reshape(-1))
    return out


def _flat(*arrays: np.ndarray) -> list[np.ndarray]:
    """Contiguous flat float64 copies (or views) of same-shaped arrays, as the kernels below take them."""
    return [np.ascontiguousarray(x, dtype=np.float64).reshape(-1) for x in arrays]


@njit(cache=True, nogil=True, error_model="numpy")
def _numpy_pick(a: float, b: float, a_wins: bool) -> float:
    """What `np.maximum` / `np.minimum` return for two floats, given whether `a` compares better.

    A NaN operand is returned itself (the first if both are NaN); otherwise `a` if it wins, else `b` (so
    `b` on a tie, as numpy: ±0). Not `crossing_env.safety.geometry`'s `_nan_max` / `_nan_min`, which keep
    `a` on a tie: the sign of a zero would differ from the numpy forms these kernels replace.
    """
    if a != a:
        return a
    if b != b:
        return b
    return a if a_wins else b


@njit(cache=True, nogil=True, error_model="numpy")
def _nan_max(a: float, b: float) -> float:
    """`np.maximum` of two floats, as numpy gives it (`_numpy_pick`)."""
    return _numpy_pick(a, b, a > b)


@njit(cache=True, nogil=True, error_model="numpy")
def _nan_min(a: float, b: float) -> float:
    """`np.minimum` of two floats, as numpy gives it (`_numpy_pick`)."""
    return _numpy_pick(a, b, a < b)


@njit(cache=True, nogil=True, error_model="numpy")
def _travel_time_kernel(d: np.ndarray, v: np.ndarray, accel: float, v_max: float, out: np.ndarray) -> None:
    """`travel_time` for accel > 0 on flat arrays, bit-identical to its numpy form.

    Accelerate from v to max(v_max, v), then cruise; the same floating-point operations in the same order.
    """
    for i in range(d.shape[0]):
        vi, di = v[i], d[i]
        vm = _nan_max(v_max, vi)
        t1 = (vm - vi) / accel
        d1 = 0.5 * (vi + vm) * t1
        t_acc = (-vi + np.sqrt(vi * vi + 2.0 * accel * di)) / accel
        t_cru = t1 + (di - d1) / _nan_max(vm, EPS)
        out[i] = t_acc if di <= d1 else t_cru


def braking_travel_time(dist: np.ndarray, v: np.ndarray, decel: np.ndarray) -> np.ndarray:
    """Time to cover `dist` (≤ 0 gives 0) from speed v braking at `decel` (> 0); inf if it stops short."""
    d = np.maximum(dist, 0.0)
    v = np.broadcast_to(v, d.shape)
    disc = v * v - 2.0 * decel * d
    t = (v - np.sqrt(np.maximum(disc, 0.0))) / decel
    return np.where(d <= 0.0, 0.0, np.where(disc >= 0.0, t, np.inf))


def corridor_interval(py: np.ndarray, vy: np.ndarray, half_width: float) -> tuple[np.ndarray, np.ndarray]:
    """When a constant-velocity pedestrian is inside |y| ≤ half_width: (t_in, t_out); t_in = inf if never.

    Computed in float64 (the views `parse_observation` builds are float64).
    """
    py, vy = np.broadcast_arrays(py, vy)
    t_in, t_out = np.empty(py.shape), np.empty(py.shape)
    _corridor_kernel(*_flat(py, vy), float(half_width), t_in.reshape(-1), t_out.reshape(-1))
    return t_in, t_out


@njit(cache=True, nogil=True, error_model="numpy")
def _corridor_kernel(
    py: np.ndarray, vy: np.ndarray, half_width: float, t_in: np.ndarray, t_out: np.ndarray
) -> None:
    """`corridor_interval` on flat arrays, bit-identical to its numpy form.

    A pedestrian moving across (|vy| > 1e-3) is inside between the two edge crossings, one standing inside
    always, one standing outside never; the same floating-point operations in the same order.
    """
    for i in range(py.shape[0]):
        p, w = py[i], vy[i]
        if abs(w) > 1e-3:
            ta = (-half_width - p) / w
            tb = (half_width - p) / w
            enter = _nan_max(_nan_min(ta, tb), 0.0)
            leave = _nan_max(ta, tb)
        elif abs(p) <= half_width:
            enter, leave = 0.0, math.inf
        else:
            enter, leave = math.inf, -math.inf
        never = leave < enter
        t_in[i] = math.inf if never else enter
        t_out[i] = -math.inf if never else leave


def path_interval(
    paths: np.ndarray, present: np.ndarray, half_width: float, min_x: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Corridor entry/exit times and entry x from predicted paths (B, K, T, 2), `HISTORY_INTERVAL` apart."""
    t = HISTORY_INTERVAL * np.arange(1, paths.shape[2] + 1)
    px, py = paths[..., PointColumn.X], paths[..., PointColumn.Y]
    inside = (np.abs(py) <= half_width) & (px > min_x) & present[..., None]
    any_in = inside.any(axis=2)
    first = np.argmax(inside, axis=2)
    last = paths.shape[2] - 1 - np.argmax(inside[..., ::-1], axis=2)
    t_in = np.where(any_in, t[first] - HISTORY_INTERVAL, np.inf)
    t_out = np.where(any_in, t[last], -np.inf)
    x_in = np.take_along_axis(px, first[..., None], axis=2)[..., 0]
    return t_in, t_out, x_in


def stop_acceleration(
    view: View, distance: np.ndarray, decel: float, gain: float, max_decel: float
) -> np.ndarray:
    """Acceleration that brings the car to rest `distance` ahead (B,), braking as late as `decel` allows.

    Below the braking profile v = sqrt(2·decel·s) it returns the profile-tracking term (usually larger
    than the cruise term, so `min` with it is neutral); above it, the exact constant deceleration v²/(2s),
    so a late stop brakes only as hard as needed (up to `max_decel`). Computed in float64 (the views
    `parse_observation` builds are float64).
    """
    v = view.speed
    s = np.asarray(distance, dtype=np.float64)
    if (s == np.inf).all() and max_decel == max_decel:  # no target (most steps): +inf, as the kernel gives
        return np.full(np.broadcast_shapes(s.shape, v.shape), np.inf)
    s, v = np.broadcast_arrays(s, v)
    out = np.empty(s.shape)
    _stop_kernel(*_flat(s, v), float(decel), float(gain), float(max_decel), out.reshape(-1))
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _stop_kernel(
    s: np.ndarray, v: np.ndarray, decel: float, gain: float, max_decel: float, out: np.ndarray
) -> None:
    """`stop_acceleration` on flat arrays, bit-identical to its numpy form (the same operations in order)."""
    for i in range(s.shape[0]):
        si, vi = s[i], v[i]
        v_allow = np.sqrt(2.0 * decel * _nan_max(si, 0.0))
        # Past the target (s < 0) it is too late for a planned stop: brake fully. Within the last 5 cm the
        # distance is floored, so a creeping car is not asked for an absurd deceleration.
        if si >= 0.0:
            a_req = vi * vi / (2.0 * _nan_max(si, 0.05))
        else:
            a_req = math.inf if vi > 0.05 else 0.0
        acc = -a_req if a_req > decel else gain * (v_allow - vi)
        if not np.isfinite(si):
            acc = math.inf
        if si <= 0.3 and vi <= 0.1:  # at the target: hold still
            acc = -decel
        out[i] = _nan_max(acc, -max_decel)
