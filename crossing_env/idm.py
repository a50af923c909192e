"""Vectorised Intelligent Driver Model (Treiber, Hennecke & Helbing 2000).

One call computes the accelerations of all vehicles at once; highway-env's per-vehicle Python objects
are what make its crossing-free intersections run at about 17 steps/s, so we keep car following in numpy.
"""

from __future__ import annotations

import numpy as np

from crossing_env.config import IDMConfig
from crossing_env.types import FloatArray


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
    a, b = params.max_acceleration, params.comfortable_deceleration
    v0 = np.maximum(desired_speed, 1e-3)
    free = 1.0 - (np.maximum(speed, 0.0) / v0) ** params.delta
    dv = speed - leader_speed
    s_star = params.min_gap + np.maximum(
        0.0, speed * params.time_headway + speed * dv / (2.0 * np.sqrt(a * b))
    )
    gap = np.maximum(gap, 1e-2)
    with np.errstate(invalid="ignore"):
        interaction = np.where(np.isfinite(gap), (s_star / gap) ** 2, 0.0)
    acc = a * (free - interaction)
    return np.minimum(np.maximum(acc, -params.max_deceleration), params.max_acceleration)
