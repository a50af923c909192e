"""Crossing-intention observation wrappers: QLB and classical (CBM) estimates from the observation only.

Both wrappers add ``"crossing_intention"`` ``(K,)`` float32 in [0, 1] to the Dict observation: for each
pedestrian slot, the estimated probability that the pedestrian is on the carriageway ahead of the ego's rear
at some moment within ``horizon`` seconds (already crossing, or starting to). Absent slots get 0.

Inputs are the observation (pedestrian positions, velocities and on-crossing / waiting / on-road flags;
vehicle positions, velocities and lengths; ego speed and signal state) plus the static map a car carries
(kerb lines relative to its lane, crossing position and type), read once from the env's scenario. Hidden
quantities (intentions, critical gaps, phases, decision states) are never read.

The model, per slot, vectorised over slots:

1. On the road ahead of the ego's rear: the event is happening now (probability ``on_road_ahead``).
2. Otherwise a pedestrian reaches the kerb after ``t_kerb`` (0 when it looks like waiting; distance over the
   speed towards the road when walking towards it; along the sidewalk to the crossing otherwise) with
   intention prior ``p_intent`` (high for waiting / walking towards the road, ``intent_prior`` otherwise).
3. At the kerb it looks at the gap: the time until the first approaching car (background vehicles and the
   ego) reaches its line, evaluated at ``t_kerb``. The observer does not know the pedestrian's critical gap,
   so its belief that the gap is safe averages ``sigmoid((gap - c) / belief_scale)`` over quantiles of the
   calibrated population critical-gap distribution (lognormal, mean 5.5 s, SD 1.2 s, floor 3 s).
4. The per-look crossing probability is a disjunction over the hidden cause "gap safe" (qlb.md §4, mapping
   (a)): classical (CBM) ``beta P(C | safe) + (1 - beta) P(C | unsafe)``, or quantum-like (QLB) with the phase
   from the Moreira & Wichert similarity heuristic
   (`crossing_env.pedestrians.quantum.disjunction_probabilities` with ``theta=None``): the observer cannot
   see each pedestrian's own phase, so the network sets it.
5. Looks every ``decision_interval`` seconds give a hazard; the probability of starting within the time left
   before the horizon (or before the ego has passed the pedestrian) is ``1 - exp(-rate * window)``.

A pedestrian facing a red signal (signalised crossing, cars green, near the crossing) is scaled by
``red_light_prior``.

Both wrappers also add ``"crossing_intent"`` ``(K,)``: the calibrated probability that the pedestrian is on
the carriageway (anywhere along it, crossing or starting to) at some moment within `INTENT_HORIZON` seconds,
the event the oracle's intent to cross stands for. It is the same model evaluated over that horizon without
the "before the ego has passed" cut (`crossing_intention` with ``ahead_only=False``), then Platt-calibrated
(``sigmoid(a logit(p) + b)``, the two numbers per variant fitted on the training seeds by
``python -m studies.train_learned_intent`` and shipped in ``predictors/weights/learned_intent.json``).
They add ``"crossing_intent_bound"`` ``(1,)`` too: the variant's release risk bound from the same file (an
intent at or below it may release a legal wait in `agents.predictive`).

These are our modelling choices, documented here; the benchmark
(`benchmarks/intention.py`) measures how well each variant ranks and calibrates against ground truth.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal, NamedTuple

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numba import njit

from crossing_common import compile_ahead
from crossing_env.observation import (
    EGO_KEY,
    PEDESTRIANS_KEY,
    VEHICLES_KEY,
    EgoColumn,
    PedestrianColumn,
    VehicleColumn,
)
from crossing_env.pedestrians.quantum import disjunction_probabilities
from predictors.forecast import Forecast, ForecastInput, ForecastSpec, SceneGeometry
from predictors.forecast_wrapper import ForecastObservation
from predictors.learned_intent_weights import platt, release_threshold, shipped_weights

__all__ = [
    "INTENT_HORIZON",
    "ClassicalIntention",
    "CrossingIntention",
    "IntentionConfig",
    "IntentionModel",
    "QLBIntention",
    "crossing_intention",
    "look_probability",
    "look_rate_table",
]

Variant = Literal["qlb", "cbm"]
INTENT_HORIZON = 10.0
"""Seconds of the ``crossing_intent`` event: on the carriageway within this time (the intent to cross here,
with a horizon long enough that a pedestrian who waits for the car to stop still counts)."""


@dataclass(frozen=True)
class IntentionConfig:
    """Parameters of the intention estimate (our design; shared by the QLB and CBM variants)."""

    critical_gap_mean: float = 5.5
    """Population mean critical gap in seconds (calibration notes)."""
    critical_gap_std: float = 1.2
    """Population SD of the critical gap in seconds."""
    critical_gap_floor: float = 3.0
    """Floor of the critical gap in seconds."""
    quantiles: int = 7
    """Number of critical-gap quantiles averaged into the observer's belief."""
    belief_scale: float = 0.4
    """Logistic scale (s) of the belief that a gap is safe around a critical gap."""
    p_cross_safe: float = 0.95
    """P(step off at one look | gap safe)."""
    p_cross_unsafe: float = 0.01
    """P(step off at one look | gap unsafe)."""
    decision_interval: float = 0.5
    """Seconds between two looks at the traffic (turns per-look probabilities into a rate)."""
    intent_waiting: float = 0.75
    """P(intends to cross) for a pedestrian standing at the kerb."""
    intent_towards_road: float = 0.7
    """P(intends to cross) for a pedestrian walking towards the road."""
    intent_prior: float = 0.5
    """P(intends to cross) for a pedestrian walking along the sidewalk towards (or at) the crossing."""
    intent_leaving_crossing: float = 0.1
    """P(intends to cross) for a pedestrian walking along the sidewalk away from the crossing."""
    intent_away: float = 0.02
    """P(intends to cross) for a pedestrian walking away from the road (e.g. having just crossed)."""
    towards_speed: float = 0.25
    """Speed (m/s) towards the road above which a pedestrian counts as walking towards it."""
    walking_speed: float = 1.35
    """Assumed walking speed (m/s) for the last steps to the road and along the sidewalk."""
    kerb_standoff: float = 0.45
    """Distance (m) from the kerb at which pedestrians stand while waiting."""
    start_delay: float = 0.2
    """Seconds lost accelerating from a standstill when stepping off (social-force relaxation time)."""
    on_road_ahead: float = 0.98
    """Probability given to a pedestrian already on the road ahead of the ego's rear."""
    red_light_prior: float = 0.1
    """Factor on the crossing rate of a pedestrian facing red at a signalised crossing (5-15 % violate)."""


