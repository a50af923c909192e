"""Physics, social force and IDM unit tests, without the Gymnasium env."""

from __future__ import annotations

import numpy as np
import pytest

from crossing_env.pedestrians.social_force import model_parameters, social_force_acceleration, walk_step
from crossing_env.physics import PhysicsWorld
from crossing_env.traffic_kernels import idm_acceleration
from scenarios.config import IDMConfig, SocialForceConfig

NO_BOXES = np.zeros((0, 4))
FAR_KERBS = (-1000.0, -999.0)  # kerbs far away: no kerb force


@pytest.mark.parametrize("speed", [10.0, 20.0, 30.0])
def test_fast_car_hits_pedestrian_without_tunnelling(speed):
    """A car covering several metres per env step still registers the contact (substepping)."""
    world = PhysicsWorld(vehicle_capacity=1, pedestrian_capacity=1, vehicle_size=(4.5, 1.8))
    car = np.array([[0.0, 0.0]])
    ped = np.array([[25.0, 0.0]])
    dt = 0.1
    contacts = []
    for _ in range(40):
        car_vel = np.array([[speed, 0.0]])
        ped_pos, _, new = world.step(
            car, car_vel, np.array([True]), ped, np.zeros((1, 2)), np.array([True]), dt, 0.5
        )
        contacts += new
        car = car + car_vel * dt
        ped = ped_pos
        if contacts:
            break
    assert len(contacts) == 1
    assert contacts[0].relative_speed == pytest.approx(speed, rel=0.05)


def test_too_large_substeps_would_tunnel():
    """Control for the test above: without substepping (huge max displacement) the car passes through."""
    world = PhysicsWorld(vehicle_capacity=1, pedestrian_capacity=1, vehicle_size=(4.5, 1.8))
    _, _, contacts = world.step(
        np.array([[0.0, 0.0]]),
        np.array([[200.0, 0.0]]),
        np.array([True]),
        np.array([[50.0, 0.0]]),
        np.zeros((1, 2)),
        np.array([True]),
        0.5,
        1000.0,
    )
    assert contacts == []


def test_inactive_slots_do_not_collide():
    world = PhysicsWorld(vehicle_capacity=1, pedestrian_capacity=1, vehicle_size=(4.5, 1.8))
    _, _, contacts = world.step(
        np.array([[0.0, 0.0]]),
        np.array([[10.0, 0.0]]),
        np.array([True]),
        np.array([[1.0, 0.0]]),
        np.zeros((1, 2)),
        np.array([False]),
        0.1,
        0.5,
    )
    assert contacts == []


DEFAULT_SF = SocialForceConfig()


def limit_speed(velocities, max_speeds):
    """Scale (P, 2) velocities down to at most `max_speeds` (P,) m/s."""
    speed = np.linalg.norm(velocities, axis=1)
    return velocities * np.minimum(1.0, max_speeds / np.maximum(speed, 1e-9))[:, None]


def _walk(positions, goals, speeds, steps, dt=0.1, params=DEFAULT_SF):
    positions, velocities = positions.astype(float).copy(), np.zeros_like(positions, dtype=float)
    radii = np.full(len(positions), 0.3)
    min_dist = np.inf
    history = []
    for _ in range(steps):
        acc = social_force_acceleration(
            positions,
            velocities,
            goals,
            speeds,
            radii,
            np.zeros(len(positions), bool),
            NO_BOXES,
            FAR_KERBS,
            params,
        )
        velocities = limit_speed(velocities + acc * dt, speeds * params.max_speed_factor)
        positions = positions + velocities * dt
        history.append((positions.copy(), velocities.copy()))
        if len(positions) > 1:
            min_dist = min(min_dist, float(np.linalg.norm(positions[0] - positions[1])))
    return history, min_dist


def test_lone_pedestrian_reaches_goal_at_desired_speed():
    history, _ = _walk(np.array([[0.0, 0.0]]), np.array([[20.0, 0.0]]), np.array([1.4]), steps=200)
    speeds = [np.linalg.norm(v[0]) for _, v in history[20:100]]  # cruising part, after τ-relaxation
    assert np.mean(speeds) == pytest.approx(1.4, abs=0.03)
    final_pos = history[-1][0][0]
    assert np.linalg.norm(final_pos - [20.0, 0.0]) < 0.3


