"""Fixed-size, padded observation of the world from the ego's point of view.

Everything here is observable by a car's sensors: positions, velocities and geometric flags (on the
zebra, standing at the kerb). Hidden quantities — intentions, rationality, the decision state — never
enter the observation; they stay in the ground truth for evaluation.

Frame: the ego's heading is +x, so relative positions are world positions minus the ego's centre.
Pedestrians hidden behind a parked vehicle (line of sight from the ego's centre) or beyond the
perception range (halved at night) are not observed.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from crossing_env.config import ObservationConfig, ScenarioConfig
from crossing_env.types import CrossingObs, FloatArray

EGO_FEATURES = (
    "speed",
    "acceleration",
    "distance_to_stop_line",
    "distance_past_crossing",
    "car_green",
    "zebra",
)
PEDESTRIAN_FEATURES = ("presence", "dx", "dy", "vx", "vy", "on_crossing", "waiting", "on_road")
VEHICLE_FEATURES = ("presence", "dx", "dy", "vx", "vy", "length", "width")
POSITION_BOUND = 500.0
VELOCITY_BOUND = 60.0
WAITING_SPEED = 0.3
"""Below this speed (m/s), a pedestrian within `WAITING_DISTANCE` of the kerb looks like it is waiting."""
WAITING_DISTANCE = 1.2


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
            "ego": spaces.Box(ego_low, ego_high, dtype=np.float32),
            "pedestrians": spaces.Box(ped_low, ped_high, dtype=np.float32),
            "pedestrian_history": spaces.Box(-pb, pb, shape=(k, h, 2), dtype=np.float32),
            "vehicles": spaces.Box(veh_low, veh_high, dtype=np.float32),
        }
    )


def _segment_hits_boxes(start: FloatArray, ends: FloatArray, boxes: FloatArray) -> np.ndarray:
    """(P,) whether the segment start→end[p] passes through any box (slab test, vectorised)."""
    if boxes.shape[0] == 0 or ends.shape[0] == 0:
        return np.zeros(ends.shape[0], dtype=bool)
    d = ends - start  # (P, 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / d
        t1 = (boxes[None, :, 0:2] - start) * inv[:, None, :]
        t2 = (boxes[None, :, 2:4] - start) * inv[:, None, :]
    t1 = np.nan_to_num(t1, nan=-np.inf)
    t2 = np.nan_to_num(t2, nan=np.inf)
    tmin = np.max(np.minimum(t1, t2), axis=2)
    tmax = np.min(np.maximum(t1, t2), axis=2)
    hit = (tmax >= np.maximum(tmin, 0.0)) & (tmin <= 1.0)
    return hit.any(axis=1)


class ObservationBuilder:
    """Turns the world's state into the padded observation dict."""

    def __init__(self, scenario: ScenarioConfig, config: ObservationConfig) -> None:
        self.scenario = scenario
        self.config = config
        self.space = observation_space(config)
        self.ped_range = config.perception_range * (0.5 if scenario.night else 1.0)
        self.last_slots = np.full(config.max_pedestrians, -1, dtype=np.int64)
        """Pool slot shown in each pedestrian observation slot at the last call (−1 = empty)."""
        self._low = {key: box.low for key, box in self.space.items()}
        self._high = {key: box.high for key, box in self.space.items()}
        crossing = scenario.crossing
        self._stop_x = crossing.position - crossing.width / 2 - crossing.stop_line_offset
        self._crossing_end = crossing.position + crossing.width / 2
        self._zebra = 1.0 if crossing.kind == "zebra" else 0.0
        self.out_of_range = 0
        """Observations whose raw values left the space and were clipped (a bug detector; tests assert 0)."""
        self.reset()

    def reset(self) -> None:
        """Forget who was seen (call at every episode start: pedestrian ids restart)."""
        self._seen_id = np.full(0, -1, dtype=np.int64)
        self._visible_steps = np.zeros(0, dtype=np.int64)

    def _track_visibility(self, peds, visible_rows: np.ndarray) -> np.ndarray:
        """Update, per pool slot, how many consecutive steps its pedestrian has been visible."""
        if self._seen_id.size != peds.capacity:
            self._seen_id = np.full(peds.capacity, -1, dtype=np.int64)
            self._visible_steps = np.zeros(peds.capacity, dtype=np.int64)
        visible = np.zeros(peds.capacity, dtype=bool)
        visible[visible_rows] = True
        same = peds.ids == self._seen_id
        self._visible_steps = np.where(visible, np.where(same, self._visible_steps + 1, 1), 0)
        self._seen_id = np.where(visible, peds.ids, -1)
        return self._visible_steps

    @staticmethod
    def _seen_history(peds, rows: np.ndarray, visible_steps: np.ndarray) -> np.ndarray:
        """History of `rows` with samples taken before the pedestrian came into view replaced.

        A sensor cannot know where a pedestrian was while it was hidden (behind a parked van, beyond range):
        those samples repeat the oldest one seen, or the current position if no sample was seen yet — the
        same padding as for a pedestrian who has just appeared.
        """
        hist = peds.history[rows]
        length = hist.shape[1]
        n, every = peds.step_count, peds.history_every
        last_sample = n - n % every
        first_seen = n - visible_steps[rows] + 1
        seen = np.where(last_sample >= first_seen, (last_sample - first_seen) // every + 1, 0)
        seen = np.minimum(seen, length)
        if np.all(seen == length):
            return hist
        extended = np.concatenate([hist, peds.position[rows][:, None, :]], axis=1)
        index = np.maximum(np.arange(length)[None, :], (length - seen)[:, None])
        return np.take_along_axis(extended, index[:, :, None], axis=1)

    def build(self, world) -> CrossingObs:
        """Observation of `world` (a `crossing_env.world.World`); fresh float32 arrays on every call."""
        cfg = self.config
        tr, peds, geo = world.traffic, world.pedestrians, world.geometry
        ex, ey = tr.x[0], tr.y[0]
        half_len = tr.length[0] / 2
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

        # Pedestrians: visible ones sorted by relevance (ahead of the ego and close to its path first).
        act = np.flatnonzero(peds.state)
        ped = np.zeros((cfg.max_pedestrians, len(PEDESTRIAN_FEATURES)), dtype=np.float32)
        history = np.zeros((cfg.max_pedestrians, cfg.history_length, 2), dtype=np.float32)
        n = 0
        rows = act
        if act.size:
            pos = peds.position[act]
            dx, dy = pos[:, 0] - ex, pos[:, 1] - ey
            dist = np.sqrt(dx * dx + dy * dy)
            visible = dist <= self.ped_range
            parked = tr.parked & tr.active
            if parked.any():
                visible &= ~_segment_hits_boxes(np.array([ex, ey]), pos, tr.boxes(parked))
            visible_steps = self._track_visibility(peds, act[visible])
            key = np.where(visible, dist + np.where(dx < -2 * half_len, 100.0, 0.0), np.inf)
            order = np.argsort(key, kind="stable")[: min(cfg.max_pedestrians, int(visible.sum()))]
            rows = act[order]
            n = rows.size
        if n:
            pos, vel = peds.position[rows], peds.velocity[rows]
            y = pos[:, 1]
            on_road = (y > geo.kerb_south) & (y < geo.kerb_north)
            kerb_dist = np.minimum(np.abs(y - geo.kerb_south), np.abs(y - geo.kerb_north))
            slow = vel[:, 0] * vel[:, 0] + vel[:, 1] * vel[:, 1] < WAITING_SPEED**2
            ped[:n, 0] = 1.0
            ped[:n, 1] = pos[:, 0] - ex
            ped[:n, 2] = y - ey
            ped[:n, 3:5] = vel
            if geo.has_crossing:
                ped[:n, 5] = world.ped_on_crossing[rows]
            ped[:n, 6] = ~on_road & (kerb_dist < WAITING_DISTANCE) & slow
            ped[:n, 7] = on_road
            if visible_steps[rows].min() > peds.history_every * peds.history_length:
                hist = peds.history[rows]  # everyone shown has been in view for the whole history
            else:
                hist = self._seen_history(peds, rows, visible_steps)
            history[:n, :, 0] = hist[:, :, 0] - ex
            history[:n, :, 1] = hist[:, :, 1] - ey
        self.last_slots[:] = -1
        self.last_slots[:n] = rows

        # Vehicles: nearest first.
        veh = np.zeros((cfg.max_vehicles, len(VEHICLE_FEATURES)), dtype=np.float32)
        bg = np.flatnonzero(tr.active[1:]) + 1
        if bg.size:
            dx, dy = tr.x[bg] - ex, tr.y[bg] - ey
            dist = np.sqrt(dx * dx + dy * dy)
            keep = dist <= cfg.perception_range
            order = np.argsort(np.where(keep, dist, np.inf), kind="stable")[
                : min(cfg.max_vehicles, int(keep.sum()))
            ]
            vrows = bg[order]
            m = vrows.size
            veh[:m, 0] = 1.0
            veh[:m, 1] = dx[order]
            veh[:m, 2] = dy[order]
            veh[:m, 3] = tr.speed[vrows] * tr.direction[vrows]
            veh[:m, 5] = tr.length[vrows]
            veh[:m, 6] = tr.width[vrows]
        obs = {"ego": ego_obs, "pedestrians": ped, "pedestrian_history": history, "vehicles": veh}
        for key, value in obs.items():  # a guarantee, not a transformation: values should already fit
            low, high = self._low[key], self._high[key]
            if (value < low).any() or (value > high).any():
                self.out_of_range += 1
                np.clip(value, low, high, out=value)
        return obs
