"""Checks that relate several fields of a scenario: geometry, ordering of bounds, capacities.

Run after every field has passed its own range (`scenarios.validation`), so each message can assume sane
single values. One function per topic; `cross_field_problems` runs them all.
"""

from __future__ import annotations

from scenarios.config import ScenarioConfig
from scenarios.errors import Problem


def _where(lane: int | str) -> str:
    return f"lane {lane}" if isinstance(lane, int) else lane


def _crossing_problems(cfg: ScenarioConfig) -> list[Problem]:
    """The crossing lies on the road; the signal offset is within its cycle."""
    road, crossing = cfg.road, cfg.crossing
    length = road.length
    out: list[Problem] = []
    half = crossing.width / 2
    if not (half <= crossing.position <= length - half):
        out.append(
            Problem(
                "crossing.position",
                crossing.position,
                f"must keep the crossing on the road: [{half:g}, {length - half:g}]",
            )
        )
    cycle = crossing.signal.pedestrian_green + crossing.signal.pedestrian_red
    if crossing.signal.offset >= cycle:
        out.append(
            Problem(
                "crossing.signal.offset", crossing.signal.offset, f"must be < the cycle length {cycle:g} s"
            )
        )
    return out


def _ego_problems(cfg: ScenarioConfig) -> list[Problem]:
    """The ego starts in a forward lane, on the road, within its own speed limit."""
    road, ego = cfg.road, cfg.ego
    length = road.length
    n_fwd = road.num_forward_lanes
    out: list[Problem] = []
    if ego.lane >= n_fwd:
        out.append(Problem("ego.lane", ego.lane, f"must be a forward lane: 0..{n_fwd - 1} for this road"))
    if not (0.0 <= ego.x < length):
        out.append(Problem("ego.x", ego.x, f"must be on the road: [0, {length:g})"))
    if ego.speed > ego.max_speed:
        out.append(Problem("ego.speed", ego.speed, f"must be <= ego.max_speed = {ego.max_speed:g}"))
    return out


def _traffic_problems(cfg: ScenarioConfig) -> list[Problem]:
    """IDM limits in order; vehicles fit their lane and pool; spawns on the road; parked cars in the strip."""
    road, traffic = cfg.road, cfg.traffic
    length = road.length
    n_lanes = road.num_lanes
    out: list[Problem] = []
    idm = traffic.idm
    if idm.max_deceleration < idm.comfortable_deceleration:
        out.append(
            Problem(
                "traffic.idm.max_deceleration",
                idm.max_deceleration,
                f"must be >= traffic.idm.comfortable_deceleration = {idm.comfortable_deceleration:g}",
            )
        )
    if traffic.width > road.lane_width:
        out.append(
            Problem(
                "traffic.width", traffic.width, f"must fit the lane: <= road.lane_width = {road.lane_width:g}"
            )
        )
    if len(traffic.spawns) > traffic.max_vehicles:
        out.append(
            Problem(
                "traffic.max_vehicles",
                traffic.max_vehicles,
                f"must be >= the {len(traffic.spawns)} spawned vehicles",
            )
        )
    for i, spawn in enumerate(traffic.spawns):
        where = f"traffic.spawns[{i}]"
        if spawn.lane >= n_lanes:
            out.append(
                Problem(f"{where}.lane", spawn.lane, f"must be a lane index 0..{n_lanes - 1} for this road")
            )
        if not (0.0 <= spawn.x <= length):
            out.append(Problem(f"{where}.x", spawn.x, f"must be on the road: [0, {length:g}]"))
        if spawn.parked and spawn.speed != 0.0:
            out.append(Problem(f"{where}.speed", spawn.speed, "must be 0 for a parked vehicle"))
    for i, spawn in enumerate(traffic.spawns):
        if spawn.parked and road.parking_strip < traffic.width:
            out.append(
                Problem(
                    f"traffic.spawns[{i}].parked",
                    spawn.parked,
                    f"needs road.parking_strip >= the vehicle width {traffic.width:g} m "
                    f"(got {road.parking_strip:g}): parked cars stand in the strip, not on the sidewalk",
                )
            )
    return out


def _overlap_problems(cfg: ScenarioConfig) -> list[Problem]:
    """Vehicles (ego included) sharing a lane, or the parking strip, do not overlap at t = 0."""
    ego, traffic = cfg.ego, cfg.traffic
    out: list[Problem] = []
    # Vehicles (ego included) sharing a lane must not overlap at t = 0. Parked vehicles stand in the
    # parking strip outside the south kerb, off the lanes, so they only clash with each other.
    placed: list[tuple[str, int | str, float]] = [("ego", ego.lane, ego.x)] + [
        (f"traffic.spawns[{i}]", "parking strip" if s.parked else s.lane, s.x)
        for i, s in enumerate(traffic.spawns)
    ]
    for a in range(len(placed)):
        for b in range(a + 1, len(placed)):
            (name_a, lane_a, x_a), (name_b, lane_b, x_b) = placed[a], placed[b]
            if lane_a == lane_b and abs(x_a - x_b) < traffic.length:
                out.append(
                    Problem(
                        f"{name_b}.x",
                        x_b,
                        f"overlaps {name_a} (x = {x_a:g}) in {_where(lane_a)}: "
                        f"centres must be >= traffic.length = {traffic.length:g} m apart",
                    )
                )
    return out