def test_two_pedestrians_walking_head_on_do_not_overlap():
    start = np.array([[0.0, 0.0], [10.0, 0.05]])
    goals = np.array([[10.0, 0.0], [0.0, 0.0]])
    history, min_dist = _walk(start, goals, np.array([1.3, 1.3]), steps=150)
    assert min_dist > 0.6  # sum of radii
    # ...and both still got past each other.
    final = history[-1][0]
    assert final[0, 0] > 8.0 and final[1, 0] < 2.0


def test_vehicle_repulsion_pushes_pedestrian_away_from_car():
    box = np.array([[-2.25, -0.9, 2.25, 0.9]])
    pos = np.array([[0.0, 1.5]])
    acc = social_force_acceleration(
        pos,
        np.zeros((1, 2)),
        pos.copy(),
        np.array([0.0]),
        np.array([0.3]),
        np.array([False]),
        box,
        FAR_KERBS,
        SocialForceConfig(),
    )
    assert acc[0, 1] > 0 and abs(acc[0, 0]) < 1e-9


def test_kerb_force_keeps_non_crossing_pedestrian_on_sidewalk():
    # Walking towards a goal on the road, but flagged to stay on the sidewalk (south kerb at y = 0).
    pos, vel = np.array([[0.0, -1.0]]), np.zeros((1, 2))
    params = SocialForceConfig()
    for _ in range(200):
        acc = social_force_acceleration(
            pos,
            vel,
            np.array([[0.0, 3.0]]),
            np.array([1.3]),
            np.array([0.3]),
            np.array([True]),
            NO_BOXES,
            (0.0, 7.0),
            params,
        )
        vel = limit_speed(vel + acc * 0.1, np.array([1.7]))
        pos = pos + vel * 0.1
    assert pos[0, 1] < 0.0


def test_idm_free_road_accelerates_and_stops_for_obstacle():
    p = IDMConfig()
    acc = idm_acceleration(np.array([5.0]), np.array([14.0]), np.array([np.inf]), np.array([0.0]), p)
    assert acc[0] == pytest.approx(p.max_acceleration * (1 - (5 / 14) ** 4))
    # Drive towards a stopped obstacle 80 m ahead: stops before it without contact.
    x, v = 0.0, 14.0
    for _ in range(600):
        a = idm_acceleration(np.array([v]), np.array([14.0]), np.array([80.0 - x]), np.array([0.0]), p)[0]
        v = max(0.0, v + a * 0.1)
        x += v * 0.1
    assert 0.0 < 80.0 - x <= p.min_gap + 0.5
    assert v < 0.05


def test_idm_follower_keeps_safe_gap_behind_braking_leader():
    p = IDMConfig()
    lead_x, lead_v, x, v = 40.0, 14.0, 0.0, 14.0
    min_gap = np.inf
    for step in range(400):
        lead_a = -4.0 if 20 <= step < 55 else 0.0  # the leader brakes hard to a stop
        lead_v = max(0.0, lead_v + lead_a * 0.1)
        lead_x += lead_v * 0.1
        a = idm_acceleration(
            np.array([v]), np.array([14.0]), np.array([lead_x - x - 4.5]), np.array([lead_v]), p
        )[0]
        v = max(0.0, v + a * 0.1)
        x += v * 0.1
        min_gap = min(min_gap, lead_x - x - 4.5)
    assert min_gap > 1.0
    assert lead_x - x - 4.5 == pytest.approx(p.min_gap, abs=0.5)  # settles at the jam distance


def test_idm_steady_state_gap_matches_theory():
    p = IDMConfig(delta=4.0)
    # In equilibrium behind a leader at speed v: s_e = (s0 + vT) / sqrt(1 − (v/v0)^δ)
    v, v0 = 10.0, 14.0
    s_e = (p.min_gap + v * p.time_headway) / np.sqrt(1 - (v / v0) ** 4)
    acc = idm_acceleration(np.array([v]), np.array([v0]), np.array([s_e]), np.array([v]), p)
    assert acc[0] == pytest.approx(0.0, abs=1e-9)


