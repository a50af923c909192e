"""Fixed-size, padded observation of the world from the ego's point of view.

Everything here is observable by a car's sensors: positions, velocities and geometric flags (on the
zebra, standing at the kerb). Hidden quantities — intentions, rationality, the decision state — never
enter the observation; they stay in the ground truth for evaluation.

Frame: the ego's heading is +x, so relative positions are world positions minus the ego's centre.
Pedestrians hidden behind a parked vehicle (line of sight from the ego's centre) or beyond the
perception range (halved at night) are not observed.

Tracks: each observed pedestrian carries a track id (``pedestrian_tracks``), as a perception stack's tracker
issues them: ids count from 1 within an episode and are never reused; a pedestrian keeps its id while it
stays observed and through an occlusion of at most `ObservationConfig.track_memory` seconds, and gets a new
one after a longer occlusion (the tracker cannot tell it is the same person), as does a new pedestrian.

Layout: the dict keys are the ``*_KEY`` constants (`BASE_KEYS` from the env, `WRAPPER_KEYS` from the
predictor wrappers) and the columns of each array are named by `EgoColumn`, `PedestrianColumn`,
`VehicleColumn` and `PointColumn` (x, y of history and path points). Readers index by these names, never
by number (``tests/test_observation_columns.py`` checks it): ``obs[PEDESTRIANS_KEY][:, PedestrianColumn.VX]``.
"""

from __future__ import annotations

import math
from enum import IntEnum
from typing import Final

import numpy as np
from gymnasium import spaces
from numba import njit

from crossing_common.cadence import HISTORY_INTERVAL
from crossing_env.types import CrossingObs, FloatArray
from scenarios.config import ObservationConfig, ScenarioConfig

__all__ = [
    "BASE_KEYS",
    "CROSSING_INTENTION_KEY",
    "CROSSING_INTENT_KEY",
    "EGO_FEATURES",
    "EGO_KEY",
    "HISTORY_INTERVAL",
    "OBSERVATION_KEYS",
    "PEDESTRIANS_KEY",
    "PEDESTRIAN_FEATURES",
    "PEDESTRIAN_HISTORY_KEY",
    "PEDESTRIAN_TRACKS_KEY",
    "POSITION_BOUND",
    "PREDICTED_PATHS_KEY",
    "PREDICTED_SAMPLES_KEY",
    "SAMPLE_WEIGHTS_KEY",
    "TRACK_ID_BOUND",
    "VEHICLES_KEY",
    "VEHICLE_FEATURES",
    "VELOCITY_BOUND",
    "WAITING_DISTANCE",
    "WAITING_SPEED",
    "WRAPPER_KEYS",
    "EgoColumn",
    "ObservationBuilder",
    "PedestrianColumn",
    "PointColumn",
    "VehicleColumn",
    "observation_space",
]

