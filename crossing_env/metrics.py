"""Safety and efficiency metrics computed from the world's ground truth, never from observations.

Definitions follow `shared/docs/safety-metrics.md` (SUMO SSM device names and defaults where they exist):
time to collision (TTC), post-encroachment time (PET), deceleration rate to avoid a crash (DRAC), minimum
separation, hard braking, yield compliance at the crossing, ego delay, time to pass, pedestrian waiting
time and collisions. Safety and efficiency are reported together: a car that never moves is "safe".

Geometry: the ego and background vehicles are axis-aligned boxes (their heading is ±x), pedestrians are
discs. All predictions assume constant velocities over the horizon (the usual TTC convention).

Layout:
- pure, vectorised geometry functions (`time_to_collision`, `box_circle_ttc`, `box_circle_separation`, ...),
- `EpisodeMetrics`, a per-step accumulator fed with `GroundTruth` snapshots, returning an `EpisodeResult`,
- aggregation helpers for the evaluation table (`wilson_interval`, `finite_percentiles`, `aggregate`).

JSON convention: `EpisodeResult.as_dict()` and `json_safe()` write non-finite floats (inf = "never",
nan = "undefined / not reached") as ``None``; `EpisodeResult.from_dict()` restores them per field.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike

from crossing_env.config import ScenarioConfig
from crossing_env.types import ConflictArea, FloatArray, GroundTruth, PedState

__all__ = [
    "EpisodeMetrics",
    "EpisodeResult",
    "MetricsConfig",
    "aggregate",
    "box_box_separation",
    "box_circle_separation",
    "box_circle_ttc",
    "crossing_drac",
    "finite_percentiles",
    "following_drac",
    "following_ttc",
    "json_safe",
    "rect_occupancy_interval",
    "time_to_collision",
    "wilson_interval",
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


# ---------------------------------------------------------------------------------------------------------
# Configuration and per-episode result
# ---------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class MetricsConfig:
    """Thresholds and the free choices of the operational definitions (SI units)."""

    hard_braking_threshold: float = 3.0
    """Deceleration (m/s², positive) counted as hard braking (crash-risk studies, ITE; `RewardConfig`)."""
    comfort_deceleration: float = 4.05
    """Deceleration (m/s²) beyond nuPlan's comfort bound (`ego_is_comfortable`, a ≥ −4.05)."""
    yield_deceleration: float = 3.0
    """Comfortable deceleration (m/s²) for the yield obligation's stopping distance v² / (2·b)."""
    serious_ttc: float = 1.5
    """TTC (s) below which a step counts as a serious conflict (Sacchi 2016; El-Basyouny 2013)."""
    encounter_ttc: float = 3.0
    """TTC (s) below which a step counts as an encounter (SUMO SSM logging threshold)."""
    critical_pet: float = 1.5
    """PET (s) below which an encounter is critical (Peesapati 2018)."""
    clearance: float = 1.0
    """Footprint distance (m) below which the ego is too close to a pedestrian (doc §5: 1–2 m typical)."""
    ttc_min_ego_speed: float = 5e-3
    """TTC is not evaluated while the ego is slower than this (m/s), as nuPlan: a stopped car is hit."""
    delay_margin: float = 5.0
    """The delay is measured until the ego centre is this far (m) past the crossing's far edge."""
    pass_trigger_distance: float = 30.0
    """Time to pass starts when the ego front is this close (m) to the crossing's near edge."""
    kerb_margin: float = 1.0
    """A waiting pedestrian counts for yielding if its x is within the crossing ± this margin (m)."""
    far_half_counts: bool = True
    """Pedestrians on the crossing in the opposite half walking towards the ego's half also create an
    obligation (UK rule 195: once a pedestrian has moved onto the crossing)."""
    offer_stop_speed: float = 0.1
    """Ego speed (m/s) regarded as stopped when offering the way."""
    offer_distance: float = 20.0
    """The ego offers the way only when stopped within this distance (m) before the stop line."""
    offer_timeout: float = 3.0
    """Stopped time (s) after which a still-waiting pedestrian is taken to have declined the offer; the
    obligation then ends as compliant (the car may go)."""


# Fields whose "missing" value means "never happened" (inf) rather than "undefined" (nan).
_INF_FIELDS = frozenset(
    {
        "min_ttc",
        "min_ttc_vehicle",
        "min_separation",
        "min_vehicle_separation",
        "min_pet_pedestrian_first",
        "min_pet_ego_first",
    }
)


