"""Tests of crossing_env.safety against hand-computed geometry (arithmetic in the comments)."""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crossing_env.safety import (
    EpisodeMetrics,
    EpisodeResult,
    MetricsConfig,
    box_box_separation,
    box_circle_separation,
    box_circle_ttc,
    crossing_drac,
    following_drac,
    following_ttc,
    json_safe,
    rect_occupancy_interval,
    time_to_collision,
)
from crossing_env.types import CollisionEvent, ConflictArea, GroundTruth, PedState
from crossing_eval.statistics import aggregate, finite_percentiles, wilson_interval
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


# ---------------------------------------------------------------------------------------------------------
# Circle-circle TTC
# ---------------------------------------------------------------------------------------------------------


def test_ttc_head_on() -> None:
    # centres 10 m apart, radii 0.5 + 0.5 -> gap 9 m; closing speed 1 + 1 = 2 m/s -> 4.5 s
    assert time_to_collision((0, 0), (1, 0), 0.5, (10, 0), (-1, 0), 0.5) == pytest.approx(4.5)


def test_ttc_oblique() -> None:
    # p = (6, 8), |p| = 10, v = (-3, -4) points straight at body 1 with speed 5; R = 1 -> (10 - 1) / 5 = 1.8
    assert time_to_collision((0, 0), (0, 0), 0.4, (6, 8), (-3, -4), 0.6) == pytest.approx(1.8)


def test_ttc_offset_paths() -> None:
    # lateral offset 0.6, R = 1: (10 - τ)² + 0.36 = 1 -> 10 - τ = 0.8 -> τ = 9.2
    assert time_to_collision((0, 0), (0, 0), 0.5, (10, 0.6), (-1, 0), 0.5) == pytest.approx(9.2)
    # lateral offset exactly R: grazing at τ = 10 (b² - ac = 100 - 1·100 = 0)
    assert time_to_collision((0, 0), (0, 0), 0.5, (10, 1.0), (-1, 0), 0.5) == pytest.approx(10.0)
    # lateral offset 1.01 > R: the paths miss
    assert time_to_collision((0, 0), (0, 0), 0.5, (10, 1.01), (-1, 0), 0.5) == math.inf


def test_ttc_special_cases() -> None:
    assert time_to_collision((0, 0), (0, 0), 0.5, (0.9, 0), (5, 0), 0.5) == 0.0  # overlapping (0.9 < 1)
    assert time_to_collision((0, 0), (0, 0), 0.5, (1.0, 0), (5, 0), 0.5) == 0.0  # touching counts as 0
    assert time_to_collision((0, 0), (0, 0), 0.5, (5, 0), (1, 0), 0.5) == math.inf  # separating
    assert time_to_collision((0, 0), (2, 1), 0.5, (5, 0), (2, 1), 0.5) == math.inf  # same velocity (a = 0)


def test_ttc_broadcasts() -> None:
    # one body against 3 others: gaps 9, 19 and a miss -> 9/1, 19/1, inf
    p2 = np.array([[10.0, 0.0], [20.0, 0.0], [10.0, 5.0]])
    out = time_to_collision(
        np.zeros(2), np.array([1.0, 0.0]), 0.5, p2, np.zeros((3, 2)), np.array([0.5, 0.5, 0.5])
    )
    assert isinstance(out, np.ndarray) and out.shape == (3,)
    np.testing.assert_allclose(out, [9.0, 19.0, math.inf])
    assert isinstance(time_to_collision((0, 0), (1, 0), 0.5, (10, 0), (0, 0), 0.5), float)
    with pytest.raises(ValueError, match="end in 2"):
        time_to_collision((0, 0, 0), (1, 0, 0), 0.5, (10, 0, 0), (0, 0, 0), 0.5)


def _physical(x: float) -> float:
    """Snap magnitudes below 1e-6 to 0: v·v of 1e-200 m/s underflows, and such speeds mean nothing here."""
    return 0.0 if abs(x) < 1e-6 else x


coord = st.floats(-50, 50, allow_nan=False).map(_physical)
speed = st.floats(-20, 20, allow_nan=False).map(_physical)
radius = st.floats(0.05, 3.0)


@settings(max_examples=200, deadline=None)
@given(coord, coord, speed, speed, radius, coord, coord, speed, speed, radius)
def test_ttc_symmetric(x1, y1, vx1, vy1, r1, x2, y2, vx2, vy2, r2) -> None:  # type: ignore[no-untyped-def]
    a = time_to_collision((x1, y1), (vx1, vy1), r1, (x2, y2), (vx2, vy2), r2)
    b = time_to_collision((x2, y2), (vx2, vy2), r2, (x1, y1), (vx1, vy1), r1)
    assert a == pytest.approx(b, rel=1e-9, abs=1e-9) or (math.isinf(a) and math.isinf(b))