def _lognormal_quantiles(mean: float, std: float, floor: float, n: int) -> np.ndarray:
    """Midpoint quantiles of the floored lognormal critical-gap distribution."""
    from statistics import NormalDist

    sigma2 = math.log(1.0 + (std / mean) ** 2)
    mu, sigma = math.log(mean) - sigma2 / 2, math.sqrt(sigma2)
    z = np.array([NormalDist().inv_cdf((k + 0.5) / n) for k in range(n)])
    return np.maximum(floor, np.exp(mu + sigma * z))


GAP_GRID = np.linspace(0.0, 40.0, 4001)
"""Gaps (s) at which the look rate is tabulated; beyond 40 s the belief is 1 to within 1e-20."""


def look_probability(gap: np.ndarray, variant: Variant, config: IntentionConfig) -> np.ndarray:
    """Per-look crossing probability at the kerb for gaps (s), the critical gap marginalised out.

    Args:
        gap: Gaps in seconds (inf allowed).
        variant: "qlb" (disjunction with the similarity-heuristic phase) or "cbm" (classical).
        config: Model parameters.

    Returns:
        Probabilities, the shape of `gap`.
    """
    c = config
    quantiles = _lognormal_quantiles(
        c.critical_gap_mean, c.critical_gap_std, c.critical_gap_floor, c.quantiles
    )
    z = (np.asarray(gap, dtype=np.float64)[..., None] - quantiles) / c.belief_scale
    belief = np.mean(0.5 * (1.0 + np.tanh(0.5 * np.clip(z, -50.0, 50.0))), axis=-1)
    if variant == "qlb":
        return disjunction_probabilities(c.p_cross_safe, c.p_cross_unsafe, belief, None)
    return belief * c.p_cross_safe + (1.0 - belief) * c.p_cross_unsafe


