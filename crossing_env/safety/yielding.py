"""Yield obligations at the crossing, and the ego-occupancy and TTC tests they rely on: one implementation.

`EpisodeMetrics` (yield compliance in `crossing-eval`) and the env's reward (`failing_to_yield`, `near_miss`)
both call what is here, so the metric and the reward cannot drift apart. The rules are documented on
`EpisodeMetrics`; in short, an obligation opens for a pedestrian on the zebra in (or walking towards) the
ego's half, or waiting at the kerb, while the ego can still stop comfortably, and it is violated when the
ego occupies the conflict area while it is open. An obligation that closed as declined or waived opens
again when its pedestrian steps onto the crossing after all, while the ego can still stop before the
crossing: a car that stood briefly and then goes owes the way to whoever then steps out.

Who can create an obligation is decided in one place, `obligation_candidates`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from crossing_env.safety.geometry import min_box_disc_ttc
from crossing_env.safety.results import DEFAULT_METRICS, MetricsConfig
from crossing_env.types import GroundTruth, PedState

__all__ = [
    "EMPTY_YIELD_STATE",
    "YieldState",
    "YieldTracker",
    "ego_in_conflict_area",
    "is_hard_braking",
    "min_pedestrian_ttc",
    "obligation_candidates",
]

OPEN, COMPLIANT, VIOLATED, WAIVED, DECLINED = 1, 2, 3, 4, 5
"""Obligation states (0: none yet)."""
_WAITING, _CROSSING = int(PedState.WAITING), int(PedState.CROSSING)


class YieldState(NamedTuple):
    """The yield obligations of an episode so far, one row per pedestrian id (sorted by id).

    Immutable by convention: `YieldTracker.update` builds a new state instead of writing into the arrays, so
    a state can be handed on (`crossing_env.safety.StepSafety`) and compared by identity.
    """

    ids: np.ndarray
    """(n,) int64 pedestrian ids, sorted."""
    status: np.ndarray
    """(n,) int8 obligation state: 0 none yet, then OPEN, COMPLIANT, VIOLATED, WAIVED or DECLINED."""
    entered_half: np.ndarray
    """(n,) bool: entered the ego's half while the obligation was open."""
    offer_time: np.ndarray
    """(n,) float64 seconds the ego has stood offering the way."""
    earlier_declined: np.ndarray
    """(n,) int64 declined obligations of this pedestrian that closed before the current one reopened."""