@settings(max_examples=200, deadline=None)
@given(coord, coord, speed, speed, radius, coord, coord, speed, speed, radius, coord, coord)
def test_ttc_translation_invariant(x1, y1, vx1, vy1, r1, x2, y2, vx2, vy2, r2, dx, dy) -> None:  # type: ignore[no-untyped-def]
    a = time_to_collision((x1, y1), (vx1, vy1), r1, (x2, y2), (vx2, vy2), r2)
    b = time_to_collision((x1 + dx, y1 + dy), (vx1, vy1), r1, (x2 + dx, y2 + dy), (vx2, vy2), r2)
    if math.isinf(a) != math.isinf(b):  # rounding of the translated positions can only flip a tangency
        assert _grazing(x2 - x1, y2 - y1, vx2 - vx1, vy2 - vy1, r1 + r2)
    elif not math.isinf(a):
        assert a == pytest.approx(b, rel=1e-6, abs=1e-6)


def _grazing(px: float, py: float, vx: float, vy: float, rr: float) -> bool:
    """True when the relative path passes within 1e-6 of tangency (numerically ambiguous)."""
    a = vx * vx + vy * vy
    if a == 0.0:
        return False
    closest = abs(px * vy - py * vx) / math.sqrt(a)
    return abs(closest - rr) < 1e-6 * max(1.0, rr)


@settings(max_examples=300, deadline=None)
@given(coord, coord, speed, speed, radius, coord, coord, speed, speed, radius)
def test_ttc_zero_iff_overlapping(x1, y1, vx1, vy1, r1, x2, y2, vx2, vy2, r2) -> None:  # type: ignore[no-untyped-def]
    ttc = time_to_collision((x1, y1), (vx1, vy1), r1, (x2, y2), (vx2, vy2), r2)
    overlapping = math.hypot(x2 - x1, y2 - y1) <= r1 + r2
    assert (ttc == 0.0) == overlapping
    if 0.0 < ttc < math.inf:  # at τ the discs touch
        dist = math.hypot(x2 - x1 + (vx2 - vx1) * ttc, y2 - y1 + (vy2 - vy1) * ttc)
        assert dist == pytest.approx(r1 + r2, abs=1e-6)


# ---------------------------------------------------------------------------------------------------------
# Box-circle TTC and separations
# ---------------------------------------------------------------------------------------------------------


def test_box_circle_ttc_front_face() -> None:
    # ego box 4.5 x 1.8 at the origin driving +x at 10 m/s; pedestrian r 0.3 standing at (20, 0):
    # contact when the front (x = 2.25) meets x = 20 - 0.3 -> gap 17.45 m / 10 m/s = 1.745 s
    assert box_circle_ttc((0, 0), (10, 0), 4.5, 1.8, (20, 0), (0, 0), 0.3) == pytest.approx(1.745)


def test_box_circle_ttc_rounded_corner() -> None:
    # pedestrian at y = 1.1, 0.2 above the box's side (half width 0.9) -> the corner arc is hit:
    # contact x offset = 2.25 + sqrt(0.3² - 0.2²) = 2.25 + 0.223607 -> (20 - 2.473607) / 10 = 1.7526393
    assert box_circle_ttc((0, 0), (10, 0), 4.5, 1.8, (20, 1.1), (0, 0), 0.3) == pytest.approx(
        1.7526393, abs=1e-7
    )
    # a conservative bounding box would give 1.745 here; 1.19 = 0.9 + 0.3 - 0.01 still grazes the arc:
    # sqrt(0.09 - 0.29²) = 0.0768 -> (20 - 2.3268) / 10 = 1.76732
    assert box_circle_ttc((0, 0), (10, 0), 4.5, 1.8, (20, 1.19), (0, 0), 0.3) == pytest.approx(
        1.767318, abs=1e-6
    )
    # 1.21 > 0.9 + 0.3: the pedestrian is passed without contact
    assert box_circle_ttc((0, 0), (10, 0), 4.5, 1.8, (20, 1.21), (0, 0), 0.3) == math.inf


def test_box_circle_ttc_side_and_special_cases() -> None:
    # stationary box, pedestrian at (0, 5) walking -y at 1.5 m/s: gap 5 - 0.9 - 0.3 = 3.8 m -> 2.5333 s
    assert box_circle_ttc((0, 0), (0, 0), 4.5, 1.8, (0, 5), (0, -1.5), 0.3) == pytest.approx(3.8 / 1.5)
    # pedestrian 5 m from the rear-left corner (-2.25, 0.9), at (-2.25 - 3, 0.9 + 4), walking straight at it
    # with velocity (3, -4) (5 m/s): contact when 0.3 m from the corner -> (5 - 0.3) / 5 = 0.94 s
    assert box_circle_ttc((0, 0), (0, 0), 4.5, 1.8, (-5.25, 4.9), (3, -4), 0.3) == pytest.approx(0.94)
    assert box_circle_ttc((0, 0), (10, 0), 4.5, 1.8, (2.4, 0), (0, 0), 0.3) == 0.0  # overlapping
    assert box_circle_ttc((0, 0), (10, 0), 4.5, 1.8, (-20, 0), (0, 0), 0.3) == math.inf  # behind, separating
    assert box_circle_ttc((0, 0), (10, 0), 4.5, 1.8, (20, 3), (10, 0), 0.3) == math.inf  # walking alongside


