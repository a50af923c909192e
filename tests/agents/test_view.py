"""The rules' helpers in `agents.view`: early returns and compiled kernels give what numpy gave."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np

from agents.config import YieldingConfig
from agents.view import (
    View,
    corridor_interval,
    follow,
    parse_observation,
    stop_acceleration,
    travel_time,
)
from crossing_env.observation import VehicleColumn


def _batch(speeds: list[float]) -> View:
    """A real observation's view repeated over a batch, one ego speed per element."""
    obs, _ = gym.make("crossing_env/Crossing-v0", scenario="zebra_case1").reset(seed=0)
    view = parse_observation(obs)
    b = len(speeds)
    return dataclasses.replace(
        view,
        lead=(b,),
        speed=np.asarray(speeds, dtype=np.float64),
        vehicles=np.repeat(view.vehicles, b, axis=0),
    )


def test_a_stop_target_at_infinity_gives_what_the_general_path_gives() -> None:
    view = _batch([10.0, 10.0, 0.0])
    cfg = YieldingConfig()
    args = (cfg.comfortable_deceleration, cfg.stop_gain, cfg.ego.max_deceleration)
    none = stop_acceleration(view, np.full(3, np.inf), *args)  # the early return
    mixed = stop_acceleration(view, np.array([np.inf, 12.0, np.inf]), *args)  # the general path
    assert none.shape == (3,) and none.dtype == np.float64
    np.testing.assert_array_equal(none[[0, 2]], mixed[[0, 2]])
    assert np.isposinf(none).all() and mixed[1] == -(10.0**2) / (2 * 12.0)


def test_following_nobody_gives_what_the_general_path_gives() -> None:
    view = _batch([10.0, 10.0])
    veh = np.zeros((2, 2, len(VehicleColumn)))
    veh[:, 0, VehicleColumn.PRESENCE] = 1.0
    veh[:, 0, VehicleColumn.DX] = -20.0  # behind the ego in both elements
    veh[:, 0, VehicleColumn.LENGTH] = 4.5
    cfg = YieldingConfig()
    nobody = follow(dataclasses.replace(view, vehicles=veh), cfg)  # the early return
    lead = veh.copy()
    lead[1, 1] = lead[1, 0]
    lead[1, 1, VehicleColumn.DX] = 30.0  # a leader ahead in the second element only
    general = follow(dataclasses.replace(view, vehicles=lead), cfg)
    assert nobody.shape == (2,) and np.isposinf(nobody).all()
    assert general[0] == nobody[0] and np.isfinite(general[1])


# The numpy forms the compiled kernels replaced, kept here as the reference they must match bit for bit.
def _travel_time_numpy(dist: np.ndarray, v: np.ndarray, accel: float, v_max: float) -> np.ndarray:
    d = np.maximum(dist, 0.0)
    v = np.broadcast_to(v, d.shape)
    with np.errstate(invalid="ignore"):  # inf - inf among the edge cases
        vm = np.maximum(v_max, v)
        t1 = (vm - v) / accel
        d1 = 0.5 * (v + vm) * t1
        t_acc = (-v + np.sqrt(v * v + 2.0 * accel * d)) / accel
        t_cru = t1 + (d - d1) / np.maximum(vm, 1e-6)
    return np.where(d <= d1, t_acc, t_cru)


def _corridor_numpy(py: np.ndarray, vy: np.ndarray, half_width: float) -> tuple[np.ndarray, np.ndarray]:
    inside = np.abs(py) <= half_width
    moving = np.abs(vy) > 1e-3
    with np.errstate(divide="ignore", invalid="ignore"):
        ta = (-half_width - py) / vy
        tb = (half_width - py) / vy
    t_in = np.where(moving, np.maximum(np.minimum(ta, tb), 0.0), np.where(inside, 0.0, np.inf))
    t_out = np.where(moving, np.maximum(ta, tb), np.where(inside, np.inf, -np.inf))
    never = t_out < t_in
    return np.where(never, np.inf, t_in), np.where(never, -np.inf, t_out)


def _stop_numpy(s: np.ndarray, v: np.ndarray, decel: float, gain: float, max_decel: float) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):  # inf - inf among the edge cases
        v_allow = np.sqrt(2.0 * decel * np.maximum(s, 0.0))
        a_req = np.where(s >= 0.0, v * v / (2.0 * np.maximum(s, 0.05)), np.where(v > 0.05, np.inf, 0.0))
        acc = np.where(a_req > decel, -a_req, gain * (v_allow - v))
    acc = np.where(np.isfinite(s), acc, np.inf)
    acc = np.where((s <= 0.3) & (v <= 0.1), -decel, acc)
    return np.maximum(acc, -max_decel)


