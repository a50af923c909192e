"""Driving policies for `crossing_env/Crossing-v0`: plain callables `policy(obs) -> action`.

Every policy reads only the observation (never the ground truth) and returns the normalised action of
`CrossingEnv` (−1 full braking … +1 full throttle, see `crossing_env.action_to_acceleration`). Policies
accept one observation (``obs["ego"]`` of shape (6,), action (1,)) or a batch with any leading axes
(``obs["ego"]`` (..., 6), action (..., 1)), so they drive Gymnasium vector envs directly.

Geometry recovered from the observation (ego frame: heading +x, origin at the ego's centre):

- the stop line lies ``length / 2 + distance_to_stop_line`` ahead of the ego's centre;
- the crossing's far edge lies ``-distance_past_crossing - length / 2`` ahead;
- pedestrian slots give relative position and velocity; the ego's lane centre is at dy = 0.

Quantities the observation does not carry (speed limit, lateral extent of the ego's half of the road,
the action scaling) come from the policy's config; `make_policy(name, scenario=...)` fills them from a
`ScenarioConfig`.

All policies except `ConstantSpeed` follow vehicles ahead in the ego's lane with the Intelligent Driver
Model, so that they differ only in how they treat pedestrians.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, fields, replace
from typing import Any, ClassVar

import numpy as np

from crossing_env.config import EgoConfig, ScenarioConfig
from crossing_env.env import acceleration_to_action

ObsLike = Mapping[str, Any]

_EPS = 1e-6
PREDICTION_STEP = 0.4
"""Time between the points of ``obs["predicted_paths"]`` (s): the trajectory predictors' 2.5 Hz cadence."""


# ---------------------------------------------------------------------------------------------------------
# Configuration
# ---------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class DrivingConfig:
    """Settings shared by every policy: vehicle, road and car-following parameters (SI units)."""

    ego: EgoConfig = field(default_factory=EgoConfig)
    """The ego's limits; its `max_acceleration` / `max_deceleration` scale the normalised action."""
    speed_limit: float = 13.9
    """Cruising speed (m/s); set from `RoadConfig.speed_limit` by `make_policy(scenario=...)`."""
    ego_length: float = 4.5
    """Ego length (m), needed to turn the observed front/rear distances into centre coordinates."""
    ego_width: float = 1.8
    """Ego width (m)."""
    lane_width: float = 3.5
    """Lane width (m); vehicles with |dy| below half of it are in the ego's lane."""
    half_right: float = -1.75
    """Lateral offset (m, ego frame, negative = right) of the outer edge of the ego's half of the road."""
    half_left: float = 1.75
    """Lateral offset (m) of the inner edge of the ego's half of the road (centre line on two-way roads)."""
    stop_line_offset: float = 3.0
    """Distance (m) from the stop line to the crossing's near edge (`CrosswalkConfig.stop_line_offset`)."""
    road_right: float = -1.75
    """Lateral offset (m, ego frame) of the right-hand (south) kerb."""
    road_left: float = 5.25
    """Lateral offset (m, ego frame) of the left-hand (north) kerb."""
    cruise_gain: float = 0.8
    """Proportional gain (1/s) of the speed controller towards the cruising speed."""
    cruise_acceleration: float = 2.0
    """Largest acceleration (m/s²) used when speeding up to the cruising speed."""
    idm_time_headway: float = 1.2
    """IDM desired time headway T (s) to a vehicle ahead in the ego's lane."""
    idm_min_gap: float = 2.5
    """IDM jam distance s0 (m)."""
    idm_comfortable_deceleration: float = 2.5
    """IDM comfortable deceleration b (m/s²)."""
    pedestrian_radius: float = 0.3
    """Assumed pedestrian body radius (m); the observation carries centres only."""


@dataclass(frozen=True)
class ConstantSpeedConfig(DrivingConfig):
    """Constant speed: the ego holds its initial speed whatever happens (never yields, never brakes)."""


