"""Hand-built ground-truth snapshots for the safety tests (arithmetic in the tests' comments)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from crossing_env.safety import EpisodeMetrics, MetricsConfig
from crossing_env.types import CollisionEvent, ConflictArea, GroundTruth, PedState
from scenarios.config import CrosswalkConfig, ScenarioConfig

# Default scenario: crossing centred at x = 120, 4 m wide -> x in [118, 122]; ego lane 0 -> y in [0, 3.5];
# stop line 3 m before the crossing -> x = 115; two-way road with one forward lane -> ego half y in [0, 3.5].
CA = ConflictArea(
    x_min=118.0, x_max=122.0, y_min=0.0, y_max=3.5, stop_line_x=115.0, half_y_min=0.0, half_y_max=3.5
)
EGO_SIZE = (4.5, 1.8)  # half length 2.25, half width 0.9
DT = 0.1


@dataclass
class Ped:
    """A pedestrian for `make_gt`; flags left None are derived from the position."""

    id: int
    pos: tuple[float, float]
    vel: tuple[float, float] = (0.0, 0.0)
    radius: float = 0.28
    state: int | None = None
    waiting: bool | None = None
    intends: bool = True


@dataclass
class Veh:
    id: int
    pos: tuple[float, float]
    vel: tuple[float, float] = (0.0, 0.0)
    size: tuple[float, float] = (4.5, 1.8)


def make_gt(
    t: float,
    ego_x: float = 30.0,
    ego_v: float = 10.0,
    acc: float = 0.0,
    ego_y: float = 1.75,
    peds: Sequence[Ped] = (),
    vehicles: Sequence[Veh] = (),
    collisions: Sequence[CollisionEvent] = (),
    green: bool | None = None,
) -> GroundTruth:
    """Build a GroundTruth; on_road: y in [0, 7] (2 lanes of 3.5 m); on_crossing: also |x - 120| <= 2."""
    pp = np.array([p.pos for p in peds], dtype=float).reshape(-1, 2)
    on_road = (pp[:, 1] >= 0.0) & (pp[:, 1] <= 7.0)
    on_crossing = on_road & (np.abs(pp[:, 0] - 120.0) <= 2.0)
    states = np.array(
        [
            p.state if p.state is not None else (PedState.CROSSING if r else PedState.APPROACHING)
            for p, r in zip(peds, on_road, strict=True)
        ],
        dtype=np.int64,
    )
    waiting = np.array(
        [
            p.waiting if p.waiting is not None else s == PedState.WAITING
            for p, s in zip(peds, states, strict=True)
        ],
        dtype=bool,
    )
    return GroundTruth(
        time=t,
        ego_position=np.array([ego_x, ego_y]),
        ego_velocity=np.array([ego_v, 0.0]),
        ego_acceleration=acc,
        ego_size=EGO_SIZE,
        vehicle_ids=np.array([v.id for v in vehicles], dtype=np.int64),
        vehicle_positions=np.array([v.pos for v in vehicles], dtype=float).reshape(-1, 2),
        vehicle_velocities=np.array([v.vel for v in vehicles], dtype=float).reshape(-1, 2),
        vehicle_sizes=np.array([v.size for v in vehicles], dtype=float).reshape(-1, 2),
        pedestrian_ids=np.array([p.id for p in peds], dtype=np.int64),
        pedestrian_positions=pp,
        pedestrian_velocities=np.array([p.vel for p in peds], dtype=float).reshape(-1, 2),
        pedestrian_radii=np.array([p.radius for p in peds], dtype=float),
        pedestrian_states=states,
        intends_to_cross=np.array([p.intends for p in peds], dtype=bool),
        intent_decided_at=np.zeros(len(peds)),
        is_bystander=np.array([not p.intends for p in peds], dtype=bool),
        on_crossing=on_crossing,
        on_road=on_road,
        waiting=waiting,
        legal=np.ones(len(peds), dtype=bool),
        conflict_area=CA,
        signal_pedestrian_green=green,
        collisions=tuple(collisions),
    )


def metrics(config: MetricsConfig | None = None, kind: str = "zebra") -> EpisodeMetrics:
    scenario = ScenarioConfig(crossing=CrosswalkConfig(kind=kind))  # type: ignore[arg-type]
    return EpisodeMetrics(scenario, DT, config)


def _ego_through(m: EpisodeMetrics, t: float, ego_x: float, peds: Sequence[Ped] = ()) -> None:
    m.update(make_gt(t, ego_x=ego_x, peds=peds))
