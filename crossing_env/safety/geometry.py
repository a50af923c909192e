"""Surrogate-safety geometry: TTC, DRAC, separation and occupancy intervals, vectorised.

Definitions follow the surrogate safety measures of SUMO's SSM device (Eclipse SUMO documentation,
"Simulation/Output/SSM Device"), with its names and defaults where they exist.
The ego and background vehicles are axis-aligned boxes (their heading is ±x), pedestrians are discs. All
predictions assume constant velocities over the horizon (the usual TTC convention).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import ArrayLike

__all__ = [
    "box_box_separation",
    "box_circle_separation",
    "box_circle_ttc",
    "crossing_drac",
    "following_drac",
    "following_ttc",
    "rect_occupancy_interval",
    "time_to_collision",
]

_INF = math.inf


# ---------------------------------------------------------------------------------------------------------
# Geometry (pure, vectorised with numpy broadcasting)
# ---------------------------------------------------------------------------------------------------------


def _scalar_or_array(x: np.ndarray) -> Any:
    """Return a Python float for 0-d results so scalar calls give scalars."""
    return float(x) if x.ndim == 0 else x


def _disc_ttc(p: np.ndarray, v: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """First τ ≥ 0 with |p + vτ| ≤ radius (p, v: (..., 2)); 0 if inside, inf if never.

    Uses the cancellation-free root τ = c / (−b + √(b² − ac)) instead of (−b − √(b² − ac)) / a; both are
    equal, this one stays accurate for near-grazing paths and never divides by a = 0 (that case has b = 0
    and falls in the ∞ branch).
    """
    a = np.einsum("...i,...i->...", v, v)
    b = np.einsum("...i,...i->...", p, v)
    c = np.einsum("...i,...i->...", p, p) - radius * radius
    disc = b * b - a * c
    hit = (b < 0.0) & (disc >= 0.0)
    denom = np.where(hit, np.sqrt(np.maximum(disc, 0.0)) - b, 1.0)
    return np.where(c <= 0.0, 0.0, np.where(hit, c / denom, _INF))


def time_to_collision(
    p1: ArrayLike, v1: ArrayLike, r1: ArrayLike, p2: ArrayLike, v2: ArrayLike, r2: ArrayLike
) -> Any:
    """Time until two discs moving at constant velocity touch (closed form).

    Solves |p + vτ|² = (r1 + r2)² with p = p2 − p1, v = v2 − v1 for the smallest τ ≥ 0. Positions and
    velocities are (..., 2) arrays (or pairs), radii scalars or (...) arrays; all broadcast together.

    Args:
        p1: Centre of body 1, metres.
        v1: Velocity of body 1, m/s.
        r1: Radius of body 1, metres.
        p2: Centre of body 2, metres.
        v2: Velocity of body 2, m/s.
        r2: Radius of body 2, metres.

    Returns:
        TTC in seconds: 0 when the discs already overlap or touch, ``inf`` when they never touch (separating,
        parallel or missing paths). A float for scalar inputs, otherwise an array of the broadcast shape.
    """
    p = np.asarray(p2, dtype=np.float64) - np.asarray(p1, dtype=np.float64)
    v = np.asarray(v2, dtype=np.float64) - np.asarray(v1, dtype=np.float64)
    radius = np.asarray(r1, dtype=np.float64) + np.asarray(r2, dtype=np.float64)
    if p.shape[-1:] != (2,) or v.shape[-1:] != (2,):
        raise ValueError(
            f"time_to_collision: positions and velocities must end in 2, got {p.shape}, {v.shape}"
        )
    return _scalar_or_array(_disc_ttc(p, v, radius))


def _slabs(q: np.ndarray, u: np.ndarray, lo: ArrayLike, hi: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Times (enter, leave) at which q + uτ is inside the box [lo, hi] (both axes at once, (..., 2)).

    Call with numpy's divide/invalid/overflow warnings off. A zero velocity component gives ±inf slab
    times, which is exactly right (always or never inside along that axis); the only degenerate case is a
    point exactly on a slab boundary with zero velocity across it (0·inf = nan), which yields an empty
    interval: a grazing contact along an edge is reported as a miss (a measure-zero event).
    """
    inv = 1.0 / u
    t1 = (lo - q) * inv
    t2 = (hi - q) * inv
    first = np.minimum(t1, t2)
    last = np.maximum(t1, t2)
    return np.maximum(first[..., 0], first[..., 1]), np.minimum(last[..., 0], last[..., 1])