# Keys of the observation dict. The env fills the first five; the predictor wrappers add the others.
EGO_KEY: Final = "ego"
"""(6,) the ego's own state, columns `EgoColumn`."""
PEDESTRIANS_KEY: Final = "pedestrians"
"""(K, 8) one row per pedestrian slot (padded, by relevance), columns `PedestrianColumn`."""
PEDESTRIAN_HISTORY_KEY: Final = "pedestrian_history"
"""(K, H, 2) each slot's last H positions, `HISTORY_INTERVAL` apart, oldest first; columns `PointColumn`."""
PEDESTRIAN_TRACKS_KEY: Final = "pedestrian_tracks"
"""(K,) each slot's track id (1, 2, ... within an episode; 0 for a padding slot): see the module docstring."""
VEHICLES_KEY: Final = "vehicles"
"""(M, 7) one row per background vehicle slot (padded, nearest first), columns `VehicleColumn`."""
CROSSING_INTENTION_KEY: Final = "crossing_intention"
"""(K,) added by the intention wrappers: P(pedestrian on the road ahead of the ego within the horizon)."""
CROSSING_INTENT_KEY: Final = "crossing_intent"
"""(K,) added by the oracle intention: P(the pedestrian means to cross at all)."""
PREDICTED_PATHS_KEY: Final = "predicted_paths"
"""(K, T, 2) added by the trajectory wrappers: most-likely future positions, `HISTORY_INTERVAL` apart, from
one interval ahead; columns `PointColumn`."""
PREDICTED_SAMPLES_KEY: Final = "predicted_samples"
"""(K, S, T, 2) added by every path forecaster: its S path samples per slot (zeros in absent slots); columns
`PointColumn`."""
SAMPLE_WEIGHTS_KEY: Final = "sample_weights"
"""(K, S) beside ``predicted_samples``: each sample's probability (summing to 1 in a present slot, 0 in an
absent one: the samples' presence flags)."""
BASE_KEYS: Final = (EGO_KEY, PEDESTRIANS_KEY, PEDESTRIAN_HISTORY_KEY, PEDESTRIAN_TRACKS_KEY, VEHICLES_KEY)
"""The keys of the bare env's observation."""
WRAPPER_KEYS: Final = (
    CROSSING_INTENTION_KEY,
    CROSSING_INTENT_KEY,
    PREDICTED_PATHS_KEY,
    PREDICTED_SAMPLES_KEY,
    SAMPLE_WEIGHTS_KEY,
)
"""The keys the predictor wrappers add."""
OBSERVATION_KEYS: Final = BASE_KEYS + WRAPPER_KEYS
"""Every key an observation may hold."""


# The compiled kernels below index by these names: they stay in this file, so that editing them also
# refreshes numba's disk cache of the kernels (which tracks only the kernel's own file).


class EgoColumn(IntEnum):
    """Entries of ``obs[EGO_KEY]`` (last axis)."""

    SPEED = 0
    """Ego speed (m/s)."""
    ACCELERATION = 1
    """Ego acceleration (m/s²)."""
    DISTANCE_TO_STOP_LINE = 2
    """Ego front to the stop line (m; negative once past it)."""
    DISTANCE_PAST_CROSSING = 3
    """Ego rear minus the crossing's far edge (m; negative before it is cleared)."""
    CAR_GREEN = 4
    """1 unless a pedestrian signal shows the pedestrians green."""
    ZEBRA = 5
    """1 at a zebra crossing."""


class PedestrianColumn(IntEnum):
    """Columns of ``obs[PEDESTRIANS_KEY]`` (last axis); positions and velocities in the ego frame."""

    PRESENCE = 0
    """1 for an observed pedestrian, 0 for a padding slot (whose other columns are 0)."""
    DX = 1
    """x relative to the ego's centre (m, along the ego's heading)."""
    DY = 2
    """y relative to the ego's centre (m, to the ego's left)."""
    VX = 3
    """Velocity along x (m/s)."""
    VY = 4
    """Velocity along y (m/s)."""
    ON_CROSSING = 5
    """1 on the marked crossing."""
    WAITING = 6
    """1 standing (below `WAITING_SPEED`) off the road within `WAITING_DISTANCE` of the kerb."""
    ON_ROAD = 7
    """1 on the carriageway."""


class VehicleColumn(IntEnum):
    """Columns of ``obs[VEHICLES_KEY]`` (last axis); positions and velocities in the ego frame."""

    PRESENCE = 0
    """1 for an observed vehicle, 0 for a padding slot."""
    DX = 1
    """x of the vehicle's centre relative to the ego's centre (m)."""
    DY = 2
    """y relative to the ego's centre (m)."""
    VX = 3
    """Velocity along x (m/s; negative for oncoming traffic)."""
    VY = 4
    """Velocity along y (m/s; 0: vehicles keep their lane)."""
    LENGTH = 5
    """Vehicle length (m)."""
    WIDTH = 6
    """Vehicle width (m)."""


class PointColumn(IntEnum):
    """Last axis of the point arrays: pedestrian history, predicted paths and predicted samples."""

    X = 0
    """x relative to the ego's centre (m)."""
    Y = 1
    """y relative to the ego's centre (m)."""


