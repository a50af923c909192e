"""Intelligent Driver Model (Treiber, Hennecke & Helbing 2000), compiled with numba.

highway-env's per-vehicle Python objects are what make its crossing-free intersections run at about
17 steps/s; here one call computes the accelerations of every vehicle, and the scalar law below is shared
with the traffic kernel that finds each car's leader (`crossing_env.traffic`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from crossing_env.config import IDMConfig
from crossing_env.types import FloatArray


def idm_parameters(params: IDMConfig) -> tuple[float, float, float, float, float, float]:
    """The config as the positional floats the compiled functions take."""
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
    a: float,
    b: float,
    max_deceleration: float,
    time_headway: float,
    min_gap: float,
    delta: float,
) -> float:
    """IDM acceleration of one vehicle (arguments as in `idm_acceleration`, parameters unpacked)."""
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
    a: float,
    b: float,
    max_deceleration: float,
    time_headway: float,
    min_gap: float,
    delta: float,
) -> FloatArray:
    out = np.empty(speed.shape[0])
    for i in range(speed.shape[0]):
        out[i] = idm_scalar(
            speed[i], desired_speed[i], gap[i], leader_speed[i], a, b, max_deceleration, time_headway,
            min_gap, delta,
        )  # fmt: skip
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
    return _idm_all(*arrays, *idm_parameters(params))
