"""Rolling the proposals out against the forecast hypotheses and scoring each by the expected episode score.

Each proposal is driven for the forecast's horizon at 0.1 s against each pedestrian hypothesis on its own
(one pedestrian at a time, so the cost is linear in the hypotheses, not exponential): the ego tracks the
proposal's target but, as every proposal of PDM-Closed follows its leader, brakes for the pedestrian in
its lane corridor ahead once a stop needs `comfortable_deceleration` (up to its `max_deceleration`) and
halts at the legal stop (before a pedestrian, `pedestrian_gap` short of them, as the rules stop). Per
hypothesis it records an at-fault collision (the ego's box and the pedestrian's disc overlap after the
pedestrian was in the corridor ahead: a pedestrian does not walk into the side of a passing car, and the
score does not blame the car for one who does), the least time to collision (gap / ego speed while the
pedestrian is in the corridor ahead), the hardest braking and the distance covered. The expectation over
hypotheses gives the terms of the episode score (`crossing_env.safety.score`):

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
    _, _, k, h, steps1, _ = hyp.points.shape
    plan = plan_index(speed, proposals, hyp, cfg)  # (B, P)
    pts = hyp.points[np.arange(b)[:, None], plan]  # (B, P, K, H, T + 1, 2)
    dt = hyp.interval / SUBSTEPS
    r = cfg.pedestrian_radius
    half_len = cfg.ego_length / 2 + r
    body = cfg.ego_width / 2 + r
    band = body + cfg.lateral_margin
    ok = present[:, None, :, None]
    cap = np.maximum(cfg.speed_limit, speed)[:, None, None, None]
    stop = np.asarray(halt, dtype=np.float64)[:, None, None, None]
    shape = (b, p, k, h)
    v = np.broadcast_to(speed[:, None, None, None], shape).astype(np.float64)
    s = np.zeros(shape)
    collision = np.zeros(shape, dtype=bool)
    met = np.zeros(shape, dtype=bool)
    least_ttc = np.full(shape, np.inf)
    hardest = np.zeros(shape)
    first = np.zeros((b, p))
    along = Proposals(target=proposals.target[:, None, None], braking=proposals.braking[:, None, None])
    for n in range(1, (steps1 - 1) * SUBSTEPS + 1):
        j, f = divmod(n - 1, SUBSTEPS)
        at = pts[..., j, :] + (f / SUBSTEPS) * (pts[..., j + 1, :] - pts[..., j, :])  # (B, P, K, H, 2)
        rel_x = at[..., 0] - s
        y = np.abs(at[..., 1])
        ahead = ok & (y <= band) & (rel_x > half_len)
        # At fault only: someone who was in the corridor ahead, not someone walking into the car's side.
        collision |= met & (y <= body) & (np.abs(rel_x) <= half_len)
        met |= ahead
        clear = rel_x - half_len
        gap = np.minimum(np.where(ahead, clear - cfg.pedestrian_gap, np.inf), stop - s)
        with np.errstate(divide="ignore", invalid="ignore"):
            need = np.where(gap > 0.05, v * v / (2.0 * np.maximum(gap, 0.05)), np.where(v > 0.0, np.inf, 0.0))
            ttc = np.where(ahead & (v > 0.1), clear / v, np.inf)
        least_ttc = np.minimum(least_ttc, ttc)
        track = command(v, along, cfg)
        acc = np.where(
            need >= cfg.comfortable_deceleration, -np.minimum(need, cfg.ego.max_deceleration), track
        )
        if n == 1:  # every hypothesis starts where the pedestrian is now: the same braking for all of them
            first = acc.min(axis=(2, 3))
        hardest = np.maximum(
            hardest, np.where(v > CREEP, -acc, 0.0)
        )  # the last creep into a stop is not braking
        nxt = np.clip(v + acc * dt, 0.0, cap)
        s = np.minimum(s + 0.5 * (v + nxt) * dt, np.maximum(stop, s))
        v = np.where(s >= stop, 0.0, nxt)
    w = hyp.weights[:, None]  # (B, 1, K, H)
    sc = cfg.score
    p_k = (w * collision).sum(axis=-1)  # (B, P, K)
    p_collision = 1.0 - np.prod(1.0 - p_k, axis=-1)
    horizon = (steps1 - 1) * hyp.interval
    covered = (w * s).sum(axis=-1).min(axis=-1)  # (B, P)
    progress = np.clip(covered / max(cfg.speed_limit * horizon, 1e-6), 0.0, 1.0)
    ttc_term = np.clip(least_ttc / sc.ttc_anchor, 0.0, 1.0)
    ttc = 1.0 - (w * (1.0 - ttc_term)).sum(axis=-1).max(axis=-1)
    span = sc.emergency_deceleration - sc.comfortable_deceleration
    comfort_term = np.clip((sc.emergency_deceleration - hardest) / span, 0.0, 1.0)
    comfort = 1.0 - (w * (1.0 - comfort_term)).sum(axis=-1).max(axis=-1)
    total = sc.progress_weight + sc.ttc_weight + sc.comfort_weight
    mean = (sc.progress_weight * progress + sc.ttc_weight * ttc + sc.comfort_weight * comfort) / total
    return Scores(score=(1.0 - p_collision) * mean, collision=p_collision, first=first)


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