@dataclass(frozen=True)
class EpisodeResult:
    """Per-episode safety and efficiency figures. Times in s, distances in m, speeds in m/s, accel. m/s²."""

    scenario: str
    """Scenario name."""
    duration: float
    """Simulation time of the last update."""
    steps: int
    """Number of updates."""
    collision: bool
    """Any ego collision (pedestrian or vehicle)."""
    pedestrian_collisions: int
    """Number of ego–pedestrian contacts."""
    vehicle_collisions: int
    """Number of ego–vehicle contacts."""
    compliant_pedestrian_collisions: int
    """Contacts with pedestrians crossing legally (`CollisionEvent.compliant`)."""
    noncompliant_pedestrian_collisions: int
    """Contacts with jaywalking / red-light pedestrians."""
    max_impact_speed: float
    """Largest ego–pedestrian impact speed; nan without pedestrian collision."""
    min_ttc: float
    """Minimum ego–pedestrian TTC (box–disc, constant velocity); inf if never on a collision course."""
    min_ttc_vehicle: float
    """Minimum following TTC to a vehicle ahead in the ego's lane; inf if never closing."""
    serious_conflict_time: float
    """Time with pedestrian TTC < `serious_ttc`."""
    encounter_time: float
    """Time with pedestrian TTC < `encounter_ttc`."""
    min_separation: float
    """Minimum ego–pedestrian footprint distance (negative = overlap); inf without pedestrians."""
    min_vehicle_separation: float
    """Minimum ego–vehicle footprint distance; inf without vehicles."""
    clearance_violation_time: float
    """Time with some pedestrian closer than `clearance` to the ego footprint."""
    max_drac_crossing: float
    """Largest crossing DRAC of the ego against pedestrians occupying the conflict area first; 0 if none."""
    max_drac_following: float
    """Largest following DRAC against vehicles ahead in the ego's lane; 0 if none."""
    min_pet_pedestrian_first: float
    """Smallest PET with the pedestrian leaving the conflict area before the ego enters; inf if none."""
    min_pet_ego_first: float
    """Smallest PET with the ego leaving before a pedestrian enters; inf if none."""
    pets_pedestrian_first: tuple[float, ...]
    """All pedestrian-first PET values (one per pedestrian and ego entry)."""
    pets_ego_first: tuple[float, ...]
    """All ego-first PET values (one per pedestrian entry after the ego left)."""
    simultaneous_occupancies: int
    """Entries into the conflict area while the other party was inside (PET undefined: a conflict)."""
    hard_braking_steps: int
    """Steps with acceleration ≤ −`hard_braking_threshold`."""
    hard_braking_events: int
    """Separate hard-braking manoeuvres (runs of consecutive hard-braking steps)."""
    comfort_violation_steps: int
    """Steps with acceleration ≤ −`comfort_deceleration`."""
    max_deceleration: float
    """Largest deceleration (positive number, SUMO maxBR); 0 if the ego never braked."""
    yield_obligations: int
    """Pedestrians the ego had to give way to (see `EpisodeMetrics`)."""
    yield_compliant: int
    """Obligations met: the ego did not enter the conflict area before the pedestrian cleared its half."""
    yield_violations: int
    """Obligations broken."""
    yield_offers_declined: int
    """Compliant obligations ended because a waiting pedestrian did not cross although the ego had stopped."""
    passed_crossing: bool
    """The ego reached the delay target (crossing far edge + `delay_margin`)."""
    delay: float
    """Time to reach the delay target minus free-flow time at the speed limit; nan if not reached."""
    time_to_pass: float
    """From the ego front `pass_trigger_distance` before the crossing until its rear clears it; nan if not."""
    distance_travelled: float
    """Ego progress along x since the start."""
    pedestrian_wait_times: tuple[float, ...]
    """Kerb arrival → stepping off, for each pedestrian who stepped off (0 if it did not stop)."""
    censored_waits: int
    """Pedestrians still waiting at the end of the episode (not in `pedestrian_wait_times`)."""

    @property
    def yield_compliance(self) -> float:
        """Compliant / obligations; nan without obligations."""
        return self.yield_compliant / self.yield_obligations if self.yield_obligations else math.nan

    def as_dict(self) -> dict[str, Any]:
        """JSON-safe dict: tuples become lists, inf and nan become None (see the module docstring)."""
        return {f.name: json_safe(getattr(self, f.name)) for f in fields(self)}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> EpisodeResult:
        """Inverse of `as_dict`: None becomes inf for the min-TTC/PET/separation fields, nan otherwise."""
        kwargs: dict[str, Any] = {}
        for f in fields(cls):
            if f.name not in data:
                raise ValueError(f"EpisodeResult.from_dict: missing field {f.name!r}")
            value = data[f.name]
            if value is None:
                value = _INF if f.name in _INF_FIELDS else math.nan
            elif isinstance(value, list):
                value = tuple(math.nan if x is None else float(x) for x in value)
            kwargs[f.name] = value
        return cls(**kwargs)


def json_safe(value: Any) -> Any:
    """Recursively convert to JSON-safe Python types: non-finite floats → None, tuples/arrays → lists."""
    if isinstance(value, bool | str) or value is None:
        return value
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, int | np.integer):
        return int(value)
    if isinstance(value, float | np.floating):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, Mapping):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return [json_safe(x) for x in value.tolist()]
    if isinstance(value, Sequence):
        return [json_safe(x) for x in value]
    return value


# ---------------------------------------------------------------------------------------------------------
# Per-pedestrian state table (ids → rows), vectorised
# ---------------------------------------------------------------------------------------------------------

_OPEN, _COMPLIANT, _VIOLATED, _WAIVED, _DECLINED = 1, 2, 3, 4, 5
_NO_STATE = -1
_APPROACHING, _WAITING, _CROSSING = int(PedState.APPROACHING), int(PedState.WAITING), int(PedState.CROSSING)