def test_box_circle_ttc_vectorised_and_broadcast() -> None:
    peds = np.array([[20.0, 0.0], [20.0, 1.1], [20.0, 1.21], [2.4, 0.0]])
    out = box_circle_ttc(np.zeros(2), np.array([10.0, 0.0]), 4.5, 1.8, peds, np.zeros((4, 2)), 0.3)
    np.testing.assert_allclose(out, [1.745, 1.7526393, math.inf, 0.0], atol=1e-7)
    # per-pedestrian radii broadcast: r = 0.5 at (20, 0) -> (20 - 2.75) / 10 = 1.725
    out2 = box_circle_ttc((0, 0), (10, 0), 4.5, 1.8, peds[:2], np.zeros((2, 2)), np.array([0.5, 0.3]))
    assert out2[0] == pytest.approx(1.725)


def _box_disc_gap(bp: np.ndarray, bv: np.ndarray, lw: tuple[float, float], cp: np.ndarray, cv: np.ndarray,
                  r: float, t: np.ndarray) -> np.ndarray:  # fmt: skip
    """Brute-force footprint distance over sampled times (independent of the closed form)."""
    q = cp[None, :] + cv[None, :] * t[:, None] - (bp[None, :] + bv[None, :] * t[:, None])
    d = np.abs(q) - 0.5 * np.array(lw)
    outside = np.hypot(np.maximum(d[:, 0], 0.0), np.maximum(d[:, 1], 0.0))
    return outside + np.minimum(np.maximum(d[:, 0], d[:, 1]), 0.0) - r


@settings(max_examples=300, deadline=None)
@given(
    coord, coord, speed, speed, st.floats(1.0, 6.0), st.floats(0.5, 3.0), radius, coord, coord, speed, speed
)
def test_box_circle_ttc_matches_sampling(bx, by, bvx, bvy, length, width, r, cx, cy, cvx, cvy) -> None:  # type: ignore[no-untyped-def]
    bp, bv, cp, cv = np.array([bx, by]), np.array([bvx, bvy]), np.array([cx, cy]), np.array([cvx, cvy])
    ttc = box_circle_ttc(bp, bv, length, width, cp, cv, r)
    gap0 = box_circle_separation(bp, length, width, cp, r)
    assert (ttc == 0.0) == (gap0 <= 0.0)
    horizon = 20.0 if math.isinf(ttc) else ttc
    t = np.linspace(0.0, horizon, 2001)[:-1] if horizon > 0 else np.zeros(0)
    gaps = _box_disc_gap(bp, bv, (length, width), cp, cv, r, t)
    assert np.all(gaps > -1e-6)  # no contact before the reported TTC (nor within 20 s if inf)
    if 0.0 < ttc < math.inf:
        at = _box_disc_gap(bp, bv, (length, width), cp, cv, r, np.array([ttc]))[0]
        assert at == pytest.approx(0.0, abs=1e-6)  # touching at τ


def test_box_circle_ttc_translation_and_swap_invariant() -> None:
    # moving both bodies by the same offset, or swapping which one moves (same relative velocity), keeps TTC
    base = box_circle_ttc((0, 0), (10, 0), 4.5, 1.8, (20, 1.1), (0, 0), 0.3)
    assert box_circle_ttc((7, -3), (10, 0), 4.5, 1.8, (27, -1.9), (0, 0), 0.3) == pytest.approx(base)
    assert box_circle_ttc((0, 0), (0, 0), 4.5, 1.8, (20, 1.1), (-10, 0), 0.3) == pytest.approx(base)


def test_separations() -> None:
    # pedestrian r 0.3 at (5, 0) in front of the 4.5 x 1.8 box: 5 - 2.25 - 0.3 = 2.45
    assert box_circle_separation((0, 0), 4.5, 1.8, (5, 0), 0.3) == pytest.approx(2.45)
    # diagonal from the corner (2.25, 0.9): offsets (3, 4) -> 5 - 0.3 = 4.7
    assert box_circle_separation((0, 0), 4.5, 1.8, (5.25, 4.9), 0.3) == pytest.approx(4.7)
    # centre inside the box: -(distance to the nearest side 0.9) - 0.3 = -1.2
    assert box_circle_separation((0, 0), 4.5, 1.8, (0, 0), 0.3) == pytest.approx(-1.2)
    # two 4 x 2 boxes offset (10, 3): gaps 10 - 4 = 6 and 3 - 2 = 1 -> sqrt(37)
    assert box_box_separation((0, 0), (4, 2), (10, 3), (4, 2)) == pytest.approx(math.sqrt(37.0))
    # same lane, 1 m apart bumper to bumper
    assert box_box_separation((0, 0), (4.5, 1.8), (5.5, 0), (4.5, 1.8)) == pytest.approx(1.0)