def _same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and a.dtype == b.dtype and bool((a.view(np.int64) == b.view(np.int64)).all())


def _edge_values(rng: np.random.Generator, n: int, loc: float, scale: float) -> np.ndarray:
    """Random values with the edge cases mixed in: ±inf, NaN, ±0 and values at the kernels' thresholds."""
    x = rng.normal(loc, scale, n)
    edges = [np.inf, -np.inf, np.nan, 0.0, -0.0, 1e-3, -1e-3, 5e-4, 0.05, 0.1, 0.3, 1.65, -1.65]
    x[rng.choice(n, len(edges), replace=False)] = edges
    return x


def test_the_compiled_kernels_give_the_numpy_forms_bits() -> None:
    rng = np.random.default_rng(0)
    for _ in range(20):
        py, vy = _edge_values(rng, 400, 0.0, 4.0), _edge_values(rng, 400, 0.0, 1.5)
        vy[rng.random(400) < 0.3] = 0.0
        got = corridor_interval(py.reshape(20, 20), vy.reshape(20, 20), 1.65)
        for a, b in zip(got, _corridor_numpy(py.reshape(20, 20), vy.reshape(20, 20), 1.65), strict=True):
            assert _same_bits(a, b)
        dist = _edge_values(rng, 400, 20.0, 30.0).reshape(2, 20, 10)
        v = np.abs(_edge_values(rng, 20, 8.0, 5.0)).reshape(20, 1)
        assert _same_bits(travel_time(dist, v, 2.0, 13.9), _travel_time_numpy(dist, v, 2.0, 13.9))
        s, speed = _edge_values(rng, 400, 10.0, 20.0), np.abs(_edge_values(rng, 400, 6.0, 5.0))
        view = dataclasses.replace(_batch([0.0]), speed=speed)
        assert _same_bits(stop_acceleration(view, s, 2.5, 1.5, 8.0), _stop_numpy(s, speed, 2.5, 1.5, 8.0))


def test_the_kernels_match_numpy_on_every_pair_of_edge_values_and_on_exact_ties() -> None:
    # Values that must land together (s = 0.3 with v <= 0.1, s < 0 with v = 0.05) and exact ties of the
    # kernels' comparisons (a_req = decel, d = d1), which random draws almost never hit.
    edges = np.array([np.inf, -np.inf, np.nan, -np.nan, 0.0, -0.0, 0.04, 0.05, 0.06, 0.1, 0.3, 0.31])
    edges = np.concatenate([edges, -edges[4:], [1.0, 5.0, 13.9, 20.0, 1e-3, -1e-3, 1.65, -1.65]])
    a, b = (x.ravel() for x in np.meshgrid(edges, edges))
    view = dataclasses.replace(_batch([0.0]), speed=b)
    for decel, gain, max_decel in ((2.5, 1.5, 8.0), (2.0, 2.0, 6.0), (2.5, 1.5, np.nan)):
        got = stop_acceleration(view, a, decel, gain, max_decel)
        assert _same_bits(got, _stop_numpy(a, b, decel, gain, max_decel))
    ties = np.array([5.0, 4.0, np.sqrt(12.5)])  # v*v / (2*max(s, 0.05)) == 2.5 at s = 5, 3.2 and 2.5
    s_ties = np.array([5.0, 3.2, 2.5])
    view = dataclasses.replace(_batch([0.0]), speed=ties)
    want = _stop_numpy(s_ties, ties, 2.5, 1.5, 8.0)
    assert _same_bits(stop_acceleration(view, s_ties, 2.5, 1.5, 8.0), want)
    for py, vy in ((a, b), (b, a)):  # every edge value as position and as speed, against every other
        for got, want in zip(corridor_interval(py, vy, 1.65), _corridor_numpy(py, vy, 1.65), strict=True):
            assert _same_bits(got, want)
    # d exactly at the end of the acceleration phase (d = d1), from the same operations as the kernel.
    v = np.array([0.0, 3.0, 8.5, 13.0, 13.9, 15.0])
    vm = np.maximum(13.9, v)
    d1 = 0.5 * (v + vm) * ((vm - v) / 2.0)
    for d in (d1, np.nextafter(d1, np.inf), np.nextafter(d1, -np.inf), a[: v.size]):
        assert _same_bits(travel_time(d, v, 2.0, 13.9), _travel_time_numpy(d, v, 2.0, 13.9))
    dist, speed = a.reshape(-1, len(edges)), np.abs(b.reshape(-1, len(edges)))
    assert _same_bits(travel_time(dist, speed, 2.0, 13.9), _travel_time_numpy(dist, speed, 2.0, 13.9))
