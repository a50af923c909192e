"""Top-down pygame rendering (pygame-ce comes with highway-env); works headless for `rgb_array`.

Orientation: +x to the right and +y *down*, the image convention the rerun viewer's 2D views use, so a
frame and ``crossing-replay``'s recording of the same step look alike. The ego is drawn in its own colour
with a white outline and labelled "ego". Pedestrians are drawn to scale (at least `MIN_PED_PX` wide) with a
heading tick and their state's colour. The caption (top) gives the scenario, the renderer's `caption`
(``crossing-replay video`` passes the policy and seed; the env knows neither), the time, the ego speed and
the signals; the legend (bottom) the colours. When the observation passed to `draw` holds
``predicted_paths`` or ``crossing_intention`` (the predictor wrappers; see `ShowPredictions`), they are
drawn too: intentions as a ring on every observed pedestrian and a percentage, dark on a light tag, for
the nearest pedestrians whose tags fit without overlapping (`INTENTION_LABEL_RANGE`). An ego collision is
marked where it happened (a red ring and cross) and named in a red banner, from its step to the end of the
episode. Night scenes are dimmed (the overlays are not).
"""

from __future__ import annotations

import os
from typing import Any

import gymnasium as gym
import numpy as np

from crossing_env.observation import (
    CROSSING_INTENTION_KEY,
    PEDESTRIANS_KEY,
    PREDICTED_PATHS_KEY,
    PedestrianColumn,
    PointColumn,
)
from crossing_env.types import PedState
from scenarios.config import EnvConfig

COLOURS = {
    "grass": (96, 128, 80),
    "sidewalk": (190, 190, 185),
    "road": (70, 70, 75),
    "stripe": (235, 235, 235),
    "lane": (220, 220, 120),
    "ego": (40, 110, 220),
    "ego_outline": (255, 255, 255),
    "tag": (245, 245, 235),
    "tag_text": (20, 20, 20),
    "collision": (230, 20, 20),
    "car": (200, 200, 60),
    "parked": (150, 150, 150),
    "outline": (20, 20, 20),
    "text": (255, 255, 255),
    "panel": (0, 0, 0),
    "prediction": (230, 70, 230),
    PedState.INACTIVE: (128, 128, 128),
    PedState.APPROACHING: (90, 170, 255),
    PedState.WAITING: (255, 200, 0),
    PedState.CROSSING: (255, 70, 50),
    PedState.LEAVING: (90, 210, 100),
    "signal_green": (30, 220, 60),
    "signal_red": (220, 30, 30),
}
"""Pedestrian states use the rerun recorder's palette: blue approaching, amber waiting, red crossing,
green leaving."""
MIN_PED_PX = 5
"""Smallest pedestrian radius drawn, pixels (a 0.28 m body is 3 px at the default 10 px/m)."""
NIGHT_DIM = 0.45
"""Brightness factor of night scenes."""
INTENTION_LABEL_RANGE = 30.0
"""Intention percentages are written only for pedestrians within this distance of the ego (m); rings are
drawn for all."""
LEGEND = (
    (PedState.APPROACHING, "approaching"),
    (PedState.WAITING, "waiting"),
    (PedState.CROSSING, "crossing"),
    (PedState.LEAVING, "leaving"),
)


