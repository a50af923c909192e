"""Top-down pygame rendering (pygame-ce comes with highway-env); works headless for `rgb_array`."""

from __future__ import annotations

import os

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
    PedState.APPROACHING: (60, 200, 60),
    PedState.WAITING: (250, 170, 30),
    PedState.CROSSING: (230, 50, 50),
    PedState.LEAVING: (120, 220, 220),
    "signal_green": (30, 220, 60),
    "signal_red": (220, 30, 30),
}


class TopDownRenderer:
    """Draws the world centred on the ego; +y is drawn upwards (north)."""

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
        self.fps = 10

    def _to_px(self, x: float, y: float, cx: float, cy: float) -> tuple[int, int]:
        return (int(self.width / 2 + (x - cx) * self.scale), int(self.height / 2 - (y - cy) * self.scale))

    def _rect(self, x0: float, y0: float, x1: float, y1: float, cx: float, cy: float):
        a = self._to_px(x0, y1, cx, cy)
        b = self._to_px(x1, y0, cx, cy)
        return self.pygame.Rect(a[0], a[1], max(1, b[0] - a[0]), max(1, b[1] - a[1]))

    def draw(self, world) -> np.ndarray:
        """Render one frame and return it as uint8 (H, W, 3)."""
        pg, s = self.pygame, self.surface
        geo, tr, peds = world.geometry, world.traffic, world.pedestrians
        road = geo.road
        cx, cy = float(tr.x[0]), road.road_width / 2
        s.fill(COLOURS["grass"])
        sw = road.sidewalk_width
        pg.draw.rect(s, COLOURS["sidewalk"], self._rect(0, -sw, road.length, road.road_width + sw, cx, cy))
        pg.draw.rect(s, COLOURS["road"], self._rect(0, 0, road.length, road.road_width, cx, cy))
        for i in range(1, road.num_lanes):
            y = i * road.lane_width
            solid = i == road.num_forward_lanes and road.two_way
            for x0 in np.arange(0, road.length, 6.0 if not solid else road.length):
                x1 = min(road.length, x0 + (3.0 if not solid else road.length))
                pg.draw.line(s, COLOURS["lane"], self._to_px(x0, y, cx, cy), self._to_px(x1, y, cx, cy), 2)
        if geo.has_crossing:
            r = geo.crossing_rect
            if world.scenario.crossing.kind == "zebra":
                for y0 in np.arange(0.25, road.road_width, 1.0):
                    pg.draw.rect(s, COLOURS["stripe"], self._rect(r.x_min, y0, r.x_max, y0 + 0.5, cx, cy))
            else:
                for x in (r.x_min, r.x_max):
                    pg.draw.line(
                        s,
                        COLOURS["stripe"],
                        self._to_px(x, 0, cx, cy),
                        self._to_px(x, road.road_width, cx, cy),
                        3,
                    )
            if geo.signal is not None:
                colour = COLOURS["signal_green" if geo.signal.pedestrian_green(world.time) else "signal_red"]
                pg.draw.circle(s, colour, self._to_px(r.x_min - 1.0, -1.0, cx, cy), 6)
        for i in np.flatnonzero(tr.active):
            x, y = tr.x[i], tr.y[i]
            hl, hw = tr.length[i] / 2, tr.width[i] / 2
            colour = COLOURS["ego"] if i == 0 else COLOURS["parked" if tr.parked[i] else "car"]
            pg.draw.rect(s, colour, self._rect(x - hl, y - hw, x + hl, y + hw, cx, cy))
        for i in np.flatnonzero(peds.active):
            centre = self._to_px(peds.position[i, 0], peds.position[i, 1], cx, cy)
            radius = max(2, int(peds.radius[i] * self.scale))
            pg.draw.circle(s, COLOURS[PedState(int(peds.state[i]))], centre, radius)
        if self.human:
            self.window.blit(s, (0, 0))
            pg.event.pump()
            pg.display.flip()
            self.clock.tick(self.fps)
        return np.transpose(pg.surfarray.array3d(s), (1, 0, 2)).astype(np.uint8)

    def close(self) -> None:
        """Close the window."""
        if self.human:
            self.pygame.display.quit()