@dataclass(frozen=True)
class YieldingConfig(DrivingConfig):
    """Parameters of `YieldingPolicy` (see its docstring for the decision rules)."""

    comfortable_deceleration: float = 2.5
    """Deceleration (m/s²) of a planned stop; the car brakes as late as this allows (−2…−3 m/s² is
    comfortable)."""
    yield_max_deceleration: float = 4.0
    """A legal yield (zebra, red light) is attempted only if stopping before the line needs at most this
    (m/s²); beyond it the car cannot stop in time and only the conflict check below applies."""
    stop_buffer: float = 0.5
    """Stop this far (m) before the stop line."""
    pedestrian_gap: float = 2.0
    """When stopping for a pedestrian away from the stop line, keep this gap (m) to its body."""
    lateral_margin: float = 0.6
    """Margin (m) added to half the ego's width and the pedestrian radius to form the ego's lane corridor."""
    time_buffer: float = 1.5
    """A conflict exists if the pedestrian's time in the corridor and the ego's passage overlap within this
    margin (s)."""
    horizon: float = 6.0
    """Only pedestrians entering the corridor within this time (s) are considered."""
    go_acceleration: float = 1.5
    """Acceleration (m/s²) assumed when asking "if I go now, when do I pass?" from a low speed."""
    kerb_margin: float = 1.5
    """A waiting pedestrian is yielded to if it stands within the crossing's extent ± this margin (m)."""
    kerb_distance: float = 2.0
    """A slow pedestrian on the sidewalk this close (m) to a kerb at the crossing counts as waiting, even
    when the observation's stricter `waiting` flag (1.2 m, 0.3 m/s) is off: people waiting shuffle about."""
    waiting_speed: float = 0.5
    """Speed (m/s) below which a pedestrian near the kerb counts as waiting."""
    intention_threshold: float = 0.5
    """With `crossing_intention` in the observation, a pedestrian off the road with at least this
    probability is treated as about to cross: at the crossing it is yielded to like a waiting one, elsewhere
    it is assumed to step towards the ego's lane at `assumed_walking_speed` in the conflict check. Waiting
    pedestrians are yielded to whatever the estimate (the legal duty does not depend on it)."""
    assumed_walking_speed: float = 1.4
    """Speed (m/s) at which a pedestrian predicted to cross is assumed to walk into the road."""
    use_predictions: bool = True
    """Use `crossing_intention` / `predicted_paths` when the observation has them."""
    stop_gain: float = 2.0
    """Gain (1/s) pulling the speed down onto the braking profile sqrt(2·b·s)."""
    occlusion_speed: float = 3.0
    """Speed (m/s) at which the car passes a stationary vehicle standing beside it near a crossing, which
    may hide a pedestrian (UK Highway Code rule 191: do not overtake a vehicle stopped at a crossing;
    StVO §26: approach at moderate speed). At 3 m/s the car stops within about a metre."""
    offer_timeout: float = 3.5
    """After standing still at the line this long (s) for pedestrians who keep waiting at the kerb, the car
    takes the offer as declined and goes (pedestrians on the crossing are still given way); half a second
    more than `MetricsConfig.offer_timeout` (3 s), so the car never leaves before an offer counts as made."""
    dt: float = 0.1
    """Time between calls (s), the env's `EnvConfig.dt`; used by the offer timer."""
    occlusion_window: float = 15.0
    """A stationary vehicle counts as an occluder if its front is within this distance (m) before the
    crossing's near edge (or on the crossing)."""


@dataclass(frozen=True)
class TTCBrakeConfig(DrivingConfig):
    """Parameters of `TTCEmergencyBrake`."""

    ttc_threshold: float = 1.5
    """Full braking when the time to collision with a pedestrian falls below this (s) (serious conflict)."""
    lateral_margin: float = 0.3
    """Margin (m) added to half the ego's width and the pedestrian radius for the collision corridor."""


@dataclass(frozen=True)
class CautiousConfig(YieldingConfig):
    """Parameters of `AlwaysCautious` (it also stops for pedestrians in its path, like `YieldingPolicy`)."""

    crawl_speed: float = 2.0
    """Speed (m/s) at which the car passes every crossing."""
    approach_deceleration: float = 1.5
    """Deceleration (m/s²) with which it slows down to the crawl before the stop line."""
    clear_distance: float = 2.0
    """It keeps the crawl until its rear is this far (m) past the crossing."""


@dataclass(frozen=True)
class HighwayRuleConfig(DrivingConfig):
    """Parameters of `HighwayEnvRule` (highway-env's priority rule transferred to pedestrians)."""

    horizon: float = 2.0
    """Prediction horizon (s) of the collision check (highway-env: 2 s)."""
    step: float = 0.25
    """Time step (s) of the constant-speed prediction."""
    brake_gain: float = 1.0 / 0.6
    """Speed-controller gain (1/s) towards a target speed of 0 when yielding (highway-env: KP_A = 1/0.6)."""
    lateral_margin: float = 0.0
    """Margin (m) added to the footprints in the collision check."""


# ---------------------------------------------------------------------------------------------------------
# Observation parsing (vectorised)
# ---------------------------------------------------------------------------------------------------------


