"""Shared type aliases and the ground-truth snapshot that metrics and recorders read.

The ground truth is the world's true state. Metrics, recorders and evaluation read it (from
`info["ground_truth"]` or `World.ground_truth()`); policies must only read the observation.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import IntEnum
from typing import Any

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]
CrossingObs = dict[str, NDArray[np.float32]]
StepReturn = tuple[CrossingObs, float, bool, bool, dict[str, Any]]


class PedState(IntEnum):
    """Phase of a pedestrian's trip."""

    INACTIVE = 0
    """Pool slot not in use."""
    APPROACHING = 1
    """Walking along the sidewalk towards the point where it will cross (or its goal)."""
    WAITING = 2
    """Standing at the kerb, deciding whether to cross."""
    CROSSING = 3
    """On the carriageway."""
    LEAVING = 4
    """Crossed (or never meant to); walking to its final goal on the sidewalk."""


@dataclass(frozen=True)
class CollisionEvent:
    """A contact between the ego and another road user (from pymunk contacts or box overlap)."""

    time: float
    """Simulation time in seconds."""
    kind: str
    """What was hit: 'pedestrian', 'vehicle' or 'static' (`crossing_env.collision_fault.COLLISION_KINDS`);
    'background' for a background car–pedestrian contact (`GroundTruth.extras`)."""
    other_id: int
    """Id of the pedestrian or vehicle hit."""
    position: tuple[float, float]
    """Contact point in world coordinates (metres)."""
    relative_speed: float
    """Speed of the ego relative to the other body at contact, m/s (impact speed)."""
    compliant: bool
    """For pedestrians: True if the pedestrian was crossing legally (on the zebra, not on red)."""
    contact_type: str = ""
    """The ego collision's class in nuPlan's terms (`crossing_env.collision_fault.CONTACT_TYPES`); "" for
    background contacts."""
    car_speed: float = 0.0
    """Speed (m/s) of the car in the contact when it began: the ego's for an ego collision (the impact speed
    as Euro NCAP measures it), the background car's for a background contact."""
    at_fault: bool = False
    """The ego is at fault (nuPlan's rule, `crossing_env.collision_fault`): it hit with its front while both
    moved, or hit a stopped body; never for background contacts."""


@dataclass(frozen=True)
class ConflictTruth:
    """A timed conflict's key pedestrian as the metrics need it (`GroundTruth.extras["conflict"]`)."""

    pedestrian_id: int
    """Its id."""
    dummy: bool
    """It is a test dummy (`ConflictConfig.dummy`): it moves on a fixed path at a fixed speed."""
    released_at: float
    """World time at which it stepped off; nan while it stands (never released: the test never ran)."""
    x: float
    """Its crossing line along the road (m)."""
    start_y: float
    """Where it stood before stepping off (y, m)."""
    speed: float
    """Its walking speed (m/s)."""
    radius: float
    """Its body radius (m)."""
    along_speed: float = 0.0
    """Its speed along the ego's direction of travel once released (m/s): 0 for a dummy crossing the road,
    the walking speed for one walking ahead in the ego's lane (Euro NCAP CPLA)."""


@dataclass(frozen=True)
class BehaviourEvent:
    """An irrational or notable act of a pedestrian (distraction, run, hesitation, ...)."""

    time: float
    """Simulation time in seconds."""
    pedestrian_id: int
    """Id of the pedestrian."""
    kind: str
    """'distracted', 'run', 'hesitate', 'turn_back', 'jaywalk', 'red_light', 'start_crossing'."""


@dataclass(frozen=True)
class ConflictArea:
    """The part of the ego's lane covered by the crossing: where ego and crossing pedestrians meet."""

    x_min: float
    """Start of the crossing along x (metres)."""
    x_max: float
    """End of the crossing along x (metres)."""
    y_min: float
    """Lower edge of the ego's lane (metres)."""
    y_max: float
    """Upper edge of the ego's lane (metres)."""
    stop_line_x: float
    """x of the ego's stop line (metres)."""
    half_y_min: float
    """Lower edge of the ego's half of the road (all lanes in its direction)."""
    half_y_max: float
    """Upper edge of the ego's half of the road."""


