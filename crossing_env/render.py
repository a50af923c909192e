"""Top-down pygame rendering (pygame-ce comes with highway-env); works headless for `rgb_array`.

Orientation: +x to the right and +y *down*, the image convention the rerun viewer's 2D views use, so a
frame and ``crossing-replay``'s recording of the same step look alike. Pedestrians are drawn to scale
(at least `MIN_PED_PX` wide) with a heading tick and their state's colour; the overlay gives time, ego
speed, the pedestrian and car signals and a colour legend. When the observation passed to `draw` holds
``predicted_paths`` or ``crossing_intention`` (the predictor wrappers; see `ShowPredictions`), they are
drawn too. Night scenes are dimmed.
"""

from __future__ import annotations

import os
from typing import Any

import gymnasium as gym
import numpy as np

from crossing_env.types import PedState
from scenarios.config import EnvConfig

COLOURS = {
    "grass": (96, 128, 80),
    "sidewalk": (190, 190, 185),
    "road": (70, 70, 75),
    "stripe": (235, 235, 235),
    "lane": (220, 220, 120),
    "ego": (40, 110, 220),
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
LEGEND = (
    (PedState.APPROACHING, "approaching"),
    (PedState.WAITING, "waiting"),
    (PedState.CROSSING, "crossing"),
    (PedState.LEAVING, "leaving"),
)


class TopDownRenderer:
    """Draws the world centred on the ego (+x right, +y down, as the rerun view)."""

    def __init__(self, config: EnvConfig, human: bool = False) -> None:
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
        self.fps = 10

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
        s.fill(COLOURS["grass"])
        self._draw_road(world, cx, cy)
        for i in np.flatnonzero(tr.active):
            x, y = tr.x[i], tr.y[i]
            hl, hw = tr.length[i] / 2, tr.width[i] / 2
            colour = COLOURS["ego"] if i == 0 else COLOURS["parked" if tr.parked[i] else "car"]
            rect = self._rect(x - hl, y - hw, x + hl, y + hw, cx, cy)
            pg.draw.rect(s, colour, rect)
            pg.draw.rect(s, COLOURS["outline"], rect, 1)
        if observation is not None:
            self._draw_predictions(observation, world, cx, cy)
        self._draw_pedestrians(world, cx, cy)
        if world.scenario.night:
            dark = pg.Surface((self.width, self.height))
            dark.fill((10, 10, 40))
            dark.set_alpha(int(255 * (1.0 - NIGHT_DIM)))
            s.blit(dark, (0, 0))
        self._draw_overlay(world)
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

    def _draw_predictions(self, obs: dict[str, np.ndarray], world: Any, cx: float, cy: float) -> None:
        """Predicted paths (magenta) and crossing intentions (a ring and a percentage) of observed slots."""
        pg, s = self.pygame, self.surface
        peds = np.asarray(obs.get("pedestrians", np.zeros((0, 8))))
        if peds.size == 0:
            return
        ego = (float(world.traffic.x[0]), float(world.traffic.y[0]))
        present = np.flatnonzero(peds[:, 0] > 0.5)
        paths = obs.get("predicted_paths")
        if paths is not None:
            for k in present:
                start = (ego[0] + float(peds[k, 1]), ego[1] + float(peds[k, 2]))
                pts = [self._to_px(*start, cx, cy)]
                pts += [self._to_px(ego[0] + float(p[0]), ego[1] + float(p[1]), cx, cy) for p in paths[k]]
                pg.draw.lines(s, COLOURS["prediction"], False, pts, 2)
        intent = obs.get("crossing_intention")
        if intent is not None:
            for k in present:
                p = float(np.clip(intent[k], 0.0, 1.0))
                centre = self._to_px(ego[0] + float(peds[k, 1]), ego[1] + float(peds[k, 2]), cx, cy)
                colour = (int(210 + 45 * p), int(210 - 150 * p), int(210 - 210 * p))  # grey → orange
                pg.draw.circle(s, colour, centre, MIN_PED_PX + 5, 2)
                label = self.font.render(f"{100 * p:.0f}%", True, colour)
                s.blit(label, (centre[0] + MIN_PED_PX + 6, centre[1] - label.get_height()))

    def _draw_overlay(self, world: Any) -> None:
        """Time, ego speed, signal states (top left) and the pedestrian colour legend (bottom)."""
        pg, s = self.pygame, self.surface
        speed = float(world.traffic.speed[0])
        green = world.geometry.pedestrian_green(world.time)
        signal = (
            "no signal"
            if green is None
            else f"ped {'GREEN' if green else 'RED'} / car {'RED' if green else 'GREEN'}"
        )
        night = "  night" if world.scenario.night else ""
        lines = [f"t {world.time:5.1f} s   ego {speed:4.1f} m/s ({3.6 * speed:3.0f} km/h)   {signal}{night}"]
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