EGO_FEATURES = tuple(column.name.lower() for column in EgoColumn)
"""Names of the `EgoColumn` entries, in order."""
PEDESTRIAN_FEATURES = tuple(column.name.lower() for column in PedestrianColumn)
"""Names of the `PedestrianColumn` columns, in order."""
VEHICLE_FEATURES = tuple(column.name.lower() for column in VehicleColumn)
"""Names of the `VehicleColumn` columns, in order."""
POSITION_BOUND = 500.0
VELOCITY_BOUND = 60.0
WAITING_SPEED = 0.3
"""Below this speed (m/s), a pedestrian within `WAITING_DISTANCE` of the kerb looks like it is waiting."""
WAITING_DISTANCE = 1.2
TRACK_ID_BOUND = float(2**24)
"""Upper bound of the track ids' Box: float32 holds every integer up to it exactly."""


def observation_space(config: ObservationConfig) -> spaces.Dict:
    """The Dict space of float32 boxes produced by `ObservationBuilder`."""
    k, m, h = config.max_pedestrians, config.max_vehicles, config.history_length
    pb, vb = POSITION_BOUND, VELOCITY_BOUND
    ego_low = np.array([0.0, -20.0, -pb, -pb, 0.0, 0.0], dtype=np.float32)
    ego_high = np.array([vb, 20.0, pb, pb, 1.0, 1.0], dtype=np.float32)
    ped_low = np.tile(np.array([0, -pb, -pb, -vb, -vb, 0, 0, 0], dtype=np.float32), (k, 1))
    ped_high = np.tile(np.array([1, pb, pb, vb, vb, 1, 1, 1], dtype=np.float32), (k, 1))
    veh_low = np.tile(np.array([0, -pb, -pb, -vb, -vb, 0, 0], dtype=np.float32), (m, 1))
    veh_high = np.tile(np.array([1, pb, pb, vb, vb, 20, 5], dtype=np.float32), (m, 1))
    return spaces.Dict(
        {
            EGO_KEY: spaces.Box(ego_low, ego_high, dtype=np.float32),
            PEDESTRIANS_KEY: spaces.Box(ped_low, ped_high, dtype=np.float32),
            PEDESTRIAN_HISTORY_KEY: spaces.Box(-pb, pb, shape=(k, h, len(PointColumn)), dtype=np.float32),
            PEDESTRIAN_TRACKS_KEY: spaces.Box(0.0, TRACK_ID_BOUND, shape=(k,), dtype=np.float32),
            VEHICLES_KEY: spaces.Box(veh_low, veh_high, dtype=np.float32),
        }
    )