# ---------------------------------------------------------------------------------------------------------
# Following TTC / DRAC, crossing DRAC, occupancy interval
# ---------------------------------------------------------------------------------------------------------


def test_following_ttc_and_drac() -> None:
    # gap 20 m closing at 5 m/s -> TTC 4 s; DRAC = 0.5 * 25 / 20 = 0.625 m/s²
    assert following_ttc(20.0, 5.0) == pytest.approx(4.0)
    assert following_drac(20.0, 5.0) == pytest.approx(0.625)
    assert following_ttc(20.0, -1.0) == math.inf and following_drac(20.0, -1.0) == 0.0
    assert following_ttc(0.0, 5.0) == 0.0 and following_drac(0.0, 5.0) == math.inf
    np.testing.assert_allclose(following_ttc(np.array([10.0, 30.0]), np.array([2.0, 3.0])), [5.0, 10.0])


def test_crossing_drac() -> None:
    # v 10, d 30, pedestrian clears at 4 s: vt = 40 <= 2d = 60 -> 2 (10 - 30/4) / 4 = 1.25 m/s²
    # check: 10·4 - 0.5·1.25·16 = 30 m exactly at t = 4 s
    assert crossing_drac(10.0, 30.0, 4.0) == pytest.approx(1.25)
    # v 10, d 20, clears at 5 s: vt = 50 > 40, the car would stop first -> v²/(2d) = 100/40 = 2.5
    # (SUMO's formula would give 2 (10 - 4) / 5 = 2.4, which reverses the car: 10 - 2.4·5 < 0)
    assert crossing_drac(10.0, 20.0, 5.0) == pytest.approx(2.5)
    assert crossing_drac(10.0, 30.0, 2.0) == 0.0  # reaches at 3 s, after the pedestrian left at 2 s
    assert crossing_drac(10.0, 60.0, math.inf) == pytest.approx(100.0 / 120.0)  # never clears: stop
    # non-decreasing in the clearing time (used by the accumulator)
    ts = np.linspace(3.01, 30.0, 200)
    assert np.all(np.diff(crossing_drac(10.0, 30.0, ts)) >= -1e-12)


def test_rect_occupancy_interval() -> None:
    # point at (0, -5) walking +y at 1 m/s through x in [-1, 1], y in [0, 3.5] grown by 0.3:
    # enters y = -0.3 after 4.7 s, leaves y = 3.8 after 8.8 s
    t_in, t_out = rect_occupancy_interval((0, -5), (0, 1), -1, 1, 0, 3.5, 0.3)
    assert float(t_in) == pytest.approx(4.7) and float(t_out) == pytest.approx(8.8)
    t_in, t_out = rect_occupancy_interval((5, -5), (0, 1), -1, 1, 0, 3.5, 0.3)  # x outside: never inside
    assert float(t_in) > float(t_out)


# ---------------------------------------------------------------------------------------------------------
# EpisodeMetrics
# ---------------------------------------------------------------------------------------------------------


def test_rejects_bad_dt_and_time_order() -> None:
    with pytest.raises(ValueError, match="dt"):
        EpisodeMetrics(ScenarioConfig(), 0.0)
    m = metrics()
    m.update(make_gt(1.0))
    with pytest.raises(ValueError, match="time went backwards"):
        m.update(make_gt(0.5))


def test_episode_ttc_separation_and_clearance() -> None:
    m = metrics()
    ped = Ped(1, (60.0, 1.75), radius=0.25)
    # step 1: ego at 30 -> front 32.25; gap 60 - 0.25 - 32.25 = 27.5 m at 10 m/s -> 2.75 s (< 3 s encounter)
    m.update(make_gt(0.1, ego_x=30.0, peds=[ped]))
    # step 2: ego at 45 -> gap 12.5 m -> 1.25 s (< 1.5 s serious), separation 12.5 m
    m.update(make_gt(0.2, ego_x=45.0, peds=[ped]))
    assert m.step_ttc == pytest.approx(1.25) and m.step_separation == pytest.approx(12.5)
    # step 3: ego stopped 0.5 m short: TTC not evaluated, separation 0.5 m (< 1 m clearance)
    m.update(make_gt(0.3, ego_x=57.0, ego_v=0.0, peds=[ped]))
    r = m.result()
    assert r.min_ttc == pytest.approx(1.25)
    assert r.encounter_time == pytest.approx(0.2) and r.serious_conflict_time == pytest.approx(0.1)
    assert r.min_separation == pytest.approx(0.5)
    assert r.clearance_violation_time == pytest.approx(0.1)


def test_episode_without_anyone_reports_never() -> None:
    m = metrics()
    m.update(make_gt(0.1))
    r = m.result()
    assert r.min_ttc == math.inf and r.min_separation == math.inf and r.min_ttc_vehicle == math.inf
    assert r.max_drac_crossing == 0.0 and r.yield_obligations == 0 and math.isnan(r.yield_compliance)


