"""Yield obligations at the crossing, and the ego-occupancy and TTC tests they rely on: one implementation.

`EpisodeMetrics` (yield compliance in `crossing-eval`) and the env's reward (`failing_to_yield`, `near_miss`)
both call what is here, so the metric and the reward cannot drift apart. The rules are documented on
`EpisodeMetrics`; in short, an obligation opens for a pedestrian on the zebra in (or walking towards) the
ego's half, or waiting at the kerb, while the ego can still stop comfortably, and it is violated when the
ego occupies the conflict area while it is open.

Who can create an obligation is decided in one place, `obligation_candidates`.
"""

from __future__ import annotations

import math

import numpy as np

from crossing_env.safety.geometry import _box_disc_ttc
from crossing_env.safety.results import MetricsConfig
from crossing_env.types import GroundTruth, PedState

__all__ = [
    "YieldTracker",
    "ego_in_conflict_area",
    "is_hard_braking",
    "min_pedestrian_ttc",
    "obligation_candidates",
]

OPEN, COMPLIANT, VIOLATED, WAIVED, DECLINED = 1, 2, 3, 4, 5
"""Obligation states (0: none yet)."""
_WAITING, _CROSSING = int(PedState.WAITING), int(PedState.CROSSING)


def obligation_candidates(gt: GroundTruth) -> np.ndarray:
    """Pedestrians (bool per ground-truth row) who may create a yield obligation at all.

    The law's duty is to people who intend to cross (UK Highway Code rule 195, StVO §26): a bystander at the
    kerb opens no obligation. The filter lives here and nowhere else, so the metric and the reward agree.
    """
    return np.asarray(gt.intends_to_cross, dtype=bool).copy()


def ego_in_conflict_area(gt: GroundTruth) -> bool:
    """Whether the ego's footprint overlaps the conflict area (ego lane x crossing)."""
    ca = gt.conflict_area
    ex, ey = float(gt.ego_position[0]), float(gt.ego_position[1])
    length, width = gt.ego_size
    return bool(
        ex + 0.5 * length > ca.x_min
        and ex - 0.5 * length < ca.x_max
        and ey + 0.5 * width > ca.y_min
        and ey - 0.5 * width < ca.y_max
    )


def is_hard_braking(gt: GroundTruth, config: MetricsConfig) -> bool:
    """Whether the ego decelerates at least `MetricsConfig.hard_braking_threshold` this step."""
    return bool(float(gt.ego_acceleration) <= -config.hard_braking_threshold)


def min_pedestrian_ttc(gt: GroundTruth, config: MetricsConfig, half: np.ndarray | None = None) -> float:
    """Minimum exact box–disc TTC from the ego to any pedestrian (s); inf when none or the ego stands still.

    `half` is the ego's half extents (taken from `gt.ego_size` when omitted).
    """
    speed = math.hypot(float(gt.ego_velocity[0]), float(gt.ego_velocity[1]))
    if not gt.pedestrian_ids.shape[0] or speed <= config.ttc_min_ego_speed:
        return math.inf
    if half is None:
        half = 0.5 * np.asarray(gt.ego_size, dtype=np.float64)
    q = gt.pedestrian_positions - gt.ego_position
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return float(
            _box_disc_ttc(q, gt.pedestrian_velocities - gt.ego_velocity, half, gt.pedestrian_radii).min()
        )