class _PedTable:
    """Rows of per-pedestrian episode state, keyed by id; lookups are vectorised (sorted ids)."""

    _FLOAT_COLS: ClassVar[tuple[str, ...]] = (
        "last_entry",
        "last_exit",
        "wait_start",
        "offer_time",
    )
    _FILL: ClassVar[dict[str, float]] = {
        "last_entry": -_INF,
        "last_exit": -_INF,
        "wait_start": math.nan,
        "offer_time": 0.0,
    }

    def __init__(self) -> None:
        self.ids = np.empty(0, dtype=np.int64)
        self.in_ca = np.empty(0, dtype=bool)
        self.entered_half = np.empty(0, dtype=bool)
        self.status = np.empty(0, dtype=np.int8)
        self.prev_state = np.empty(0, dtype=np.int64)
        for name in self._FLOAT_COLS:
            setattr(self, name, np.empty(0, dtype=np.float64))

    def rows(self, ids: np.ndarray) -> np.ndarray:
        """Row index of every id, adding rows for ids seen for the first time."""
        n = self.ids.shape[0]
        pos = np.searchsorted(self.ids, ids)
        if n == 0 or np.count_nonzero(self.ids[np.minimum(pos, n - 1)] != ids):
            self._add(ids)
            pos = np.searchsorted(self.ids, ids)
        return pos

    def _add(self, ids: np.ndarray) -> None:
        new = np.setdiff1d(np.unique(ids), self.ids)
        all_ids = np.concatenate([self.ids, new])
        order = np.argsort(all_ids, kind="stable")
        k = new.shape[0]
        self.ids = all_ids[order]
        self.in_ca = np.concatenate([self.in_ca, np.zeros(k, dtype=bool)])[order]
        self.entered_half = np.concatenate([self.entered_half, np.zeros(k, dtype=bool)])[order]
        self.status = np.concatenate([self.status, np.zeros(k, dtype=np.int8)])[order]
        self.prev_state = np.concatenate([self.prev_state, np.full(k, _NO_STATE, dtype=np.int64)])[order]
        for name in self._FLOAT_COLS:
            col = np.concatenate([getattr(self, name), np.full(k, self._FILL[name])])[order]
            setattr(self, name, col)


# ---------------------------------------------------------------------------------------------------------
# Episode accumulator
# ---------------------------------------------------------------------------------------------------------