def test_episode_braking_counts() -> None:
    m = metrics()
    for k, a in enumerate([-1.0, -3.5, -4.2, -2.0, -3.0, -0.5, 1.0]):
        m.update(make_gt(0.1 * (k + 1), acc=a))
    r = m.result()
    assert r.hard_braking_steps == 3  # -3.5, -4.2, -3.0 (threshold inclusive)
    assert r.hard_braking_events == 2  # runs (-3.5, -4.2) and (-3.0)
    assert r.comfort_violation_steps == 1  # -4.2 <= -4.05
    assert r.max_deceleration == pytest.approx(4.2)


def test_episode_collisions() -> None:
    m = metrics()
    hit = [
        CollisionEvent(0.1, "pedestrian", 3, (50.0, 1.0), 5.0, True),
        CollisionEvent(0.1, "pedestrian", 4, (50.0, 1.5), 7.5, False),
        CollisionEvent(0.1, "vehicle", 9, (52.0, 1.5), 2.0, True),
    ]
    m.update(make_gt(0.1, collisions=hit))
    r = m.result()
    assert r.collision and r.pedestrian_collisions == 2 and r.vehicle_collisions == 1
    assert r.compliant_pedestrian_collisions == 1 and r.noncompliant_pedestrian_collisions == 1
    assert r.max_impact_speed == pytest.approx(7.5)
    assert math.isnan(metrics().result().max_impact_speed)


def test_episode_following_vehicle() -> None:
    m = metrics()
    cars = [
        Veh(1, (50.0, 1.75), (5.0, 0.0)),  # same lane, 20 m ahead centre to centre
        Veh(2, (40.0, 5.25), (-10.0, 0.0)),  # oncoming lane: not scored for TTC
        Veh(3, (20.0, 1.75), (15.0, 0.0)),  # behind the ego: not scored
    ]
    m.update(make_gt(0.1, ego_x=30.0, vehicles=cars))
    r = m.result()
    # gap 20 - 4.5 = 15.5 m, closing 10 - 5 = 5 m/s -> TTC 3.1 s, DRAC 0.5·25/15.5 = 0.80645 m/s²
    assert r.min_ttc_vehicle == pytest.approx(3.1)
    assert r.max_drac_following == pytest.approx(0.5 * 25 / 15.5)
    # nearest footprint: car 2 at dx 10, dy 3.5 -> gaps 10 - 4.5 = 5.5 and 3.5 - 1.8 = 1.7 -> 5.757;
    # car 3: dx 10 -> 5.5 m bumper to bumper (smaller)
    assert r.min_vehicle_separation == pytest.approx(5.5)


def test_episode_crossing_drac() -> None:
    # A pedestrian standing in the conflict area never clears it: DRAC = stopping deceleration.
    # ego front at 98 (x = 95.75): d = 118 - 98 = 20 m at 10 m/s -> 100 / 40 = 2.5 m/s²
    m = metrics()
    m.update(make_gt(0.1, ego_x=95.75, peds=[Ped(1, (120.0, 1.0))]))
    assert m.result().max_drac_crossing == pytest.approx(2.5)
    # A pedestrian walking +y at 1.25 m/s from y = 1.0 leaves the grown area (y = 3.5 + 0.28) after
    # (3.78 - 1.0) / 1.25 = 2.224 s; the ego front is 20 m away at 10 m/s (arrives at 2 s, earlier):
    # vt = 22.24 <= 2d = 40 -> DRAC = 2 (10 - 20/2.224) / 2.224 = 0.90571 m/s²
    m = metrics()
    m.update(make_gt(0.1, ego_x=95.75, peds=[Ped(1, (120.0, 1.0), (0.0, 1.25))]))
    t_a = (3.78 - 1.0) / 1.25
    assert m.result().max_drac_crossing == pytest.approx(2 * (10 - 20 / t_a) / t_a)
    # ego 30 m away arrives at 3 s, after the pedestrian left (2.224 s): no deceleration needed
    m = metrics()
    m.update(make_gt(0.1, ego_x=85.75, peds=[Ped(1, (120.0, 1.0), (0.0, 1.25))]))
    assert m.result().max_drac_crossing == 0.0


def _ego_through(m: EpisodeMetrics, t: float, ego_x: float, peds: Sequence[Ped] = ()) -> None:
    m.update(make_gt(t, ego_x=ego_x, peds=peds))


def test_pet_pedestrian_first_then_ego_first() -> None:
    m = metrics()
    inside, outside = Ped(7, (120.0, 1.0)), Ped(7, (120.0, 5.0))
    # pedestrian 7 occupies the conflict area at t = 1.0, has left at t = 1.6
    _ego_through(m, 1.0, 60.0, [inside])
    _ego_through(m, 1.6, 80.0, [outside])
    # ego enters at t = 3.0 (front 116.0 + 2.25 = 118.25 > 118) -> PET = 3.0 - 1.6 = 1.4
    _ego_through(m, 3.0, 116.0, [outside])
    # ego has left at t = 4.0 (rear 124.5 - 2.25 = 122.25 > 122); pedestrian 8 enters at t = 5.0 -> PET 1.0
    _ego_through(m, 4.0, 124.5, [outside, Ped(8, (119.0, -1.0))])
    _ego_through(m, 5.0, 134.5, [outside, Ped(8, (119.0, 0.5))])
    r = m.result()
    assert r.pets_pedestrian_first == pytest.approx((1.4,))
    assert r.pets_ego_first == pytest.approx((1.0,))
    assert r.min_pet_pedestrian_first == pytest.approx(1.4) and r.min_pet_ego_first == pytest.approx(1.0)
    assert r.simultaneous_occupancies == 0


