"""The yielding policy, which gives way as the law asks, and its always-cautious variant.

It reads only the observation (never the ground truth); with the prediction wrappers on it also reads
``crossing_intention`` and ``predicted_paths`` (through `agents.view.View`). Vehicles ahead are followed with
the Intelligent Driver Model.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar, NamedTuple

import numpy as np

from agents.config import CautiousConfig, YieldingConfig
from agents.view import (
    EPS,
    ObsLike,
    View,
    corridor_interval,
    cruise,
    finish,
    follow,
    parse_observation,
    path_interval,
    stop_acceleration,
    travel_time,
)
from crossing_env.observation import VehicleColumn


@dataclass
class TrackMemory:
    """What the policy remembers about one pedestrian track (one batch element's observation)."""

    origin: float
    """Side of the road it was first seen on (+1 left of the road's centre, −1 right), or walking from."""
    seen: float
    """Policy clock (s) when last observed."""
    was_on_road: bool = False
    """Seen on the carriageway at some point."""
    away_time: float = 0.0
    """Time (s) it has kept walking along the kerb away from the crossing, without a break."""


class LegalDuty(NamedTuple):
    """What the legal-yield step of the last `YieldingPolicy._targets` call saw (read by `agents.shield`)."""

    line: np.ndarray
    """(B,) the crossing's stop point (m ahead of the ego's front): `stop_buffer` before the stop line, or
    before the crossing's near edge once past the line; negative once the front is past it. Unlike the
    legal target it is never given up (inf only without a crossing ahead)."""
    needs: np.ndarray
    """(B,) bool: a legal duty holds now (someone on the zebra in or towards the ego's half, someone waiting
    at the kerb who has not declined, a red light), whether or not the rule can still stop for it."""
    candidates: np.ndarray
    """(B, K) bool: pedestrians off the road at a zebra ahead whom the rule has not set aside (settled by its
    track memory, or declined its offer): they may yet wait at the kerb or step onto the zebra."""


class YieldingPolicy:
    """Gives way at crossings like a careful human driver, and proceeds as soon as the conflict is clear.

    Each step it computes stopping targets (distances ahead of the ego's front) and brakes for the
    nearest, as late as `comfortable_deceleration` allows (harder only when a target appears late):

    1. **Legal yield** (zebra, UK rule 195 / StVO §26): a pedestrian on the crossing inside the ego's half
       of the road or walking towards it, or one who may be waiting at the kerb within the crossing's
       extent ± `kerb_margin` (within `kerb_distance` of the kerb and not walking away from the road: the
       car cannot tell a pedestrian about to cross from one passing by; with the intention wrapper on,
       also one predicted to cross there), makes the car stop before the stop line; at a signalised
       crossing a red light for cars does. Attempted only if it needs at most `yield_max_deceleration`: a
       car that can no longer stop comfortably does not slam on the brakes for a pedestrian still on the
       kerb. If the car has stood at the line for `offer_timeout` while the only reason was people who
       keep waiting, they have declined the offer and it goes; someone who arrives later gets an offer.
    2. **Conflict check** (any pedestrian, anywhere): with constant velocity, the predicted path (when
       ``predicted_paths`` is present) and, for pedestrians the intention estimate expects to cross, a walk
       straight into the road, the pedestrian's time inside the ego's lane corridor is compared with the
       time the ego needs to pass its position "if it goes now" (accelerating at `go_acceleration` to the
       speed limit). If they overlap within `time_buffer`, the car stops `pedestrian_gap` before the
       pedestrian (or at the stop line when that is nearer), with any deceleration up to the maximum.
    3. **Occlusion**: a stationary vehicle beside the ego's lane just before the crossing may hide a
       pedestrian (the multiple-threat case); the car passes it at `occlusion_speed`. At a zebra it does
       not overtake the adjacent-lane vehicle nearest the crossing at all (UK rule 191).

    Otherwise it cruises at the speed limit and follows vehicles ahead (IDM). "Proceed when clear" falls
    out of re-evaluating the rules each step; the only state is the offer timer and who declined (per
    batch element), which reset themselves when the car is far before or past a crossing (`reset` clears
    them explicitly), and, when the observation carries ``pedestrian_tracks``, a memory per track.

    **Memory** (`_settled`, per batch element, with ``pedestrian_tracks``): a pedestrian who has crossed
    (seen on the road, now off it on the other side) or who keeps walking along the kerb away from the
    crossing (faster than `along_kerb_speed` for `along_kerb_time`) is not waiting to cross; someone who
    has crossed counts again while stepping towards the road. The law's duty is to people who want to
    cross; the rule "anyone by the kerb not walking away" otherwise stops the car again for people leaving
    the crossing they have just used. Without tracks the car remembers nothing and treats them as waiting.

    Departures from the literature: legal rules are simplified to what the observation shows (no gaze or
    gesture); the German "influenced" test is approximated by stopping at the line rather than creeping
    up to the pedestrian; waiting pedestrians are yielded to whatever the intention estimate says.
    """

    name: ClassVar[str] = "yielding"
    uses_predictors: ClassVar[bool] = True
    batched: ClassVar[bool] = True
    """Acts for a batch of episodes in one call, each element as alone (`agents.policy_is_batched`)."""

    def __init__(self, config: YieldingConfig | None = None) -> None:
        self.config = config or YieldingConfig()
        self.reset()

    def reset(self, seed: int | None = None) -> None:
        """Forget offer timers, stop commitments and tracks (`agents.Policy.reset`; `seed` unused)."""
        self._offers = np.zeros((0, 0, 4))
        self._committed = np.zeros(0, dtype=bool)
        self._tracks: list[dict[int, TrackMemory]] = []
        self._clock = np.zeros(0)
        self._last_to_stop = np.zeros(0)
        self.duty: LegalDuty | None = None
        """The legal-yield state of the last call (`LegalDuty`), for `agents.shield.YieldingShield`."""

    def _kerb_gap(self, view: View) -> np.ndarray:
        """(B, K) each pedestrian's lateral distance (m) to the nearer kerb."""
        cfg = self.config
        return np.minimum(np.abs(view.py - cfg.road_right), np.abs(view.py - cfg.road_left))

    def _settled(self, view: View) -> np.ndarray:
        """Update the track memory; return (B, K): pedestrians not waiting to cross by what they did.

        Settled are those who have crossed (seen on the road and now off it on the other side than they
        came from; someone first seen on the road came from the side they walk away from, or the nearer
        one), unless stepping towards the road faster than `returning_speed`, and those who have walked
        along the kerb away from the crossing's centre faster than `along_kerb_speed` for
        `along_kerb_time`. A vector env restarts an element's episode without `reset`: the ego's distance
        to the stop line, which never grows within an episode (the car does not reverse), jumps up, and
        the element's memory is cleared (track ids restart at 1 each episode).
        """
        b, k = view.present.shape
        settled = np.zeros((b, k), dtype=bool)
        if view.tracks is None or not self.config.remember_tracks:
            return settled
        cfg = self.config
        if len(self._tracks) != b:
            self._tracks = [{} for _ in range(b)]
            self._clock = np.zeros(b)
            self._last_to_stop = np.full(b, np.inf)
        self._clock += cfg.dt
        mid = 0.5 * (cfg.road_right + cfg.road_left)
        side = np.where(view.py > mid, 1.0, -1.0)
        towards_road = self._towards_road(view)
        near, far = self._crossing_span(view)
        away_x = (view.px - 0.5 * (near + far)) * view.vx > 0.0
        along_away = away_x & (np.abs(view.vx) > cfg.along_kerb_speed) & (towards_road <= cfg.returning_speed)
        for e in range(b):
            memory = self._tracks[e]
            if view.to_stop[e] > self._last_to_stop[e] + 0.5:  # a new episode in this element
                memory.clear()
            self._last_to_stop[e] = view.to_stop[e]
            now = float(self._clock[e])
            for j in np.flatnonzero(view.tracks[e] > 0):
                track = int(view.tracks[e, j])
                entry = memory.get(track)
                if entry is None:
                    origin = side[e, j]
                    if view.on_road[e, j] and abs(view.vy[e, j]) > cfg.returning_speed:
                        origin = -np.sign(view.vy[e, j])  # the side it walks from
                    entry = memory[track] = TrackMemory(origin=float(origin), seen=now)
                entry.away_time = entry.away_time + cfg.dt if along_away[e, j] else 0.0
                entry.seen = now
                entry.was_on_road |= bool(view.on_road[e, j])
                crossed = entry.was_on_road and not view.on_road[e, j] and side[e, j] != entry.origin
                returning = towards_road[e, j] > cfg.returning_speed
                settled[e, j] = (crossed and not returning) or entry.away_time >= cfg.along_kerb_time - 1e-9
            for track in [t for t, entry in memory.items() if now - entry.seen > cfg.track_forget]:
                del memory[track]
        return settled

    def _offer_state(self, view: View, waiting: np.ndarray, legal_xing: np.ndarray) -> np.ndarray:
        """Update the offer timers; return (B, K): which waiting pedestrians have declined the car's offer.

        Each pedestrian standing (below `still_speed`) at the crossing while the car stands (< 0.1 m/s)
        within a few metres of the stop line, with no one on the crossing to give way to, has been offered
        the way; after `offer_timeout` of that they have declined it. They are followed by track id when
        the observation has ``pedestrian_tracks``, else by position (the nearest waiting pedestrian within
        `decline_match_radius` of where they were last step), as (x, y, offered time, track id) per batch
        element, until the car has passed the crossing or is again far (> 20 m) before the line, which also
        resets a vector env's elements at the start of an episode. Someone who arrives later starts their
        own timer: the metric, and the law, give them their own offer.
        """
        b, k = waiting.shape
        if self._offers.shape[:2] != (b, k):
            self._offers = np.full((b, k, 4), np.nan)
        offers = self._offers
        fresh = (view.past >= 0.0) | (view.to_stop > 20.0)
        offers[fresh] = np.nan
        tracked = np.isfinite(offers[..., 0])  # (B, D)
        standing = (view.speed < 0.1) & (view.to_stop < 3.0) & ~legal_xing
        if not tracked.any() and not (waiting & standing[:, None]).any():
            # Nobody followed and no newcomer (most steps): no timer runs, nothing to update.
            return waiting & (0.0 >= self.config.offer_timeout - 1e-9)
        match = np.full((b, k), -1)
        if tracked.any() and view.tracks is not None:
            same = (view.tracks[:, :, None] == offers[:, None, :, 3]) & waiting[:, :, None]  # (B, K, D)
            match = np.where(same.any(axis=2), np.argmax(same, axis=2), -1)
        elif tracked.any():
            dx = view.px[:, :, None] - offers[:, None, :, 0]
            dy = view.py[:, :, None] - offers[:, None, :, 1]
            dist = np.where(waiting[:, :, None] & tracked[:, None, :], np.hypot(dx, dy), np.inf)  # (B,K,D)
            nearest = np.argmin(dist, axis=2)
            close = (
                np.take_along_axis(dist, nearest[..., None], axis=2)[..., 0]
                <= self.config.decline_match_radius
            )
            match = np.where(close, nearest, -1)
        still = np.hypot(view.vx, view.vy) < self.config.still_speed
        # Newcomers while the car stands get a free tracking slot each (free slots in order, per element).
        new = waiting & (match < 0) & standing[:, None]
        if new.any():
            free = ~np.isfinite(offers[..., 0])
            order = np.argsort(~free, axis=1, kind="stable")  # free slots first
            rank = np.cumsum(new, axis=1) - 1
            new &= rank < free.sum(axis=1)[:, None]
            slot = np.take_along_axis(order, np.clip(rank, 0, k - 1), axis=1)
            match = np.where(new, slot, match)
            e, p = np.nonzero(new)
            offers[e, slot[e, p], 2] = 0.0
            offers[e, slot[e, p], 3] = np.nan if view.tracks is None else view.tracks[e, p]
        e, p = np.nonzero(match >= 0)
        d = match[e, p]
        offers[e, d, 0] = view.px[e, p]
        offers[e, d, 1] = view.py[e, p]
        offers[e, d, 2] += np.where(standing[e] & still[e, p], self.config.dt, 0.0)
        timers = np.where(match >= 0, np.take_along_axis(offers[..., 2], np.maximum(match, 0), axis=1), 0.0)
        return waiting & (timers >= self.config.offer_timeout - 1e-9)

    def _commitments(self, needs_line: np.ndarray) -> np.ndarray:
        """Which batch elements are already stopping for a legal duty that still holds."""
        if self._committed.shape != needs_line.shape:
            self._committed = np.zeros(needs_line.shape, dtype=bool)
        return self._committed & needs_line

    def _crossing_span(self, view: View) -> tuple[np.ndarray, np.ndarray]:
        """(near, far) edges of the crossing, (B, 1) each, relative to the ego's centre along x."""
        front = self.config.ego_length / 2
        return front + view.to_stop[:, None] + self.config.stop_line_offset, -view.past[:, None] - front

    def _towards_road(self, view: View) -> np.ndarray:
        """(B, K) each pedestrian's speed towards the carriageway (m/s; negative: away from it)."""
        cfg = self.config
        return np.where(view.py > 0.5 * (cfg.road_right + cfg.road_left), -view.vy, view.vy)

    def _at_crossing(self, view: View) -> np.ndarray:
        """(B, K) pedestrians within `kerb_margin` of the crossing along the road."""
        near, far = self._crossing_span(view)
        margin = self.config.kerb_margin
        return (view.px >= near - margin) & (view.px <= far + margin)

    def _targets(self, view: View) -> tuple[np.ndarray, np.ndarray]:
        """(legal_target, conflict_target): stop distances (B,) ahead of the ego front, inf when none."""
        cfg = self.config
        front = cfg.ego_length / 2
        r = cfg.pedestrian_radius
        hw = cfg.ego_width / 2 + r + cfg.lateral_margin
        v = view.speed

        # Crossing geometry in the ego frame.
        crossing_ahead = view.past[:, None] < 0.0
        at_crossing = self._at_crossing(view)
        # Stop target for crossing-related yields: the stop line, or the crossing's edge once past the line.
        stop_point = np.where(
            view.to_stop > 0.0,
            view.to_stop - cfg.stop_buffer,
            view.to_stop + cfg.stop_line_offset - cfg.stop_buffer,
        )
        line_target = np.where(stop_point > -0.3, np.maximum(stop_point, 0.0), np.inf)  # (B,)

        # 1. Legal yield.
        use_pred = cfg.use_predictions
        in_half = (view.py >= cfg.half_right - r) & (view.py <= cfg.half_left + r)
        centre = 0.5 * (cfg.half_right + cfg.half_left)
        toward = (centre - view.py) * view.vy > 0.0
        on_xing = view.on_crossing & (in_half | toward)
        kerb_gap = self._kerb_gap(view)
        towards_road = self._towards_road(view)
        lingering = view.present & (towards_road > -cfg.leaving_speed) & (kerb_gap <= cfg.kerb_distance)
        settled = self._settled(view)
        waiting = (view.waiting | lingering) & ~view.on_road & ~settled
        likely = self._likely_to_cross(view, kerb_gap) if use_pred and view.intention is not None else None
        if likely is not None:
            likely = likely & ~settled
        waiting = self._yield_waiting(view, waiting, likely, kerb_gap) & ~settled
        zebra = view.zebra[:, None] > 0.5
        legal_xing = (zebra & crossing_ahead & at_crossing & on_xing).any(axis=1)
        waiting_here = zebra & crossing_ahead & at_crossing & waiting
        declined = self._offer_state(view, waiting_here, legal_xing)
        legal_wait = (waiting_here & ~declined).any(axis=1)
        red = (view.zebra < 0.5) & (view.car_green < 0.5) & (view.past < 0.0)
        needs_line = legal_xing | legal_wait | red
        with np.errstate(divide="ignore", invalid="ignore"):
            a_req = np.where(line_target > 0.05, v * v / (2.0 * np.maximum(line_target, 0.05)), np.inf)
        # A legal stop starts only when it is comfortable, but once started it is not given up while the
        # car can still make it (harder, up to its braking limit): the duty opened when it could stop.
        committed = self._commitments(needs_line)
        limit = np.where(committed, cfg.ego.max_deceleration, cfg.yield_max_deceleration)
        can_stop = (a_req <= limit) | (v < 0.5)
        self._committed = needs_line & can_stop
        legal_target = np.where(needs_line & can_stop, line_target, np.inf)
        self.duty = LegalDuty(
            line=np.where(view.past < 0.0, stop_point, np.inf),
            needs=needs_line,
            candidates=zebra & crossing_ahead & view.present & ~view.on_road & ~settled & ~declined,
        )

        # 2. Conflict check (constant velocity ∪ predicted path): only present pedestrians can conflict.
        if not view.present.any():
            return legal_target, np.full(v.shape, np.inf)
        t_in, t_out = corridor_interval(view.py, view.vy, hw)
        x_in = view.px + view.vx * np.where(np.isfinite(t_in), np.minimum(t_in, cfg.horizon), 0.0)
        if use_pred and view.paths is not None:
            pt_in, pt_out, px_in = path_interval(view.paths, view.present, hw, -front)
            if self.paths_replace_constant_velocity:
                # Paths alone, except where constant velocity puts the pedestrian in the corridor soon (or
                # now): paths come from 0.4 s histories and lag a sudden start.
                guard = t_in <= getattr(cfg, "constant_velocity_guard", np.inf)
                # At a zebra, someone walking towards the road at the crossing is kept on constant velocity:
                # a path that (rightly) predicts a stop at the kerb is exactly when the law asks the car to
                # be able to give way, so the car must not build up speed on it.
                guard |= zebra & crossing_ahead & at_crossing
                x_in = np.where(guard & (t_in <= pt_in), x_in, np.where(np.isfinite(pt_in), px_in, x_in))
                t_in, t_out = (
                    np.where(guard, np.minimum(t_in, pt_in), pt_in),
                    np.where(guard, np.maximum(t_out, pt_out), pt_out),
                )
            else:
                x_in = np.where(pt_in < t_in, px_in, x_in)
                t_in = np.minimum(t_in, pt_in)
                t_out = np.maximum(t_out, pt_out)
        anticipated = None if likely is None else self._anticipated(view, likely)
        if anticipated is not None:
            # Anticipation: a pedestrian the intention estimate expects to cross walks straight in.
            towards_lane = np.where(view.py > 0.0, -1.0, 1.0) * cfg.assumed_walking_speed
            a_in, a_out = corridor_interval(view.py, towards_lane, hw)
            a_in = np.where(anticipated, a_in, np.inf)
            x_in = np.where(a_in < t_in, view.px, x_in)
            t_in = np.minimum(t_in, a_in)
            t_out = np.maximum(t_out, np.where(anticipated, a_out, -np.inf))
        behind = x_in + r < -front
        s_arr = x_in - r - front
        s_clr = x_in + r + front
        t_arr, t_clr = self._arrival_times(view, s_arr, s_clr)
        conflict = (
            view.present
            & ~behind
            & (t_in < cfg.horizon)
            & (t_in < t_clr + cfg.time_buffer)
            & (t_out > t_arr - cfg.time_buffer)
        )
        ped_target = s_arr - cfg.pedestrian_gap
        # Conflicts at the crossing: stop at the line when it is nearer than the pedestrian.
        ped_target = np.where(
            at_crossing & crossing_ahead, np.minimum(ped_target, line_target[:, None]), ped_target
        )
        ped_target = np.where(conflict, np.maximum(ped_target, 0.0), np.inf)
        return legal_target, ped_target.min(axis=1, initial=np.inf)

    def _arrival_times(
        self, view: View, s_arr: np.ndarray, s_clr: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """(B, K) times the ego's front reaches and its rear clears each pedestrian's entry point (hook).

        Here as if it drives on, accelerating at `go_acceleration` up to the speed limit.
        """
        cfg = self.config
        v = view.speed[:, None]
        vmax = max(cfg.speed_limit, EPS)
        both = travel_time(np.stack((s_arr, s_clr)), v, cfg.go_acceleration, vmax)  # one call, elementwise
        return both[0], both[1]

    paths_replace_constant_velocity: ClassVar[bool] = False
    """With ``predicted_paths``, check conflicts on the paths alone (True) or on their union with constant
    velocity (False: predictions only ever add caution)."""

    def _likely_to_cross(self, view: View, kerb_gap: np.ndarray) -> np.ndarray:
        """(B, K) pedestrians off the road that the intention estimate expects to cross (hook)."""
        return (view.intention >= self.config.intention_threshold) & view.present & ~view.on_road

    def _anticipated(self, view: View, likely: np.ndarray) -> np.ndarray:
        """(B, K) pedestrians assumed to walk straight into the road in the conflict check (hook)."""
        return likely

    def _yield_waiting(
        self, view: View, waiting: np.ndarray, likely: np.ndarray | None, kerb_gap: np.ndarray
    ) -> np.ndarray:
        """(B, K) pedestrians the legal rule treats as waiting to cross (hook); here predictions only add."""
        return waiting if likely is None else waiting | likely

    def _occlusion_cap(self, view: View) -> np.ndarray:
        """Acceleration (B,) that slows the car to `occlusion_speed` by the front of an occluding vehicle."""
        cfg = self.config
        veh = view.vehicles
        if veh.shape[1] == 0:
            return np.full(view.speed.shape, np.inf)
        front = cfg.ego_length / 2
        speed = np.hypot(veh[..., VehicleColumn.VX], veh[..., VehicleColumn.VY])
        standing = (veh[..., VehicleColumn.PRESENCE] > 0.5) & (speed < 0.5)
        if not standing.any():  # no standing vehicle, no occluder: the same +inf, computed cheaply
            return np.full(view.speed.shape, np.inf)
        near_rel, far_rel = self._crossing_span(view)
        veh_front = veh[..., VehicleColumn.DX] + veh[..., VehicleColumn.LENGTH] / 2
        lateral = np.abs(veh[..., VehicleColumn.DY])
        beside = (lateral >= cfg.lane_width / 2) & (lateral <= 2.5 * cfg.lane_width)
        occluder = (
            standing
            & beside
            & (veh_front >= near_rel - cfg.occlusion_window)
            & (veh_front <= far_rel)
            & (veh_front > -front)
            & (view.past[:, None] < 0.0)
        )
        # Distance from the ego front to the occluder's front: reach the crawl there.
        s = np.where(occluder, veh_front - front, np.inf).min(axis=1, initial=np.inf)
        v_cap = np.sqrt(cfg.occlusion_speed**2 + 2.0 * cfg.comfortable_deceleration * np.maximum(s, 0.0))
        over = view.speed - v_cap
        with np.errstate(invalid="ignore"):
            a = np.where(
                np.isfinite(s) & (over > -0.5),
                np.maximum(
                    -cfg.ego.max_deceleration, -cfg.stop_gain * over - cfg.comfortable_deceleration * (s > 0)
                ),
                np.inf,
            )
        return a

    def _no_overtaking(self, view: View) -> np.ndarray:
        """IDM acceleration (B,) that keeps the ego behind the adjacent-lane vehicle nearest a zebra ahead.

        UK Highway Code rule 191: within the approach to a crossing, do not overtake the moving vehicle
        nearest it (it may be slowing for a pedestrian it hides). Candidates drive in the ego's direction,
        faster than `moving_speed`, in another lane of its half of the road (parked cars stand outside the
        carriageway), are ahead of the ego and have their front within `no_overtaking_zone` before the
        crossing's near edge, or on it. Braking is capped at the comfortable deceleration: this is a rule
        of the approach, not an emergency. A vehicle that has stopped is passed at `occlusion_speed`
        instead (`_occlusion_cap`), ready to stop at the line: the rule also forbids passing it, but a
        background driver who waits on a pedestrian who never crosses would then hold the ego for good (a
        dev run of always_cautious stood 30 s behind one on four_lane_arterial).
        """
        cfg = self.config
        veh = view.vehicles
        if veh.shape[1] == 0:
            return np.full(view.speed.shape, np.inf)
        moving = (
            (veh[..., VehicleColumn.PRESENCE] > 0.5)
            & (veh[..., VehicleColumn.VX] > cfg.moving_speed)
            & (veh[..., VehicleColumn.DX] > 0.0)
            & ((view.zebra > 0.5) & (view.past < 0.0))[:, None]
        )
        if not moving.any():  # no moving vehicle ahead before a zebra: no candidate, the same +inf
            return np.full(view.speed.shape, np.inf)
        near_rel, far_rel = self._crossing_span(view)
        veh_front = veh[..., VehicleColumn.DX] + veh[..., VehicleColumn.LENGTH] / 2
        dy = veh[..., VehicleColumn.DY]
        adjacent = (np.abs(dy) >= cfg.lane_width / 2) & (dy > cfg.road_right) & (dy < cfg.half_left)
        candidate = (
            moving & adjacent & (veh_front >= near_rel - cfg.no_overtaking_zone) & (veh_front <= far_rel)
        )
        if not candidate.any():
            return np.full(view.speed.shape, np.inf)
        masked = veh.copy()
        masked[..., VehicleColumn.PRESENCE] = candidate
        masked[..., VehicleColumn.DY] = 0.0  # treat it as if in the ego's lane
        a = follow(replace(view, vehicles=masked), cfg)
        return np.maximum(a, -cfg.comfortable_deceleration)

    def acceleration(self, obs: ObsLike) -> np.ndarray:
        """Commanded acceleration (m/s²) of shape (B,) for the flattened batch."""
        view = parse_observation(obs)
        return self._acceleration(view)

    def _acceleration(self, view: View) -> np.ndarray:
        legal, conflict = self._targets(view)
        return self._acceleration_for(view, legal, conflict)

    def _acceleration_for(self, view: View, legal: np.ndarray, conflict: np.ndarray) -> np.ndarray:
        """The rule's acceleration for stop targets already computed by `_targets` (which advances timers)."""
        cfg = self.config
        a = np.minimum(cruise(view, cfg), follow(view, cfg))
        a_legal = stop_acceleration(
            view, legal, cfg.comfortable_deceleration, cfg.stop_gain, cfg.ego.max_deceleration
        )
        a_conf = stop_acceleration(
            view, conflict, cfg.comfortable_deceleration, cfg.stop_gain, cfg.ego.max_deceleration
        )
        a = np.minimum(a, np.minimum(self._occlusion_cap(view), self._no_overtaking(view)))
        return np.minimum(a, np.minimum(a_legal, a_conf))

    def __call__(self, obs: ObsLike) -> np.ndarray:
        """Normalised action(s) for one or a batch of observations."""
        view = parse_observation(obs)
        return finish(self._acceleration(view), view, self.config)


class AlwaysCautious(YieldingPolicy):
    """Slows to a crawl at every crossing, whoever is there, and stops for pedestrians in its path.

    Approaching a crossing (any kind) it brakes at `approach_deceleration` so as to reach `crawl_speed` at
    the stop line and keeps the crawl until its rear is `clear_distance` past the crossing. On top it
    applies `YieldingPolicy`'s rules, so it is safe but slow: the efficiency end of the Pareto front.
    """

    name: ClassVar[str] = "always_cautious"
    uses_predictors: ClassVar[bool] = False

    def __init__(self, config: CautiousConfig | None = None) -> None:
        super().__init__(config or CautiousConfig())
        self.config: CautiousConfig

    def _acceleration(self, view: View) -> np.ndarray:
        cfg = self.config
        a = super()._acceleration(view)
        crawl = cfg.crawl_speed
        before = np.maximum(view.to_stop, 0.0)
        v_allow = np.sqrt(crawl * crawl + 2.0 * cfg.approach_deceleration * before)
        near = view.past < cfg.clear_distance
        target = np.where(near, np.minimum(v_allow, cfg.speed_limit), cfg.speed_limit)
        a_crawl = np.where(
            view.speed > target,
            np.maximum(-cfg.comfortable_deceleration, cfg.stop_gain * (target - view.speed)),
            np.inf,
        )
        # Below the profile: do not accelerate above the crawl-speed envelope.
        a_cap = np.clip(
            cfg.cruise_gain * (target - view.speed), -cfg.comfortable_deceleration, cfg.cruise_acceleration
        )
        return np.minimum(a, np.minimum(a_crawl, a_cap))
