"""Helbing & Molnár (1995) social force model for pedestrians, compiled with numba.

Accelerations of all pedestrians are computed in one call:

    a_i = (v0_i e_i − v_i) / τ                                   goal attraction with relaxation time τ
        + Σ_j w(φ_ij) k_p A exp((r_i + r_j − d_ij) / B_p) n_ij  pedestrian repulsion
        + Σ_c w(φ_ic) k_v A exp((r_i − d_ic) / B_v) n_ic          vehicle repulsion (distance to the box)
        + kerb repulsion for pedestrians that must stay on the sidewalk

with the anisotropy weight w(φ) = λ + (1 − λ)(1 + cos φ)/2 (Helbing et al. 2000): pedestrians react more
to what is in front of them. The intensities k_p = 0.42 and k_v = 0.71 are the seed paper's calibration
(Song et al. 2022, Case 2); `A` and the ranges `B` are ours (see `SocialForceConfig`): the paper gives
relative intensities only. Departure: we use the exponential "circular specification" rather than the
elliptical potential of the 1995 paper, which is the form most implementations and calibrations use.

Why numba rather than numpy broadcasting: with the few to few dozen pedestrians of a crossing, the (P, P)
numpy version spent its time in the ~40 array operations' fixed overheads (120 µs at 5 pedestrians), while
the compiled loop takes a few µs; it is also the tool PySocialForce, the reference Python implementation,
uses. The kernel is cached on disk (`cache=True`), so only the first import on a machine compiles it.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from crossing_env.types import BoolArray, FloatArray
from scenarios.config import SocialForceConfig

_MIN_EXPONENT = -30.0
"""Exponents are clipped here: exp(−30) ≈ 1e-13 is negligible, and it keeps far-apart pairs out of the
subnormal range, where floating-point arithmetic is orders of magnitude slower."""


def social_force_acceleration(
    positions: FloatArray,
    velocities: FloatArray,
    goals: FloatArray,
    desired_speeds: FloatArray,
    radii: FloatArray,
    stay_on_sidewalk: BoolArray,
    vehicle_boxes: FloatArray,
    kerbs: tuple[float, float],
    params: SocialForceConfig,
    ped_intensity: FloatArray | float | None = None,
) -> FloatArray:
    """Social force acceleration of each pedestrian.

    Args:
        positions: (P, 2) pedestrian centres.
        velocities: (P, 2) current velocities.
        goals: (P, 2) current waypoints.
        desired_speeds: (P,) desired speeds (0 to stand still).
        radii: (P,) body radii.
        stay_on_sidewalk: (P,) pedestrians repelled from the kerb edge (not crossing).
        vehicle_boxes: (C, 4) axis-aligned vehicle boxes [x_min, y_min, x_max, y_max].
        kerbs: (south, north) kerb y coordinates; the carriageway lies between them.
        params: model parameters.
        ped_intensity: optional per-pedestrian ped–ped intensity (QLB-updated, seed Case 2).

    Returns:
        (P, 2) accelerations in m/s².
    """
    n = positions.shape[0]
    if n == 0:
        return np.zeros((0, 2))
    k_p = np.broadcast_to(
        np.asarray(params.ped_intensity if ped_intensity is None else ped_intensity, dtype=np.float64), (n,)
    )
    return _social_force_kernel(
        np.arange(n),
        np.ascontiguousarray(positions, dtype=np.float64),
        np.ascontiguousarray(velocities, dtype=np.float64),
        np.ascontiguousarray(goals, dtype=np.float64),
        np.ascontiguousarray(desired_speeds, dtype=np.float64),
        np.ascontiguousarray(radii, dtype=np.float64),
        np.ascontiguousarray(stay_on_sidewalk, dtype=np.bool_),
        np.ascontiguousarray(vehicle_boxes, dtype=np.float64).reshape(-1, 4),
        float(kerbs[0]),
        float(kerbs[1]),
        np.ascontiguousarray(k_p),
        model_parameters(params),
    )


def model_parameters(params: SocialForceConfig) -> tuple[float, ...]:
    """The config as the tuple the kernels take: (τ, A, B_p, B_v, k_v, λ, kerb strength, kerb range)."""
    return (
        float(params.relaxation_time),
        float(params.base_strength),
        float(params.ped_range),
        float(params.vehicle_range),
        float(params.vehicle_intensity),
        float(params.anisotropy),
        float(params.kerb_strength),
        float(params.kerb_range),
    )


@njit(cache=True, nogil=True)
def walk_step(
    rows: np.ndarray,
    pos: FloatArray,
    vel: FloatArray,
    goals: FloatArray,
    desired: FloatArray,
    radii: FloatArray,
    stay: BoolArray,
    boxes: FloatArray,
    south: float,
    north: float,
    k_p: FloatArray,
    dt: float,
    max_speed_factor: float,
    params: tuple[float, float, float, float, float, float, float, float],
) -> None:
    """Advance the velocities of pool `rows` by one step of the social force, in place.

    The same as `social_force_acceleration` on the gathered rows, an explicit Euler velocity update, and
    the speed scaled down to at most `max(desired, 0.05) · max_speed_factor`, without the gathers (a
    pedestrian pool is mostly addressed through its active rows).
    """
    acc = _social_force_kernel(rows, pos, vel, goals, desired, radii, stay, boxes, south, north, k_p, params)
    for k in range(rows.shape[0]):
        i = rows[k]
        vx, vy = vel[i, 0] + acc[k, 0] * dt, vel[i, 1] + acc[k, 1] * dt
        scale = min(1.0, max(desired[i], 0.05) * max_speed_factor / max(math.sqrt(vx * vx + vy * vy), 1e-9))
        vel[i, 0] = vx * scale
        vel[i, 1] = vy * scale


@njit(cache=True, nogil=True)
def _stable_argsort(values: FloatArray) -> np.ndarray:
    """``np.argsort(values, kind="mergesort")`` (NaN last, ties in index order), exactly.

    A plain bottom-up merge sort: numba's generic one costs about 3 s of compilation on an empty cache. A
    stable sort's permutation is fixed by its order, so the indices are NumPy's. Kept in each module that
    sorts (numba refreshes a cached kernel only when its own file changes).
    """
    n = values.shape[0]
    order = np.empty(n, np.int64)
    for i in range(n):
        order[i] = i
    spare = np.empty(n, np.int64)
    width = 1
    while width < n:
        for lo in range(0, n, 2 * width):
            mid, hi = min(lo + width, n), min(lo + 2 * width, n)
            i, j = lo, mid
            for k in range(lo, hi):
                if j < hi and i < mid:
                    a, b = values[order[j]], values[order[i]]
                    take_right = a < b or (np.isnan(b) and not np.isnan(a))  # strictly before
                else:
                    take_right = j < hi
                if take_right:
                    spare[k] = order[j]
                    j += 1
                else:
                    spare[k] = order[i]
                    i += 1
        order, spare = spare, order
        width *= 2
    return order


@njit(cache=True, nogil=True)
def _social_force_kernel(
    rows: np.ndarray,
    pos: FloatArray,
    vel: FloatArray,
    goals: FloatArray,
    desired: FloatArray,
    radii: FloatArray,
    stay: BoolArray,
    boxes: FloatArray,
    south: float,
    north: float,
    k_p: FloatArray,
    params: tuple[float, float, float, float, float, float, float, float],
) -> FloatArray:
    """The model of the module docstring for the pedestrians at `rows` of the arrays, one at a time.

    Compiled: no (P, P) temporaries. Returns (len(rows), 2); `k_p` is indexed like the arrays.

    Pairs whose exponent is below `_MIN_EXPONENT` (centres more than ~9 m apart) are skipped: their term is
    below 1e-11 m/s².
    """
    tau, base, ped_range, vehicle_range, vehicle_intensity, lam, kerb_strength, kerb_range = params
    n = rows.shape[0]
    acc = np.empty((n, 2))
    # Neighbours are scanned outwards in x order and the scan stops once |dx| alone puts the exponent below
    # the cut-off: the same pairs contribute as in an all-pairs loop, at a near-linear cost in long crowds.
    xs = np.empty(n)
    r_max = 0.0
    for k in range(n):
        xs[k] = pos[rows[k], 0]
        r_max = max(r_max, radii[rows[k]])
    order = _stable_argsort(xs)
    rank = np.empty(n, np.int64)
    for k in range(n):
        rank[order[k]] = k
    for row in range(n):
        i = rows[row]
        x, y = pos[i, 0], pos[i, 1]
        gx, gy = goals[i, 0] - x, goals[i, 1] - y
        dist_goal = math.sqrt(gx * gx + gy * gy)
        ex, ey = (gx / dist_goal, gy / dist_goal) if dist_goal > 1e-6 else (0.0, 0.0)
        # Slow down on arrival so pedestrians stop at waypoints instead of orbiting them.
        v0 = desired[i] * min(1.0, dist_goal / 0.5)
        vx, vy = vel[i, 0], vel[i, 1]
        ax = (v0 * ex - vx) / tau
        ay = (v0 * ey - vy) / tau
        speed = math.sqrt(vx * vx + vy * vy)
        hx, hy = (vx / speed, vy / speed) if speed > 0.05 else (ex, ey)
        # Anisotropy w(φ) = λ + (1 − λ)(1 + cos φ)/2 with cos φ = −heading · n_ij.
        fx = fy = 0.0
        reach = radii[i] + r_max - _MIN_EXPONENT * ped_range
        for step in (-1, 1):
            k = rank[row] + step
            while 0 <= k < n:
                j = rows[order[k]]
                k += step
                dx, dy = x - pos[j, 0], y - pos[j, 1]  # from j to i
                if abs(dx) > reach:
                    break
                dist = math.sqrt(dx * dx + dy * dy)
                exponent = (radii[i] + radii[j] - dist) / ped_range
                if exponent < _MIN_EXPONENT:
                    continue
                inv = 1.0 / max(dist, 1e-9)
                w = lam + (1.0 - lam) * 0.5 * (1.0 - (hx * dx + hy * dy) * inv)
                f = w * base * math.exp(exponent) * inv
                fx += f * dx
                fy += f * dy
        ax += k_p[i] * fx
        ay += k_p[i] * fy
        fx = fy = 0.0
        for c in range(boxes.shape[0]):
            dx = x - min(max(x, boxes[c, 0]), boxes[c, 2])
            dy = y - min(max(y, boxes[c, 1]), boxes[c, 3])
            dist = math.sqrt(dx * dx + dy * dy)
            exponent = (radii[i] - dist) / vehicle_range
            if dist <= 1e-9 or exponent < _MIN_EXPONENT:
                continue  # inside the box contact physics takes over; far away the term is negligible
            inv = 1.0 / dist
            w = lam + (1.0 - lam) * 0.5 * (1.0 - (hx * dx + hy * dy) * inv)
            f = w * base * math.exp(exponent) * inv
            fx += f * dx
            fy += f * dy
        ax += vehicle_intensity * fx
        ay += vehicle_intensity * fy
        if stay[i]:
            # Distance from the body edge to the kerb it must not cross (negative once it steps over).
            below = y < 0.5 * (south + north)
            d = south - (y + radii[i]) if below else (y - radii[i]) - north
            push = min(kerb_strength * math.exp(max(-d / kerb_range, _MIN_EXPONENT)), 50.0)
            ay += -push if below else push
        acc[row, 0] = ax
        acc[row, 1] = ay
    return acc