@dataclass(frozen=True, eq=False)
class GroundTruth:
    """True state of the world after a step. Arrays are copies (safe to keep).

    Equality compares every field exactly (arrays element-wise), so two runs with the same seed can be
    checked for identical ground truth, as Gymnasium's `check_env` does with `info`.
    """

    time: float
    """Simulation time in seconds."""
    ego_position: FloatArray
    """(2,) ego centre, metres."""
    ego_velocity: FloatArray
    """(2,) ego velocity, m/s."""
    ego_acceleration: float
    """Longitudinal acceleration applied this step, m/s²."""
    ego_size: tuple[float, float]
    """(length, width) of the ego, metres; the ego's heading is +x."""
    vehicle_ids: IntArray
    """(N,) ids of active background vehicles."""
    vehicle_positions: FloatArray
    """(N, 2) centres."""
    vehicle_velocities: FloatArray
    """(N, 2) velocities."""
    vehicle_sizes: FloatArray
    """(N, 2) length and width."""
    pedestrian_ids: IntArray
    """(P,) ids of active pedestrians."""
    pedestrian_positions: FloatArray
    """(P, 2) centres."""
    pedestrian_velocities: FloatArray
    """(P, 2) velocities."""
    pedestrian_radii: FloatArray
    """(P,) body radii."""
    pedestrian_states: IntArray
    """(P,) `PedState` codes."""
    intends_to_cross: BoolArray
    """(P,) whether the pedestrian means to cross the road (hidden intention); False for bystanders."""
    intent_decided_at: FloatArray
    """(P,) simulation time (s) at which the pedestrian's current intent (to cross or not) was decided: its
    spawn time for a plan fixed at spawn, the time of a change of mind otherwise; NaN if undecided."""
    is_bystander: BoolArray
    """(P,) a bystander near the crossing with no intent to cross: walking past along the sidewalk,
    waiting at a bus stop or shop front by the kerb, or in a group talking at the corner."""
    on_crossing: BoolArray
    """(P,) pedestrian centre inside the zebra area (on the carriageway)."""
    on_road: BoolArray
    """(P,) pedestrian centre on the carriageway (anywhere)."""
    waiting: BoolArray
    """(P,) waiting at the kerb to cross."""
    legal: BoolArray
    """(P,) crossing legally (on the zebra and not against a red signal) or not crossing at all."""
    conflict_area: ConflictArea
    """Ego lane × crossing rectangle."""
    signal_pedestrian_green: bool | None
    """Pedestrian signal state, None when the crossing has no signal."""
    collisions: tuple[CollisionEvent, ...] = ()
    """Ego collisions that began during this step."""
    events: tuple[BehaviourEvent, ...] = ()
    """Behaviour events that happened during this step."""
    extras: dict[str, Any] = field(default_factory=dict)
    """Room for model-specific ground truth (e.g. per-pedestrian phases)."""

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, GroundTruth):
            return NotImplemented
        for name in self.__dataclass_fields__:
            a, b = getattr(self, name), getattr(other, name)
            if name == "extras":
                if a.keys() != b.keys() or not all(np.array_equal(a[k], b[k]) for k in a):
                    return False
            elif isinstance(a, np.ndarray):
                if not np.array_equal(a, b):
                    return False
            elif a != b:
                return False
        return True

    __hash__ = None  # mutable arrays inside: not hashable

    @property
    def safety(self) -> Any:
        """The per-step safety quantities computed from this snapshot (a `crossing_env.safety.StepSafety`).

        The env computes them once per step, for its reward, and attaches them here so that
        `EpisodeMetrics` reuses them instead of computing them again. None for snapshots built elsewhere
        (e.g. with `dataclasses.replace`). Derived data, not state: not a dataclass field, so it takes no
        part in equality, digests or pickles.
        """
        return self.__dict__.get("_safety")

    def attach_safety(self, safety: Any) -> None:
        """Attach the step's safety quantities (see `safety`); the env calls this once per snapshot."""
        object.__setattr__(self, "_safety", safety)

    def __getstate__(self) -> dict[str, Any]:
        """Pickle the fields only (the attached safety quantities are derived data)."""
        state = dict(self.__dict__)
        state.pop("_safety", None)
        return state