def look_rate_table(variant: Variant, config: IntentionConfig, factor: float = 1.0) -> np.ndarray:
    """Decision rate (1/s) on `GAP_GRID`: ``-log(1 - factor * p_look) / decision_interval``."""
    p = np.minimum(factor * look_probability(GAP_GRID, variant, config), 1.0 - 1e-9)
    return -np.log1p(-p) / config.decision_interval


def crossing_intention(
    obs: dict[str, np.ndarray],
    horizon: float,
    road_map: SceneGeometry,
    config: IntentionConfig,
    rate_table: np.ndarray,
    red_rate_table: np.ndarray,
    ahead_only: bool = True,
) -> np.ndarray:
    """Per-slot crossing probability within `horizon` from one observation (see the module docstring).

    Args:
        obs: The env observation (`PEDESTRIANS_KEY` (K, 8), `VEHICLES_KEY` (M, 7), `EGO_KEY` (6,)).
        horizon: Seconds ahead.
        road_map: Static map facts relative to the ego.
        config: Model parameters.
        rate_table: `look_rate_table` of the variant (the only place QLB and CBM differ).
        red_rate_table: The same for pedestrians facing red.
        ahead_only: Count only the road ahead of the ego's rear, before the ego has passed (the
            ``crossing_intention`` event); False: anywhere on the road within `horizon` (the raw
            ``crossing_intent``).

    Returns:
        (K,) float32 in [0, 1], 0 for absent slots.
    """
    return _probability(
        _intention_parts(obs, road_map, config, rate_table, red_rate_table), horizon, ahead_only, config
    )


class _IntentionParts(NamedTuple):
    """What `crossing_intention` computes before the horizon enters (shared by both wrapper outputs)."""

    present: np.ndarray
    on_road: np.ndarray
    ahead: np.ndarray
    t_pass: np.ndarray
    t_kerb: np.ndarray
    """Seconds until the pedestrian reaches the kerb."""
    t_enter: np.ndarray
    """Seconds from the kerb onto the road."""
    p_intent: np.ndarray
    rate: np.ndarray


def _intention_parts(
    obs: dict[str, np.ndarray],
    road_map: SceneGeometry,
    config: IntentionConfig,
    rate_table: np.ndarray,
    red_rate_table: np.ndarray,
) -> _IntentionParts:
    """The horizon-free parts of `crossing_intention` for one observation."""
    c = config
    ped = np.ascontiguousarray(obs[PEDESTRIANS_KEY], dtype=np.float64)
    veh = np.ascontiguousarray(obs[VEHICLES_KEY])
    ego = obs[EGO_KEY]
    speed = max(float(ego[EgoColumn.SPEED]), 0.0)
    to_stop_line = float(ego[EgoColumn.DISTANCE_TO_STOP_LINE])
    k = ped.shape[0]
    present, on_road = np.empty(k, dtype=np.bool_), np.empty(k, dtype=np.bool_)
    ahead, t_pass, t_kerb, t_enter, p_intent, gap, cross_dx = (np.empty(k) for _ in range(7))
    _parts_kernel(  # scalars as float and bool, so that one compiled signature serves every map
        ped,
        veh,
        speed,
        max(speed, 1e-3),
        float(to_stop_line + road_map.crossing_offset),
        bool(road_map.has_crossing),
        float(road_map.ego_length),
        float(road_map.kerb_low),
        float(road_map.kerb_high),
        float(road_map.crossing_half_width),
        np.array(
            [
                c.towards_speed,
                c.kerb_standoff,
                c.walking_speed,
                c.start_delay,
                c.intent_prior,
                c.intent_leaving_crossing,
                c.intent_waiting,
                c.intent_towards_road,
                c.intent_away,
            ]
        ),
        (present, on_road, ahead, t_pass, t_kerb, t_enter, p_intent, gap, cross_dx),
    )

    # Decision rate at that gap (tabulated: belief averaged over the unknown critical gap, then CBM or QLB).
    rate = np.interp(gap, GAP_GRID, rate_table)
    cars_green = ego[EgoColumn.CAR_GREEN] > 0.5
    if road_map.signalised and cars_green:  # cars green: pedestrians at the crossing face red
        at_crossing = np.abs(cross_dx) <= road_map.crossing_half_width + 1.0
        rate = np.where(at_crossing, np.interp(gap, GAP_GRID, red_rate_table), rate)
    return _IntentionParts(present, on_road, ahead, t_pass, t_kerb, t_enter, p_intent, rate)