def _pedestrian_problems(cfg: ScenarioConfig) -> list[Problem]:
    """Speed bounds in order, the gap floor under the mean, spawns along the road, groups on one side."""
    road, peds = cfg.road, cfg.pedestrians
    length = road.length
    out: list[Problem] = []
    if not (peds.desired_speed_min <= peds.desired_speed_mean <= peds.desired_speed_max):
        out.append(
            Problem(
                "pedestrians.desired_speed_mean",
                peds.desired_speed_mean,
                f"must lie within [desired_speed_min, desired_speed_max] = "
                f"[{peds.desired_speed_min:g}, {peds.desired_speed_max:g}]",
            )
        )
    behaviour = peds.behaviour
    if behaviour.critical_gap_floor > behaviour.critical_gap_mean:
        out.append(
            Problem(
                "pedestrians.behaviour.critical_gap_floor",
                behaviour.critical_gap_floor,
                f"must be <= critical_gap_mean = {behaviour.critical_gap_mean:g}",
            )
        )
    if len(peds.spawns) > peds.max_pedestrians:
        out.append(
            Problem(
                "pedestrians.max_pedestrians",
                peds.max_pedestrians,
                f"must be >= the {len(peds.spawns)} spawned pedestrians",
            )
        )
    group_sides: dict[int, str] = {}
    for i, spawn in enumerate(peds.spawns):
        where = f"pedestrians.spawns[{i}]"
        if not (0.0 <= spawn.x <= length):
            out.append(Problem(f"{where}.x", spawn.x, f"must be along the road: [0, {length:g}]"))
        if spawn.crossing_x is not None and not (0.0 <= spawn.crossing_x <= length):
            out.append(
                Problem(f"{where}.crossing_x", spawn.crossing_x, f"must be along the road: [0, {length:g}]")
            )
        if spawn.time > cfg.duration:
            out.append(Problem(f"{where}.time", spawn.time, f"must be <= duration = {cfg.duration:g} s"))
        if spawn.group >= 0:
            side = group_sides.setdefault(spawn.group, spawn.side)
            if side != spawn.side:
                out.append(
                    Problem(
                        f"{where}.side", spawn.side, f"must match the side {side!r} of group {spawn.group}"
                    )
                )
    return out


def _bystander_problems(cfg: ScenarioConfig) -> list[Problem]:
    """Bystander places on the sidewalk, arrivals with somewhere to go, a pool that holds everyone."""
    road, peds = cfg.road, cfg.pedestrians
    length = road.length
    out: list[Problem] = []
    bystanders = peds.bystanders
    for i, place in enumerate(bystanders.places):
        where = f"pedestrians.bystanders.places[{i}]"
        if not (0.0 <= place.x <= length):
            out.append(Problem(f"{where}.x", place.x, f"must be along the road: [0, {length:g}]"))
        if place.kerb_distance > road.sidewalk_width - 0.3:
            out.append(
                Problem(
                    f"{where}.kerb_distance",
                    place.kerb_distance,
                    f"must be <= sidewalk_width - 0.3 = {road.sidewalk_width - 0.3:g} m",
                )
            )
    if bystanders.arrival_rate > 0 and not any(p.weight > 0 for p in bystanders.places):
        out.append(
            Problem(
                "pedestrians.bystanders.arrival_rate",
                bystanders.arrival_rate,
                "needs at least one place with weight > 0 in pedestrians.bystanders.places",
            )
        )
    initial = len(peds.spawns) + sum(p.initial for p in bystanders.places)
    if initial > peds.max_pedestrians:
        out.append(
            Problem(
                "pedestrians.max_pedestrians",
                peds.max_pedestrians,
                f"must be >= the {initial} pedestrians present or spawned by the scenario",
            )
        )
    return out


def _conflict_problems(cfg: ScenarioConfig) -> list[Problem]:
    """A pedestrian walking ahead in the ego's lane is a test dummy.

    The social force walks people off the road, and nothing else keeps one on its line.
    """
    conflict = cfg.conflict
    if conflict is not None and conflict.side == "ahead" and not conflict.dummy:
        return [
            Problem(
                "conflict.dummy",
                conflict.dummy,
                "must be true when conflict.side is 'ahead' (only a test dummy walks along the car's lane)",
            )
        ]
    return []


_CROSS_FIELD_CHECKS = (
    _crossing_problems,
    _ego_problems,
    _traffic_problems,
    _overlap_problems,
    _pedestrian_problems,
    _bystander_problems,
    _conflict_problems,
)


def cross_field_problems(cfg: ScenarioConfig) -> list[Problem]:
    """Checks that relate several fields: geometry, ordering of bounds, capacities."""
    return [problem for check in _CROSS_FIELD_CHECKS for problem in check(cfg)]