def _reference_social_force(pos, vel, goals, v0, radii, stay, boxes, kerbs, p, k_p):
    """Independent (P, P)-broadcast formulation of the module's equations, as an oracle for the kernel."""
    to_goal = goals - pos
    dist_goal = np.linalg.norm(to_goal, axis=1, keepdims=True)
    e = np.divide(to_goal, dist_goal, out=np.zeros_like(to_goal), where=dist_goal > 1e-6)
    acc = (v0[:, None] * np.minimum(1.0, dist_goal / 0.5) * e - vel) / p.relaxation_time
    speed = np.linalg.norm(vel, axis=1, keepdims=True)
    heading = np.where(speed > 0.05, vel / np.maximum(speed, 1e-9), e)

    def repulsion(diff, reach, scale):
        dist = np.linalg.norm(diff, axis=2)
        exponent = (reach - dist) / scale
        cos_phi = -np.einsum("ik,ijk->ij", heading, diff) / np.maximum(dist, 1e-9)
        w = p.anisotropy + (1 - p.anisotropy) * 0.5 * (1 + cos_phi)
        mag = np.where((exponent >= -30.0) & (dist > 1e-9), p.base_strength * np.exp(exponent), 0.0)
        return ((w * mag / np.maximum(dist, 1e-9))[:, :, None] * diff).sum(axis=1)

    diff = pos[:, None, :] - pos[None, :, :]
    diff[np.arange(len(pos)), np.arange(len(pos))] = 1e6  # no self-interaction
    acc += k_p[:, None] * repulsion(diff, radii[:, None] + radii[None, :], p.ped_range)
    nearest = np.clip(pos[:, None, :], boxes[None, :, :2], boxes[None, :, 2:])
    acc += p.vehicle_intensity * repulsion(pos[:, None, :] - nearest, radii[:, None], p.vehicle_range)
    south, north = kerbs
    below = pos[:, 1] < 0.5 * (south + north)
    d = np.where(below, south - (pos[:, 1] + radii), (pos[:, 1] - radii) - north)
    push = np.where(stay, np.minimum(p.kerb_strength * np.exp(np.maximum(-d / p.kerb_range, -30.0)), 50.0), 0)
    acc[:, 1] += np.where(below, -push, push)
    return acc


@pytest.mark.parametrize("count", [1, 2, 7, 40])
def test_compiled_social_force_matches_broadcast_formulation(count):
    rng = np.random.default_rng(count)
    pos = rng.uniform([0.0, -4.0], [15.0, 11.0], (count, 2))
    vel = rng.normal(0.0, 1.0, (count, 2))
    vel[0] = 0.01  # standing: heading falls back to the goal direction
    goals = rng.uniform([0.0, -4.0], [15.0, 11.0], (count, 2))
    v0, radii = rng.uniform(0.8, 1.6, count), rng.uniform(0.2, 0.3, count)
    stay, k_p = rng.random(count) < 0.5, rng.uniform(0.3, 0.6, count)
    boxes = np.array([[2.0, 1.0, 6.5, 2.8], [9.0, 4.5, 13.5, 6.3]])
    p = SocialForceConfig()
    got = social_force_acceleration(pos, vel, goals, v0, radii, stay, boxes, (0.0, 7.0), p, ped_intensity=k_p)
    want = _reference_social_force(pos, vel, goals, v0, radii, stay, boxes, (0.0, 7.0), p, k_p)
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9)
    assert np.abs(got).max() > 0.1  # the configuration exercises real forces


def test_walk_step_on_pool_rows_matches_gathered_acceleration_and_speed_limit():
    rng = np.random.default_rng(3)
    n = 12
    pos, vel = rng.uniform(0.0, 8.0, (n, 2)), rng.normal(0.0, 1.0, (n, 2))
    goals, v0 = rng.uniform(0.0, 8.0, (n, 2)), rng.uniform(0.0, 1.6, n)
    radii, stay, k_p = np.full(n, 0.3), rng.random(n) < 0.5, rng.uniform(0.3, 0.6, n)
    boxes = np.array([[2.0, 1.0, 6.5, 2.8]])
    rows = np.array([0, 2, 3, 7, 11])  # the other slots are free and must neither act nor move
    p = DEFAULT_SF
    acc = social_force_acceleration(
        pos[rows], vel[rows], goals[rows], v0[rows], radii[rows], stay[rows], boxes, (0.0, 7.0), p, k_p[rows]
    )
    want = vel.copy()
    want[rows] = limit_speed(vel[rows] + acc * 0.1, np.maximum(v0[rows], 0.05) * p.max_speed_factor)
    got = vel.copy()
    walk_step(rows, pos, got, goals, v0, radii, stay, boxes, 0.0, 7.0, k_p, 0.1, p.max_speed_factor,
              model_parameters(p))  # fmt: skip
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)
    assert not np.allclose(got[rows], vel[rows])