class EpisodeMetrics:
    """Accumulates safety and efficiency metrics over one episode from `GroundTruth` snapshots.

    Call `update(gt)` after every environment step (cheap, vectorised over pedestrians and vehicles) and
    `result()` at the end. Conventions and simplifications:

    - TTC to pedestrians: exact box–disc TTC (`box_circle_ttc`), not evaluated while the ego is stopped
      (nuPlan). TTC to vehicles: following TTC to vehicles ahead whose footprint overlaps the ego's
      laterally (same lane); vehicles behind the ego and oncoming traffic are not scored.
    - Conflict area (CA) = `GroundTruth.conflict_area` (ego lane × crossing). The ego occupies it when its
      box overlaps the rectangle, a pedestrian when its centre is on the carriageway (`on_road`, so people
      at the kerb do not count) and its disc's bounding square overlaps the rectangle (conservative by at
      most r·(√2 − 1) ≈ 0.12 m at the rectangle's corners; it shares the slab test with the DRAC).
      Entry and exit times have the resolution of one step.
    - PET: at each ego entry, one pedestrian-first PET per pedestrian that left the CA since the ego's
      previous entry; at each pedestrian entry, one ego-first PET if the ego left the CA since that
      pedestrian's previous entry. Entering while the other is inside counts as a simultaneous occupancy.
    - Crossing DRAC: for each pedestrian whose constant-velocity disc (rectangle grown by its radius) will
      occupy the CA before the ego front reaches it and still occupy it then, `crossing_drac` of the ego
      with t_A = the pedestrian's exit time; pedestrians are never asked to brake (ego-first case unscored).
    - Yield compliance (doc §7, simplified): only at a zebra, or at a signalised crossing while the
      pedestrian signal is green. A pedestrian creates one obligation per episode when, with the ego front
      farther than v²/(2·`yield_deceleration`) from the stop line, it is on the crossing in the ego's half
      (or, with `far_half_counts`, in the other half walking towards it) or waiting at the kerb within
      `kerb_margin` of the crossing. The obligation is violated if the ego footprint is in the CA while it
      is open; it ends compliant when the pedestrian, having entered the ego's half, is outside it again
      (crossed or turned back), or when the ego has stood still within `offer_distance` of the stop line
      for `offer_timeout` while the pedestrian kept waiting (declined offer); it is dropped (not counted)
      if the pedestrian leaves the kerb without crossing (state neither `WAITING` nor `CROSSING`, centre
      off the road) before entering the ego's half. Obligations still open at the
      end count as compliant. The German "influenced" test (pedestrian forced to slow down) is not
      applied: it would need the pedestrian's desired speed, which the ground truth does not carry.
    - Delay: from t = 0 at `EgoConfig.x` until the ego centre passes `conflict_area.x_max + delay_margin`
      (linear interpolation between steps), minus that distance at the speed limit.
    - Pedestrian waiting time: first step seen `WAITING` → first step seen `CROSSING`; 0 for pedestrians
      that step off straight from `APPROACHING`.
    """

    def __init__(self, scenario: ScenarioConfig, dt: float, config: MetricsConfig | None = None) -> None:
        """Create an accumulator for one episode of `scenario` stepped every `dt` seconds."""
        if not (isinstance(dt, int | float) and math.isfinite(dt) and dt > 0.0):
            raise ValueError(f"EpisodeMetrics: dt must be a positive finite number of seconds, got {dt!r}")
        self.scenario = scenario
        self.dt = float(dt)
        self.config = config if config is not None else MetricsConfig()
        self.reset()

    def reset(self) -> None:
        """Forget everything (reuse the accumulator for a new episode of the same scenario)."""
        self.step_ttc = _INF
        """Minimum ego–pedestrian TTC of the latest update (inf if none or the ego stands), for plots."""
        self.step_separation = _INF
        """Minimum ego–pedestrian footprint distance of the latest update (inf without pedestrians)."""
        self.step_drac = 0.0
        """Crossing DRAC of the latest update (0 if no pedestrian holds the conflict area first)."""
        self._steps = 0
        self._time = 0.0
        self._start_x = float(self.scenario.ego.x)
        self._last_x = self._start_x
        self._last_front = math.nan
        self._last_rear = math.nan
        self._last_t = 0.0
        # collisions
        self._ped_collisions = 0
        self._veh_collisions = 0
        self._compliant_collisions = 0
        self._max_impact = math.nan
        # TTC / separation / DRAC
        self._min_ttc = _INF
        self._min_ttc_veh = _INF
        self._serious_time = 0.0
        self._encounter_time = 0.0
        self._min_sep = _INF
        self._min_sep_veh = _INF
        self._clearance_time = 0.0
        self._max_drac_cross = 0.0
        self._max_drac_follow = 0.0
        # PET
        self._ego_in_ca = False
        self._ego_last_entry = -_INF
        self._ego_last_exit = -_INF
        self._pets_ped_first: list[float] = []
        self._pets_ego_first: list[float] = []
        self._simultaneous = 0
        # braking
        self._hard_steps = 0
        self._hard_events = 0
        self._was_hard = False
        self._comfort_steps = 0
        self._max_decel = 0.0
        # efficiency
        self._target_x = math.nan
        self._reach_time = math.nan
        self._trigger_time = math.nan
        self._clear_time = math.nan
        self._waits: list[float] = []
        self._peds = _PedTable()
        self._ca: ConflictArea | None = None
        self._ca_arrays: tuple[np.ndarray, np.ndarray] = (np.zeros(2), np.zeros(2))
        self._size: tuple[float, float] = (math.nan, math.nan)
        self._half: np.ndarray | None = None

    # -- per step -------------------------------------------------------------------------------------

    def update(self, gt: GroundTruth) -> None:
        """Add one ground-truth snapshot (call once per environment step, in time order)."""
        cfg = self.config
        t = float(gt.time)
        if t < self._last_t:
            raise ValueError(f"EpisodeMetrics.update: GroundTruth.time went backwards ({t} < {self._last_t})")
        ca = gt.conflict_area
        ego_p = gt.ego_position
        ego_v = gt.ego_velocity
        ex, ey = float(ego_p[0]), float(ego_p[1])
        evx = float(ego_v[0])
        speed = math.hypot(evx, float(ego_v[1]))
        length, width = gt.ego_size
        front, rear = ex + 0.5 * length, ex - 0.5 * length
        self._steps += 1
        if self._steps == 1:
            self._target_x = ca.x_max + cfg.delay_margin
            self._last_front = self._start_x + 0.5 * length
            self._last_rear = self._start_x - 0.5 * length

        # Braking and comfort.
        acc = float(gt.ego_acceleration)
        hard = acc <= -cfg.hard_braking_threshold
        self._hard_steps += hard
        self._hard_events += hard and not self._was_hard
        self._was_hard = hard
        self._comfort_steps += acc <= -cfg.comfort_deceleration
        if -acc > self._max_decel:
            self._max_decel = -acc

        # Efficiency: interpolated crossing times of the delay target, the pass trigger and the clearing.
        t0 = self._last_t
        if math.isnan(self._reach_time) and ex >= self._target_x:
            self._reach_time = _cross_time(t0, t, self._last_x, ex, self._target_x)
        trig = ca.x_min - cfg.pass_trigger_distance
        if math.isnan(self._trigger_time) and front >= trig:
            self._trigger_time = _cross_time(t0, t, self._last_front, front, trig)
        if math.isnan(self._clear_time) and rear >= ca.x_max:
            self._clear_time = _cross_time(t0, t, self._last_rear, rear, ca.x_max)
        self._last_t, self._last_x, self._last_front, self._last_rear = t, ex, front, rear

        # Ego occupancy of the conflict area.
        ego_in = (
            front > ca.x_min
            and rear < ca.x_max
            and ey + 0.5 * width > ca.y_min
            and ey - 0.5 * width < ca.y_max
        )
        ego_entered = ego_in and not self._ego_in_ca
        if not ego_in and self._ego_in_ca:
            self._ego_last_exit = t
        prev_ego_entry = self._ego_last_entry
        if ego_entered:
            self._ego_last_entry = t
        self._ego_in_ca = ego_in

        # Collisions.
        for ev in gt.collisions:
            if ev.kind == "pedestrian":
                self._ped_collisions += 1
                self._compliant_collisions += bool(ev.compliant)
                if not ev.relative_speed <= self._max_impact:  # also replaces the initial nan
                    self._max_impact = float(ev.relative_speed)
            else:
                self._veh_collisions += 1

        if self._half is None or self._size != (length, width):
            self._size = (length, width)
            self._half = np.array([0.5 * length, 0.5 * width])
        self.step_ttc, self.step_separation, self.step_drac = _INF, _INF, 0.0
        if gt.vehicle_ids.shape[0]:
            self._update_vehicles(gt, evx, self._half)
        if gt.pedestrian_ids.shape[0]:
            self._update_pedestrians(gt, t, ego_in, ego_entered, prev_ego_entry, front, speed, self._half)
        self._time = t

    def _update_vehicles(self, gt: GroundTruth, evx: float, half: np.ndarray) -> None:
        """Following TTC / DRAC against vehicles ahead in the ego's lane, and box–box separation."""
        q = gt.vehicle_positions - gt.ego_position
        reach = half + 0.5 * gt.vehicle_sizes  # half extents of the Minkowski sum of both boxes
        d = np.abs(q) - reach
        dx, dy = d[:, 0], d[:, 1]
        sep = np.hypot(np.maximum(dx, 0.0), np.maximum(dy, 0.0)) + np.minimum(np.maximum(dx, dy), 0.0)
        min_sep = float(sep.min())
        if min_sep < self._min_sep_veh:
            self._min_sep_veh = min_sep
        ahead = (q[:, 0] > 0.0) & (dy < 0.0)  # in front and overlapping laterally: same lane
        if np.count_nonzero(ahead):
            gap = dx[ahead]  # bumper-to-bumper distance (q_x > 0)
            closing = evx - gt.vehicle_velocities[ahead, 0]
            fast = closing > 0.0
            if np.count_nonzero(fast):
                gap, closing = gap[fast], closing[fast]
                with np.errstate(divide="ignore"):
                    ttc = float((np.maximum(gap, 0.0) / closing).min())
                    drac = float((0.5 * closing * closing / np.maximum(gap, 0.0)).max())
                self._min_ttc_veh = min(self._min_ttc_veh, ttc)
                self._max_drac_follow = max(self._max_drac_follow, drac)

    def _conflict_arrays(self, ca: ConflictArea) -> tuple[np.ndarray, np.ndarray]:
        """Low and high corners of the conflict area as arrays, cached across steps."""
        if ca != self._ca:
            self._ca = ca
            self._ca_arrays = (np.array([ca.x_min, ca.y_min]), np.array([ca.x_max, ca.y_max]))
        return self._ca_arrays

    def _update_pedestrians(
        self,
        gt: GroundTruth,
        t: float,
        ego_in: bool,
        ego_entered: bool,
        prev_ego_entry: float,
        front: float,
        speed: float,
        half: np.ndarray,
    ) -> None:
        """Per-pedestrian TTC, separation, DRAC, PET, yielding and waiting, vectorised over pedestrians."""
        cfg = self.config
        dt = self.dt
        ca = gt.conflict_area
        tab = self._peds
        rows = tab.rows(gt.pedestrian_ids)
        pp: FloatArray = gt.pedestrian_positions
        pv: FloatArray = gt.pedestrian_velocities
        rad = gt.pedestrian_radii
        ca_lo, ca_hi = self._conflict_arrays(ca)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            # Separation: signed distance from each disc to the ego box.
            q = pp - gt.ego_position
            d = np.abs(q) - half
            sep = np.hypot(np.maximum(d[:, 0], 0.0), np.maximum(d[:, 1], 0.0))
            sep += np.minimum(np.maximum(d[:, 0], d[:, 1]), 0.0) - rad
            min_sep = float(sep.min())
            self.step_separation = min_sep
            if min_sep < self._min_sep:
                self._min_sep = min_sep
            if min_sep < cfg.clearance:
                self._clearance_time += dt
            # TTC: exact box–disc, only while the ego moves.
            if speed > cfg.ttc_min_ego_speed:
                min_ttc = float(_box_disc_ttc(q, pv - gt.ego_velocity, half, rad).min())
                self.step_ttc = min_ttc
                if min_ttc < self._min_ttc:
                    self._min_ttc = min_ttc
                if min_ttc < cfg.serious_ttc:
                    self._serious_time += dt
                if min_ttc < cfg.encounter_ttc:
                    self._encounter_time += dt
            # Conflict-area occupancy interval of each disc's bounding square (constant velocity).
            margin = rad[:, None]
            t_in, t_out = _slabs(pp, pv, ca_lo - margin, ca_hi + margin)
            ped_in = (t_in <= 0.0) & (t_out >= 0.0) & gt.on_road
            # Crossing DRAC: pedestrians holding the conflict area when the ego front would reach it.
            d_b = ca.x_min - front
            evx = float(gt.ego_velocity[0])
            if d_b > 0.0 and evx > 0.0:
                t_ego = d_b / evx
                first = (t_in <= t_ego) & (t_out > t_ego)
                if np.count_nonzero(first):
                    # crossing_drac is non-decreasing in t_A, so the latest exit gives the maximum.
                    drac = _crossing_drac_scalar(evx, d_b, float(t_out[first].max()))
                    self.step_drac = drac
                    if drac > self._max_drac_cross:
                        self._max_drac_cross = drac

        was_in = tab.in_ca[rows]
        if ego_entered or np.count_nonzero(ped_in != was_in):
            self._update_pet(t, rows, ped_in, was_in, ego_in, ego_entered, prev_ego_entry)

        # Pedestrian waiting times (only on state changes).
        states = gt.pedestrian_states
        prev = tab.prev_state[rows]
        changed = states != prev
        if np.count_nonzero(changed):
            self._update_waits(t, rows, states, prev, changed)

        self._update_yielding(gt, rows, front, speed)

    def _update_pet(
        self,
        t: float,
        rows: np.ndarray,
        ped_in: np.ndarray,
        was_in: np.ndarray,
        ego_in: bool,
        ego_entered: bool,
        prev_ego_entry: float,
    ) -> None:
        """Record conflict-area entries and exits and the PET pairs they close."""
        tab = self._peds
        tab.last_exit[rows[was_in & ~ped_in]] = t
        # Pedestrian first: the ego enters after pedestrians that left since its previous entry.
        if ego_entered:
            self._simultaneous += int(np.count_nonzero(ped_in))  # pedestrians inside as the ego enters
            last_exit = tab.last_exit[rows]
            pair = ~ped_in & (last_exit > prev_ego_entry)
            if np.count_nonzero(pair):
                self._pets_ped_first.extend((t - last_exit[pair]).tolist())
        # Ego first: a pedestrian enters after the ego left since that pedestrian's previous entry.
        entered = ped_in & ~was_in
        if np.count_nonzero(entered):
            if ego_in and not ego_entered:
                self._simultaneous += int(np.count_nonzero(entered))
            elif not ego_in:
                pair = entered & (tab.last_entry[rows] < self._ego_last_exit)
                self._pets_ego_first.extend([t - self._ego_last_exit] * int(np.count_nonzero(pair)))
            tab.last_entry[rows[entered]] = t
        tab.in_ca[rows] = ped_in

    def _update_waits(
        self, t: float, rows: np.ndarray, states: np.ndarray, prev: np.ndarray, changed: np.ndarray
    ) -> None:
        """Kerb arrival → stepping off, from `PedState` transitions."""
        tab = self._peds
        tab.wait_start[rows[changed & (states == _WAITING)]] = t
        step_off = changed & (states == _CROSSING) & ((prev == _WAITING) | (prev == _APPROACHING))
        if np.count_nonzero(step_off):
            r_off = rows[step_off]
            ws = tab.wait_start[r_off]
            self._waits.extend(np.where(np.isnan(ws), 0.0, t - ws).tolist())
        # Leaving the kerb any other way (stepping off, giving up, vanishing) ends the wait.
        tab.wait_start[rows[changed & (prev == _WAITING)]] = math.nan
        tab.prev_state[rows] = states

    def _update_yielding(self, gt: GroundTruth, rows: np.ndarray, front: float, speed: float) -> None:
        """Open, resolve and check yield obligations (see the class docstring)."""
        kind = self.scenario.crossing.kind
        if kind == "none":
            return
        # At a signal, obligations open only on pedestrian green; ones opened earlier are still checked.
        may_open = kind != "signalised" or bool(gt.signal_pedestrian_green)
        cfg = self.config
        ca = gt.conflict_area
        tab = self._peds
        status = tab.status[rows]
        open_ = status == _OPEN
        dist = ca.stop_line_x - front
        can_open = may_open and dist > speed * speed / (2.0 * cfg.yield_deceleration)
        candidates = can_open and np.count_nonzero((gt.on_crossing | gt.waiting) & (status == 0))
        if not candidates and not np.count_nonzero(open_):
            return  # nothing open and nobody who could open an obligation now

        px = gt.pedestrian_positions[:, 0]
        py = gt.pedestrian_positions[:, 1]
        in_half = gt.on_road & (py >= ca.half_y_min) & (py <= ca.half_y_max)
        near = np.abs(px - 0.5 * (ca.x_min + ca.x_max)) <= 0.5 * (ca.x_max - ca.x_min) + cfg.kerb_margin
        waiting = gt.waiting & near

        # Resolve open obligations from the pedestrians' side.
        entered_half = tab.entered_half[rows] | (open_ & in_half)
        cleared = open_ & entered_half & ~in_half
        states = gt.pedestrian_states
        gave_up = (states != _WAITING) & (states != _CROSSING) & ~gt.on_road  # walked off, never stepped on
        dropped = open_ & ~entered_half & gave_up
        status = np.where(cleared, _COMPLIANT, np.where(dropped, _WAIVED, status))

        # Declined offers: the ego stands just before the stop line while the pedestrian keeps waiting.
        if speed <= cfg.offer_stop_speed and 0.0 <= dist <= cfg.offer_distance:
            offering = (status == _OPEN) & waiting
            if np.count_nonzero(offering):
                r_off = rows[offering]
                tab.offer_time[r_off] += self.dt
                status[offering] = np.where(
                    tab.offer_time[r_off] >= cfg.offer_timeout - 1e-9, _DECLINED, _OPEN
                )

        # Open new obligations while the ego can still stop comfortably before the stop line.
        if can_open:
            relevant = gt.on_crossing & in_half
            if cfg.far_half_counts:
                toward = (0.5 * (ca.half_y_min + ca.half_y_max) - py) * gt.pedestrian_velocities[:, 1] > 0.0
                relevant |= gt.on_crossing & ~in_half & toward
            new = (status == 0) & (relevant | waiting)
            status[new] = _OPEN
            entered_half |= new & in_half

        # Violations: the ego occupies the conflict area while an obligation is open.
        if self._ego_in_ca:
            status[status == _OPEN] = _VIOLATED
        tab.status[rows] = status
        tab.entered_half[rows] = entered_half

    # -- end of episode -------------------------------------------------------------------------------

    def result(self) -> EpisodeResult:
        """Summarise the episode so far (can be called at any time; does not reset)."""
        road = self.scenario.road
        status = self._peds.status
        compliant = int(np.count_nonzero((status == _OPEN) | (status == _COMPLIANT) | (status == _DECLINED)))
        violations = int(np.count_nonzero(status == _VIOLATED))
        passed = not math.isnan(self._reach_time)
        delay = math.nan
        if passed:
            free_flow = (self._target_x - self._start_x) / road.speed_limit
            delay = self._reach_time - free_flow
        ttp = math.nan
        if not math.isnan(self._clear_time):
            trigger = 0.0 if math.isnan(self._trigger_time) else self._trigger_time
            ttp = self._clear_time - trigger
        pets_p = tuple(self._pets_ped_first)
        pets_e = tuple(self._pets_ego_first)
        return EpisodeResult(
            scenario=self.scenario.name,
            duration=self._time,
            steps=self._steps,
            collision=self._ped_collisions + self._veh_collisions > 0,
            pedestrian_collisions=self._ped_collisions,
            vehicle_collisions=self._veh_collisions,
            compliant_pedestrian_collisions=self._compliant_collisions,
            noncompliant_pedestrian_collisions=self._ped_collisions - self._compliant_collisions,
            max_impact_speed=self._max_impact,
            min_ttc=self._min_ttc,
            min_ttc_vehicle=self._min_ttc_veh,
            serious_conflict_time=self._serious_time,
            encounter_time=self._encounter_time,
            min_separation=self._min_sep,
            min_vehicle_separation=self._min_sep_veh,
            clearance_violation_time=self._clearance_time,
            max_drac_crossing=self._max_drac_cross,
            max_drac_following=self._max_drac_follow,
            min_pet_pedestrian_first=min(pets_p, default=_INF),
            min_pet_ego_first=min(pets_e, default=_INF),
            pets_pedestrian_first=pets_p,
            pets_ego_first=pets_e,
            simultaneous_occupancies=self._simultaneous,
            hard_braking_steps=int(self._hard_steps),
            hard_braking_events=int(self._hard_events),
            comfort_violation_steps=int(self._comfort_steps),
            max_deceleration=self._max_decel,
            yield_obligations=compliant + violations,
            yield_compliant=compliant,
            yield_violations=violations,
            yield_offers_declined=int(np.count_nonzero(status == _DECLINED)),
            passed_crossing=passed,
            delay=delay,
            time_to_pass=ttp,
            distance_travelled=self._last_x - self._start_x,
            pedestrian_wait_times=tuple(self._waits),
            censored_waits=int(np.count_nonzero(~np.isnan(self._peds.wait_start))),
        )