@dataclass
class _View:
    """Flattened batch view of an observation: leading axes folded into B."""

    lead: tuple[int, ...]
    speed: np.ndarray  # (B,)
    to_stop: np.ndarray  # (B,) ego front → stop line
    past: np.ndarray  # (B,) ego rear − crossing far edge
    car_green: np.ndarray  # (B,)
    zebra: np.ndarray  # (B,)
    present: np.ndarray  # (B, K) bool
    px: np.ndarray  # (B, K)
    py: np.ndarray
    vx: np.ndarray
    vy: np.ndarray
    on_crossing: np.ndarray  # (B, K) bool
    waiting: np.ndarray
    on_road: np.ndarray
    vehicles: np.ndarray  # (B, M, 7)
    intention: np.ndarray | None  # (B, K)
    paths: np.ndarray | None  # (B, K, T, 2)


def _view(obs: ObsLike) -> _View:
    """Parse a single or batched observation into (B, ...) float64 arrays; raise on a bad layout."""
    for key in ("ego", "pedestrians"):
        if key not in obs:
            raise KeyError(f"policy observation lacks {key!r}; got keys {sorted(obs)}")
    ego = np.asarray(obs["ego"], dtype=np.float64)
    if ego.ndim < 1 or ego.shape[-1] != 6:
        raise ValueError(f"obs['ego'] must have shape (..., 6), got {ego.shape}")
    lead = ego.shape[:-1]
    ego = ego.reshape(-1, 6)
    b = ego.shape[0]
    ped = np.asarray(obs["pedestrians"], dtype=np.float64)
    if ped.shape[: len(lead)] != lead or ped.ndim != len(lead) + 2 or ped.shape[-1] != 8:
        raise ValueError(f"obs['pedestrians'] must have shape {(*lead, 'K', 8)}, got {ped.shape}")
    ped = ped.reshape(b, -1, 8)
    k = ped.shape[1]
    if "vehicles" in obs:
        veh = np.asarray(obs["vehicles"], dtype=np.float64).reshape(b, -1, 7)
    else:
        veh = np.zeros((b, 0, 7))
    intention = obs.get("crossing_intention")
    if intention is not None:
        intention = np.asarray(intention, dtype=np.float64).reshape(b, k)
    paths = obs.get("predicted_paths")
    if paths is not None:
        paths = np.asarray(paths, dtype=np.float64)
        paths = paths.reshape(b, k, paths.shape[-2], 2)
    present = ped[..., 0] > 0.5
    return _View(
        lead=lead,
        speed=ego[:, 0],
        to_stop=ego[:, 2],
        past=ego[:, 3],
        car_green=ego[:, 4],
        zebra=ego[:, 5],
        present=present,
        px=ped[..., 1],
        py=ped[..., 2],
        vx=ped[..., 3],
        vy=ped[..., 4],
        on_crossing=present & (ped[..., 5] > 0.5),
        waiting=present & (ped[..., 6] > 0.5),
        on_road=present & (ped[..., 7] > 0.5),
        vehicles=veh,
        intention=intention,
        paths=paths,
    )


def _finish(accel: np.ndarray, view: _View, cfg: DrivingConfig) -> np.ndarray:
    """Acceleration (B,) → normalised float32 action of shape (*lead, 1)."""
    return acceleration_to_action(accel, cfg.ego).reshape(*view.lead, 1)


def _cruise(view: _View, cfg: DrivingConfig, target: np.ndarray | float | None = None) -> np.ndarray:
    """Proportional speed control towards `target` (default: the speed limit), bounded comfortably."""
    goal = cfg.speed_limit if target is None else target
    return np.clip(
        cfg.cruise_gain * (goal - view.speed), -cfg.idm_comfortable_deceleration, cfg.cruise_acceleration
    )


def _follow(view: _View, cfg: DrivingConfig) -> np.ndarray:
    """IDM acceleration (B,) behind the nearest vehicle ahead in the ego's lane (+inf when none)."""
    veh = view.vehicles
    if veh.shape[1] == 0:
        return np.full(view.speed.shape, np.inf)
    ahead = (veh[..., 0] > 0.5) & (np.abs(veh[..., 2]) < cfg.lane_width / 2) & (veh[..., 1] > 0.0)
    gap = veh[..., 1] - cfg.ego_length / 2 - veh[..., 5] / 2
    gap = np.where(ahead, gap, np.inf)
    j = np.argmin(gap, axis=1)
    rows = np.arange(gap.shape[0])
    s = np.maximum(gap[rows, j], 0.1)
    lead_v = veh[rows, j, 3]
    v = view.speed
    a_max, b = cfg.cruise_acceleration, cfg.idm_comfortable_deceleration
    s_star = cfg.idm_min_gap + np.maximum(
        0.0, v * cfg.idm_time_headway + v * (v - lead_v) / (2 * np.sqrt(a_max * b))
    )
    v0 = max(cfg.speed_limit, _EPS)
    acc = a_max * (1.0 - (v / v0) ** 4 - (s_star / s) ** 2)
    acc = np.maximum(acc, -cfg.ego.max_deceleration)
    return np.where(np.isfinite(gap[rows, j]), acc, np.inf)