def _frozen(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


EMPTY_YIELD_STATE = YieldState(
    _frozen(np.empty(0, dtype=np.int64)),
    _frozen(np.empty(0, dtype=np.int8)),
    _frozen(np.empty(0, dtype=bool)),
    _frozen(np.empty(0, dtype=np.float64)),
    _frozen(np.empty(0, dtype=np.int64)),
)
"""The state of every new `YieldTracker` (one shared object, so trackers that saw the same steps from the
start hold identical states)."""


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
    ev = gt.ego_velocity
    speed = math.hypot(float(ev[0]), float(ev[1]))
    if not gt.pedestrian_ids.shape[0] or speed <= config.ttc_min_ego_speed:
        return math.inf
    if half is None:
        hx, hy = 0.5 * float(gt.ego_size[0]), 0.5 * float(gt.ego_size[1])
    else:
        hx, hy = float(half[0]), float(half[1])
    ep = gt.ego_position
    return min_box_disc_ttc(
        gt.pedestrian_positions,
        gt.pedestrian_velocities,
        gt.pedestrian_radii,
        float(ep[0]),
        float(ep[1]),
        float(ev[0]),
        float(ev[1]),
        hx,
        hy,
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
        self.config = config if config is not None else DEFAULT_METRICS
        self.state = EMPTY_YIELD_STATE
        """The obligations so far; replaced (never modified) by each `update` that changes them."""

    @property
    def ids(self) -> np.ndarray:
        """(n,) sorted ids of every pedestrian seen so far."""
        return self.state.ids

    @property
    def status(self) -> np.ndarray:
        """(n,) obligation state per id: 0 none yet, then OPEN, COMPLIANT, VIOLATED, WAIVED or DECLINED."""
        return self.state.status

    @property
    def entered_half(self) -> np.ndarray:
        """(n,) whether the pedestrian entered the ego's half while its obligation was open."""
        return self.state.entered_half

    @property
    def offer_time(self) -> np.ndarray:
        """(n,) seconds the ego has stood offering the way to the (waiting) pedestrian."""
        return self.state.offer_time

    def _rows(self, ids: np.ndarray) -> np.ndarray:
        st = self.state
        # The empty start state is read-only: searching it would compile `_find_rows` a second time.
        pos = _find_rows(st.ids, ids) if st.ids.shape[0] else np.empty(0, dtype=np.int64)
        if pos.shape[0] != ids.shape[0]:  # ids seen for the first time: add rows (sorted by id)
            new = np.setdiff1d(np.unique(ids), st.ids)
            all_ids = np.concatenate([st.ids, new])
            order = np.argsort(all_ids, kind="stable")
            k = new.shape[0]
            st = self.state = YieldState(
                all_ids[order],
                np.concatenate([st.status, np.zeros(k, dtype=np.int8)])[order],
                np.concatenate([st.entered_half, np.zeros(k, dtype=bool)])[order],
                np.concatenate([st.offer_time, np.zeros(k)])[order],
                np.concatenate([st.earlier_declined, np.zeros(k, dtype=np.int64)])[order],
            )
            pos = np.searchsorted(st.ids, ids)
        return pos

    def update(self, gt: GroundTruth, ego_in_ca: bool | None = None) -> int:
        """Open, resolve and check obligations for one snapshot; returns the violations of this step.

        The rules (see the module docstring and `EpisodeMetrics`) run in one compiled pass over the
        pedestrians, `_update_obligations`.
        """
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
        dist = ca.stop_line_x - front
        stopping = speed * speed / (2.0 * cfg.yield_deceleration)
        can_open = may_open and dist > stopping
        # A closed obligation reopens while the ego can still stop before the crossing itself (it may
        # have stood between the stop line and the crossing while it offered the way).
        can_reopen = may_open and ca.x_min - front > stopping
        # Declined offers: the ego stands before the crossing (at most `offer_distance` before the stop line,
        # or between the line and the crossing) while the pedestrian keeps waiting.
        offering = speed <= cfg.offer_stop_speed and front <= ca.x_min and dist <= cfg.offer_distance
        st = self.state
        violated, status, entered, offer_time, earlier = _update_obligations(
            st.status,
            st.entered_half,
            st.offer_time,
            st.earlier_declined,
            rows,
            gt.pedestrian_positions,
            gt.pedestrian_velocities,
            gt.pedestrian_states,
            gt.on_road,
            gt.on_crossing,
            gt.waiting,
            obligation_candidates(gt),
            bool(can_open),
            bool(can_reopen),
            bool(offering),
            bool(ego_in_ca),
            bool(cfg.far_half_counts),
            ca.half_y_min,
            ca.half_y_max,
            0.5 * (ca.half_y_min + ca.half_y_max),
            0.5 * (ca.x_min + ca.x_max),
            0.5 * (ca.x_max - ca.x_min) + cfg.kerb_margin,
            self.dt,
            cfg.offer_timeout - 1e-9,
        )
        if status is not None:
            self.state = YieldState(
                st.ids,
                status,
                entered,
                offer_time if offer_time is not None else st.offer_time,
                earlier if earlier is not None else st.earlier_declined,
            )
        return violated

    def counts(self) -> tuple[int, int, int, int]:
        """(compliant, violated, declined, unresolved) obligations so far.

        Declined offers are compliant (and counted apart too); an obligation still open is unresolved: it is
        neither met nor broken, and an episode that ends with it open has not shown that the car gives way
        (a car that stops far from the crossing and waits, or one that crashed first).
        """
        s = self.status
        earlier = int(self.state.earlier_declined.sum())  # declined, then reopened: each one counts
        declined = int(np.count_nonzero(s == DECLINED)) + earlier
        compliant = int(np.count_nonzero(s == COMPLIANT)) + declined
        return compliant, int(np.count_nonzero(s == VIOLATED)), declined, int(np.count_nonzero(s == OPEN))


@njit(cache=True, nogil=True)
def _find_rows(table: np.ndarray, ids: np.ndarray) -> np.ndarray:
    """Row of each id in the sorted `table`; an empty array if any id is missing."""
    pos = np.searchsorted(table, ids)
    n = table.shape[0]
    for i in range(ids.shape[0]):
        if pos[i] >= n or table[pos[i]] != ids[i]:
            return np.empty(0, dtype=pos.dtype)
    return pos


@njit(cache=True, nogil=True)
def _update_obligations(
    status_all: np.ndarray,
    entered_all: np.ndarray,
    offer_all: np.ndarray,
    earlier_all: np.ndarray,
    rows: np.ndarray,
    positions: np.ndarray,
    velocities: np.ndarray,
    states: np.ndarray,
    on_road: np.ndarray,
    on_crossing: np.ndarray,
    waiting_gt: np.ndarray,
    may_owe: np.ndarray,
    can_open: bool,
    can_reopen: bool,
    offering: bool,
    ego_in_ca: bool,
    far_half_counts: bool,
    half_y_min: float,
    half_y_max: float,
    half_y_mid: float,
    crossing_x_mid: float,
    near_x: float,
    dt: float,
    offer_limit: float,
) -> tuple[int, np.ndarray | None, np.ndarray | None, np.ndarray | None, np.ndarray | None]:
    """One step of the yield rules for the pedestrians at `rows` of the obligation table.

    Returns (violations, status, entered_half, offer_time, earlier_declined): new full-table arrays (the
    inputs are never written), or None where nothing changed (offer_time: where no offer clock ran or was
    reset; earlier_declined: where nothing reopened).
    """
    n = rows.shape[0]
    busy = False  # anything open, or anyone who could open or reopen an obligation now
    for i in range(n):
        s = status_all[rows[i]]
        if s == OPEN or (can_open and s == 0 and (on_crossing[i] or waiting_gt[i]) and may_owe[i]):
            busy = True
            break
        if can_reopen and (s == DECLINED or s == WAIVED) and on_crossing[i] and on_road[i] and may_owe[i]:
            busy = True
            break
    if not busy:
        return 0, None, None, None, None
    status = status_all.copy()
    entered = entered_all.copy()
    offer = offer_all
    offered = False
    earlier = earlier_all
    reopened = False
    violated = 0
    for i in range(n):
        r = rows[i]
        s = status[r]
        py = positions[i, 1]
        in_half = on_road[i] and py >= half_y_min and py <= half_y_max
        waiting = waiting_gt[i] and abs(positions[i, 0] - crossing_x_mid) <= near_x
        was_open = s == OPEN
        # Resolve open obligations from the pedestrians' side.
        ent = entered[r] or (was_open and in_half)
        if was_open and ent and not in_half:
            s = COMPLIANT  # crossed, or turned back after entering the ego's half
        elif was_open and not ent and states[i] != _WAITING and states[i] != _CROSSING and not on_road[i]:
            s = WAIVED  # walked off, never stepped on
        if offering and s == OPEN and waiting:
            if not offered:
                offer = offer_all.copy()
                offered = True
            offer[r] += dt
            s = DECLINED if offer[r] >= offer_limit else OPEN
        relevant = on_crossing[i] and in_half
        if far_half_counts and on_crossing[i] and not in_half:
            relevant = relevant or (half_y_mid - py) * velocities[i, 1] > 0.0
        # Open new obligations while the ego can still stop comfortably before the stop line.
        if can_open and s == 0 and may_owe[i]:
            if relevant or waiting:
                s = OPEN
                ent = ent or in_half
        # Reopen a declined or waived one when its pedestrian steps onto the crossing after all.
        elif can_reopen and (s == DECLINED or s == WAIVED) and may_owe[i] and relevant and on_road[i]:
            if not reopened:
                earlier = earlier_all.copy()
                reopened = True
            if not offered:
                offer = offer_all.copy()
                offered = True
            earlier[r] += s == DECLINED  # the declined obligation stays counted; a waived one never was
            offer[r] = 0.0
            s = OPEN
            ent = in_half
        # Violations: the ego occupies the conflict area while an obligation is open.
        if ego_in_ca and s == OPEN:
            violated += 1
            s = VIOLATED
        status[r] = s
        entered[r] = ent
    return violated, status, entered, offer if offered else None, earlier if reopened else None