_P, _X, _Y, _VX, _VY = (
    int(PedestrianColumn.PRESENCE),
    int(PedestrianColumn.DX),
    int(PedestrianColumn.DY),
    int(PedestrianColumn.VX),
    int(PedestrianColumn.VY),
)
_ON_ROAD, _WAITING = int(PedestrianColumn.ON_ROAD), int(PedestrianColumn.WAITING)
_CAR_X, _CAR_VX, _CAR_LENGTH = int(VehicleColumn.DX), int(VehicleColumn.VX), int(VehicleColumn.LENGTH)


@njit(cache=True, nogil=True, error_model="numpy")
def _parts_kernel(
    ped: np.ndarray,
    veh: np.ndarray,
    speed: float,
    pass_speed: float,
    crossing_x: float,
    has_crossing: bool,
    ego_length: float,
    kerb_low: float,
    kerb_high: float,
    crossing_half_width: float,
    c: np.ndarray,
    out: tuple[np.ndarray, ...],
) -> None:
    """`_intention_parts` per pedestrian slot, bit for bit as its numpy form (the same operations in order).

    `crossing_x`: the crossing's x ahead of the ego (stop line plus offset); without a crossing
    (`has_crossing` False) the distance along the kerb to it is 0. `c`: the `IntentionConfig` fields in
    the order of the call. Cars are the ego (first) and the vehicle slots; an absent slot is all zeros,
    hence not moving.
    """
    towards_speed, standoff, walking_speed, start_delay = c[0], c[1], c[2], c[3]
    intent_prior, intent_leaving, intent_waiting, intent_towards, intent_away = c[4], c[5], c[6], c[7], c[8]
    present, on_road, ahead, t_pass, t_kerb, t_enter, p_intent, gap, cross_dx = out
    half_len = ego_length / 2
    for i in range(ped.shape[0]):
        dx, dy, vx, vy = ped[i, _X], ped[i, _Y], ped[i, _VX], ped[i, _VY]
        present[i] = ped[i, _P] > 0.5
        on_road[i] = ped[i, _ON_ROAD] > 0.5
        # Time until the ego's rear passes the pedestrian's x (the event needs the pedestrian ahead of it).
        ahead[i] = dx + half_len
        t_pass[i] = 0.0 if ahead[i] <= 0.0 else ahead[i] / pass_speed
        # Where the pedestrian is relative to the nearer kerb and how fast it walks towards the road.
        south = dy < kerb_low
        kerb_dist = kerb_low - dy if south else dy - kerb_high
        towards = vy if south else -vy
        waiting = ped[i, _WAITING] > 0.5
        walking_in = towards > towards_speed and not waiting
        # From the spot where it decides to the carriageway: the remaining distance, plus the start from rest.
        start = _np_max(kerb_dist, 0.0) if waiting else standoff
        t_enter[i] = start / walking_speed + start_delay
        to_kerb = _np_max(kerb_dist - standoff, 0.0)
        t_walk_in = to_kerb / _np_max(towards, towards_speed)
        # Walking along the sidewalk: to the crossing (if any) then to the kerb.
        cross_dx[i] = crossing_x - dx if has_crossing else 0.0
        along = _np_max(abs(cross_dx[i]) - crossing_half_width, 0.0)
        t_along = (along + to_kerb) / walking_speed
        t_kerb[i] = 0.0 if waiting else (t_walk_in if walking_in else t_along)
        walking_away = towards < -towards_speed and not waiting
        to_crossing = vx * cross_dx[i] > 0.0 or along <= 1.0
        p_along = intent_prior if to_crossing else intent_leaving
        if waiting:
            p_intent[i] = intent_waiting
        elif walking_in:
            p_intent[i] = intent_towards
        elif walking_away:
            p_intent[i] = intent_away
        else:
            p_intent[i] = p_along
        # Gap at the moment the pedestrian would look: first approaching car to reach its x after t_kerb.
        first = math.inf
        for j in range(veh.shape[0] + 1):
            if j == 0:
                car_x, car_vx, car_length = 0.0, speed, ego_length
            else:
                car_x = float(veh[j - 1, _CAR_X])
                car_vx = float(veh[j - 1, _CAR_VX])
                car_length = float(veh[j - 1, _CAR_LENGTH])
            car_spd = abs(car_vx)
            car_half = 0.5 * car_length
            dist = (dx - car_x) * _sign(car_vx) - car_half  # car front to the pedestrian's line
            tta = dist / _np_max(car_spd, 0.3) if dist >= 0.0 else -1.0
            if dist < 0.0 and dist > -2.0 * car_half - 0.5:  # a car body covering the line
                tta = 0.0
            tta -= t_kerb[i]
            if tta < 0.0 or car_spd <= 0.3:  # gone by the time it looks, or not moving
                tta = math.inf
            first = tta if j == 0 else _np_min(first, tta)
        gap[i] = first