class ObservationBuilder:
    """Turns the world's state into the padded observation dict.

    The per-slot work (visibility, occlusion, relevance sort, features, history) runs in compiled
    kernels below: in numpy it was ~70 small-array operations per step, the largest single cost of
    `env.step`.
    """

    def __init__(self, scenario: ScenarioConfig, config: ObservationConfig) -> None:
        self.scenario = scenario
        self.config = config
        self.space = observation_space(config)
        self.ped_range = float(config.perception_range) * (0.5 if scenario.night else 1.0)
        self.last_slots = np.full(config.max_pedestrians, -1, dtype=np.int64)
        """Pool slot shown in each pedestrian observation slot at the last call (−1 = empty)."""
        self._bounds = {key: (box.low.reshape(-1), box.high.reshape(-1)) for key, box in self.space.items()}
        crossing = scenario.crossing
        self._stop_x = crossing.position - crossing.width / 2 - crossing.stop_line_offset
        self._crossing_end = crossing.position + crossing.width / 2
        self._zebra = 1.0 if crossing.kind == "zebra" else 0.0
        self.out_of_range = 0
        """Observations whose raw values left the space and were clipped (a bug detector; tests assert 0)."""
        self.reset()

    def reset(self) -> None:
        """Forget who was seen (call at every episode start: pedestrian ids restart, track ids from 1)."""
        self._seen_id = np.full(0, -1, dtype=np.int64)
        self._visible_steps = np.zeros(0, dtype=np.int64)
        self._track = np.zeros(0, dtype=np.int64)
        self._track_owner = np.full(0, -1, dtype=np.int64)
        self._track_seen = np.zeros(0)
        self._next_track = np.ones(1, dtype=np.int64)

    def build(self, world) -> CrossingObs:
        """Observation of `world` (a `crossing_env.world.World`); fresh float32 arrays on every call."""
        cfg = self.config
        tr, peds, geo = world.traffic, world.pedestrians, world.geometry
        ex, ey = float(tr.x[0]), float(tr.y[0])
        half_len = float(tr.length[0]) / 2
        car_green = 1.0 if geo.signal is None or not geo.signal.pedestrian_green(world.time) else 0.0
        ego_obs = np.array(
            [
                tr.speed[0],
                tr.acceleration[0],
                self._stop_x - (ex + half_len),
                ex - half_len - self._crossing_end,
                car_green,
                self._zebra,
            ],
            dtype=np.float32,
        )
        if self._seen_id.size != peds.capacity:
            self._seen_id = np.full(peds.capacity, -1, dtype=np.int64)
            self._visible_steps = np.zeros(peds.capacity, dtype=np.int64)
        if self._track.size != peds.capacity:  # the episode's first call: every pool slot untracked
            self._track = np.zeros(peds.capacity, dtype=np.int64)
            self._track_owner = np.full(peds.capacity, -1, dtype=np.int64)
            self._track_seen = np.full(peds.capacity, -np.inf)
        tracks = np.zeros(cfg.max_pedestrians, dtype=np.float32)
        ped = np.zeros((cfg.max_pedestrians, len(PEDESTRIAN_FEATURES)), dtype=np.float32)
        history = np.zeros((cfg.max_pedestrians, cfg.history_length, len(PointColumn)), dtype=np.float32)
        occluders = tr.boxes(tr.parked & tr.active)
        _fill_pedestrian_slots(
            peds.position,
            peds.velocity,
            peds.state,
            peds.ids,
            peds.history,
            world.ped_on_crossing,
            peds.step_count,
            peds.history_every,
            ex,
            ey,
            half_len,
            self.ped_range,
            geo.kerb_south,
            geo.kerb_north,
            occluders,
            self._seen_id,
            self._visible_steps,
            self._track,
            self._track_owner,
            self._track_seen,
            self._next_track,
            float(world.time),
            float(cfg.track_memory),
            ped,
            history,
            tracks,
            self.last_slots,
        )
        veh = np.zeros((cfg.max_vehicles, len(VEHICLE_FEATURES)), dtype=np.float32)
        _fill_vehicle_slots(
            tr.x,
            tr.y,
            tr.speed,
            tr.direction,
            tr.length,
            tr.width,
            tr.active,
            ex,
            ey,
            cfg.perception_range,
            veh,
        )
        obs = {
            EGO_KEY: ego_obs,
            PEDESTRIANS_KEY: ped,
            PEDESTRIAN_HISTORY_KEY: history,
            PEDESTRIAN_TRACKS_KEY: tracks,
            VEHICLES_KEY: veh,
        }
        for key, value in obs.items():  # a guarantee, not a transformation: values should already fit
            low, high = self._bounds[key]
            if _clip_in_place(value.reshape(-1), low, high):
                self.out_of_range += 1
        return obs


@njit(cache=True, nogil=True)
def _segment_hits_box(x0: float, y0: float, x1: float, y1: float, box: FloatArray) -> bool:
    """Whether the segment (x0, y0)→(x1, y1) passes through the axis-aligned box (slab test)."""
    t_enter, t_exit = 0.0, 1.0
    for axis in range(2):
        start, delta = (x0, x1 - x0) if axis == 0 else (y0, y1 - y0)
        low, high = box[axis], box[axis + 2]
        if delta == 0.0:
            if start < low or start > high:
                return False
            continue
        t1, t2 = (low - start) / delta, (high - start) / delta
        t_enter = max(t_enter, min(t1, t2))
        t_exit = min(t_exit, max(t1, t2))
    return t_exit >= t_enter


