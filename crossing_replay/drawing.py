"""Drawing an episode into a rerun stream: colours, box outlines and `EpisodeRecorder` (road and frames).

The entities it logs are listed in `crossing_replay.recorder`; ``rerun`` is imported inside the methods.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from crossing_env import safety
from crossing_env.observation import CROSSING_INTENTION_KEY, PREDICTED_PATHS_KEY
from crossing_env.road import RoadGeometry
from crossing_env.types import GroundTruth, PedState
from crossing_replay.episodes import Frame
from scenarios.config import ScenarioConfig

PED_COLOURS: dict[int, tuple[int, int, int]] = {
    PedState.INACTIVE: (128, 128, 128),
    PedState.APPROACHING: (90, 170, 255),
    PedState.WAITING: (255, 200, 0),
    PedState.CROSSING: (255, 70, 50),
    PedState.LEAVING: (90, 210, 100),
}
"""Pedestrian colour per `PedState`: blue approaching, amber waiting, red crossing, green leaving."""
EGO_COLOUR = (0, 230, 255)
VEHICLE_COLOUR = (235, 235, 235)
PREDICTION_COLOUR = (230, 70, 230)
METRIC_PLOTS: tuple[tuple[str, str], ...] = (
    ("ego_speed", "ego speed (m/s)"),
    ("ego_acceleration", "ego acceleration (m/s²)"),
    ("min_distance", "closest pedestrian (m)"),
    ("ttc", "TTC to a pedestrian (s)"),
)
"""Entities under ``/metrics`` and the title (with unit) of each one's own plot."""


def box_corners(centres: np.ndarray, sizes: np.ndarray, headings: np.ndarray) -> np.ndarray:
    """(N, 5, 2) closed outlines of oriented boxes: centre (N, 2), (length, width) (N, 2), heading (N,)."""
    half = sizes[:, None, :] / 2 * np.array([[1, 1], [1, -1], [-1, -1], [-1, 1], [1, 1]], dtype=np.float64)
    c, s = np.cos(headings)[:, None], np.sin(headings)[:, None]
    x = half[..., 0] * c - half[..., 1] * s
    y = half[..., 0] * s + half[..., 1] * c
    return np.stack([x, y], axis=-1) + centres[:, None, :]


def _dashes(x0: float, x1: float, y: float, dash: float = 3.0, gap: float = 6.0) -> np.ndarray:
    starts = np.arange(x0, x1 - dash, dash + gap)
    return np.stack(
        [
            np.stack([starts, np.full_like(starts, y)], 1),
            np.stack([starts + dash, np.full_like(starts, y)], 1),
        ],
        axis=1,
    )