@njit(cache=True, nogil=True, error_model="numpy")
def _np_max(a: float, b: float) -> float:
    """`np.maximum` of two floats as numpy gives it: a NaN operand wins (the first), a tie gives `b` (±0).

    Kept here rather than shared: a kernel calls only kernels of its own module, since numba refreshes a
    kernel's on-disk cache only when its own file changes (tests/test_lint.py).
    """
    return a if a != a else (b if b != b or not a > b else a)


@njit(cache=True, nogil=True, error_model="numpy")
def _np_min(a: float, b: float) -> float:
    """`np.minimum` of two floats as numpy gives it (see `_np_max`)."""
    return a if a != a else (b if b != b or not a < b else a)


@njit(cache=True, nogil=True, error_model="numpy")
def _sign(v: float) -> float:
    """`np.sign` of a float (0.0 for either zero, NaN for NaN)."""
    if v > 0.0:
        return 1.0
    if v < 0.0:
        return -1.0
    return 0.0 if v == 0.0 else v


def _probability(
    parts: _IntentionParts, horizon: float, ahead_only: bool, config: IntentionConfig
) -> np.ndarray:
    """The crossing probability within `horizon` from the shared parts (see `crossing_intention`)."""
    window_end = np.minimum(horizon, parts.t_pass) if ahead_only else np.full_like(parts.t_pass, horizon)
    window = np.maximum(window_end - parts.t_kerb - parts.t_enter, 0.0)
    p_start = parts.p_intent * -np.expm1(-parts.rate * window)
    ahead = parts.ahead
    road = config.on_road_ahead
    on_road_p = (ahead > 0.0) * road if ahead_only else np.full_like(ahead, road)
    prob = np.where(parts.on_road, on_road_p, p_start)  # all factors lie in [0, 1]
    return (prob * parts.present).astype(np.float32)


def parts_kernel_is_cached() -> bool:
    """Whether numba's on-disk cache holds `_parts_kernel`.

    `crossing_common.compile_ahead.is_cached`: True where numba's index cannot be read, so that nothing
    is compiled aside and the kernel compiles where it is first called.
    """
    return compile_ahead.is_cached(_parts_kernel)


def compile_parts_kernel() -> None:
    """Compile `_parts_kernel` for the argument types `_intention_parts` gives it, on an empty scene."""
    obs = {
        PEDESTRIANS_KEY: np.zeros((1, len(PedestrianColumn)), dtype=np.float32),
        VEHICLES_KEY: np.zeros((1, len(VehicleColumn)), dtype=np.float32),
        EGO_KEY: np.zeros(len(EgoColumn), dtype=np.float32),
    }
    table = np.zeros_like(GAP_GRID)
    _intention_parts(
        obs, SceneGeometry(-1.0, 1.0, 4.0, 0.0, 1.0, False, True), IntentionConfig(), table, table
    )