def _travel_time(dist: np.ndarray, v: np.ndarray, accel: float, v_max: float) -> np.ndarray:
    """Time to cover `dist` (≥ 0; ≤ 0 gives 0) from speed v accelerating at `accel` up to `v_max`."""
    d = np.maximum(dist, 0.0)
    v = np.broadcast_to(v, d.shape)
    if accel <= 0.0:
        with np.errstate(divide="ignore"):
            return np.where(d <= 0.0, 0.0, np.where(v > _EPS, d / np.maximum(v, _EPS), np.inf))
    vm = np.maximum(v_max, v)
    t1 = (vm - v) / accel
    d1 = 0.5 * (v + vm) * t1
    t_acc = (-v + np.sqrt(v * v + 2.0 * accel * d)) / accel
    t_cru = t1 + (d - d1) / np.maximum(vm, _EPS)
    return np.where(d <= d1, t_acc, t_cru)


def _corridor_interval(py: np.ndarray, vy: np.ndarray, half_width: float) -> tuple[np.ndarray, np.ndarray]:
    """When a constant-velocity pedestrian is inside |y| ≤ half_width: (t_in, t_out); t_in = inf if never."""
    inside = np.abs(py) <= half_width
    moving = np.abs(vy) > 1e-3
    with np.errstate(divide="ignore", invalid="ignore"):
        ta = (-half_width - py) / vy
        tb = (half_width - py) / vy
    t_in = np.where(moving, np.maximum(np.minimum(ta, tb), 0.0), np.where(inside, 0.0, np.inf))
    t_out = np.where(moving, np.maximum(ta, tb), np.where(inside, np.inf, -np.inf))
    never = t_out < t_in
    return np.where(never, np.inf, t_in), np.where(never, -np.inf, t_out)


