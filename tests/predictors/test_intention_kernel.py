"""The crossing-intention kernel gives what its numpy form gave, to the last bit (sign of zero included)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from crossing_env.observation import (
    EGO_KEY,
    PEDESTRIANS_KEY,
    VEHICLES_KEY,
    EgoColumn,
    PedestrianColumn,
    VehicleColumn,
)
from predictors.forecast import SceneGeometry
from predictors.intention import (
    GAP_GRID,
    IntentionConfig,
    _intention_parts,
    _IntentionParts,
    look_rate_table,
)

REPO = Path(__file__).resolve().parents[2]


# The numpy form the kernel replaced, kept here as the reference.
def _numpy_parts(
    obs: dict[str, np.ndarray],
    road_map: SceneGeometry,
    config: IntentionConfig,
    rate_table: np.ndarray,
    red_rate_table: np.ndarray,
) -> _IntentionParts:
    """The numpy form `_intention_parts` had before its kernel: the reference it must match bit for bit."""
    c = config
    ped = obs[PEDESTRIANS_KEY].astype(np.float64)
    veh = obs[VEHICLES_KEY]
    ego = obs[EGO_KEY]
    present = ped[:, PedestrianColumn.PRESENCE] > 0.5
    dx, dy = ped[:, PedestrianColumn.DX], ped[:, PedestrianColumn.DY]
    vx, vy = ped[:, PedestrianColumn.VX], ped[:, PedestrianColumn.VY]
    on_road = ped[:, PedestrianColumn.ON_ROAD] > 0.5
    speed = max(float(ego[EgoColumn.SPEED]), 0.0)
    half_len = road_map.ego_length / 2

    # Time until the ego's rear passes the pedestrian's x (the event needs the pedestrian ahead of it).
    ahead = dx + half_len
    t_pass = np.where(ahead <= 0.0, 0.0, ahead / max(speed, 1e-3))

    # Where the pedestrian is relative to the nearer kerb and how fast it walks towards the road.
    south = dy < road_map.kerb_low
    kerb_dist = np.where(south, road_map.kerb_low - dy, dy - road_map.kerb_high)
    towards = np.where(south, vy, -vy)
    waiting = ped[:, PedestrianColumn.WAITING] > 0.5
    walking_in = (towards > c.towards_speed) & ~waiting
    # From the spot where it decides to the carriageway: the remaining distance, plus the start from rest.
    t_enter = np.where(waiting, np.maximum(kerb_dist, 0.0), c.kerb_standoff) / c.walking_speed + c.start_delay
    t_walk_in = np.maximum(kerb_dist - c.kerb_standoff, 0.0) / np.maximum(towards, c.towards_speed)
    # Walking along the sidewalk: to the crossing (if any) then to the kerb.
    to_stop_line = float(ego[EgoColumn.DISTANCE_TO_STOP_LINE])
    cross_dx = to_stop_line + road_map.crossing_offset - dx if road_map.has_crossing else np.zeros_like(dx)
    along = np.maximum(np.abs(cross_dx) - road_map.crossing_half_width, 0.0)
    t_along = (along + np.maximum(kerb_dist - c.kerb_standoff, 0.0)) / c.walking_speed
    t_kerb = np.where(waiting, 0.0, np.where(walking_in, t_walk_in, t_along))
    walking_away = (towards < -c.towards_speed) & ~waiting
    to_crossing = (vx * cross_dx > 0.0) | (along <= 1.0)
    p_along = np.where(to_crossing, c.intent_prior, c.intent_leaving_crossing)
    p_intent = np.where(
        waiting,
        c.intent_waiting,
        np.where(walking_in, c.intent_towards_road, np.where(walking_away, c.intent_away, p_along)),
    )

    # Gap at the moment the pedestrian would look: first approaching car to reach its x after t_kerb.
    # Cars as rows (dx, vx, length), the ego first; absent vehicle slots are all zeros, hence not moving.
    cars = np.empty((veh.shape[0] + 1, 3))
    cars[0] = (0.0, speed, road_map.ego_length)
    cars[1:] = veh[:, (VehicleColumn.DX, VehicleColumn.VX, VehicleColumn.LENGTH)]
    car_spd = np.abs(cars[:, 1])
    car_half = 0.5 * cars[:, 2]
    dist = (dx[:, None] - cars[:, 0]) * np.sign(cars[:, 1]) - car_half  # car front to the ped's line
    tta = np.where(dist >= 0.0, dist / np.maximum(car_spd, 0.3), -1.0)
    tta[(dist < 0.0) & (dist > -2.0 * car_half - 0.5)] = 0.0  # a car body covering the line
    tta -= t_kerb[:, None]
    tta[(tta < 0.0) | (car_spd <= 0.3)] = np.inf  # cars gone by the time it looks, or not moving
    gap = tta.min(axis=1)

    # Decision rate at that gap (tabulated: belief averaged over the unknown critical gap, then CBM or QLB).
    rate = np.interp(gap, GAP_GRID, rate_table)
    cars_green = ego[EgoColumn.CAR_GREEN] > 0.5
    if road_map.signalised and cars_green:  # cars green: pedestrians at the crossing face red
        at_crossing = np.abs(cross_dx) <= road_map.crossing_half_width + 1.0
        rate = np.where(at_crossing, np.interp(gap, GAP_GRID, red_rate_table), rate)
    return _IntentionParts(present, on_road, ahead, t_pass, t_kerb, t_enter, p_intent, rate)


def _observation(rng: np.random.Generator, k: int = 12, m: int = 6) -> dict[str, np.ndarray]:
    """A random observation with the awkward values: exact zeros of both signs, walkers, waiters, cars."""
    ped = rng.normal(0.0, 6.0, size=(k, len(PedestrianColumn))).astype(np.float32)
    ped[:, PedestrianColumn.PRESENCE] = rng.random(k) < 0.8
    ped[:, PedestrianColumn.WAITING] = rng.random(k) < 0.3
    ped[:, PedestrianColumn.ON_ROAD] = rng.random(k) < 0.3
    ped[:, PedestrianColumn.VX] = rng.choice([0.0, -0.0, 1.3, -1.3, 0.05], size=k)
    ped[:, PedestrianColumn.VY] = rng.choice([0.0, -0.0, 1.4, -1.4, 0.2], size=k)
    ped[rng.random(k) < 0.2, PedestrianColumn.DX] = 0.0
    veh = np.zeros((m, len(VehicleColumn)), dtype=np.float32)
    n = int(rng.integers(0, m + 1))
    veh[:n, VehicleColumn.PRESENCE] = 1.0
    veh[:n, VehicleColumn.DX] = rng.normal(0.0, 30.0, size=n)
    veh[:n, VehicleColumn.VX] = rng.choice([0.0, -0.0, 8.0, -8.0, 0.2], size=n)
    veh[:n, VehicleColumn.LENGTH] = 4.5
    ego = np.zeros(len(EgoColumn), dtype=np.float32)
    ego[EgoColumn.SPEED] = rng.choice([0.0, -0.0, 0.0005, 7.0, 13.9])
    ego[EgoColumn.DISTANCE_TO_STOP_LINE] = rng.normal(10.0, 20.0)
    ego[EgoColumn.CAR_GREEN] = rng.random() < 0.5
    return {PEDESTRIANS_KEY: ped, VEHICLES_KEY: veh, EGO_KEY: ego}


@pytest.mark.parametrize("signalised", [False, True])
@pytest.mark.parametrize("has_crossing", [False, True])
def test_the_kernel_gives_the_numpy_form_bit_for_bit(signalised: bool, has_crossing: bool) -> None:
    rng = np.random.default_rng(7)
    road = SceneGeometry(-3.5, 3.5, 4.5, 2.0, 2.0, signalised, has_crossing)
    config = IntentionConfig()
    rates = look_rate_table("qlb", config)
    red = look_rate_table("qlb", config, 0.2)
    assert GAP_GRID.size == rates.size
    for _ in range(300):
        obs = _observation(rng)
        got, want = (
            _intention_parts(obs, road, config, rates, red),
            _numpy_parts(obs, road, config, rates, red),
        )
        for name in _IntentionParts._fields:
            a, b = np.asarray(getattr(got, name)), np.asarray(getattr(want, name))
            assert a.dtype == b.dtype and a.tobytes() == b.tobytes(), name


COMPILE_ASIDE = """
from predictors.intention import compile_parts_kernel, parts_kernel_is_cached
from rollout import make_env
wrapper = make_env("zebra_case1", intention="qlb")[0]  # built, never stepped: no env kernel compiles
assert not parts_kernel_is_cached(), "the cache folder was not empty"
offer = wrapper.get_wrapper_attr("kernel_to_compile")()
assert offer is compile_parts_kernel, "nothing offered for compiling on an empty cache"
offer()
assert parts_kernel_is_cached(), "the compiled kernel is not in the cache"
assert wrapper.get_wrapper_attr("kernel_to_compile")() is None, "a cached kernel is offered again"
"""


def test_the_kernel_is_offered_for_compiling_aside_only_while_it_is_not_cached(
    run_with_empty_numba_cache: Callable[[str], None],
) -> None:
    """`crossing_eval.tasks.warm_up` compiles it aside on a fresh install, never again once cached."""
    run_with_empty_numba_cache(COMPILE_ASIDE)


def test_compiling_aside_gives_the_signature_a_real_episode_uses() -> None:
    """What the child compiles is what the wrapped steps call: they find it, they do not compile again."""
    from predictors import intention
    from rollout import make_env

    intention.compile_parts_kernel()
    env, _ = make_env("four_lane_arterial", intention="qlb")
    env.reset(seed=3)
    for _ in range(5):
        env.step(np.zeros(1, dtype=np.float32))
    assert len(intention._parts_kernel.signatures) == 1


def test_warm_up_compiles_what_every_wrapper_offers(monkeypatch: pytest.MonkeyPatch) -> None:
    from crossing_eval import tasks
    from rollout import make_env

    env, _ = make_env("zebra_case1", intention="qlb", predictor="s-cgru")
    called: list[str] = []
    monkeypatch.setattr("predictors.intention.parts_kernel_is_cached", lambda: False)
    monkeypatch.setattr("predictors.intention.compile_parts_kernel", lambda: called.append("intention"))
    monkeypatch.setattr(
        "predictors.trajectory_wrapper.PathModel.kernel_to_compile",
        lambda self: lambda: called.append("trajectory"),
    )
    compile_all = tasks._kernels_to_compile(env)
    assert compile_all is not None
    compile_all()
    assert sorted(called) == ["intention", "trajectory"]
    assert tasks._kernels_to_compile(make_env("zebra_case1")[0]) is None  # no wrapper, nothing aside