class IntentionModel:
    """Forecaster of ``crossing_intention`` and ``crossing_intent`` (the module docstring's model).

    ``crossing_intent`` is calibrated with the shipped Platt coefficients.

    Args:
        horizon: Seconds ahead.
        variant: ``"qlb"`` (quantum-like) or ``"cbm"`` (classical Bayesian model).
        config: Model parameters; defaults to `IntentionConfig()`.
    """

    def __init__(
        self, horizon: float = 2.0, variant: Variant = "qlb", config: IntentionConfig | None = None
    ) -> None:
        if not (math.isfinite(horizon) and horizon > 0.0):
            raise ValueError(f"crossing intention: horizon must be > 0 seconds, got {horizon}")
        if variant not in ("qlb", "cbm"):
            raise ValueError(f"crossing intention: variant must be 'qlb' or 'cbm', got {variant!r}")
        self.horizon = float(horizon)
        self.variant: Variant = variant
        self.config = config or IntentionConfig()
        self.spec = ForecastSpec(paths=False, intent=True, intent_bound=True)
        self._rates = look_rate_table(variant, self.config)
        self._red_rates = look_rate_table(variant, self.config, self.config.red_light_prior)
        self._calibration = tuple(shipped_weights()["calibration"][variant])
        self._bound = release_threshold("qlb" if variant == "qlb" else "classical")

    def reset(self, seed: int | None) -> None:
        """Nothing to reset: the estimate is a function of the current observation."""

    def forecast(self, inputs: ForecastInput) -> Forecast:
        """Both intent probabilities of every slot (0 for absent slots)."""
        if inputs.scene is None:
            raise ValueError(
                "crossing intention needs a crossing_env env (env.unwrapped.scenario) for the map"
            )
        # Both outputs share everything but the horizon (computed once: the forecaster runs every step).
        parts = _intention_parts(inputs.observation, inputs.scene, self.config, self._rates, self._red_rates)
        raw = _probability(parts, INTENT_HORIZON, False, self.config)
        return Forecast(
            intention=_probability(parts, self.horizon, True, self.config),
            intent=(platt(raw, self._calibration) * inputs.present).astype(np.float32),
            intent_bound=self._bound,
        )

    def kernel_to_compile(self) -> Callable[[], None] | None:
        """A call that compiles this model's kernel, where numba's on-disk cache lacks it (else None).

        `crossing_eval.tasks.warm_up` compiles it in a second process, beside the trajectory predictor's,
        while the env's kernels compile in the first.
        """
        return None if parts_kernel_is_cached() else compile_parts_kernel


def _check_space(env: gym.Env) -> None:
    space = env.observation_space
    needed = {PEDESTRIANS_KEY, VEHICLES_KEY, EGO_KEY}
    if not isinstance(space, spaces.Dict) or not needed <= set(space.spaces):
        raise ValueError(
            f"crossing intention needs a Dict observation with pedestrians/vehicles/ego, got {space}"
        )
    if getattr(env.unwrapped, "scenario", None) is None:
        raise ValueError(
            "crossing intention needs a crossing_env env (env.unwrapped.scenario) for the static map"
        )


class CrossingIntention(ForecastObservation):
    """Add ``crossing_intention`` and ``crossing_intent`` (K,): an `IntentionModel` in the one wrapper.

    Args:
        env: A ``crossing_env/Crossing-v0`` env (possibly wrapped).
        horizon: Seconds ahead.
        variant: ``"qlb"`` (quantum-like) or ``"cbm"`` (classical Bayesian model).
        config: Model parameters; defaults to `IntentionConfig()`.
    """

    def __init__(
        self,
        env: gym.Env,
        horizon: float = 2.0,
        variant: Variant = "qlb",
        config: IntentionConfig | None = None,
    ) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, horizon=horizon, variant=variant, config=config)
        model = IntentionModel(horizon, variant, config)
        _check_space(env)
        super().__init__(env, model, "qlb" if variant == "qlb" else "classical")
        self.horizon = model.horizon
        self.variant: Variant = variant
        self.config = model.config


class QLBIntention(CrossingIntention):
    """Quantum-like (QLB) crossing intention: the disjunction over "gap safe" with interference."""

    def __init__(self, env: gym.Env, horizon: float = 2.0, config: IntentionConfig | None = None) -> None:
        gym.utils.RecordConstructorArgs.__init__(
            self, horizon=horizon, config=config
        )  # first: it keeps the first call
        super().__init__(env, horizon=horizon, variant="qlb", config=config)


class ClassicalIntention(CrossingIntention):
    """Classical Bayesian (CBM) crossing intention: the same network without interference."""

    def __init__(self, env: gym.Env, horizon: float = 2.0, config: IntentionConfig | None = None) -> None:
        gym.utils.RecordConstructorArgs.__init__(
            self, horizon=horizon, config=config
        )  # first: it keeps the first call
        super().__init__(env, horizon=horizon, variant="cbm", config=config)