@njit(cache=True, nogil=True)
def _stable_argsort(values: FloatArray) -> np.ndarray:
    """``np.argsort(values, kind="mergesort")`` (NaN last, ties in index order), exactly.

    A plain bottom-up merge sort: numba's generic one costs about 3 s of compilation on an empty cache. A
    stable sort's permutation is fixed by its order, so the indices are NumPy's. Kept in each module that
    sorts (numba refreshes a cached kernel only when its own file changes).
    """
    n = values.shape[0]
    order = np.empty(n, np.int64)
    for i in range(n):
        order[i] = i
    spare = np.empty(n, np.int64)
    width = 1
    while width < n:
        for lo in range(0, n, 2 * width):
            mid, hi = min(lo + width, n), min(lo + 2 * width, n)
            i, j = lo, mid
            for k in range(lo, hi):
                if j < hi and i < mid:
                    a, b = values[order[j]], values[order[i]]
                    take_right = a < b or (np.isnan(b) and not np.isnan(a))  # strictly before
                else:
                    take_right = j < hi
                if take_right:
                    spare[k] = order[j]
                    j += 1
                else:
                    spare[k] = order[i]
                    i += 1
        order, spare = spare, order
        width *= 2
    return order


@njit(cache=True, nogil=True)
def _fill_pedestrian_slots(
    position: FloatArray,
    velocity: FloatArray,
    state: np.ndarray,
    ids: np.ndarray,
    pool_history: FloatArray,
    on_crossing: np.ndarray,
    step_count: int,
    history_every: int,
    ex: float,
    ey: float,
    half_len: float,
    ped_range: float,
    kerb_south: float,
    kerb_north: float,
    occluders: FloatArray,
    seen_id: np.ndarray,
    visible_steps: np.ndarray,
    track: np.ndarray,
    track_owner: np.ndarray,
    track_seen: FloatArray,
    next_track: np.ndarray,
    time: float,
    track_memory: float,
    ped: FloatArray,
    history: FloatArray,
    tracks: FloatArray,
    last_slots: np.ndarray,
) -> None:
    """Fill the pedestrian slots: visible pedestrians (in range, not behind a parked car) by relevance.

    Relevance is the distance from the ego, plus 100 m for those already behind it. `seen_id` /
    `visible_steps` count, per pool slot, the consecutive steps its pedestrian has been visible: a sensor
    cannot know where a pedestrian was while hidden, so history samples older than that repeat the oldest
    one seen (or the current position if none was seen yet) — the padding of a pedestrian who has just
    appeared.

    Tracks: per pool slot, `track` (0: none), the pedestrian id it was issued for (`track_owner`) and the
    time it was last observed (`track_seen`). A visible pedestrian keeps its slot's track if it is the
    same pedestrian and was observed at most `track_memory` seconds ago; otherwise it gets the next id
    (`next_track[0]`, in pool order). Every visible pedestrian is tracked, also those beyond the K slots.
    """
    capacity = position.shape[0]
    slots, length = ped.shape[0], history.shape[1]
    key = np.full(capacity, np.inf)
    any_active = False
    for p in range(capacity):
        if state[p] == 0:
            continue
        any_active = True
        dx, dy = position[p, 0] - ex, position[p, 1] - ey
        dist = math.sqrt(dx * dx + dy * dy)
        visible = dist <= ped_range
        if visible:
            for b in range(occluders.shape[0]):
                if _segment_hits_box(ex, ey, position[p, 0], position[p, 1], occluders[b]):
                    visible = False
                    break
        if visible:
            key[p] = dist + (100.0 if dx < -2 * half_len else 0.0)
    if any_active:  # with nobody around, the counters wait (pedestrian ids never repeat)
        for p in range(capacity):
            if np.isfinite(key[p]):
                visible_steps[p] = visible_steps[p] + 1 if ids[p] == seen_id[p] else 1
                seen_id[p] = ids[p]
            else:
                visible_steps[p] = 0
                seen_id[p] = -1
    for p in range(capacity):
        if not np.isfinite(key[p]):
            continue
        if track[p] == 0 or track_owner[p] != ids[p] or time - track_seen[p] > track_memory + 1e-6:
            track[p] = next_track[0]
            next_track[0] += 1
            track_owner[p] = ids[p]
        track_seen[p] = time
    order = _stable_argsort(key)  # stable: ties keep pool order
    last_sample = step_count - step_count % history_every
    last_slots[:] = -1
    for k in range(min(slots, capacity)):  # a pool smaller than the slots fills only its own number
        p = order[k]
        if not np.isfinite(key[p]):
            break
        last_slots[k] = p
        tracks[k] = track[p]
        x, y, vx, vy = position[p, 0], position[p, 1], velocity[p, 0], velocity[p, 1]
        on_road = kerb_south < y < kerb_north
        kerb_dist = min(abs(y - kerb_south), abs(y - kerb_north))
        ped[k, PedestrianColumn.PRESENCE] = 1.0
        ped[k, PedestrianColumn.DX] = x - ex
        ped[k, PedestrianColumn.DY] = y - ey
        ped[k, PedestrianColumn.VX] = vx
        ped[k, PedestrianColumn.VY] = vy
        # The world's mask: never set without a zebra.
        ped[k, PedestrianColumn.ON_CROSSING] = 1.0 if on_crossing[p] else 0.0
        ped[k, PedestrianColumn.WAITING] = (
            1.0
            if not on_road and kerb_dist < WAITING_DISTANCE and vx * vx + vy * vy < WAITING_SPEED**2
            else 0.0
        )
        ped[k, PedestrianColumn.ON_ROAD] = 1.0 if on_road else 0.0
        first_seen = step_count - visible_steps[p] + 1
        seen = (last_sample - first_seen) // history_every + 1 if last_sample >= first_seen else 0
        first = length - min(seen, length)  # samples before this one were taken while hidden
        for t in range(length):
            if t >= first:
                history[k, t, PointColumn.X] = pool_history[p, t, 0] - ex
                history[k, t, PointColumn.Y] = pool_history[p, t, 1] - ey
            elif first < length:
                history[k, t, PointColumn.X] = pool_history[p, first, 0] - ex
                history[k, t, PointColumn.Y] = pool_history[p, first, 1] - ey
            else:
                history[k, t, PointColumn.X] = x - ex
                history[k, t, PointColumn.Y] = y - ey