def test_kerb_pedestrian_does_not_occupy_conflict_area() -> None:
    m = metrics()
    # centre 0.2 m onto the sidewalk (y = -0.2): the 0.28 m body overhangs the kerb but is not on the road
    kerb = Ped(5, (120.0, -0.2), state=PedState.WAITING, waiting=False)
    _ego_through(m, 1.0, 80.0, [kerb])
    _ego_through(m, 2.0, 117.0, [kerb])
    assert m.result().simultaneous_occupancies == 0


def test_pet_simultaneous_occupancy_and_id_order() -> None:
    m = metrics()
    # two pedestrians, ids listed in different orders between steps: the state must follow the ids
    _ego_through(m, 1.0, 80.0, [Ped(20, (120.0, 1.0)), Ped(3, (150.0, -2.0))])
    # ego enters while pedestrian 20 is still inside: no PET, one simultaneous occupancy
    _ego_through(m, 2.0, 117.0, [Ped(3, (150.0, -2.0)), Ped(20, (120.0, 2.0))])
    r = m.result()
    assert r.simultaneous_occupancies == 1 and r.pets_pedestrian_first == () and r.pets_ego_first == ()


def test_yield_compliant_after_pedestrian_clears() -> None:
    m = metrics()
    # ego at 50 (front 52.25), 10 m/s: 62.75 m to the stop line > 10²/(2·3) = 16.7 m -> obligation opens
    _ego_through(m, 0.1, 50.0, [Ped(1, (120.0, -0.5), state=PedState.WAITING)])
    # stepping off: state CROSSING while the centre is still over the sidewalk must not drop the obligation
    _ego_through(m, 1.0, 60.0, [Ped(1, (120.0, -0.2), (0, 1.3), state=PedState.CROSSING)])
    _ego_through(m, 2.0, 70.0, [Ped(1, (120.0, 1.0), (0, 1.3))])  # in the ego's half
    _ego_through(m, 4.0, 90.0, [Ped(1, (120.0, 4.0), (0, 1.3))])  # cleared it (y > 3.5)
    _ego_through(m, 5.0, 118.0, [Ped(1, (120.0, 5.5), (0, 1.3))])  # ego in the conflict area: fine
    r = m.result()
    assert (r.yield_obligations, r.yield_compliant, r.yield_violations) == (1, 1, 0)
    assert r.yield_compliance == 1.0


def test_yield_violation_when_entering_before_clearance() -> None:
    m = metrics()
    _ego_through(m, 0.1, 50.0, [Ped(1, (120.0, 1.0), (0, 1.3))])  # on the crossing in the ego's half
    _ego_through(m, 1.0, 118.0, [Ped(1, (120.0, 2.2), (0, 1.3))])  # ego enters, pedestrian still there
    _ego_through(m, 3.0, 130.0, [Ped(1, (120.0, 4.8), (0, 1.3))])
    r = m.result()
    assert (r.yield_obligations, r.yield_compliant, r.yield_violations) == (1, 0, 1)
    assert r.yield_compliance == 0.0


def test_no_obligation_when_too_close_to_stop() -> None:
    m = metrics()
    # front at 110.25: 4.75 m to the stop line < 16.7 m comfortable stopping distance -> no obligation
    _ego_through(m, 0.1, 108.0, [Ped(1, (120.0, 1.0), (0, 1.3))])
    _ego_through(m, 1.0, 118.0, [Ped(1, (120.0, 2.2), (0, 1.3))])
    assert m.result().yield_obligations == 0


def test_far_half_pedestrian_walking_towards_ego_half() -> None:
    walker = [Ped(1, (120.0, 5.0), (0, -1.3))]  # north half (y > 3.5) walking south, towards the ego's half
    m = metrics()
    _ego_through(m, 0.1, 50.0, walker)
    _ego_through(m, 1.0, 118.0, walker)
    assert m.result().yield_violations == 1
    m = metrics(MetricsConfig(far_half_counts=False))
    _ego_through(m, 0.1, 50.0, walker)
    _ego_through(m, 1.0, 118.0, walker)
    assert m.result().yield_obligations == 0
    # walking away (north) after having crossed the ego's half: no obligation either
    m = metrics()
    _ego_through(m, 0.1, 50.0, [Ped(1, (120.0, 5.0), (0, 1.3))])
    _ego_through(m, 1.0, 118.0, [Ped(1, (120.0, 6.0), (0, 1.3))])
    assert m.result().yield_obligations == 0