class EpisodeRecorder:
    """Logs the static road and each `Frame` of an episode to a rerun recording stream."""

    def __init__(self, rec: Any, scenario: ScenarioConfig, dt: float) -> None:
        self.rec = rec
        self.scenario = scenario
        self.dt = dt
        self.intention_ids: set[int] = set()

    def log_static(self) -> None:
        """Road surface, sidewalks, kerbs, lane markings, stop lines and the crossing's stripes."""
        import rerun as rr

        sc = self.scenario
        geo = RoadGeometry(sc.road, sc.crossing)
        self._log_road(geo)
        self._log_markings()
        if geo.has_crossing:
            self._log_crossing(geo)
        # Text logs are shown only on a timeline (a static entry is hidden): log this one at frame 0.
        self.rec.set_time("step", sequence=0)
        self.rec.set_time("sim_time", duration=0.0)
        self.rec.log("events/info", rr.TextLog(f"scenario {sc.name}: {sc.description}", level="INFO"))

    def _log_road(self, geo: RoadGeometry) -> None:
        """Road surface, sidewalks and kerbs (static)."""
        import rerun as rr

        road, length, w = self.scenario.road, self.scenario.road.length, self.scenario.road.road_width
        log = self.rec.log
        log(
            "world/road/surface",
            rr.LineStrips2D(
                [[[0.0, w / 2], [length, w / 2]]], radii=w / 2, colors=(70, 70, 75), draw_order=0.0
            ),
            static=True,
        )
        sw = road.sidewalk_width
        walks = [[[0.0, -sw / 2], [length, -sw / 2]], [[0.0, w + sw / 2], [length, w + sw / 2]]]
        log(
            "world/road/sidewalks",
            rr.LineStrips2D(
                walks,
                radii=sw / 2,
                colors=(125, 120, 110),
                draw_order=1.0,
            ),
            static=True,
        )
        log(
            "world/road/kerbs",
            rr.LineStrips2D(
                [
                    [[0.0, geo.kerb_south], [length, geo.kerb_south]],
                    [[0.0, geo.kerb_north], [length, geo.kerb_north]],
                ],
                radii=0.12,
                colors=(210, 210, 200),
                draw_order=2.0,
            ),
            static=True,
        )

    def _log_markings(self) -> None:
        """Lane markings (static): a solid centre line between the two directions, dashes elsewhere."""
        import rerun as rr

        road, length = self.scenario.road, self.scenario.road.length
        n_fwd, lw = road.num_forward_lanes, road.lane_width
        strips: list[np.ndarray] = []
        colours: list[tuple[int, int, int]] = []
        for i in range(1, road.num_lanes):
            y = i * lw
            if i == n_fwd and 0 < n_fwd < road.num_lanes:  # centre line between the two directions
                strips.append(np.array([[0.0, y], [length, y]]))
                colours.append((240, 200, 0))
            else:
                for d in _dashes(0.0, length, y):
                    strips.append(d)
                    colours.append((230, 230, 230))
        if strips:
            self.rec.log(
                "world/road/markings",
                rr.LineStrips2D(strips, radii=0.08, colors=colours, draw_order=2.0),
                static=True,
            )

    def _log_crossing(self, geo: RoadGeometry) -> None:
        """The crossing's stripes and the stop line of every lane (static)."""
        import rerun as rr

        road = self.scenario.road
        rect = geo.crossing_rect
        ys = np.arange(rect.y_min + 0.5, rect.y_max - 0.25, 1.0)
        stripes = [[[rect.x_min, y], [rect.x_max, y]] for y in ys]
        self.rec.log(
            "world/crossing/stripes",
            rr.LineStrips2D(stripes, radii=0.25, colors=(245, 245, 245), draw_order=3.0),
            static=True,
        )
        stops = []
        for lane in range(road.num_lanes):
            direction = geo.lane_direction[lane]
            x = geo.stop_line_x(direction)
            lo, hi = geo.lane_bounds(lane)
            stops.append([[x, lo + 0.1], [x, hi - 0.1]])
        self.rec.log(
            "world/road/stop_lines",
            rr.LineStrips2D(stops, radii=0.15, colors=(245, 245, 245), draw_order=3.0),
            static=True,
        )

    def _safety(self, gt: GroundTruth) -> tuple[float, float]:
        """(minimum ego–pedestrian separation, minimum ego–pedestrian TTC); inf without pedestrians."""
        if gt.pedestrian_ids.size == 0:
            return np.inf, np.inf
        length, width = gt.ego_size
        sep = safety.box_circle_separation(
            gt.ego_position, length, width, gt.pedestrian_positions, gt.pedestrian_radii
        )
        ttc = safety.box_circle_ttc(
            gt.ego_position,
            gt.ego_velocity,
            length,
            width,
            gt.pedestrian_positions,
            gt.pedestrian_velocities,
            gt.pedestrian_radii,
        )
        return float(np.min(sep)), float(np.min(ttc))

    def log_frame(self, frame: Frame) -> None:
        """Log one frame at ``step = frame.step`` and ``sim_time = gt.time``."""
        gt = frame.ground_truth
        self.rec.set_time("step", sequence=frame.step)
        self.rec.set_time("sim_time", duration=float(gt.time))
        self._log_vehicles(gt)
        self._log_pedestrians(gt)
        self._log_signal(gt)
        self._log_predictions(frame)
        self._log_metrics(gt)
        self._log_events(gt)

    def _log_vehicles(self, gt: GroundTruth) -> None:
        """Ego and other vehicles as oriented box outlines."""
        import rerun as rr

        ego = box_corners(gt.ego_position[None], np.asarray([gt.ego_size]), np.zeros(1))
        self.rec.log(
            "world/ego", rr.LineStrips2D(ego, radii=0.12, colors=EGO_COLOUR, labels=["ego"], draw_order=10.0)
        )
        heading = np.where(gt.vehicle_velocities[:, 0] < 0, np.pi, 0.0)
        cars = box_corners(gt.vehicle_positions, gt.vehicle_sizes, heading)
        self.rec.log(
            "world/vehicles",
            rr.LineStrips2D(
                cars,
                radii=0.08,
                colors=VEHICLE_COLOUR,
                labels=[f"car {i}" for i in gt.vehicle_ids],
                draw_order=9.0,
            ),
        )

    def _log_pedestrians(self, gt: GroundTruth) -> None:
        """Pedestrians as discs coloured by state, labelled with their ids."""
        import rerun as rr

        colours = np.array(
            [PED_COLOURS.get(int(s), (128, 128, 128)) for s in gt.pedestrian_states], dtype=np.uint8
        ).reshape(-1, 3)
        self.rec.log(
            "world/pedestrians",
            rr.Points2D(
                gt.pedestrian_positions,
                radii=gt.pedestrian_radii,
                colors=colours,
                labels=[str(i) for i in gt.pedestrian_ids],
                class_ids=gt.pedestrian_states.astype(np.uint16),
                draw_order=12.0,
            ),
        )

    def _log_signal(self, gt: GroundTruth) -> None:
        """The pedestrian signal's colour on both kerbs, when the crossing has one."""
        import rerun as rr

        if gt.signal_pedestrian_green is None:
            return
        x = self.scenario.crossing.position
        colour = (60, 230, 60) if gt.signal_pedestrian_green else (240, 40, 40)
        self.rec.log(
            "world/signal",
            rr.Points2D(
                [[x, -0.6], [x, self.scenario.road.road_width + 0.6]],
                radii=0.45,
                colors=colour,
                draw_order=11.0,
            ),
        )

    def _log_metrics(self, gt: GroundTruth) -> None:
        """Ego speed and acceleration, and the closest separation and TTC to a pedestrian (when finite)."""
        import rerun as rr

        rec = self.rec
        speed = float(np.hypot(*gt.ego_velocity))
        rec.log("metrics/ego_speed", rr.Scalars(speed))
        rec.log("metrics/ego_acceleration", rr.Scalars(gt.ego_acceleration))
        dist, ttc = self._safety(gt)
        # NaN where undefined (no pedestrian, no closing course): the plotted line breaks there instead
        # of joining the points on either side of the gap with a straight line.
        rec.log("metrics/min_distance", rr.Scalars(dist if np.isfinite(dist) else np.nan))
        rec.log("metrics/ttc", rr.Scalars(ttc if np.isfinite(ttc) else np.nan))

    def _log_events(self, gt: GroundTruth) -> None:
        """Collisions (errors) and pedestrian behaviour events (warnings for rule-breaking ones)."""
        import rerun as rr

        for c in gt.collisions:
            self.rec.log(
                "events/collisions",
                rr.TextLog(
                    f"t={c.time:.1f}s collision with {c.kind} {c.other_id} at {c.relative_speed:.1f} m/s"
                    f" ({'ego at fault' if c.at_fault else 'ego not at fault'}, {c.contact_type}) "
                    f"({'compliant' if c.compliant else 'non-compliant'} road user)",
                    level="ERROR",
                ),
            )
        for c in gt.extras.get("background_collisions", ()):
            self.rec.log(
                "events/background_collisions",
                rr.TextLog(
                    f"t={c.time:.1f}s background car hit pedestrian {c.other_id} at "
                    f"{c.relative_speed:.1f} m/s ({'legal' if c.compliant else 'non-compliant'} pedestrian;"
                    " world health, not the ego)",
                    level="ERROR",
                ),
            )
        for e in gt.events:
            level = "WARN" if e.kind in ("jaywalk", "red_light", "run", "distracted") else "INFO"
            self.rec.log(
                "events/behaviour",
                rr.TextLog(f"t={e.time:.1f}s pedestrian {e.pedestrian_id}: {e.kind}", level=level),
            )

    def _log_predictions(self, frame: Frame) -> None:
        import rerun as rr

        obs, ids, gt = frame.observation, frame.slot_ids, frame.ground_truth
        paths = obs.get(PREDICTED_PATHS_KEY)
        if paths is not None and ids.size:
            present = np.flatnonzero(ids[: paths.shape[0]] >= 0)
            strips = paths[present].astype(np.float64) + gt.ego_position  # ego frame → world
            rec_ids = ids[present]
            rows = {int(i): k for k, i in enumerate(gt.pedestrian_ids)}
            starts = np.array(
                [
                    gt.pedestrian_positions[rows[int(i)]] if int(i) in rows else s[0]
                    for i, s in zip(rec_ids, strips, strict=True)
                ]
            ).reshape(-1, 2)
            full = np.concatenate([starts[:, None], strips], axis=1) if len(strips) else strips
            self.rec.log(
                "world/predictions",
                rr.LineStrips2D(
                    full,
                    radii=0.06,
                    colors=PREDICTION_COLOUR,
                    labels=[str(i) for i in rec_ids],
                    show_labels=False,
                    draw_order=8.0,
                ),
            )
        intent = obs.get(CROSSING_INTENTION_KEY)
        if intent is not None and ids.size:
            present = np.flatnonzero(ids[: intent.shape[0]] >= 0)
            states = {int(i): int(st) for i, st in zip(gt.pedestrian_ids, gt.pedestrian_states, strict=True)}
            for k in present:
                pid = int(ids[k])
                # Coloured by the pedestrian's state (as in the scene), not by id: 16 id hues look alike.
                colour = PED_COLOURS.get(states.get(pid, PedState.INACTIVE), PED_COLOURS[PedState.INACTIVE])
                self.rec.log(
                    f"intention/ped_{pid}", rr.Scalars(float(intent[k])), rr.SeriesLines(colors=colour)
                )
                self.intention_ids.add(pid)