@njit(cache=True, nogil=True)
def _fill_vehicle_slots(
    x: FloatArray,
    y: FloatArray,
    speed: FloatArray,
    direction: FloatArray,
    length: FloatArray,
    width: FloatArray,
    active: np.ndarray,
    ex: float,
    ey: float,
    perception_range: float,
    veh: FloatArray,
) -> None:
    """Fill the vehicle slots with the background cars in range, nearest first (slot 0, the ego, skipped)."""
    dist = np.full(x.shape[0], np.inf)
    for i in range(1, x.shape[0]):
        if active[i]:
            d = math.sqrt((x[i] - ex) ** 2 + (y[i] - ey) ** 2)
            if d <= perception_range:
                dist[i] = d
    order = _stable_argsort(dist)
    for k in range(min(veh.shape[0], x.shape[0])):
        i = order[k]
        if not np.isfinite(dist[i]):
            break
        veh[k, VehicleColumn.PRESENCE] = 1.0
        veh[k, VehicleColumn.DX] = x[i] - ex
        veh[k, VehicleColumn.DY] = y[i] - ey
        veh[k, VehicleColumn.VX] = speed[i] * direction[i]
        veh[k, VehicleColumn.LENGTH] = length[i]
        veh[k, VehicleColumn.WIDTH] = width[i]


@njit(cache=True, nogil=True)
def _clip_in_place(values: FloatArray, low: FloatArray, high: FloatArray) -> bool:
    """Clip `values` into [low, high] element-wise; True if anything was outside."""
    outside = False
    for i in range(values.shape[0]):
        if values[i] < low[i]:
            values[i] = low[i]
            outside = True
        elif values[i] > high[i]:
            values[i] = high[i]
            outside = True
    return outside
