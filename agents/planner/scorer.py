"""Rolling the proposals out against the forecast hypotheses and scoring each by the expected episode score.

Each proposal is driven for the forecast's horizon at 0.1 s against each pedestrian hypothesis on its own
(one pedestrian at a time, so the cost is linear in the hypotheses, not exponential): the ego tracks the
proposal's target but, as every proposal of PDM-Closed follows its leader, brakes for the pedestrian in
its lane corridor ahead once a stop needs `comfortable_deceleration` (up to its `max_deceleration`) and
halts at the legal stop (before a pedestrian, `pedestrian_gap` short of them, as the rules stop). Per
hypothesis it records a collision (the ego's box and the pedestrian's disc overlap; under the step-off
hypothesis only once they were in the corridor ahead: someone who reacts to the car does not walk into the
side of one passing in front of them, whereas a forecast path is taken as it is), the least time to
collision (gap / closing speed while the pedestrian is in the corridor ahead), the hardest braking and the
distance covered. The expectation over hypotheses gives the terms of the episode score
(`crossing_env.safety.score`):

    expected score = (1 − P(collision)) · (w_p·progress + w_t·TTC + w_c·comfort) / (w_p + w_t + w_c)

with P(collision) = 1 − Π_k (1 − P_k) over pedestrians (independent), progress the distance covered
against the speed limit's over the horizon (the least over pedestrians: the one who holds the car most),
and the TTC and comfort terms (the episode's are its least TTC and hardest braking, one each) 1 less the
largest expected shortfall over pedestrians. The speed-limit term is 1 for every
proposal (none exceeds the limit) and is left out; the yield gate is a hard constraint (every proposal
halts at the legal stop), not a term.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from agents.config import PlannerConfig
from agents.planner.forecasts import Hypotheses
from agents.planner.proposals import Proposals, command

SUBSTEPS = 4
"""Ego integration steps per forecast interval (0.4 s / 4 = the env's 0.1 s)."""
CREEP = 0.5
"""Speed (m/s) below which the roll-out's braking does not count towards comfort: the last 0.1 s of a stop
at a point ends in a step the discrete roll-out cannot brake smoothly."""


class Scores(NamedTuple):
    """Per batch element and proposal."""

    score: np.ndarray
    """(B, P) expected score in [0, 1]."""
    collision: np.ndarray
    """(B, P) forecast probability of a collision."""
    first: np.ndarray
    """(B, P) the proposal's acceleration now (m/s²)."""


def plan_index(speed: np.ndarray, proposals: Proposals, hyp: Hypotheses, cfg: PlannerConfig) -> np.ndarray:
    """(B, P) the plan whose forecast each proposal is rolled against: nearest to its mean acceleration."""
    b, p = speed.shape[0], proposals.target.shape[0]
    if hyp.plan_accelerations is None:
        return np.zeros((b, p), dtype=np.int64)
    horizon = (hyp.points.shape[-2] - 1) * hyp.interval
    v = np.broadcast_to(speed[:, None], (b, p)).astype(np.float64)
    dt = hyp.interval / SUBSTEPS
    for _ in range(round(horizon / dt)):
        v = np.clip(v + command(v, proposals, cfg) * dt, 0.0, max(cfg.speed_limit, float(speed.max())))
    mean = (v - speed[:, None]) / horizon
    return np.argmin(np.abs(mean[..., None] - hyp.plan_accelerations), axis=-1)


def score_proposals(
    speed: np.ndarray,
    halt: np.ndarray,
    present: np.ndarray,
    proposals: Proposals,
    hyp: Hypotheses,
    cfg: PlannerConfig,
) -> Scores:
    """Roll every proposal against every hypothesis and score it (see the module docstring).

    `speed` (B,), `halt` (B,) the legal stop's distance ahead of the ego's front (inf: none), `present`
    (B, K) the pedestrian slots in use.
    """
    b, p = speed.shape[0], proposals.target.shape[0]
    h, steps1 = hyp.points.shape[3], hyp.points.shape[4]
    plan = plan_index(speed, proposals, hyp, cfg)  # (B, P)
    # Only pedestrians who can matter: present, and not behind the car in every forecast (it only goes on).
    half_len = cfg.ego_length / 2 + cfg.pedestrian_radius
    relevant = present & (hyp.points[..., 0].max(axis=(1, 3, 4)) > -half_len)  # (B, K)
    keep = relevant.any(axis=0)
    keep[0] |= not keep.any()  # one (empty) slot keeps the shapes: the proposals alone
    points = np.ascontiguousarray(hyp.points[:, :, keep], dtype=np.float64)
    w = hyp.weights[np.arange(b)[:, None], plan][:, :, keep]  # (B, P, K, H): each under its plan
    k = int(keep.sum())
    shape = (b, p, k, h)
    collision = np.zeros(shape, dtype=np.bool_)
    least_ttc = np.full(shape, np.inf)
    hardest = np.zeros(shape)
    distance = np.zeros(shape)
    first = np.zeros(shape)
    params = np.array(
        [
            hyp.interval / SUBSTEPS,
            half_len,
            cfg.ego_width / 2 + cfg.pedestrian_radius,
            cfg.lateral_margin,
            cfg.pedestrian_gap,
            cfg.comfortable_deceleration,
            cfg.ego.max_deceleration,
            cfg.speed_gain,
            cfg.go_acceleration,
            cfg.speed_limit,
            hyp.interval,
            cfg.clearance,
        ]
    )
    _rollout(
        points,
        plan.astype(np.int64),
        np.ascontiguousarray(relevant[:, keep]),
        hyp.reactive.astype(np.bool_),
        np.asarray(speed, dtype=np.float64),
        np.asarray(halt, dtype=np.float64),
        proposals.target.astype(np.float64),
        proposals.braking.astype(np.float64),
        params,
        collision,
        least_ttc,
        hardest,
        distance,
        first,
    )
    first = first.min(axis=(2, 3))  # every hypothesis starts where the pedestrian is now
    sc = cfg.score
    p_k = (w * collision).sum(axis=-1)  # (B, P, K)
    p_collision = 1.0 - np.prod(1.0 - p_k, axis=-1)
    horizon = (steps1 - 1) * hyp.interval
    covered = (w * distance).sum(axis=-1).min(axis=-1)  # (B, P): the pedestrian who holds the car most
    progress = covered / max(cfg.speed_limit * horizon, 1e-6)
    progress = np.clip(progress - _deferred_wait(hyp, plan, keep, covered, cfg) / horizon, 0.0, 1.0)
    ttc_term = np.clip(least_ttc / sc.ttc_anchor, 0.0, 1.0)
    ttc = 1.0 - (w * (1.0 - ttc_term)).sum(axis=-1).max(axis=-1)
    span = sc.emergency_deceleration - sc.comfortable_deceleration
    comfort_term = np.clip((sc.emergency_deceleration - hardest) / span, 0.0, 1.0)
    comfort = 1.0 - (w * (1.0 - comfort_term)).sum(axis=-1).max(axis=-1)
    total = sc.progress_weight + sc.ttc_weight + sc.comfort_weight
    mean = (sc.progress_weight * progress + sc.ttc_weight * ttc + sc.comfort_weight * comfort) / total
    return Scores(score=(1.0 - p_collision) * mean, collision=p_collision, first=first)


@njit(cache=True, nogil=True, error_model="numpy")
def _rollout(
    points: np.ndarray,
    plan: np.ndarray,
    present: np.ndarray,
    reactive: np.ndarray,
    speed: np.ndarray,
    halt: np.ndarray,
    target: np.ndarray,
    braking: np.ndarray,
    params: np.ndarray,
    collision: np.ndarray,
    least_ttc: np.ndarray,
    hardest: np.ndarray,
    covered: np.ndarray,
    first: np.ndarray,
) -> None:
    """Drive proposal p against hypothesis h of pedestrian k in batch element b (see the module docstring).

    `points` (B, C, K, H, T + 1, 2), `plan` (B, P) the forecast plan of each proposal, `present` (B, K),
    `reactive` (H) the hypotheses in which the pedestrian does not walk into the car's side;
    writes (B, P, K, H): `collision`, `least_ttc`, `hardest` braking, `covered` distance and
    `first` acceleration.
    """
    dt, half_len, body, margin, ped_gap, comfortable, max_dec, gain, go, limit, interval, room = params
    band = body + margin
    b_n, p_n = plan.shape
    k_n, h_n, steps = points.shape[2], points.shape[3], points.shape[4] - 1
    sub = SUBSTEPS
    for b in range(b_n):
        cap = max(limit, speed[b])
        stop = halt[b]
        for p in range(p_n):
            c = plan[b, p]
            full = braking[p] > comfortable
            for k in range(k_n):
                ok = present[b, k]
                for h in range(h_n):
                    v = speed[b]
                    s = 0.0
                    met = False
                    hit = False
                    ttc_min = np.inf
                    worst = 0.0
                    for n in range(steps * sub):
                        j = n // sub
                        f = (n % sub) / sub
                        x0 = points[b, c, k, h, j, 0]
                        y0 = points[b, c, k, h, j, 1]
                        dx = points[b, c, k, h, j + 1, 0] - x0
                        at_x = x0 + f * dx
                        y = abs(y0 + f * (points[b, c, k, h, j + 1, 1] - y0))
                        away = max(dx / interval, 0.0)
                        rel_x = at_x - s
                        ahead = ok and y <= band and rel_x > half_len
                        if (
                            ok
                            and (met or not reactive[h])
                            and y <= body
                            and abs(rel_x) <= half_len + (0.0 if reactive[h] else room)
                        ):
                            hit = True
                        met = met or ahead
                        clear = rel_x - half_len
                        to_stop = stop - s
                        gap = to_stop
                        lead = 0.0
                        if ahead and clear - ped_gap < gap:
                            gap = clear - ped_gap
                            lead = min(away, v)  # behind someone walking away: slow to their pace
                        if gap > 0.05:
                            need = (v * v - lead * lead) / (2.0 * gap)
                        elif v > lead:
                            need = np.inf
                        else:
                            need = 0.0
                        closing = v - (away if ahead else 0.0)
                        if ahead and closing > 0.1:
                            ttc_min = min(ttc_min, clear / closing)
                        if need >= comfortable:
                            acc = -min(need, max_dec)
                        elif full and v > 0.0:
                            acc = -braking[p]
                        else:
                            acc = min(max(gain * (target[p] - v), -braking[p]), go)
                        if n == 0:
                            first[b, p, k, h] = acc
                        if v > CREEP:  # the last creep into a stop is not braking
                            worst = max(worst, -acc)
                        nxt = min(max(v + acc * dt, 0.0), cap)
                        s = min(s + 0.5 * (v + nxt) * dt, max(stop, s))
                        v = 0.0 if s >= stop else nxt
                    collision[b, p, k, h] = hit
                    least_ttc[b, p, k, h] = ttc_min
                    hardest[b, p, k, h] = worst
                    covered[b, p, k, h] = s


def _deferred_wait(
    hyp: Hypotheses, plan: np.ndarray, keep: np.ndarray, covered: np.ndarray, cfg: PlannerConfig
) -> np.ndarray:
    """(B, P) seconds the car will still wait, after the horizon, for someone a proposal only defers.

    With plan-conditioned forecasts a pedestrian who waits for the car (a Euro NCAP dummy steps off when
    the car's time to arrive falls to a set value) crosses under a fast plan and stays on the kerb under a
    slow one: the slow plan's forecast is free of them, yet the crossing is still ahead of the car. A
    proposal whose plan keeps on the kerb, ahead of the car, someone whom another plan has crossing is
    charged the time they need to walk across its corridor at `assumed_walking_speed` (at most the
    horizon) less the time the car needs, at the limit, to drive from where the proposal leaves it
    (`covered`, (B, P)) to them: without it a car that re-plans every step keeps slowing and creeps up
    to a person who keeps waiting for it.
    """
    b, p = plan.shape
    if hyp.plan_accelerations is None or hyp.crossing.shape[1] < 2:
        return np.zeros((b, p))
    crossing = hyp.crossing[:, :, keep]  # (B, C, K)
    mine = crossing[np.arange(b)[:, None], plan]  # (B, P, K)
    elsewhere = crossing.max(axis=1, keepdims=True)  # (B, 1, K)
    now = hyp.points[:, 0, keep, 0, 0]  # (B, K, 2): where they are
    ahead = (now[..., 0] > cfg.ego_length / 2)[:, None]
    deferred = (mine < 0.5) & (elsewhere >= 0.5) & ahead
    band = cfg.ego_width / 2 + cfg.pedestrian_radius + cfg.lateral_margin
    horizon = (hyp.points.shape[-2] - 1) * hyp.interval
    walk = np.minimum((np.abs(now[..., 1]) + band) / cfg.assumed_walking_speed, horizon)[:, None]
    drive = np.maximum(now[..., 0][:, None] - cfg.ego_length / 2 - covered[..., None], 0.0) / cfg.speed_limit
    return np.where(deferred, np.maximum(walk - drive, 0.0), 0.0).max(axis=-1, initial=0.0)


def choose(scores: Scores, current: np.ndarray, cfg: PlannerConfig) -> np.ndarray:
    """Proposal index (B,): the best expected score among those meeting the chance constraint.

    Where none meets it, the least likely to collide (the best score among equals). The proposal followed
    last step (`current`, −1 for none) is kept unless another scores `switch_margin` more or it no longer
    meets the constraint.
    """
    feasible = scores.collision <= cfg.collision_chance
    any_ok = feasible.any(axis=1)
    ranked = np.where(feasible, scores.score, -np.inf)
    least = scores.collision.min(axis=1, keepdims=True)
    fallback = np.where(scores.collision <= least + 1e-9, scores.score, -np.inf)
    best = np.where(any_ok, np.argmax(ranked, axis=1), np.argmax(fallback, axis=1))
    rows = np.arange(best.shape[0])
    cur = np.maximum(current, 0)
    keep = (current >= 0) & any_ok & feasible[rows, cur]
    keep &= scores.score[rows, best] - scores.score[rows, cur] < cfg.switch_margin
    return np.where(keep, cur, best)