class TopDownRenderer:
    """Draws the world centred on the ego (+x right, +y down, as the rerun view)."""

    def __init__(self, config: EnvConfig, human: bool = False, caption: str | None = None) -> None:
        """A renderer of `config.render_size` frames; `caption` follows the scenario's name (policy, seed).

        ``crossing-replay video`` passes e.g. ``"policy yielding   seed 3"``; the env's own `render` has none.
        """
        if human and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
            os.environ.setdefault("SDL_VIDEODRIVER", "dummy")  # headless machines: draw off-screen
        import pygame

        self.pygame = pygame
        self.width, self.height = config.render_size
        self.scale = self.width / config.render_extent
        self.human = human
        if human:
            pygame.display.init()
            self.window = pygame.display.set_mode((self.width, self.height))
            pygame.display.set_caption("crossing-env")
            self.clock = pygame.time.Clock()
        self.surface = pygame.Surface((self.width, self.height))
        pygame.font.init()
        self.font = pygame.font.Font(None, max(14, self.height // 18))
        self.label_font = pygame.font.Font(None, max(14, self.height // 20))
        self.fps = 10
        self.caption = caption
        self._world_id: int | None = None
        self._collisions: list[Any] = []
        self._labels: list[Any] = []
        """Screen rectangles already taken by labels in the frame being drawn."""

    def _to_px(self, x: float, y: float, cx: float, cy: float) -> tuple[int, int]:
        return (int(self.width / 2 + (x - cx) * self.scale), int(self.height / 2 + (y - cy) * self.scale))

    def _rect(self, x0: float, y0: float, x1: float, y1: float, cx: float, cy: float):
        a = self._to_px(x0, y0, cx, cy)
        b = self._to_px(x1, y1, cx, cy)
        return self.pygame.Rect(a[0], a[1], max(1, b[0] - a[0]), max(1, b[1] - a[1]))

    def draw(self, world: Any, observation: dict[str, np.ndarray] | None = None) -> np.ndarray:
        """Render one frame as uint8 (H, W, 3); an `observation` with predictions adds them."""
        pg, s = self.pygame, self.surface
        geo, tr = world.geometry, world.traffic
        road = geo.road
        cx, cy = float(tr.x[0]), road.road_width / 2
        if id(world) != self._world_id:  # a new episode: forget the previous one's collisions
            self._world_id = id(world)
            self._collisions = []
        # The step's new collisions (a frame drawn twice for one step adds nothing).
        self._collisions += [ev for ev in getattr(world, "collisions", ()) if ev not in self._collisions]
        self._labels = []
        s.fill(COLOURS["grass"])
        self._draw_road(world, cx, cy)
        ego_rect = None
        for i in np.flatnonzero(tr.active):
            x, y = tr.x[i], tr.y[i]
            hl, hw = tr.length[i] / 2, tr.width[i] / 2
            colour = COLOURS["ego"] if i == 0 else COLOURS["parked" if tr.parked[i] else "car"]
            rect = self._rect(x - hl, y - hw, x + hl, y + hw, cx, cy)
            pg.draw.rect(s, colour, rect)
            if i == 0:
                ego_rect = rect
            else:
                pg.draw.rect(s, COLOURS["outline"], rect, 1)
        if observation is not None:
            self._draw_prediction_paths(observation, world, cx, cy)
        self._draw_pedestrians(world, cx, cy)
        if world.scenario.night:
            dark = pg.Surface((self.width, self.height))
            dark.fill((10, 10, 40))
            dark.set_alpha(int(255 * (1.0 - NIGHT_DIM)))
            s.blit(dark, (0, 0))
        if ego_rect is not None:
            self._mark_ego(ego_rect)
        self._draw_overlay(world)
        if observation is not None:
            self._draw_intentions(observation, world, cx, cy)
        self._draw_collisions(cx, cy)
        if self.human:
            self.window.blit(s, (0, 0))
            pg.event.pump()
            pg.display.flip()
            self.clock.tick(self.fps)
        return np.transpose(pg.surfarray.array3d(s), (1, 0, 2)).astype(np.uint8)

    def _draw_road(self, world: Any, cx: float, cy: float) -> None:
        pg, s, geo = self.pygame, self.surface, world.geometry
        road = geo.road
        sw = road.sidewalk_width
        pg.draw.rect(s, COLOURS["sidewalk"], self._rect(0, -sw, road.length, road.road_width + sw, cx, cy))
        pg.draw.rect(s, COLOURS["road"], self._rect(0, 0, road.length, road.road_width, cx, cy))
        for i in range(1, road.num_lanes):
            y = i * road.lane_width
            solid = i == road.num_forward_lanes and road.two_way
            for x0 in np.arange(0, road.length, 6.0 if not solid else road.length):
                x1 = min(road.length, x0 + (3.0 if not solid else road.length))
                pg.draw.line(s, COLOURS["lane"], self._to_px(x0, y, cx, cy), self._to_px(x1, y, cx, cy), 2)
        if not geo.has_crossing:
            return
        r = geo.crossing_rect
        if world.scenario.crossing.kind == "zebra":
            for y0 in np.arange(0.25, road.road_width, 1.0):
                pg.draw.rect(s, COLOURS["stripe"], self._rect(r.x_min, y0, r.x_max, y0 + 0.5, cx, cy))
        else:
            for x in (r.x_min, r.x_max):
                a, b = self._to_px(x, 0, cx, cy), self._to_px(x, road.road_width, cx, cy)
                pg.draw.line(s, COLOURS["stripe"], a, b, 3)
        green = geo.pedestrian_green(world.time)
        if green is not None:
            ped = COLOURS["signal_green" if green else "signal_red"]
            car = COLOURS["signal_red" if green else "signal_green"]
            for y in (-sw / 2, road.road_width + sw / 2):  # pedestrian heads on both kerbs
                pg.draw.circle(s, ped, self._to_px(r.x_min - 1.0, y, cx, cy), 6)
                pg.draw.circle(s, COLOURS["outline"], self._to_px(r.x_min - 1.0, y, cx, cy), 6, 1)
            stop = self._to_px(r.x_min - 2.0, -sw, cx, cy)  # the car head beside the ego's lanes
            pg.draw.rect(s, COLOURS["outline"], pg.Rect(stop[0] - 6, stop[1] - 6, 12, 12))
            pg.draw.circle(s, car, stop, 5)

    def _draw_pedestrians(self, world: Any, cx: float, cy: float) -> None:
        pg, s, peds = self.pygame, self.surface, world.pedestrians
        for i in np.flatnonzero(peds.active):
            px, py = peds.position[i]
            centre = self._to_px(px, py, cx, cy)
            radius = max(MIN_PED_PX, round(float(peds.radius[i]) * self.scale))
            state = PedState(int(peds.state[i]))
            pg.draw.circle(s, COLOURS.get(state, COLOURS[PedState.INACTIVE]), centre, radius)
            pg.draw.circle(s, COLOURS["outline"], centre, radius, 1)
            v = peds.velocity[i]
            speed = float(np.hypot(v[0], v[1]))
            if speed > 0.05:
                tip = (
                    centre[0] + int(1.8 * radius * v[0] / speed),
                    centre[1] + int(1.8 * radius * v[1] / speed),
                )
                pg.draw.line(s, COLOURS["outline"], centre, tip, 2)

    def _observed(self, obs: dict[str, np.ndarray], world: Any) -> tuple[np.ndarray, np.ndarray]:
        """World positions (k, 2) of the observed pedestrian slots and the slots' indices."""
        peds = np.asarray(obs.get(PEDESTRIANS_KEY, np.zeros((0, len(PedestrianColumn)))))
        if peds.size == 0:
            return np.zeros((0, 2)), np.zeros(0, dtype=np.intp)
        present = np.flatnonzero(peds[:, PedestrianColumn.PRESENCE] > 0.5)
        ego = np.array([float(world.traffic.x[0]), float(world.traffic.y[0])])
        rel = peds[present][:, [PedestrianColumn.DX, PedestrianColumn.DY]].astype(np.float64)
        return ego + rel, present

    def _draw_prediction_paths(self, obs: dict[str, np.ndarray], world: Any, cx: float, cy: float) -> None:
        """Predicted paths (magenta) of the observed slots, under the pedestrians."""
        paths = obs.get(PREDICTED_PATHS_KEY)
        if paths is None:
            return
        pg, s = self.pygame, self.surface
        ego = (float(world.traffic.x[0]), float(world.traffic.y[0]))
        positions, present = self._observed(obs, world)
        for (px, py), k in zip(positions, present, strict=True):
            pts = [self._to_px(px, py, cx, cy)]
            pts += [
                self._to_px(ego[0] + float(p[PointColumn.X]), ego[1] + float(p[PointColumn.Y]), cx, cy)
                for p in paths[k]
            ]
            pg.draw.lines(s, COLOURS["prediction"], False, pts, 2)

    def _draw_intentions(self, obs: dict[str, np.ndarray], world: Any, cx: float, cy: float) -> None:
        """Crossing intentions: a ring (grey → orange) on every observed pedestrian, and a percentage tag.

        Tags (dark text on light) go to the nearest pedestrians first, within `INTENTION_LABEL_RANGE`, on
        the first side of the pedestrian where they cover no other label; the others keep their ring only.
        """
        intent = obs.get(CROSSING_INTENTION_KEY)
        if intent is None:
            return
        pg, s = self.pygame, self.surface
        positions, present = self._observed(obs, world)
        ego = np.array([float(world.traffic.x[0]), float(world.traffic.y[0])])
        order = np.argsort(np.hypot(*(positions - ego).T)) if len(present) else []
        frame = pg.Rect(0, 0, self.width, self.height)
        r = MIN_PED_PX + 5
        shares = [float(np.clip(intent[k], 0.0, 1.0)) for k in present]
        colours = [
            (int(210 + 45 * p), int(210 - 150 * p), int(210 - 210 * p)) for p in shares
        ]  # grey → orange
        centres = [self._to_px(*xy, cx, cy) for xy in positions]
        for centre, colour in zip(centres, colours, strict=True):  # every ring first: no tag under a ring
            pg.draw.circle(s, colour, centre, r, 2)
        rings = [pg.Rect(c[0] - r, c[1] - r, 2 * r, 2 * r) for c in centres]
        for j in order:
            if float(np.hypot(*(positions[j] - ego))) > INTENTION_LABEL_RANGE:
                continue
            text = self.label_font.render(f"{100 * shares[j]:.0f}%", True, COLOURS["tag_text"])
            w, h = text.get_width() + 6, text.get_height() + 2
            x, y = centres[j]
            for dx, dy in ((r + 2, -h - 1), (r + 2, 1), (-r - 2 - w, -h - 1), (-r - 2 - w, 1)):
                tag = pg.Rect(x + dx, y + dy, w, h)
                if frame.contains(tag) and tag.collidelist(self._labels) < 0 and tag.collidelist(rings) < 0:
                    self._tag(text, tag, colours[j])
                    break

    def _tag(self, text: Any, rect: Any, border: tuple[int, int, int]) -> None:
        """Blit `text` on a light tag with a coloured border at `rect`; the rectangle is taken."""
        pg, s = self.pygame, self.surface
        pg.draw.rect(s, COLOURS["tag"], rect)
        pg.draw.rect(s, border, rect, 1)
        s.blit(text, (rect.x + 3, rect.y + 1))
        self._labels.append(rect)

    def _mark_ego(self, rect: Any) -> None:
        """A white outline around the ego's box (over the night dimming) and an "ego" tag above it."""
        pg, s = self.pygame, self.surface
        pg.draw.rect(s, COLOURS["ego_outline"], rect.inflate(4, 4), 2)
        pg.draw.rect(s, COLOURS["outline"], rect.inflate(8, 8), 1)
        text = self.label_font.render("ego", True, COLOURS["tag_text"])
        w, h = text.get_width() + 6, text.get_height() + 2
        tag = pg.Rect(rect.centerx - w // 2, rect.top - h - 6, w, h)
        if tag.top < 0:
            tag.top = rect.bottom + 6
        self._tag(text, tag, COLOURS["ego"])

    def _draw_collisions(self, cx: float, cy: float) -> None:
        """Each ego collision of the episode so far: a red ring and cross where it happened, and a banner."""
        if not self._collisions:
            return
        pg, s = self.pygame, self.surface
        for ev in self._collisions:
            x, y = self._to_px(float(ev.position[0]), float(ev.position[1]), cx, cy)
            pg.draw.circle(s, COLOURS["collision"], (x, y), 14, 3)
            pg.draw.line(s, COLOURS["collision"], (x - 9, y - 9), (x + 9, y + 9), 3)
            pg.draw.line(s, COLOURS["collision"], (x - 9, y + 9), (x + 9, y - 9), 3)
        ev = self._collisions[0]
        more = f" (+{len(self._collisions) - 1})" if len(self._collisions) > 1 else ""
        text = self.font.render(
            f"COLLISION with a {ev.kind} at t {ev.time:.1f} s, {ev.relative_speed:.1f} m/s,"
            f" {'ego at fault' if ev.at_fault else 'ego not at fault'}{more}",
            True,
            (255, 255, 255),
        )
        box = pg.Rect(0, 0, text.get_width() + 12, text.get_height() + 6)
        box.midbottom = (self.width // 2, self.height - self.font.get_height() - 12)
        pg.draw.rect(s, COLOURS["collision"], box)
        pg.draw.rect(s, COLOURS["outline"], box, 1)
        s.blit(text, (box.x + 6, box.y + 3))

    def _draw_overlay(self, world: Any) -> None:
        """The caption (top left) and the pedestrian colour legend (bottom).

        Caption: scenario, `caption` and time on the first line, ego speed and signal states on the second.
        """
        pg, s = self.pygame, self.surface
        speed = float(world.traffic.speed[0])
        green = world.geometry.pedestrian_green(world.time)
        signal = (
            "no signal"
            if green is None
            else f"ped {'GREEN' if green else 'RED'} / car {'RED' if green else 'GREEN'}"
        )
        night = "   night" if world.scenario.night else ""
        head = "   ".join(x for x in (world.scenario.name or "custom scenario", self.caption) if x)
        lines = [
            f"{head}   t {world.time:5.1f} s",
            f"ego {speed:4.1f} m/s ({3.6 * speed:3.0f} km/h)   {signal}{night}",
        ]
        y = 4
        for text in lines:
            label = self.font.render(text, True, COLOURS["text"])
            box = pg.Surface((label.get_width() + 8, label.get_height() + 4))
            box.set_alpha(150)
            box.fill(COLOURS["panel"])
            s.blit(box, (4, y))
            s.blit(label, (8, y + 2))
            y += label.get_height() + 6
        x = 8
        y = self.height - self.font.get_height() - 6
        box = pg.Surface((self.width, self.font.get_height() + 6))
        box.set_alpha(150)
        box.fill(COLOURS["panel"])
        s.blit(box, (0, y - 3))
        for state, name in LEGEND:
            pg.draw.circle(s, COLOURS[state], (x + 5, y + self.font.get_height() // 2), 5)
            label = self.font.render(name, True, COLOURS["text"])
            s.blit(label, (x + 14, y))
            x += label.get_width() + 28
        label = self.font.render("predicted path", True, COLOURS["prediction"])
        s.blit(label, (x, y))
        x += label.get_width() + 14
        label = self.font.render("ring: crossing intention %", True, (255, 140, 40))
        s.blit(label, (x, y))

    def close(self) -> None:
        """Close the window."""
        if self.human:
            self.pygame.display.quit()


class ShowPredictions(gym.Wrapper):
    """Outermost wrapper that hands the latest (wrapped) observation to the renderer.

    The base env renders the world only; the predictor wrappers above it add ``predicted_paths`` and
    ``crossing_intention`` to the observation, which this wrapper passes on, so ``render()`` draws them:
    ``ShowPredictions(TrajectoryPrediction(QLBIntention(gym.make(..., render_mode="rgb_array"))))``.
    """

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self._last: dict[str, np.ndarray] | None = None

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict]:
        """Reset and remember the observation."""
        obs, info = self.env.reset(seed=seed, options=options)
        self._last = obs
        return obs, info

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict]:
        """Step and remember the observation."""
        out = self.env.step(action)
        self._last = out[0]
        return out

    def render(self) -> np.ndarray | None:
        """The base env's frame with the latest observation's predictions drawn."""
        base = self.env.unwrapped
        return base.render(observation=self._last)  # type: ignore[call-arg]