def _cross_time(t0: float, t1: float, x0: float, x1: float, target: float) -> float:
    """Time at which a coordinate moving linearly from x0 (t0) to x1 (t1) reaches target."""
    if x1 <= x0 or target <= x0:
        return t0 if target <= x0 else t1
    return t0 + (t1 - t0) * (target - x0) / (x1 - x0)


# ---------------------------------------------------------------------------------------------------------
# Aggregation over episodes
# ---------------------------------------------------------------------------------------------------------


def wilson_interval(successes: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """Wilson score interval for a binomial proportion (95% for z = 1.96).

    Preferred over the normal approximation because it stays inside [0, 1] and is sensible at 0 or n
    successes, the usual case for collision rates. Returns (0, 1) for n = 0 (nothing is known).
    """
    if n < 0 or successes < 0 or successes > n:
        raise ValueError(f"wilson_interval: need 0 <= successes <= n, got successes={successes}, n={n}")
    if n == 0:
        return 0.0, 1.0
    p = successes / n
    z2 = z * z
    denom = 1.0 + z2 / n
    centre = (p + z2 / (2 * n)) / denom
    half = z * math.sqrt(p * (1.0 - p) / n + z2 / (4 * n * n)) / denom
    return max(0.0, centre - half), min(1.0, centre + half)


def finite_percentiles(values: ArrayLike, qs: Sequence[float]) -> list[float]:
    """Percentiles (0–100) of the finite values only (inf = "never" is ignored); nan if none is finite."""
    arr = np.asarray(values, dtype=np.float64).ravel()
    arr = arr[np.isfinite(arr)]
    if arr.size == 0:
        return [math.nan for _ in qs]
    return [float(x) for x in np.percentile(arr, list(qs))]


def _mean(values: Sequence[float] | np.ndarray) -> float:
    arr = np.asarray(values, dtype=np.float64)
    arr = arr[~np.isnan(arr)]
    return float(arr.mean()) if arr.size else math.nan


def aggregate(results: Sequence[EpisodeResult], config: MetricsConfig | None = None) -> dict[str, Any]:
    """Summarise episodes for the evaluation table.

    Keys (floats may be nan when undefined; pass through `json_safe` before writing JSON):
    episodes; collision_rate and collision_ci95 (any collision, Wilson); pedestrian_collision_rate and
    pedestrian_collision_ci95; compliant/noncompliant_pedestrian_collisions; mean_impact_speed;
    min_ttc_p5/p50 (episode minima, inf ignored), min_ttc_finite_fraction (episodes with a finite minimum
    TTC, to read the percentiles against) and serious_conflict_rate (episodes with min TTC <
    `serious_ttc`); min_separation_p5/p50; pet_pedestrian_first_p5/p50, pet_ego_first_p5/p50 and
    critical_pet_rate (episodes with a PET < `critical_pet`); simultaneous_occupancies; drac_crossing_mean /
    _max and drac_following_max; hard_brakes_per_episode (events), comfort_violations_per_episode (steps),
    max_deceleration_mean; yield_obligations, yield_compliance (= compliant / obligations) and
    yield_compliance_ci95; pass_rate, mean_delay and mean_time_to_pass (episodes that passed);
    mean_pedestrian_wait; mean_distance.
    """
    cfg = config if config is not None else MetricsConfig()
    n = len(results)
    if n == 0:
        raise ValueError("aggregate: no episode results given")

    def col(name: str) -> np.ndarray:
        return np.array([getattr(r, name) for r in results], dtype=np.float64)

    collisions = sum(r.collision for r in results)
    ped_coll = sum(r.pedestrian_collisions > 0 for r in results)
    min_ttc = col("min_ttc")
    pet_p = col("min_pet_pedestrian_first")
    pet_e = col("min_pet_ego_first")
    obligations = sum(r.yield_obligations for r in results)
    compliant = sum(r.yield_compliant for r in results)
    ttc5, ttc50 = finite_percentiles(min_ttc, (5, 50))
    sep5, sep50 = finite_percentiles(col("min_separation"), (5, 50))
    pp5, pp50 = finite_percentiles(pet_p, (5, 50))
    pe5, pe50 = finite_percentiles(pet_e, (5, 50))
    passed = np.array([r.passed_crossing for r in results])
    drac = col("max_drac_crossing")
    waits = [w for r in results for w in r.pedestrian_wait_times]
    return {
        "episodes": n,
        "collision_rate": collisions / n,
        "collision_ci95": wilson_interval(collisions, n),
        "pedestrian_collision_rate": ped_coll / n,
        "pedestrian_collision_ci95": wilson_interval(ped_coll, n),
        "compliant_pedestrian_collisions": sum(r.compliant_pedestrian_collisions for r in results),
        "noncompliant_pedestrian_collisions": sum(r.noncompliant_pedestrian_collisions for r in results),
        "mean_impact_speed": _mean(col("max_impact_speed")),
        "min_ttc_p5": ttc5,
        "min_ttc_p50": ttc50,
        "min_ttc_finite_fraction": float(np.mean(np.isfinite(min_ttc))),
        "serious_conflict_rate": float(np.mean(min_ttc < cfg.serious_ttc)),
        "min_separation_p5": sep5,
        "min_separation_p50": sep50,
        "pet_pedestrian_first_p5": pp5,
        "pet_pedestrian_first_p50": pp50,
        "pet_ego_first_p5": pe5,
        "pet_ego_first_p50": pe50,
        "critical_pet_rate": float(np.mean(np.minimum(pet_p, pet_e) < cfg.critical_pet)),
        "simultaneous_occupancies": sum(r.simultaneous_occupancies for r in results),
        "drac_crossing_mean": float(drac[np.isfinite(drac)].mean()) if np.isfinite(drac).any() else math.nan,
        "drac_crossing_max": float(drac.max()),
        "drac_following_max": float(col("max_drac_following").max()),
        "hard_brakes_per_episode": float(col("hard_braking_events").mean()),
        "comfort_violations_per_episode": float(col("comfort_violation_steps").mean()),
        "max_deceleration_mean": float(col("max_deceleration").mean()),
        "yield_obligations": obligations,
        "yield_compliance": compliant / obligations if obligations else math.nan,
        "yield_compliance_ci95": wilson_interval(compliant, obligations),
        "pass_rate": float(passed.mean()),
        "mean_delay": _mean(col("delay")),
        "mean_time_to_pass": _mean(col("time_to_pass")),
        "mean_pedestrian_wait": _mean(waits),
        "mean_distance": float(col("distance_travelled").mean()),
    }