def _path_interval(
    paths: np.ndarray, present: np.ndarray, half_width: float, min_x: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Corridor entry/exit times and entry x from predicted paths (B, K, T, 2) sampled every 0.4 s."""
    t = PREDICTION_STEP * np.arange(1, paths.shape[2] + 1)
    inside = (np.abs(paths[..., 1]) <= half_width) & (paths[..., 0] > min_x) & present[..., None]
    any_in = inside.any(axis=2)
    first = np.argmax(inside, axis=2)
    last = paths.shape[2] - 1 - np.argmax(inside[..., ::-1], axis=2)
    t_in = np.where(any_in, t[first] - PREDICTION_STEP, np.inf)
    t_out = np.where(any_in, t[last], -np.inf)
    x_in = np.take_along_axis(paths[..., 0], first[..., None], axis=2)[..., 0]
    return t_in, t_out, x_in


def _stop_acceleration(
    view: _View, distance: np.ndarray, decel: float, gain: float, max_decel: float
) -> np.ndarray:
    """Acceleration that brings the car to rest `distance` ahead (B,), braking as late as `decel` allows.

    Below the braking profile v = sqrt(2·decel·s) it returns the profile-tracking term (usually larger
    than the cruise term, so `min` with it is neutral); above it, the exact constant deceleration v²/(2s),
    so a late stop brakes only as hard as needed (up to `max_decel`).
    """
    v = view.speed
    s = np.asarray(distance, dtype=np.float64)
    v_allow = np.sqrt(2.0 * decel * np.maximum(s, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        # Past the target (s < 0) it is too late for a planned stop: brake fully. Within the last 5 cm the
        # distance is floored, so a creeping car is not asked for an absurd deceleration.
        a_req = np.where(s >= 0.0, v * v / (2.0 * np.maximum(s, 0.05)), np.where(v > 0.05, np.inf, 0.0))
    track = gain * (v_allow - v)
    acc = np.where(a_req > decel, -a_req, track)
    acc = np.where(np.isfinite(s), acc, np.inf)
    # At the target: hold still.
    acc = np.where((s <= 0.3) & (v <= 0.1), -decel, acc)
    return np.maximum(acc, -max_decel)


# ---------------------------------------------------------------------------------------------------------
# Policies
# ---------------------------------------------------------------------------------------------------------


class ConstantSpeed:
    """Holds its current speed: never yields, never brakes (the worst-case baseline).

    Args:
        config: only `ego` (the action scaling) matters.
    """

    name: ClassVar[str] = "constant_speed"
    uses_predictors: ClassVar[bool] = False

    def __init__(self, config: ConstantSpeedConfig | None = None) -> None:
        self.config = config or ConstantSpeedConfig()

    def __call__(self, obs: ObsLike) -> np.ndarray:
        """Action 0 ("hold speed") for every observation in the batch."""
        view = _view(obs)
        return _finish(np.zeros_like(view.speed), view, self.config)


class YieldingPolicy:
    """Gives way at crossings like a careful human driver, and proceeds as soon as the conflict is clear.

    Each step it computes stopping targets (distances ahead of the ego's front) and brakes for the
    nearest, as late as `comfortable_deceleration` allows (harder only when a target appears late):

    1. **Legal yield** (zebra, UK rule 195 / StVO §26): a pedestrian on the crossing inside the ego's half
       of the road or walking towards it, or one waiting at the kerb within the crossing's extent ±
       `kerb_margin` (or, with the intention wrapper on, predicted to cross there), makes the car stop
       before the stop line; at a signalised crossing a red light for cars does. Attempted only if it needs
       at most `yield_max_deceleration`: a car that can no longer stop comfortably does not slam on the
       brakes for a pedestrian still on the kerb. If the car has stood at the line for `offer_timeout`
       while the only reason was a pedestrian who keeps waiting, the offer counts as declined and it goes.
    2. **Conflict check** (any pedestrian, anywhere): with constant velocity, the predicted path (when
       ``predicted_paths`` is present) and, for pedestrians the intention estimate expects to cross, a walk
       straight into the road, the pedestrian's time inside the ego's lane corridor is compared with the
       time the ego needs to pass its position "if it goes now" (accelerating at `go_acceleration` to the
       speed limit). If they overlap within `time_buffer`, the car stops `pedestrian_gap` before the
       pedestrian (or at the stop line when that is nearer), with any deceleration up to the maximum.
    3. **Occlusion**: a stationary vehicle beside the ego's lane just before the crossing may hide a
       pedestrian (the multiple-threat case); the car passes it at `occlusion_speed`.

    Otherwise it cruises at the speed limit and follows vehicles ahead (IDM). "Proceed when clear" falls
    out of re-evaluating the rules each step; the only state is the offer timer, one per batch element,
    which resets itself when the car is far before or past a crossing (`reset` clears it explicitly).

    Departures from the literature: legal rules are simplified to what the observation shows (no gaze or
    gesture); the German "influenced" test is approximated by stopping at the line rather than creeping
    up to the pedestrian; waiting pedestrians are yielded to whatever the intention estimate says.
    """

    name: ClassVar[str] = "yielding"
    uses_predictors: ClassVar[bool] = True

    def __init__(self, config: YieldingConfig | None = None) -> None:
        self.config = config or YieldingConfig()
        self._stopped = np.zeros(0)
        self._declined = np.zeros(0, dtype=bool)

    def reset(self) -> None:
        """Forget the offer timers (call between episodes; they also reset by themselves, see below)."""
        self._stopped = np.zeros(0)
        self._declined = np.zeros(0, dtype=bool)

    def _offer_state(self, view: _View, waiting_only: np.ndarray) -> np.ndarray:
        """Update the per-batch-element offer timers; return which elements treat the offer as declined.

        A timer runs while the car stands (< 0.1 m/s) within a few metres of the stop line and the only
        reason to stand is a pedestrian waiting at the kerb. After `offer_timeout` the offer counts as
        declined until the car has passed the crossing or is again far (> 20 m) before the line, which
        also makes timers reset by themselves at the start of an episode in a vector env.
        """
        b = view.speed.shape[0]
        if self._stopped.shape[0] != b:
            self._stopped = np.zeros(b)
            self._declined = np.zeros(b, dtype=bool)
        fresh = (view.past >= 0.0) | (view.to_stop > 20.0)
        self._declined &= ~fresh
        standing = (view.speed < 0.1) & (view.to_stop < 3.0) & waiting_only
        self._stopped = np.where(standing, self._stopped + self.config.dt, 0.0)
        self._declined |= self._stopped >= self.config.offer_timeout - 1e-9
        return self._declined.copy()

    def _targets(self, view: _View) -> tuple[np.ndarray, np.ndarray]:
        """(legal_target, conflict_target): stop distances (B,) ahead of the ego front, inf when none."""
        cfg = self.config
        front = cfg.ego_length / 2
        r = cfg.pedestrian_radius
        hw = cfg.ego_width / 2 + r + cfg.lateral_margin
        v = view.speed

        # Crossing geometry in the ego frame.
        stop_rel = front + view.to_stop[:, None]  # (B, 1) centre → stop line
        near_rel = stop_rel + cfg.stop_line_offset
        far_rel = -view.past[:, None] - front
        crossing_ahead = view.past[:, None] < 0.0
        at_crossing = (view.px >= near_rel - cfg.kerb_margin) & (view.px <= far_rel + cfg.kerb_margin)
        # Stop target for crossing-related yields: the stop line, or the crossing's edge once past the line.
        line_target = np.where(
            view.to_stop > 0.0,
            view.to_stop - cfg.stop_buffer,
            view.to_stop + cfg.stop_line_offset - cfg.stop_buffer,
        )
        line_target = np.where(line_target > -0.3, np.maximum(line_target, 0.0), np.inf)  # (B,)

        # 1. Legal yield.
        use_pred = cfg.use_predictions
        in_half = (view.py >= cfg.half_right - r) & (view.py <= cfg.half_left + r)
        centre = 0.5 * (cfg.half_right + cfg.half_left)
        toward = (centre - view.py) * view.vy > 0.0
        on_xing = view.on_crossing & (in_half | toward)
        kerb_gap = np.minimum(np.abs(view.py - cfg.road_right), np.abs(view.py - cfg.road_left))
        slow = np.hypot(view.vx, view.vy) < cfg.waiting_speed
        waiting = (view.waiting | (view.present & slow & (kerb_gap <= cfg.kerb_distance))) & ~view.on_road
        likely = None
        if use_pred and view.intention is not None:
            likely = (view.intention >= cfg.intention_threshold) & view.present & ~view.on_road
            waiting = waiting | likely
        zebra = view.zebra[:, None] > 0.5
        legal_xing = (zebra & crossing_ahead & at_crossing & on_xing).any(axis=1)
        legal_wait = (zebra & crossing_ahead & at_crossing & waiting).any(axis=1)
        declined = self._offer_state(view, legal_wait & ~legal_xing)
        red = (view.zebra < 0.5) & (view.car_green < 0.5) & (view.past < 0.0)
        needs_line = legal_xing | (legal_wait & ~declined) | red
        with np.errstate(divide="ignore", invalid="ignore"):
            a_req = np.where(line_target > 0.05, v * v / (2.0 * np.maximum(line_target, 0.05)), np.inf)
        can_stop = (a_req <= cfg.yield_max_deceleration) | (v < 0.5)
        legal_target = np.where(needs_line & can_stop, line_target, np.inf)

        # 2. Conflict check (constant velocity ∪ predicted path).
        t_in, t_out = _corridor_interval(view.py, view.vy, hw)
        x_in = view.px + view.vx * np.where(np.isfinite(t_in), np.minimum(t_in, cfg.horizon), 0.0)
        if use_pred and view.paths is not None:
            pt_in, pt_out, px_in = _path_interval(view.paths, view.present, hw, -front)
            x_in = np.where(pt_in < t_in, px_in, x_in)
            t_in = np.minimum(t_in, pt_in)
            t_out = np.maximum(t_out, pt_out)
        if likely is not None:
            # Anticipation: a pedestrian the intention estimate expects to cross walks straight in.
            towards_lane = np.where(view.py > 0.0, -1.0, 1.0) * cfg.assumed_walking_speed
            a_in, a_out = _corridor_interval(view.py, towards_lane, hw)
            a_in = np.where(likely, a_in, np.inf)
            x_in = np.where(a_in < t_in, view.px, x_in)
            t_in = np.minimum(t_in, a_in)
            t_out = np.maximum(t_out, np.where(likely, a_out, -np.inf))
        behind = x_in + r < -front
        s_arr = x_in - r - front
        s_clr = x_in + r + front
        vmax = max(cfg.speed_limit, _EPS)
        t_arr = _travel_time(s_arr, v[:, None], cfg.go_acceleration, vmax)
        t_clr = _travel_time(s_clr, v[:, None], cfg.go_acceleration, vmax)
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

    def _occlusion_cap(self, view: _View) -> np.ndarray:
        """Acceleration (B,) that slows the car to `occlusion_speed` by the front of an occluding vehicle."""
        cfg = self.config
        veh = view.vehicles
        if veh.shape[1] == 0:
            return np.full(view.speed.shape, np.inf)
        front = cfg.ego_length / 2
        near_rel = front + view.to_stop[:, None] + cfg.stop_line_offset
        far_rel = -view.past[:, None] - front
        veh_front = veh[..., 1] + veh[..., 5] / 2
        speed = np.hypot(veh[..., 3], veh[..., 4])
        beside = (np.abs(veh[..., 2]) >= cfg.lane_width / 2) & (np.abs(veh[..., 2]) <= 2.5 * cfg.lane_width)
        occluder = (
            (veh[..., 0] > 0.5)
            & beside
            & (speed < 0.5)
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

    def acceleration(self, obs: ObsLike) -> np.ndarray:
        """Commanded acceleration (m/s²) of shape (B,) for the flattened batch."""
        view = _view(obs)
        return self._acceleration(view)

    def _acceleration(self, view: _View) -> np.ndarray:
        cfg = self.config
        legal, conflict = self._targets(view)
        a = np.minimum(_cruise(view, cfg), _follow(view, cfg))
        a_legal = _stop_acceleration(
            view, legal, cfg.comfortable_deceleration, cfg.stop_gain, cfg.ego.max_deceleration
        )
        a_conf = _stop_acceleration(
            view, conflict, cfg.comfortable_deceleration, cfg.stop_gain, cfg.ego.max_deceleration
        )
        return np.minimum(np.minimum(a, self._occlusion_cap(view)), np.minimum(a_legal, a_conf))

    def __call__(self, obs: ObsLike) -> np.ndarray:
        """Normalised action(s) for one or a batch of observations."""
        view = _view(obs)
        return _finish(self._acceleration(view), view, self.config)


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

    def _acceleration(self, view: _View) -> np.ndarray:
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


class TTCEmergencyBrake:
    """Cruises at the speed limit and brakes fully when the TTC to any pedestrian drops below a threshold.

    TTC: constant velocities for both; the pedestrian (disc) must be inside the ego's corridor
    (half the ego width + radius + margin) while the ego's footprint spans its x; the first instant of that
    overlap is the TTC. A reactive AEB-like baseline: no anticipation, no legal yielding.
    """

    name: ClassVar[str] = "ttc_brake"
    uses_predictors: ClassVar[bool] = False

    def __init__(self, config: TTCBrakeConfig | None = None) -> None:
        self.config = config or TTCBrakeConfig()

    def ttc(self, obs: ObsLike) -> np.ndarray:
        """(B,) smallest pedestrian TTC under constant velocities (inf when none)."""
        return self._ttc(_view(obs))

    def _ttc(self, view: _View) -> np.ndarray:
        cfg = self.config
        front = cfg.ego_length / 2
        r = cfg.pedestrian_radius
        hw = cfg.ego_width / 2 + r + cfg.lateral_margin
        t_in, t_out = _corridor_interval(view.py, view.vy, hw)
        rel_v = view.speed[:, None] - view.vx  # closing speed along x
        with np.errstate(divide="ignore", invalid="ignore"):
            gap_front = view.px - r - front
            gap_rear = view.px + r + front
            t_arr = np.where(gap_front <= 0.0, 0.0, np.where(rel_v > _EPS, gap_front / rel_v, np.inf))
            t_clr = np.where(gap_rear <= 0.0, -np.inf, np.where(rel_v > _EPS, gap_rear / rel_v, np.inf))
        start = np.maximum(t_arr, t_in)
        end = np.minimum(t_clr, t_out)
        ttc = np.where(view.present & (start <= end) & (view.speed[:, None] > 5e-3), start, np.inf)
        return ttc.min(axis=1, initial=np.inf)

    def __call__(self, obs: ObsLike) -> np.ndarray:
        """Full braking if TTC < threshold, else cruise / follow."""
        view = _view(obs)
        cfg = self.config
        a = np.minimum(_cruise(view, cfg), _follow(view, cfg))
        a = np.where(self._ttc(view) < cfg.ttc_threshold, -cfg.ego.max_deceleration, a)
        return _finish(a, view, cfg)


class HighwayEnvRule:
    """highway-env's priority rule, applied to pedestrians: yield when a collision is predicted within 2 s.

    Like `highway_env.road.regulation.RegulatedRoad.respect_priorities` /
    `is_conflict_possible`, ego and pedestrians are propagated with constant speed in `step` increments up
    to `horizon`; if the ego's box (grown by `lateral_margin`) overlaps a pedestrian disc at any sample, the
    car yields: target speed 0 tracked with highway-env's speed gain (KP_A = 1/0.6), clipped to the maximum
    deceleration. Departure: highway-env compares vehicle pairs by lane priority; here pedestrians always
    have priority once a collision is predicted, and no stop line is targeted.
    """

    name: ClassVar[str] = "highway_rule"
    uses_predictors: ClassVar[bool] = False

    def __init__(self, config: HighwayRuleConfig | None = None) -> None:
        self.config = config or HighwayRuleConfig()

    def _predicted_collision(self, view: _View) -> np.ndarray:
        cfg = self.config
        t = np.arange(0.0, cfg.horizon + 1e-9, cfg.step)  # (T,)
        ex = view.speed[:, None] * t  # (B, T) ego centre x
        px = view.px[..., None] + view.vx[..., None] * t  # (B, K, T)
        py = view.py[..., None] + view.vy[..., None] * t
        hx = cfg.ego_length / 2 + cfg.lateral_margin
        hy = cfg.ego_width / 2 + cfg.lateral_margin
        qx = np.maximum(np.abs(px - ex[:, None, :]) - hx, 0.0)
        qy = np.maximum(np.abs(py) - hy, 0.0)
        hit = (qx * qx + qy * qy <= cfg.pedestrian_radius**2) & view.present[..., None]
        return hit.any(axis=(1, 2))

    def __call__(self, obs: ObsLike) -> np.ndarray:
        """Yield (target speed 0) if a collision is predicted, else cruise / follow."""
        view = _view(obs)
        cfg = self.config
        a = np.minimum(_cruise(view, cfg), _follow(view, cfg))
        brake = np.maximum(-cfg.brake_gain * view.speed, -cfg.ego.max_deceleration)
        a = np.where(self._predicted_collision(view), np.minimum(a, brake), a)
        return _finish(a, view, cfg)


# ---------------------------------------------------------------------------------------------------------
# Registry
# ---------------------------------------------------------------------------------------------------------

Policy = Callable[[ObsLike], np.ndarray]

_REGISTRY: dict[str, tuple[type, type[DrivingConfig]]] = {
    "yielding": (YieldingPolicy, YieldingConfig),
    "constant_speed": (ConstantSpeed, ConstantSpeedConfig),
    "ttc_brake": (TTCEmergencyBrake, TTCBrakeConfig),
    "always_cautious": (AlwaysCautious, CautiousConfig),
    "highway_rule": (HighwayEnvRule, HighwayRuleConfig),
}
POLICIES: tuple[str, ...] = tuple(_REGISTRY)
"""Names accepted by `make_policy` (and `crossing-eval --policies`)."""


def scenario_settings(scenario: ScenarioConfig) -> dict[str, Any]:
    """`DrivingConfig` fields that follow from a scenario (ego limits, speed limit, geometry)."""
    road = scenario.road
    w = road.lane_width
    ego_y = (scenario.ego.lane + 0.5) * w
    return {
        "ego": scenario.ego,
        "speed_limit": road.speed_limit,
        "lane_width": w,
        "ego_length": scenario.traffic.length,
        "ego_width": scenario.traffic.width,
        "half_right": 0.0 - ego_y,
        "half_left": road.num_forward_lanes * w - ego_y,
        "stop_line_offset": scenario.crossing.stop_line_offset,
        "road_right": 0.0 - ego_y,
        "road_left": road.road_width - ego_y,
    }


def make_policy(
    name: str, scenario: ScenarioConfig | None = None, dt: float | None = None, **overrides: Any
) -> Policy:
    """Build a registered policy by name.

    `scenario` fills the road-dependent settings, `dt` the step time of policies with timers (ignored by
    the others), `overrides` any config field.

    Raises:
        ValueError: unknown policy name or config field (the message lists the allowed ones).
    """
    if name not in _REGISTRY:
        raise ValueError(f"unknown policy {name!r}; choose from {', '.join(POLICIES)}")
    cls, cfg_cls = _REGISTRY[name]
    allowed = {f.name for f in fields(cfg_cls)}
    unknown = sorted(set(overrides) - allowed)
    if unknown:
        raise ValueError(f"policy {name!r}: unknown config field(s) {unknown}; allowed: {sorted(allowed)}")
    cfg = cfg_cls()
    if scenario is not None:
        cfg = replace(cfg, **scenario_settings(scenario))
    if dt is not None and "dt" in allowed:
        cfg = replace(cfg, dt=float(dt))
    if overrides:
        cfg = replace(cfg, **overrides)
    return cls(cfg)


def policy_uses_predictors(name: str) -> bool:
    """Whether the evaluation should put the predictor wrappers on for this policy."""
    if name not in _REGISTRY:
        raise ValueError(f"unknown policy {name!r}; choose from {', '.join(POLICIES)}")
    return bool(getattr(_REGISTRY[name][0], "uses_predictors", False))