def test_yield_declined_offer_and_dropped_waiter() -> None:
    m = metrics()
    waiter = Ped(1, (120.0, -0.5), state=PedState.WAITING)
    # ego stopped with its front 1 m before the stop line (x = 111.75) while the pedestrian waits 3 s
    for k in range(31):
        m.update(make_gt(0.1 * (k + 1), ego_x=111.75, ego_v=0.0, peds=[waiter]))
    m.update(make_gt(3.5, ego_x=118.0, ego_v=3.0, peds=[waiter]))  # then drives through
    r = m.result()
    assert (r.yield_obligations, r.yield_compliant, r.yield_violations, r.yield_offers_declined) == (
        1,
        1,
        0,
        1,
    )
    # a car that crept over the line and stands before the crossing (front at 117 m, crossing from 118 m)
    # is still offering: the offer is declined after 3 s, not violated
    m = metrics()
    m.update(make_gt(0.1, ego_x=50.0, ego_v=10.0, peds=[waiter]))  # the obligation opens
    for k in range(31):
        m.update(make_gt(0.2 + 0.1 * k, ego_x=114.75, ego_v=0.0, peds=[waiter]))
    m.update(make_gt(3.5, ego_x=118.0, ego_v=3.0, peds=[waiter]))
    r = m.result()
    assert (r.yield_obligations, r.yield_violations, r.yield_offers_declined) == (1, 0, 1)
    # a pedestrian who stops waiting and walks off along the sidewalk is not an obligation
    m = metrics()
    _ego_through(m, 0.1, 50.0, [waiter])
    _ego_through(m, 1.0, 60.0, [Ped(1, (125.0, -0.5), (1.3, 0), state=PedState.LEAVING)])
    _ego_through(m, 2.0, 118.0, [Ped(1, (126.0, -0.5), (1.3, 0), state=PedState.LEAVING)])
    assert m.result().yield_obligations == 0


def test_waiting_far_from_crossing_and_crossing_kinds() -> None:
    m = metrics()
    _ego_through(m, 0.1, 50.0, [Ped(1, (100.0, -0.5), state=PedState.WAITING)])  # 20 m from the zebra
    _ego_through(m, 1.0, 118.0, [Ped(1, (100.0, -0.5), state=PedState.WAITING)])
    assert m.result().yield_obligations == 0
    on_half = [Ped(1, (120.0, 1.0), (0, 1.3))]
    for kind, green, expected in [("none", None, 0), ("signalised", False, 0), ("signalised", True, 1)]:
        m = metrics(kind=kind)
        m.update(make_gt(0.1, ego_x=50.0, peds=on_half, green=green))
        m.update(make_gt(1.0, ego_x=118.0, peds=on_half, green=green))
        assert m.result().yield_violations == expected, kind


def test_delay_and_time_to_pass() -> None:
    m = metrics()
    # ego from x = 30 at a constant 10 m/s: x(t) = 30 + 10 t
    for k in range(120):
        t = DT * (k + 1)
        m.update(make_gt(t, ego_x=30.0 + 10.0 * t))
    r = m.result()
    # target 122 + 5 = 127 reached at t = 9.7; free flow 97 m / 13.9 m/s = 6.97842 s -> delay 2.72158 s
    assert r.passed_crossing and r.delay == pytest.approx(9.7 - 97.0 / 13.9)
    # trigger: front 30 m before 118 -> x = 88 - 2.25 = 85.75 at t = 5.575; rear clears 122 at
    # x = 124.25, t = 9.425 -> 3.85 s
    assert r.time_to_pass == pytest.approx(3.85)
    assert r.distance_travelled == pytest.approx(120.0)
    m = metrics()
    m.update(make_gt(0.1, ego_x=31.0))
    r = m.result()
    assert not r.passed_crossing and math.isnan(r.delay) and math.isnan(r.time_to_pass)


def test_pedestrian_waiting_times() -> None:
    m = metrics()
    a_wait = [PedState.APPROACHING] * 2 + [PedState.WAITING] * 8 + [PedState.CROSSING]
    for k, s in enumerate(a_wait):
        t = DT * (k + 1)
        peds = [
            Ped(1, (120.0, -0.5 if s != PedState.CROSSING else 0.3), state=s),
            # pedestrian 2 steps straight off at t = 0.5 without stopping -> 0 s
            Ped(
                2, (119.0, 7.5 if k < 4 else 6.8), state=PedState.APPROACHING if k < 4 else PedState.CROSSING
            ),
            # pedestrian 3 arrives at the kerb at t = 0.6 and is still waiting at the end
            Ped(3, (121.0, -0.6), state=PedState.APPROACHING if k < 5 else PedState.WAITING),
        ]
        m.update(make_gt(t, ego_x=30.0 + t, peds=peds))
    r = m.result()
    # pedestrian 1: WAITING first seen at t = 0.3, CROSSING at t = 1.1 -> 0.8 s
    assert sorted(r.pedestrian_wait_times) == pytest.approx([0.0, 0.8])
    assert r.censored_waits == 1