class YieldTracker:
    """Per-pedestrian yield obligations over one episode (ids → rows, vectorised over pedestrians).

    `update` once per step, after the world moved; it returns how many obligations the ego violated in
    that step (the reward's `failing_to_yield` count). `counts()` gives the episode's totals.
    """

    def __init__(self, crossing_kind: str, dt: float, config: MetricsConfig | None = None) -> None:
        """Track obligations at a crossing of `crossing_kind` ('zebra', 'signalised' or 'none')."""
        self.kind = crossing_kind
        self.dt = float(dt)
        self.config = config if config is not None else MetricsConfig()
        self.ids = np.empty(0, dtype=np.int64)
        self.status = np.empty(0, dtype=np.int8)
        self.entered_half = np.empty(0, dtype=bool)
        self.offer_time = np.empty(0, dtype=np.float64)

    def _rows(self, ids: np.ndarray) -> np.ndarray:
        n = self.ids.shape[0]
        pos = np.searchsorted(self.ids, ids)
        if n == 0 or np.count_nonzero(self.ids[np.minimum(pos, n - 1)] != ids):
            new = np.setdiff1d(np.unique(ids), self.ids)
            all_ids = np.concatenate([self.ids, new])
            order = np.argsort(all_ids, kind="stable")
            k = new.shape[0]
            self.ids = all_ids[order]
            self.status = np.concatenate([self.status, np.zeros(k, dtype=np.int8)])[order]
            self.entered_half = np.concatenate([self.entered_half, np.zeros(k, dtype=bool)])[order]
            self.offer_time = np.concatenate([self.offer_time, np.zeros(k)])[order]
            pos = np.searchsorted(self.ids, ids)
        return pos

    def update(self, gt: GroundTruth, ego_in_ca: bool | None = None) -> int:
        """Open, resolve and check obligations for one snapshot; returns the violations of this step."""
        if self.kind == "none" or not gt.pedestrian_ids.shape[0]:
            return 0
        if ego_in_ca is None:
            ego_in_ca = ego_in_conflict_area(gt)
        rows = self._rows(gt.pedestrian_ids)
        # At a signal, obligations open only on pedestrian green; ones opened earlier are still checked.
        may_open = self.kind != "signalised" or bool(gt.signal_pedestrian_green)
        cfg = self.config
        ca = gt.conflict_area
        front = float(gt.ego_position[0]) + 0.5 * gt.ego_size[0]
        speed = math.hypot(float(gt.ego_velocity[0]), float(gt.ego_velocity[1]))
        status = self.status[rows]
        open_ = status == OPEN
        dist = ca.stop_line_x - front
        can_open = may_open and dist > speed * speed / (2.0 * cfg.yield_deceleration)
        may_owe = obligation_candidates(gt)
        candidates = can_open and np.count_nonzero((gt.on_crossing | gt.waiting) & (status == 0) & may_owe)
        if not candidates and not np.count_nonzero(open_):
            return 0  # nothing open and nobody who could open an obligation now

        px = gt.pedestrian_positions[:, 0]
        py = gt.pedestrian_positions[:, 1]
        in_half = gt.on_road & (py >= ca.half_y_min) & (py <= ca.half_y_max)
        near = np.abs(px - 0.5 * (ca.x_min + ca.x_max)) <= 0.5 * (ca.x_max - ca.x_min) + cfg.kerb_margin
        waiting = gt.waiting & near

        # Resolve open obligations from the pedestrians' side.
        entered_half = self.entered_half[rows] | (open_ & in_half)
        cleared = open_ & entered_half & ~in_half
        states = gt.pedestrian_states
        gave_up = (states != _WAITING) & (states != _CROSSING) & ~gt.on_road  # walked off, never stepped on
        dropped = open_ & ~entered_half & gave_up
        status = np.where(cleared, COMPLIANT, np.where(dropped, WAIVED, status))

        # Declined offers: the ego stands before the crossing (at most `offer_distance` before the stop line,
        # or between the line and the crossing) while the pedestrian keeps waiting.
        if speed <= cfg.offer_stop_speed and front <= ca.x_min and dist <= cfg.offer_distance:
            offering = (status == OPEN) & waiting
            if np.count_nonzero(offering):
                r_off = rows[offering]
                self.offer_time[r_off] += self.dt
                status[offering] = np.where(
                    self.offer_time[r_off] >= cfg.offer_timeout - 1e-9, DECLINED, OPEN
                )

        # Open new obligations while the ego can still stop comfortably before the stop line.
        if can_open:
            relevant = gt.on_crossing & in_half
            if cfg.far_half_counts:
                toward = (0.5 * (ca.half_y_min + ca.half_y_max) - py) * gt.pedestrian_velocities[:, 1] > 0.0
                relevant |= gt.on_crossing & ~in_half & toward
            new = (status == 0) & (relevant | waiting) & may_owe
            status[new] = OPEN
            entered_half |= new & in_half

        # Violations: the ego occupies the conflict area while an obligation is open.
        violated = 0
        if ego_in_ca:
            now_open = status == OPEN
            violated = int(np.count_nonzero(now_open))
            status[now_open] = VIOLATED
        self.status[rows] = status
        self.entered_half[rows] = entered_half
        return violated

    def counts(self) -> tuple[int, int, int]:
        """(compliant, violated, declined) obligations so far; open ones count as compliant."""
        s = self.status
        compliant = int(np.count_nonzero((s == OPEN) | (s == COMPLIANT) | (s == DECLINED)))
        return compliant, int(np.count_nonzero(s == VIOLATED)), int(np.count_nonzero(s == DECLINED))