def _box_disc_ttc(q: np.ndarray, u: np.ndarray, half: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Kernel of `box_circle_ttc` in the box frame (q, u, half: (n, 2); r: (n,)); caller sets errstate."""
    grown = half + r[..., None]
    t_in, t_out = _slabs(q, u, -grown, grown)
    hit = (t_in <= t_out) & (t_out >= 0.0)
    t0 = np.maximum(t_in, 0.0)
    t0[~hit] = _INF
    entry = q + u * t0[..., None]
    side = np.abs(entry) > half
    corner = hit & side[..., 0] & side[..., 1]
    if np.count_nonzero(corner):  # entry in a corner square: the contact is with that corner's quarter disc
        e = entry[corner]
        h = np.broadcast_to(half, entry.shape)[corner]
        t0[corner] += _disc_ttc(e - np.copysign(h, e), u[corner], r[corner])
    return t0


@njit(cache=True, nogil=True)
def _nan_max(a: float, b: float) -> float:
    """`np.maximum` of two floats: NaN if either is NaN."""
    if a != a or b != b:
        return math.nan
    return a if a >= b else b


@njit(cache=True, nogil=True)
def _nan_min(a: float, b: float) -> float:
    """`np.minimum` of two floats: NaN if either is NaN."""
    if a != a or b != b:
        return math.nan
    return a if a <= b else b


@njit(cache=True, nogil=True)
def _min_box_disc_ttc(
    positions: np.ndarray,
    velocities: np.ndarray,
    radii: np.ndarray,
    bx: float,
    by: float,
    bvx: float,
    bvy: float,
    hx: float,
    hy: float,
) -> float:
    """`_box_disc_ttc(...).min()` for one box and n discs, operation for operation (bit-identical).

    Each disc is moved into the box frame (q = p - box, u = v - box velocity) and run through the same
    slab test and corner disc test as the numpy kernel, in the same order of floating-point operations.
    """
    best = math.inf
    for i in range(positions.shape[0]):
        qx = positions[i, 0] - bx
        qy = positions[i, 1] - by
        ux = velocities[i, 0] - bvx
        uy = velocities[i, 1] - bvy
        r = radii[i]
        gx = hx + r
        gy = hy + r
        # _slabs(q, u, -grown, grown)
        ix = 1.0 / ux if ux != 0.0 else math.copysign(math.inf, ux)
        iy = 1.0 / uy if uy != 0.0 else math.copysign(math.inf, uy)
        t1x = (-gx - qx) * ix
        t2x = (gx - qx) * ix
        t1y = (-gy - qy) * iy
        t2y = (gy - qy) * iy
        t_in = _nan_max(_nan_min(t1x, t2x), _nan_min(t1y, t2y))
        t_out = _nan_min(_nan_max(t1x, t2x), _nan_max(t1y, t2y))
        if not (t_in <= t_out and t_out >= 0.0):
            t0 = math.inf
        else:
            t0 = _nan_max(t_in, 0.0)
            ex = qx + ux * t0
            ey = qy + uy * t0
            if abs(ex) > hx and abs(ey) > hy:  # entry in a corner square: that corner's quarter disc
                px = ex - math.copysign(hx, ex)
                py = ey - math.copysign(hy, ey)
                a = ux * ux + uy * uy
                b = px * ux + py * uy
                c = (px * px + py * py) - r * r
                disc = b * b - a * c
                if c <= 0.0:
                    t0 += 0.0
                elif b < 0.0 and disc >= 0.0:
                    t0 += c / (math.sqrt(max(disc, 0.0)) - b)
                else:
                    t0 += math.inf
        if t0 != t0:
            return math.nan
        if t0 < best:
            best = t0
    return best


def min_box_disc_ttc(
    positions: np.ndarray,
    velocities: np.ndarray,
    radii: np.ndarray,
    box_x: float,
    box_y: float,
    box_vx: float,
    box_vy: float,
    half_length: float,
    half_width: float,
) -> float:
    """Minimum exact TTC between one axis-aligned box and n discs (`box_circle_ttc`'s definition), seconds.

    A compiled loop over the discs (no temporary arrays), equal bit for bit to the minimum of
    `box_circle_ttc`; inf for no discs.

    Args:
        positions: (n, 2) disc centres, metres.
        velocities: (n, 2) disc velocities, m/s.
        radii: (n,) disc radii, metres.
        box_x: Box centre x, metres.
        box_y: Box centre y, metres.
        box_vx: Box velocity x, m/s.
        box_vy: Box velocity y, m/s.
        half_length: Half the box's extent along x, metres.
        half_width: Half the box's extent along y, metres.
    """
    return float(
        _min_box_disc_ttc(
            np.asarray(positions, dtype=np.float64),
            np.asarray(velocities, dtype=np.float64),
            np.asarray(radii, dtype=np.float64),
            box_x,
            box_y,
            box_vx,
            box_vy,
            half_length,
            half_width,
        )
    )


def box_circle_ttc(
    box_position: ArrayLike,
    box_velocity: ArrayLike,
    length: ArrayLike,
    width: ArrayLike,
    circle_position: ArrayLike,
    circle_velocity: ArrayLike,
    radius: ArrayLike,
) -> Any:
    """Exact TTC between an axis-aligned box (length along x) and a disc, constant velocities.

    In the box's frame the disc centre moves on a ray q + uτ; contact happens when the ray enters the
    Minkowski sum of box and disc, a rectangle with rounded corners. The ray is first clipped to the
    rounded box's bounding rectangle (slab test); if the entry point lies in a corner square, the true
    entry is the ray's first hit of that corner's quarter disc (a ray that misses it leaves the bounding
    rectangle through its outer edges, so it misses the whole shape). Exact, no sampling.

    Args:
        box_position: (..., 2) box centre, metres.
        box_velocity: (..., 2) box velocity, m/s.
        length: Box extent along x, metres.
        width: Box extent along y, metres.
        circle_position: (..., 2) disc centre, metres.
        circle_velocity: (..., 2) disc velocity, m/s.
        radius: Disc radius, metres.

    Returns:
        TTC in seconds (0 if overlapping or touching, inf if never); float for scalar inputs.
    """
    q = np.asarray(circle_position, dtype=np.float64) - np.asarray(box_position, dtype=np.float64)
    u = np.asarray(circle_velocity, dtype=np.float64) - np.asarray(box_velocity, dtype=np.float64)
    lw = np.stack(np.broadcast_arrays(np.asarray(length, np.float64), np.asarray(width, np.float64)), -1)
    r = np.asarray(radius, dtype=np.float64)
    if q.shape[-1:] != (2,) or u.shape[-1:] != (2,):
        raise ValueError(f"box_circle_ttc: positions and velocities must end in 2, got {q.shape}, {u.shape}")
    shape = np.broadcast_shapes(q.shape[:-1], u.shape[:-1], lw.shape[:-1], r.shape)
    q2 = np.broadcast_to(q, (*shape, 2)).reshape(-1, 2)
    u2 = np.broadcast_to(u, (*shape, 2)).reshape(-1, 2)
    half = 0.5 * np.broadcast_to(lw, (*shape, 2)).reshape(-1, 2)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        out = _box_disc_ttc(q2, u2, half, np.broadcast_to(r, shape).reshape(-1))
    return _scalar_or_array(out.reshape(shape))


def _box_sdf(q: np.ndarray, hx: ArrayLike, hy: ArrayLike) -> np.ndarray:
    """Signed distance from points q (relative to the box centre) to an axis-aligned box; < 0 inside."""
    dx = np.abs(q[..., 0]) - hx
    dy = np.abs(q[..., 1]) - hy
    outside = np.hypot(np.maximum(dx, 0.0), np.maximum(dy, 0.0))
    return outside + np.minimum(np.maximum(dx, dy), 0.0)


def box_circle_separation(
    box_position: ArrayLike,
    length: ArrayLike,
    width: ArrayLike,
    circle_position: ArrayLike,
    radius: ArrayLike,
) -> Any:
    """Edge-to-edge distance between an axis-aligned box and a disc, metres.

    Positive when apart; zero when touching; negative when overlapping (minus the penetration depth along
    the shallowest axis). Vectorised like `box_circle_ttc`.
    """
    q = np.asarray(circle_position, dtype=np.float64) - np.asarray(box_position, dtype=np.float64)
    d = _box_sdf(q, 0.5 * np.asarray(length, dtype=np.float64), 0.5 * np.asarray(width, dtype=np.float64))
    return _scalar_or_array(d - np.asarray(radius, dtype=np.float64))


def box_box_separation(position1: ArrayLike, size1: ArrayLike, position2: ArrayLike, size2: ArrayLike) -> Any:
    """Edge-to-edge distance between two axis-aligned boxes (sizes are (..., 2) length, width), metres.

    Exact: the distance between two boxes equals the distance from one centre to the box whose half
    extents are the sums of both (their Minkowski difference). Negative when overlapping.
    """
    q = np.asarray(position2, dtype=np.float64) - np.asarray(position1, dtype=np.float64)
    half = 0.5 * (np.asarray(size1, dtype=np.float64) + np.asarray(size2, dtype=np.float64))
    return _scalar_or_array(_box_sdf(q, half[..., 0], half[..., 1]))


def following_ttc(gap: ArrayLike, closing_speed: ArrayLike) -> Any:
    """Car-following TTC = gap / closing speed (SUMO), defined only when the follower is faster.

    Args:
        gap: Bumper-to-bumper distance to the leader, metres (≤ 0 means contact).
        closing_speed: Follower speed minus leader speed, m/s.

    Returns:
        Seconds: 0 for gap ≤ 0, inf when not closing.
    """
    g = np.asarray(gap, dtype=np.float64)
    s = np.asarray(closing_speed, dtype=np.float64)
    closing = s > 0.0
    out = np.where(g <= 0.0, 0.0, np.where(closing, g / np.where(closing, s, 1.0), _INF))
    return _scalar_or_array(out)


def following_drac(gap: ArrayLike, closing_speed: ArrayLike) -> Any:
    """Following DRAC = 0.5 Δv² / gap (SUMO), m/s²; 0 when not closing, inf at contact with closing speed."""
    g = np.asarray(gap, dtype=np.float64)
    s = np.asarray(closing_speed, dtype=np.float64)
    closing = s > 0.0
    with np.errstate(divide="ignore"):
        drac = 0.5 * s * s / np.where(g > 0.0, g, 0.0)
    return _scalar_or_array(np.where(closing, drac, 0.0))


def crossing_drac(speed: ArrayLike, distance: ArrayLike, clear_time: ArrayLike) -> Any:
    """Least constant deceleration that keeps B out of the conflict area until A has left it, m/s².

    SUMO's crossing DRAC is 2·(v_B − d_B/t_A)/t_A: the deceleration that brings B to the area exactly at
    t_A. It is only valid if B still moves at t_A (v_B·t_A ≤ 2·d_B); otherwise B stops short of the area
    and the least sufficient deceleration is the stopping one, v_B² / (2 d_B). This piecewise form is a
    departure from SUMO, which applies the first formula unconditionally (and so can report a
    deceleration that would reverse the car). ``clear_time = inf`` (A never leaves) gives the stopping
    deceleration. Returns 0 when B reaches the area after t_A anyway, inf when d_B ≤ 0 and v_B > 0.

    Args:
        speed: Speed v_B of the user who arrives second, m/s.
        distance: Distance d_B of B to the conflict area, metres.
        clear_time: Time t_A until the first user has left the conflict area, seconds.
    """
    v = np.asarray(speed, dtype=np.float64)
    d = np.asarray(distance, dtype=np.float64)
    t = np.asarray(clear_time, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        stop = np.where(d > 0.0, 0.5 * v * v / np.where(d > 0.0, d, 1.0), _INF)
        sumo = 2.0 * (v - d / t) / t
    arrives_early = v * t > d
    out = np.where(v * t <= 2.0 * d, sumo, stop)
    out = np.where(arrives_early & (v > 0.0), out, 0.0)
    return _scalar_or_array(out)


def _crossing_drac_scalar(speed: float, distance: float, clear_time: float) -> float:
    """Scalar `crossing_drac` for the per-step hot path (same piecewise definition)."""
    if speed <= 0.0 or speed * clear_time <= distance:
        return 0.0
    if speed * clear_time <= 2.0 * distance:
        return 2.0 * (speed - distance / clear_time) / clear_time
    return 0.5 * speed * speed / distance if distance > 0.0 else _INF


def rect_occupancy_interval(
    position: ArrayLike,
    velocity: ArrayLike,
    x_min: float,
    x_max: float,
    y_min: float,
    y_max: float,
    margin: ArrayLike = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Times (enter, leave) during which a point moving at constant velocity is inside a rectangle.

    The rectangle is grown by `margin` on every side; for a disc of radius r this is a slightly
    conservative stand-in for the rounded Minkowski sum (it also counts the four small corner squares).
    Empty intervals have enter > leave; times may be negative (already inside).
    """
    q = np.asarray(position, dtype=np.float64)
    u = np.asarray(velocity, dtype=np.float64)
    m = np.asarray(margin, dtype=np.float64)[..., None]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return _slabs(q, u, np.array([x_min, y_min]) - m, np.array([x_max, y_max]) + m)