# ---------------------------------------------------------------------------------------------------------
# Results, JSON and aggregation
# ---------------------------------------------------------------------------------------------------------


def _result(**kw: object) -> EpisodeResult:
    m = metrics()
    m.update(make_gt(0.1))
    return dataclasses.replace(m.result(), **kw)  # type: ignore[arg-type]


def test_as_dict_is_json_safe_and_round_trips() -> None:
    r = _result(pets_pedestrian_first=(1.5, 2.0), delay=3.25)
    d = r.as_dict()
    text = json.dumps(d, allow_nan=False)  # raises on inf / nan
    assert d["min_ttc"] is None and d["delay"] == 3.25 and d["pets_pedestrian_first"] == [1.5, 2.0]
    back = EpisodeResult.from_dict(json.loads(text))
    assert back.min_ttc == math.inf and math.isnan(back.max_impact_speed)
    assert back.pets_pedestrian_first == (1.5, 2.0) and back.delay == 3.25
    with pytest.raises(ValueError, match="missing field 'delay'"):
        EpisodeResult.from_dict({k: v for k, v in d.items() if k != "delay"})
    assert json_safe({"a": (math.inf, np.float64(2.0), np.int64(3), np.bool_(True))}) == {
        "a": [None, 2.0, 3, True]
    }


def test_wilson_interval() -> None:
    # 0/10: centre = (0 + 1.96²/20) / (1 + 1.96²/10) = 0.19208 / 1.38416 = 0.138771; half width equal
    lo, hi = wilson_interval(0, 10)
    assert lo == 0.0 and hi == pytest.approx(0.277541, abs=1e-6)
    # 5/10: centre 0.5; half = 1.96 sqrt(0.025 + 0.009604) / 1.38416 = 1.96 * 0.1860215 / 1.38416 = 0.263410
    lo, hi = wilson_interval(5, 10)
    assert lo == pytest.approx(0.236590, abs=1e-6) and hi == pytest.approx(0.763410, abs=1e-6)
    assert wilson_interval(0, 0) == (0.0, 1.0)
    # At 0 or n successes the bound is exactly the estimate: rounding put it a hair inside for n = 27
    # (0/27), which made crossing-eval's safety-vs-efficiency plot fail on a negative error bar.
    assert all(wilson_interval(0, n)[0] == 0.0 and wilson_interval(n, n)[1] == 1.0 for n in range(1, 500))
    with pytest.raises(ValueError, match="successes"):
        wilson_interval(11, 10)


def test_finite_percentiles() -> None:
    assert finite_percentiles([1.0, 2.0, 3.0, math.inf], [50]) == [2.0]
    assert finite_percentiles([1.0, 3.0], [0, 100]) == [1.0, 3.0]
    assert all(math.isnan(x) for x in finite_percentiles([math.inf, math.inf], [5, 50]))


def test_aggregate() -> None:
    results = [
        _result(collision=True, pedestrian_collisions=1, min_ttc=0.0, hard_braking_events=2,
                yield_obligations=2, yield_compliant=1, delay=4.0, passed_crossing=True),
        _result(min_ttc=1.0, hard_braking_events=0, yield_obligations=1, yield_compliant=1, delay=2.0,
                passed_crossing=True),
        _result(min_ttc=2.0, hard_braking_events=1, yield_obligations=1, yield_compliant=1),
        _result(min_ttc=math.inf, hard_braking_events=1, min_pet_pedestrian_first=1.2),
    ]  # fmt: skip
    agg = aggregate(results)
    assert agg["episodes"] == 4 and agg["collision_rate"] == 0.25
    assert agg["collision_ci95"] == pytest.approx(wilson_interval(1, 4))
    assert agg["pedestrian_collision_rate"] == 0.25
    assert agg["min_ttc_p50"] == pytest.approx(1.0)  # median of (0, 1, 2); inf ignored
    assert agg["min_ttc_finite_fraction"] == 0.75
    assert agg["serious_conflict_rate"] == 0.5  # 0.0 and 1.0 are below 1.5 s
    assert agg["hard_brakes_per_episode"] == 1.0  # (2 + 0 + 1 + 1) / 4
    assert agg["yield_compliance"] == 0.75 and agg["yield_obligations"] == 4  # (1 + 1 + 1) / (2 + 1 + 1)
    assert agg["mean_delay"] == 3.0 and agg["pass_rate"] == 0.5  # nan delays of unfinished episodes ignored
    assert agg["critical_pet_rate"] == 0.25 and agg["pet_pedestrian_first_p50"] == pytest.approx(1.2)
    json.dumps(json_safe(agg), allow_nan=False)
    with pytest.raises(ValueError, match="no episode"):
        aggregate([])


def test_reset_forgets_episode() -> None:
    m = metrics()
    m.update(make_gt(0.1, acc=-5.0, peds=[Ped(1, (40.0, 1.75))]))
    m.reset()
    m.update(make_gt(0.1))
    r = m.result()
    assert r.hard_braking_steps == 0 and r.min_separation == math.inf and r.steps == 1
