"""Who is at fault in an ego collision: nuPlan's contact classes and fault rule, as NAVSIM re-implements it.

A collision with the ego is classified the moment it begins, in this order (nuPlan's
``no_ego_at_fault_collisions`` metric; NAVSIM's PDM score uses the same classes):

1. ``stopped_ego``: the ego's speed is at most `STOPPED_SPEED` (0.05 m/s);
2. ``stopped_track``: the other body's speed is at most `STOPPED_SPEED`, or it is static (never moves);
3. ``active_rear``: the other body's centre lies behind the ego: the angle between the ego's heading and
   the line from its rear axle to that centre exceeds `BEHIND_ANGLE` (150°);
4. ``active_front``: the other body touches the ego's front edge (the segment between its front corners);
5. ``active_lateral``: anything else (a side contact while both move).

The ego is **at fault** for ``active_front`` and ``stopped_track``; not for ``stopped_ego`` (it stood still)
nor ``active_rear`` (it was hit from behind). nuPlan blames a lateral contact only when the ego straddles
lanes or leaves the drivable area; the ego here never leaves its lane, so ``active_lateral`` is not at
fault (a pedestrian walking into the side of a moving car).
"""

from __future__ import annotations

import math

__all__ = [
    "AT_FAULT_TYPES",
    "BEHIND_ANGLE",
    "COLLISION_KINDS",
    "CONTACT_TYPES",
    "REAR_AXLE_OFFSET",
    "STOPPED_SPEED",
    "contact_type",
    "front_touches_box",
    "front_touches_disc",
    "is_behind",
]

COLLISION_KINDS = ("pedestrian", "vehicle", "static")
"""What the ego can hit: a pedestrian, a moving road user's vehicle, or a static body (a parked vehicle or
an obstacle that never moves)."""
STOPPED_SPEED = 0.05
"""Speed (m/s) at or below which a body counts as stopped (nuPlan's ``stopped_speed_threshold``)."""
BEHIND_ANGLE = math.radians(150.0)
"""A body is behind the ego when the angle from the ego's heading to it, seen from the rear axle, exceeds
this (nuPlan's ``is_agent_behind`` tolerance)."""
REAR_AXLE_OFFSET = 0.28
"""Rear axle behind the ego's centre, as a fraction of its length (nuPlan's ego, a Chrysler Pacifica:
1.46 m of 5.18 m)."""
CONTACT_TYPES = ("stopped_ego", "stopped_track", "active_rear", "active_front", "active_lateral")
"""nuPlan's collision classes, in the order they are tested."""
AT_FAULT_TYPES = frozenset({"stopped_track", "active_front"})
"""The classes in which the ego is at fault."""


def contact_type(
    ego_speed: float,
    other_speed: float,
    other_static: bool,
    other_behind: bool,
    front_touch: bool,
) -> str:
    """The collision's class in nuPlan's terms, from the five facts that decide it (module docstring)."""
    if ego_speed <= STOPPED_SPEED:
        return "stopped_ego"
    if other_static or other_speed <= STOPPED_SPEED:
        return "stopped_track"
    if other_behind:
        return "active_rear"
    if front_touch:
        return "active_front"
    return "active_lateral"


def is_behind(
    ego_x: float, ego_y: float, heading: float, length: float, other_x: float, other_y: float
) -> bool:
    """Whether (other_x, other_y) lies behind the ego (`BEHIND_ANGLE` from its rear axle)."""
    cos_h, sin_h = math.cos(heading), math.sin(heading)
    axle_x = ego_x - REAR_AXLE_OFFSET * length * cos_h
    axle_y = ego_y - REAR_AXLE_OFFSET * length * sin_h
    dx, dy = other_x - axle_x, other_y - axle_y
    norm = math.hypot(dx, dy)
    if norm == 0.0:
        return False
    cos_angle = (dx * cos_h + dy * sin_h) / norm
    return math.acos(max(-1.0, min(1.0, cos_angle))) > BEHIND_ANGLE


def front_touches_disc(
    ego_x: float,
    ego_y: float,
    heading: float,
    length: float,
    width: float,
    cx: float,
    cy: float,
    radius: float,
    tolerance: float = 1e-6,
) -> bool:
    """Whether a disc (centre, radius) touches the ego's front edge, the segment between its front corners."""
    cos_h, sin_h = math.cos(heading), math.sin(heading)
    dx, dy = cx - ego_x, cy - ego_y
    along = dx * cos_h + dy * sin_h  # in the ego's frame
    across = -dx * sin_h + dy * cos_h
    gap_along = along - 0.5 * length
    gap_across = max(0.0, abs(across) - 0.5 * width)
    return math.hypot(gap_along, gap_across) <= radius + tolerance


def front_touches_box(
    ego_x: float,
    ego_length: float,
    heading_sign: float,
    other_x: float,
    other_length: float,
) -> bool:
    """Whether a box in the ego's lane (aligned with it) touches the ego's front edge."""
    front = ego_x + 0.5 * ego_length * heading_sign
    return abs(other_x - front) <= 0.5 * other_length
