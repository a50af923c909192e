"""Vectorised Helbing & Molnár (1995) social force model for pedestrians.

Accelerations of all pedestrians are computed in one batch of numpy operations:

    a_i = (v0_i e_i − v_i) / τ                                   goal attraction with relaxation time τ
        + Σ_j w(φ_ij) k_p A exp((r_i + r_j − d_ij) / B_p) n_ij  pedestrian repulsion
        + Σ_c w(φ_ic) k_v A exp((r_i − d_ic) / B_v) n_ic          vehicle repulsion (distance to the box)
        + kerb repulsion for pedestrians that must stay on the sidewalk

with the anisotropy weight w(φ) = λ + (1 − λ)(1 + cos φ)/2 (Helbing et al. 2000): pedestrians react more
to what is in front of them. The intensities k_p = 0.42 and k_v = 0.71 are the seed paper's calibration
(Song et al. 2022, Case 2); `A` and the ranges `B` are ours (see `SocialForceConfig`): the paper gives
relative intensities only. Departure: we use the exponential "circular specification" rather than the
elliptical potential of the 1995 paper, which is the form most implementations and calibrations use.
"""

from __future__ import annotations

import numpy as np

from crossing_env.config import SocialForceConfig
from crossing_env.types import BoolArray, FloatArray

_MIN_EXPONENT = -30.0
"""Exponents are clipped here: exp(−30) ≈ 1e-13 is negligible, and it keeps far-apart pairs out of the
subnormal range, where floating-point arithmetic is orders of magnitude slower."""


def _norm(v: FloatArray) -> FloatArray:
    """Euclidean norm over the last axis of (..., 2) arrays (cheaper than np.linalg.norm for small arrays)."""
    return np.sqrt(v[..., 0] * v[..., 0] + v[..., 1] * v[..., 1])


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
    to_goal = goals - positions
    dist_goal = _norm(to_goal)[:, None]
    e = np.divide(to_goal, dist_goal, out=np.zeros_like(to_goal), where=dist_goal > 1e-6)
    # Slow down on arrival so pedestrians stop at waypoints instead of orbiting them.
    v0 = desired_speeds[:, None] * np.minimum(1.0, dist_goal / 0.5)
    acc = (v0 * e - velocities) / params.relaxation_time
    speed = _norm(velocities)[:, None]
    heading = np.where(speed > 0.05, velocities / np.maximum(speed, 1e-9), e)

    k_p = params.ped_intensity if ped_intensity is None else np.asarray(ped_intensity)
    x, y = positions[:, 0], positions[:, 1]
    hx, hy = heading[:, 0:1], heading[:, 1:2]
    lam = params.anisotropy
    if n > 1:
        # Components kept as separate (P, P) arrays: fewer temporaries than (P, P, 2) stacks.
        dx = x[:, None] - x[None, :]  # from j to i
        dy = y[:, None] - y[None, :]
        dist = np.sqrt(dx * dx + dy * dy)
        np.fill_diagonal(dist, np.inf)
        inv = 1.0 / np.maximum(dist, 1e-9)
        overlap = radii[:, None] + radii[None, :] - dist
        mag = params.base_strength * np.exp(np.maximum(overlap * (1.0 / params.ped_range), _MIN_EXPONENT))
        # Anisotropy w(φ) = λ + (1 − λ)(1 + cos φ)/2 with cos φ = −heading · n_ij.
        w = lam + (1.0 - lam) * 0.5 * (1.0 - (hx * dx + hy * dy) * inv)
        f = w * mag * inv
        acc[:, 0] += k_p * (f * dx).sum(axis=1)
        acc[:, 1] += k_p * (f * dy).sum(axis=1)

    if vehicle_boxes.shape[0]:
        px, py = x[:, None], y[:, None]
        dx = px - np.minimum(np.maximum(px, vehicle_boxes[None, :, 0]), vehicle_boxes[None, :, 2])
        dy = py - np.minimum(np.maximum(py, vehicle_boxes[None, :, 1]), vehicle_boxes[None, :, 3])
        dist = np.sqrt(dx * dx + dy * dy)
        inside = dist <= 1e-9  # inside the box: contact physics takes over
        inv = np.where(inside, 0.0, 1.0 / np.maximum(dist, 1e-9))
        mag = params.base_strength * np.exp(
            np.maximum((radii[:, None] - dist) * (1.0 / params.vehicle_range), _MIN_EXPONENT)
        )
        w = lam + (1.0 - lam) * 0.5 * (1.0 - (hx * dx + hy * dy) * inv)
        f = w * mag * inv
        acc[:, 0] += params.vehicle_intensity * (f * dx).sum(axis=1)
        acc[:, 1] += params.vehicle_intensity * (f * dy).sum(axis=1)

    south, north = kerbs
    y, r = positions[:, 1], radii
    below = y < 0.5 * (south + north)
    # Distance from the body edge to the kerb it must not cross (negative once it steps over).
    d = np.where(below, south - (y + r), (y - r) - north)
    push = params.kerb_strength * np.exp(np.maximum(-d / params.kerb_range, _MIN_EXPONENT))
    push = np.where(stay_on_sidewalk, np.minimum(push, 50.0), 0.0)
    acc[:, 1] += np.where(below, -push, push)
    return acc


def limit_speed(velocities: FloatArray, max_speeds: FloatArray) -> FloatArray:
    """Scale velocities down to at most `max_speeds` (P,) m/s."""
    speed = _norm(velocities)
    scale = np.minimum(1.0, max_speeds / np.maximum(speed, 1e-9))
    return velocities * scale[:, None]
