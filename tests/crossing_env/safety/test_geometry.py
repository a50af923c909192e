"""Tests of crossing_env.safety.geometry against hand-computed geometry (arithmetic in the comments)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crossing_env.safety import (
    box_box_separation,
    box_circle_separation,
    box_circle_ttc,
    crossing_drac,
    following_drac,
    following_ttc,
    rect_occupancy_interval,
    time_to_collision,
)

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


def test_min_box_disc_ttc_equals_the_minimum_of_box_circle_ttc_bit_for_bit() -> None:
    from crossing_env.safety.geometry import min_box_disc_ttc

    rng = np.random.default_rng(0)
    for trial in range(3000):
        n = int(rng.integers(1, 6))
        p = rng.normal(0.0, 10.0, (n, 2))
        v = rng.normal(0.0, 3.0, (n, 2))
        if trial % 3 == 0:  # exact zeros and integers: the slab test's ±inf and 0·inf cases
            p, v = np.round(p), np.round(v)
        r = rng.uniform(0.2, 0.4, n)
        bx, by, bvx = float(rng.normal(0.0, 5.0)), float(rng.normal(0.0, 2.0)), float(rng.uniform(0.0, 15.0))
        ref = np.min(box_circle_ttc((bx, by), (bvx, 0.0), 4.5, 1.8, p, v, r))
        got = min_box_disc_ttc(p, v, r, bx, by, bvx, 0.0, 2.25, 0.9)
        assert np.float64(got).tobytes() == np.float64(ref).tobytes()
    none = np.empty((0, 2))
    assert min_box_disc_ttc(none, none, np.empty(0), 0.0, 0.0, 1.0, 0.0, 2.25, 0.9) == math.inf
