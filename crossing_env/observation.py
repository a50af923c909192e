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

EGO_FEATURES = ("speed", "acceleration", "distance_to_stop_line", "distance_past_crossing", "car_green",
                "zebra")
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
    return spaces.Dict({
        "ego": spaces.Box(ego_low, ego_high, dtype=np.float32),
        "pedestrians": spaces.Box(ped_low, ped_high, dtype=np.float32),
        "pedestrian_history": spaces.Box(-pb, pb, shape=(k, h, 2), dtype=np.float32),
        "vehicles": spaces.Box(veh_low, veh_high, dtype=np.float32),
    })


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

    def build(self, world) -> CrossingObs:  # noqa: ANN001 - World, avoided for an import cycle
        """Observation of `world` (a `crossing_env.world.World`)."""
        cfg = self.config
        tr, peds, geo = world.traffic, world.pedestrians, world.geometry
        ego = world.ego_position
        speed = tr.speed[0]
        stop_x = geo.stop_line_x(1.0)
        car_green = 1.0 if geo.signal is None or not geo.signal.pedestrian_green(world.time) else 0.0
        ego_obs = np.array([
            speed, tr.acceleration[0], stop_x - (ego[0] + tr.length[0] / 2),
            ego[0] - tr.length[0] / 2 - geo.crossing_rect.x_max, car_green,
            1.0 if self.scenario.crossing.kind == "zebra" else 0.0,
        ])

        # Pedestrians: visible ones sorted by relevance (ahead of the ego and close to its path first).
        act = np.flatnonzero(peds.active)
        rel = peds.position[act] - ego
        dist = np.hypot(rel[:, 0], rel[:, 1])
        visible = dist <= self.ped_range
        parked = tr.active & tr.parked
        if parked.any() and act.size:
            visible &= ~_segment_hits_boxes(ego, peds.position[act], tr.boxes(parked))
        act, rel, dist = act[visible], rel[visible], dist[visible]
        key = dist + np.where(rel[:, 0] < -tr.length[0], 100.0, 0.0)
        order = np.argsort(key, kind="stable")[: cfg.max_pedestrians]
        rows = act[order]
        n = rows.size
        ped = np.zeros((cfg.max_pedestrians, len(PEDESTRIAN_FEATURES)))
        history = np.zeros((cfg.max_pedestrians, cfg.history_length, 2))
        if n:
            pos, vel = peds.position[rows], peds.velocity[rows]
            y = pos[:, 1]
            kerb_dist = np.minimum(np.abs(y - geo.kerb_south), np.abs(y - geo.kerb_north))
            on_road = (y > geo.kerb_south) & (y < geo.kerb_north)
            waiting = ~on_road & (kerb_dist < WAITING_DISTANCE) & (np.hypot(vel[:, 0], vel[:, 1]) < WAITING_SPEED)
            on_crossing = geo.crossing_rect.contains(pos) if geo.has_crossing else np.zeros(n, dtype=bool)
            ped[:n, 0] = 1.0
            ped[:n, 1:3] = pos - ego
            ped[:n, 3:5] = vel
            ped[:n, 5] = on_crossing
            ped[:n, 6] = waiting
            ped[:n, 7] = on_road
            history[:n] = peds.history[rows] - ego
        self.last_slots[:] = -1
        self.last_slots[:n] = rows

        # Vehicles: nearest first.
        bg = np.flatnonzero(tr.active)
        bg = bg[bg != 0]
        pos = tr.positions()[bg]
        rel_v = pos - ego
        dist_v = np.hypot(rel_v[:, 0], rel_v[:, 1])
        keep = dist_v <= cfg.perception_range
        bg, rel_v, dist_v = bg[keep], rel_v[keep], dist_v[keep]
        order = np.argsort(dist_v, kind="stable")[: cfg.max_vehicles]
        vrows = bg[order]
        veh = np.zeros((cfg.max_vehicles, len(VEHICLE_FEATURES)))
        m = vrows.size
        if m:
            veh[:m, 0] = 1.0
            veh[:m, 1:3] = rel_v[order]
            veh[:m, 3:5] = tr.velocities()[vrows]
            veh[:m, 5] = tr.length[vrows]
            veh[:m, 6] = tr.width[vrows]
        obs = {"ego": ego_obs, "pedestrians": ped, "pedestrian_history": history, "vehicles": veh}
        return {
            key: np.clip(value, self.space[key].low, self.space[key].high).astype(np.float32)
            for key, value in obs.items()
        }

